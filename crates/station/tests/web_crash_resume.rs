//! A `serve` killed (SIGKILL) under a run: at the next
//! start the run is marked interrupted, History offers to resume it, and
//! the resumed run completes with its earlier steps kept. On SQLite and on
//! PostgreSQL.

#[path = "common/web.rs"]
mod web;

use std::time::{Duration, Instant};
use web::{Backend, Client, add_user, serve};

fn crashed_run_is_marked_interrupted_and_resumed_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "op", "operator", "op-password");
    add_user(dir.path(), "admin", "admin", "admin-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(
        dir.path().join("plans").join("crash.toml"),
        web::short_plan("crash", &["CR-1", "CR-2"]),
    )
    .expect("plan");
    let server = serve(dir.path(), "5");
    let mut op = Client::login(&server, "op", "op-password");
    let r = op.send("POST", "/api/runs", Some(r#"{"plan": "crash"}"#));
    assert_eq!(r.status, 201, "{:?}", r.json());
    let run_id = r.json()["run_id"].as_str().expect("id").to_string();
    // Past the tumble: some steps done.
    for _ in 0..3 {
        op.wait_status(120, |s| s["prompt"].is_string());
        op.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
    }
    op.wait_status(120, |s| s["points"].as_u64().is_some_and(|p| p >= 2));
    drop(server); // SIGKILL: no safe state, no record of the end.

    let server = serve(dir.path(), "0");
    let mut op = Client::login(&server, "op", "op-password");
    let runs = op.get_json("/api/runs", 200);
    let run = runs
        .as_array()
        .expect("runs")
        .iter()
        .find(|r| r["id"] == run_id.as_str())
        .expect("the run")
        .clone();
    assert_eq!(run["state"], "interrupted", "{run}");
    assert!(
        run["reason"].as_str().is_some_and(|r| r.contains("crash")),
        "{run}"
    );
    // The centrifuge overdue: a resume moves the table as a new run does,
    // so it passes the same gate: refused, an operator may not override,
    // an admin may with a reason, audited.
    let mut admin = Client::login(&server, "admin", "admin-password");
    let overdue = serde_json::json!({"identity": "C 1", "certificate": "K-1", "calibrated_on": "2020-01-01", "due_on": "2021-01-01"});
    let r = admin.send(
        "PUT",
        "/api/equipment/centrifuge",
        Some(&overdue.to_string()),
    );
    assert_eq!(r.status, 200, "{:?}", r.json());
    let resume = format!("/api/runs/{run_id}/resume");
    let r = op.send("POST", &resume, Some("null"));
    assert_eq!(r.status, 409, "{:?}", r.json());
    let with_reason = r#"{"override_overdue": "certificate renewal in the post"}"#;
    assert_eq!(op.send("POST", &resume, Some(with_reason)).status, 403);
    let r = admin.send("POST", &resume, Some(with_reason));
    assert_eq!(r.status, 201, "{:?}", r.json());
    let audit = admin.get_json("/api/audit", 200);
    assert!(
        audit.as_array().expect("a list").iter().any(|e| e["action"]
            == "override overdue calibration"
            && e["detail"]
                .as_str()
                .is_some_and(|d| d.contains("resumed") && d.contains("renewal"))),
        "{audit}"
    );
    let started = Instant::now();
    loop {
        let s = op.wait_status(300, |s| s["prompt"].is_string() || s["active"].is_null());
        if s["active"].is_null() {
            assert_eq!(s["state"], "completed", "{s}");
            break;
        }
        op.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
        assert!(started.elapsed() < Duration::from_secs(300));
    }
    let run = op.get_json(&format!("/api/runs/{run_id}"), 200);
    assert_eq!(run["state"], "completed", "{run}");
    // A completed run is not resumed again.
    let r = op.send("POST", &format!("/api/runs/{run_id}/resume"), None);
    assert_eq!(r.status, 409, "{:?}", r.json());
    // In the web's words: the run by its id, no command line, no path of
    // the server's.
    let said = r.json()["error"].as_str().unwrap_or_default().to_string();
    let data = dir.path().display().to_string();
    assert!(
        said.contains(&format!("run {run_id}"))
            && said.contains("already completed")
            && !said.contains("--resume")
            && !said.contains("spinbench ")
            && !said.contains(&data),
        "{said}"
    );
    // Nor a run of no such id.
    let r = op.send("POST", "/api/runs/..%2Fetc/resume", None);
    assert!(r.status == 404 || r.status == 400, "{}", r.status);
}

#[test]
fn sqlite_a_crashed_run_is_marked_interrupted_and_resumed_from_the_web() {
    crashed_run_is_marked_interrupted_and_resumed_on(Backend::Sqlite);
}

#[test]
fn postgres_a_crashed_run_is_marked_interrupted_and_resumed_from_the_web() {
    crashed_run_is_marked_interrupted_and_resumed_on(Backend::Postgres);
}
