//! Webhooks, on SQLite and on PostgreSQL: a receiver written with Python's
//! own http.server and hmac (`scripts/mes/webhook_receiver.py`, not the
//! station's code) checks every delivery's signature and is down for the
//! first one; the station tries again, and the receiver gets the run's
//! start and end, each once delivered, in order; the deliveries are listed
//! for an admin and counted in `/metrics`. Bad webhook options stop
//! `serve` before anything starts.

#[path = "common/web.rs"]
mod web;

use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use web::{Backend, Client, add_user, serve_with};

#[test]
fn webhooks_reach_a_receiver_signed_retried_and_listed() {
    webhooks_on(Backend::Sqlite);
}

#[test]
fn postgres_webhooks_reach_a_receiver_signed_retried_and_listed() {
    webhooks_on(Backend::Postgres);
}

/// The receiver, killed when dropped.
struct Receiver {
    child: Child,
    url: String,
    log: PathBuf,
}

impl Drop for Receiver {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Receiver {
    /// Start it on a free loopback port, down for the first `fail_first`.
    fn start(dir: &Path, secret_file: &Path, fail_first: u32) -> Receiver {
        let script =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scripts/mes/webhook_receiver.py");
        let log = dir.join("received.jsonl");
        let mut child = Command::new("python3")
            .arg(script)
            .arg(secret_file)
            .arg(&log)
            .args(["--fail-first", &fail_first.to_string()])
            .stdout(Stdio::piped())
            .spawn()
            .expect("python3 (the webhook receiver)");
        let mut port = String::new();
        BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut port)
            .expect("the receiver's port");
        let port: u16 = port.trim().parse().expect("a port");
        Receiver {
            child,
            url: format!("http://127.0.0.1:{port}/spinbench/hook"),
            log,
        }
    }

    /// Every request it got, in order.
    fn received(&self) -> Vec<Value> {
        std::fs::read_to_string(&self.log)
            .unwrap_or_default()
            .lines()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect()
    }
}

fn webhooks_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "admin", "admin", "admin-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(
        dir.path().join("plans").join("hook.toml"),
        web::short_plan("hook", &["WH-1"]),
    )
    .expect("plan");
    let secret_file = dir.path().join("webhook-secret");
    std::fs::write(&secret_file, "a2f0c5d1e9b84c7d9e0f1a2b3c4d5e6f\n").expect("secret");
    let receiver = Receiver::start(dir.path(), &secret_file, 1);
    let secret_arg = secret_file.to_str().expect("UTF-8");
    let server = serve_with(
        dir.path(),
        "0",
        &[
            "--webhook-url",
            &receiver.url,
            "--webhook-secret-file",
            secret_arg,
        ],
    );
    let mut admin = Client::login(&server, "admin", "admin-password");
    let hooks = admin.get_json("/api/webhooks", 200);
    assert_eq!(hooks["url"], receiver.url.as_str(), "{hooks}");

    let r = admin.send(
        "POST",
        "/api/runs",
        Some(&serde_json::json!({"plan": "hook", "serials": {"1": "WH-1"}}).to_string()),
    );
    assert_eq!(r.status, 201, "{:?}", r.json());
    let run_id = r.json()["run_id"].as_str().expect("run id").to_string();
    assert!(admin.answer_prompts_until_end(&run_id) >= 3);

    // The receiver gets the end (after the start's back-off).
    let until = std::time::Instant::now() + std::time::Duration::from_secs(30);
    let got = loop {
        let got = receiver.received();
        if got
            .iter()
            .any(|g| g["event"] == "run.ended" && g["answered"] == 204)
        {
            break got;
        }
        assert!(
            std::time::Instant::now() < until,
            "no run.ended delivered in 30 s: {got:?}"
        );
        std::thread::sleep(std::time::Duration::from_millis(100));
    };
    assert!(
        got.iter().all(|g| g["signature_valid"] == true),
        "every signature holds under Python's hmac: {got:?}"
    );
    assert!(got.iter().all(|g| g["content_type"] == "application/json"));
    let events: Vec<(&str, i64)> = got
        .iter()
        .map(|g| {
            (
                g["event"].as_str().unwrap_or(""),
                g["answered"].as_i64().unwrap_or(0),
            )
        })
        .collect();
    assert_eq!(
        events,
        [
            ("run.started", 503),
            ("run.started", 204),
            ("run.ended", 204)
        ],
        "the start tried again after the receiver was down, then the end, in order"
    );
    assert_eq!(got[0]["delivery"], got[1]["delivery"], "the same delivery");
    assert_ne!(got[1]["delivery"], got[2]["delivery"]);
    let started = &got[1]["body"];
    assert_eq!(started["run_id"], run_id.as_str(), "{started}");
    assert_eq!(started["plan"], "hook", "{started}");
    assert_eq!(started["operator"], "admin", "{started}");
    assert_eq!(started["delivery"], got[1]["delivery"]);
    let ended = &got[2]["body"];
    assert_eq!(ended["state"], "completed", "{ended}");
    assert_eq!(ended["run"], format!("/api/runs/{run_id}"));
    let outcome = ended["outcomes"]["WH-1"].as_str().unwrap_or("");
    assert!(
        ["pass", "marginal", "fail", "inconclusive"].contains(&outcome),
        "{ended}"
    );
    // What the webhook says is what the store says.
    let run = admin.get_json(&format!("/api/runs/{run_id}"), 200);
    assert_eq!(run["state"], "completed");
    assert!(
        run["results"]
            .as_array()
            .is_some_and(|r| r.iter().any(|u| u["outcome"] == outcome)),
        "{run}"
    );

    // Listed for the admin, newest first; counted for the monitoring.
    let hooks = admin.get_json("/api/webhooks", 200);
    web::matches_document(&mut admin, "WebhooksReply", &hooks, "GET /api/webhooks");
    let listed: Vec<(String, String, i64)> = hooks["deliveries"]
        .as_array()
        .expect("deliveries")
        .iter()
        .map(|d| {
            (
                d["event"].as_str().unwrap_or("").to_string(),
                d["state"].as_str().unwrap_or("").to_string(),
                d["attempts"].as_i64().unwrap_or(0),
            )
        })
        .collect();
    assert_eq!(
        listed,
        [
            ("run.ended".to_string(), "delivered".to_string(), 1),
            ("run.started".to_string(), "delivered".to_string(), 2),
        ],
        "{hooks}"
    );
    let metrics = String::from_utf8(admin.send("GET", "/metrics", None).body).expect("utf-8");
    for line in [
        "spinbench_webhook_deliveries_total{result=\"delivered\"} 2",
        "spinbench_webhook_failed_attempts_total 1",
        "spinbench_webhook_waiting 0",
    ] {
        assert!(metrics.lines().any(|l| l == line), "{line} in:\n{metrics}");
    }
    // An operator does not see them.
    add_user(dir.path(), "op", "operator", "op-password");
    let mut op = Client::login(&server, "op", "op-password");
    assert_eq!(op.send("GET", "/api/webhooks", None).status, 403);
}

#[test]
fn bad_webhook_options_stop_serve_before_it_starts() {
    let dir = tempfile::tempdir().expect("tempdir");
    let good = dir.path().join("secret");
    std::fs::write(&good, "0123456789abcdef0123").expect("secret");
    let short = dir.path().join("short");
    std::fs::write(&short, "too-short\n").expect("secret");
    let missing = dir.path().join("missing");
    let data = dir.path().join("data");
    for (url, file, said) in [
        ("ftp://mes/hook", &good, "--webhook-url"),
        ("http://", &good, "--webhook-url"),
        ("http://mes/ hook", &good, "--webhook-url"),
        ("http://mes/hook", &short, "9 bytes"),
        ("http://mes/hook", &missing, "cannot read"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
            .args(["serve", "--simulate", "--bind", "127.0.0.1:0", "--data"])
            .arg(&data)
            .args(["--webhook-url", url, "--webhook-secret-file"])
            .arg(file)
            .output()
            .expect("spinbench serve");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{url}: {err}");
        assert!(err.contains(said), "{url}: {err}");
        assert!(
            !data.exists(),
            "nothing made before the options are checked"
        );
    }
    // One without the other is refused by the parser.
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["serve", "--simulate", "--webhook-url", "http://mes/hook"])
        .output()
        .expect("spinbench serve");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--webhook-secret-file"));
}

#[test]
fn the_openapi_document_describes_the_webhook() {
    let doc: Value =
        serde_json::from_str(spinbench_station::web::openapi()).expect("the document is JSON");
    let hook = &doc["webhooks"]["runEvent"]["post"];
    let body = &hook["requestBody"]["content"]["application/json"]["schema"];
    assert_eq!(
        body["properties"]["event"]["enum"],
        serde_json::json!(["run.started", "run.ended", "run.faulted"])
    );
    // Every $ref of it resolves in the document.
    for reference in ["LiveRunState", "OutcomeName"] {
        assert!(
            doc["components"]["schemas"].get(reference).is_some(),
            "{reference}"
        );
    }
    let headers: Vec<&str> = hook["parameters"]
        .as_array()
        .expect("headers")
        .iter()
        .filter_map(|p| p["name"].as_str())
        .collect();
    assert_eq!(
        headers,
        [
            "X-Spinbench-Event",
            "X-Spinbench-Delivery",
            "X-Spinbench-Timestamp",
            "X-Spinbench-Signature"
        ]
    );
}
