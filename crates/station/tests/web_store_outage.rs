//! `spinbench serve` rides out its database: a PostgreSQL of
//! the test's own restarted under a run (the run completes with all its
//! points; logins and `/api/runs` answer within 15 s of the database's
//! return), and stalled (SIGSTOP) under a run (the abort reaches the safe
//! state within 10 s, store routes answer 503 with Retry-After, SIGTERM ends
//! the server in time).

#[path = "common/postgres.rs"]
mod postgres;
#[path = "common/web.rs"]
mod web;

use postgres::Cluster;
use std::time::{Duration, Instant};
use web::{Client, add_user, serve};

const PLAN: &str = "name = \"outage\"\nrange_g = 20\nlevels = [0, 1, 5, 10, 15, 20]\n\
                    passes = [\"P\"]\nwarmup_s = 0\ndwell = { seconds = 10 }\n\
                    stability = { hold_s = 3 }\n[serials]\n1 = \"WEB-1\"\n2 = \"WEB-2\"\n";

/// A server on its own PostgreSQL, an operator logged in, a run started
/// and its first prompts answered (it measures levels now).
fn running(db: &Cluster, data: &std::path::Path) -> (web::Server, Client) {
    std::fs::write(data.join("test-store-url"), &db.url).expect("the store's URL");
    add_user(data, "op", "operator", "op-password");
    std::fs::create_dir_all(data.join("plans")).expect("plans");
    std::fs::write(data.join("plans").join("outage.toml"), PLAN).expect("plan");
    let server = serve(data, "5");
    let mut op = Client::login(&server, "op", "op-password");
    let r = op.send("POST", "/api/runs", Some(r#"{"plan": "outage"}"#));
    assert_eq!(r.status, 201, "{:?}", r.json());
    // Tumble up, tumble down, mounting P: then the levels.
    for _ in 0..3 {
        op.wait_status(120, |s| s["prompt"].is_string());
        let r = op.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
        assert_eq!(r.status, 200, "{:?}", r.json());
    }
    op.wait_status(120, |s| {
        s["step"]["label"]
            .as_str()
            .is_some_and(|l| l.contains("5 g"))
    });
    (server, op)
}

/// Answer prompts until the run ends; its final status.
fn to_the_end(op: &mut Client) -> serde_json::Value {
    loop {
        let s = op.wait_status(300, |s| s["prompt"].is_string() || s["active"].is_null());
        if s["active"].is_null() {
            return s;
        }
        op.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
    }
}

#[test]
fn serve_rides_out_a_postgres_restart_under_a_run() {
    let Some(db) = Cluster::start() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let (server, mut op) = running(&db, dir.path());
    db.restart();
    let back = Instant::now();
    // The store's routes answer again by themselves.
    loop {
        let r = op.send("GET", "/api/runs", None);
        if r.status == 200 {
            break;
        }
        assert!(
            r.status == 503,
            "a store outage is a 503, not {}: {:?}",
            r.status,
            r.json()
        );
        assert!(
            back.elapsed() < Duration::from_secs(15),
            "/api/runs still {} {:?}",
            r.status,
            r.json()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    let runs_back_s = back.elapsed().as_secs_f64();
    let mut fresh = Client::new(&server).log_in("op", "op-password");
    assert!(back.elapsed() < Duration::from_secs(15));
    eprintln!(
        "restart: /api/runs answered 200 {runs_back_s:.1} s after the restart began, a login {:.1} s",
        back.elapsed().as_secs_f64()
    );
    let s = to_the_end(&mut op);
    assert_eq!(s["state"], "completed", "{s}");
    let runs = fresh.get_json("/api/runs", 200);
    let run = &runs.as_array().expect("runs")[0];
    assert_eq!(run["state"], "completed", "{run}");
    let store =
        spinbench_store::Store::connect(&spinbench_store::StoreTarget::Postgres(db.url.clone()))
            .expect("store");
    let id = store.runs().expect("runs")[0].id.clone();
    assert_eq!(store.results(&id).expect("results").len(), 2);
    // Six levels up, five down, two instruments.
    assert_eq!(store.points(&id).expect("points").len(), 22);
}

#[test]
fn serve_aborts_and_stops_with_its_postgres_stalled() {
    let Some(db) = Cluster::start() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let (mut server, mut op) = running(&db, dir.path());
    db.pause();
    // The status says the database does not answer (a stall fails no
    // write: it is seen as writes that do not come back).
    let s = op.wait_status(20, |s| s["store"]["up"] == false);
    assert!(s["store"]["queue_events"].as_u64().is_some(), "{s}");
    // A store route: 503 with Retry-After at its deadline, not a hang.
    let asked = Instant::now();
    let r = op.send("GET", "/api/runs", None);
    assert_eq!(r.status, 503, "{:?}", r.json());
    assert_eq!(r.retry_after.as_deref(), Some("5"));
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("database cannot answer")),
        "{:?}",
        r.json()
    );
    assert!(asked.elapsed() < Duration::from_secs(15));
    // The abort needs no database: applied, and the safe state reached.
    let asked = Instant::now();
    let asked_unix_s = spinbench_store::now_s();
    let r = op.send("POST", "/api/run/abort", None);
    assert_eq!(r.status, 200, "{:?}", r.json());
    let s = op.wait_status(10, |s| s["ended"] == true);
    assert_eq!(s["state"], "aborted", "{s}");
    assert!(
        asked.elapsed() < Duration::from_secs(10),
        "{:?}",
        asked.elapsed()
    );
    eprintln!(
        "stall: the abort's safe state done {:.1} s after it was asked",
        asked.elapsed().as_secs_f64()
    );
    // The stop was confirmed (read back) and nothing else left unsafe.
    let reason = s["reason"].as_str().unwrap_or_default();
    assert!(!reason.contains("making safe"), "{reason}");
    assert_eq!(s["demand_deg_s"], 0.0, "{s}");
    // The store back 8 s later: the abort's audit entry is written then,
    // dated when the abort was made, not when the store took it.
    std::thread::sleep(Duration::from_secs(8));
    db.resume();
    let target = spinbench_store::StoreTarget::Postgres(db.url.clone());
    let entry = (0..60)
        .find_map(|_| {
            let found = spinbench_store::Store::connect(&target)
                .ok()
                .and_then(|store| store.audit_log(50).ok())
                .and_then(|log| log.into_iter().find(|a| a.action == "abort"));
            if found.is_none() {
                std::thread::sleep(Duration::from_millis(500));
            }
            found
        })
        .expect("the abort's audit entry, once the store is back");
    assert!(
        (asked_unix_s - 1..=asked_unix_s + 2).contains(&entry.at),
        "abort asked at {asked_unix_s}, audited at {}",
        entry.at
    );
    db.pause();
    // SIGTERM: the server ends well inside the unit's 90 s.
    let signalled = Instant::now();
    server.terminate();
    let status = server.wait_exit(Duration::from_secs(60));
    assert!(
        status.is_some(),
        "serve alive {:?} after SIGTERM",
        signalled.elapsed()
    );
    eprintln!(
        "stall: serve exited {:.1} s after SIGTERM",
        signalled.elapsed().as_secs_f64()
    );
    // Back: the next start writes what the store had not taken.
    db.resume();
    let store =
        spinbench_store::Store::connect(&spinbench_store::StoreTarget::Postgres(db.url.clone()))
            .expect("store");
    let recovered =
        spinbench_station::recovery::recover(dir.path(), "spinbench virtual bench", &store);
    assert!(recovered.problems.is_empty(), "{recovered:?}");
    let runs = store.runs().expect("runs");
    assert_eq!(runs[0].state.as_str(), "aborted", "{:?}", runs[0]);
}
