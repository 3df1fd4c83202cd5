//! `GET /metrics`: the Prometheus text format, checked by
//! `promtool check metrics` (Debian's prometheus package, installed by
//! `scripts/test-tools`), with the station's state, the table's rate, the
//! run's progress, the live instruments, each slot's temperature, the
//! store's write latency, HTTP requests by route and status, and login
//! failures — before, during and after a run.

#[path = "common/web.rs"]
mod web;

use serde_json::json;
use std::io::Write;
use std::process::{Command, Stdio};
use web::{Backend, Client, add_user, serve};

/// `promtool check metrics` on `text`: its verdict and what it said.
fn promtool(text: &str) -> (bool, String) {
    let mut child = Command::new("promtool")
        .args(["check", "metrics"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("promtool (scripts/test-tools installs Debian's prometheus)");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(text.as_bytes())
        .expect("write");
    let out = child.wait_with_output().expect("promtool");
    (
        out.status.success(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
    )
}

/// A file of the shipped `packaging/` folder.
fn packaging(file: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../packaging")
        .join(file)
}

/// The `spinbench_…` metric names `text` reads.
fn metric_names(text: &str) -> std::collections::BTreeSet<String> {
    let mut names = std::collections::BTreeSet::new();
    let mut rest = text;
    while let Some(at) = rest.find("spinbench_") {
        let tail = &rest[at..];
        let end = tail
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(tail.len());
        names.insert(tail[..end].to_string());
        rest = &tail[end..];
    }
    names
}

#[test]
fn the_shipped_alert_rules_are_valid_and_fire_on_the_series_that_should_raise_them() {
    // promtool (Debian's prometheus, installed by scripts/test-tools).
    let rules = packaging("prometheus-alerts.yml");
    let out = Command::new("promtool")
        .arg("check")
        .arg("rules")
        .arg(&rules)
        .output()
        .expect("promtool (scripts/test-tools installs Debian's prometheus)");
    let said =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && said.contains("6 rules found"),
        "{said}"
    );
    let out = Command::new("promtool")
        .arg("test")
        .arg("rules")
        .arg(packaging("prometheus-alerts.test.yml"))
        .output()
        .expect("promtool");
    let said =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && said.contains("SUCCESS"), "{said}");
}

/// The value of the sample line starting with `series` (name and labels).
fn sample(text: &str, series: &str) -> Option<f64> {
    text.lines()
        .find(|l| l.starts_with(series) && l[series.len()..].starts_with(' '))
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|v| v.parse().ok())
}

#[test]
fn the_metrics_are_valid_prometheus_text_and_follow_a_run() {
    the_metrics_are_valid_prometheus_text_and_follow_a_run_on(Backend::Sqlite);
}

#[test]
fn postgres_the_metrics_are_valid_prometheus_text_and_follow_a_run() {
    the_metrics_are_valid_prometheus_text_and_follow_a_run_on(Backend::Postgres);
}

fn the_metrics_are_valid_prometheus_text_and_follow_a_run_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "op", "operator", "op-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(
        dir.path().join("plans").join("m.toml"),
        web::short_plan("metrics", &["M-1", "M-2"]),
    )
    .expect("plan");
    let server = serve(dir.path(), "0");
    let mut anon = Client::new(&server);
    let scrape = |c: &mut Client| -> String {
        let r = c.send("GET", "/metrics", None);
        assert_eq!(r.status, 200);
        assert!(
            r.content_type.starts_with("text/plain; version=0.0.4"),
            "{}",
            r.content_type
        );
        String::from_utf8(r.body).expect("utf-8")
    };

    // Idle, and a refused login counted.
    let bad = anon.send(
        "POST",
        "/api/login",
        Some(r#"{"user": "op", "password": "wrong-password"}"#),
    );
    assert_eq!(bad.status, 401);
    let idle = scrape(&mut anon);
    let (ok, said) = promtool(&idle);
    assert!(ok, "promtool: {said}\n{idle}");
    let mut served = idle.clone();
    assert_eq!(
        sample(&idle, "spinbench_station_state{state=\"idle\"}"),
        Some(1.0),
        "{idle}"
    );
    assert_eq!(sample(&idle, "spinbench_login_failures_total"), Some(1.0));
    // No run has read the table: its rate is not known (NaN), not 0.
    assert!(
        sample(&idle, "spinbench_table_rate_degrees_per_second").is_some_and(f64::is_nan),
        "{idle}"
    );
    assert_eq!(
        sample(
            &idle,
            "spinbench_http_requests_total{route=\"/api/login\",status=\"401\"}"
        ),
        Some(1.0),
        "{idle}"
    );

    // During a run: running, progress, the table turning at a level,
    // instruments live, slots' temperatures, the store's writes timed.
    let mut op = Client::login(&server, "op", "op-password");
    let r = op.send("POST", "/api/runs", Some(&json!({"plan": "m"}).to_string()));
    assert_eq!(r.status, 201, "{:?}", r.json());
    let mut seen_turning = false;
    let until = std::time::Instant::now() + std::time::Duration::from_secs(180);
    loop {
        let s = op.get_json("/api/status", 200);
        if s["active"].is_null() && s["state"] == "completed" {
            break;
        }
        let m = scrape(&mut anon);
        if sample(&m, "spinbench_table_rate_degrees_per_second").unwrap_or(0.0) > 10.0 {
            assert_eq!(
                sample(&m, "spinbench_station_state{state=\"running\"}"),
                Some(1.0),
                "{m}"
            );
            let p = sample(&m, "spinbench_run_progress_ratio").unwrap_or(-1.0);
            assert!(p > 0.0 && p <= 1.0, "{m}");
            assert_eq!(sample(&m, "spinbench_instruments_live"), Some(2.0), "{m}");
            assert!(
                m.contains("spinbench_slot_temperature_celsius{slot=\"1\"}"),
                "{m}"
            );
            let (ok, said) = promtool(&m);
            assert!(ok, "promtool: {said}\n{m}");
            served.push_str(&m);
            seen_turning = true;
        }
        if s["prompt"].is_string() {
            op.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
        }
        assert!(
            std::time::Instant::now() < until,
            "the run did not end in 180 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    assert!(seen_turning, "no scrape saw the table turning");
    std::thread::sleep(std::time::Duration::from_secs(3));
    let after = scrape(&mut anon);
    // Every metric the shipped dashboard and alert rules read is one the
    // station serves.
    for file in ["grafana-dashboard.json", "prometheus-alerts.yml"] {
        let text = std::fs::read_to_string(packaging(file)).expect("packaging file");
        let used = metric_names(&text);
        assert!(!used.is_empty(), "{file} reads no spinbench metric");
        for name in used {
            let family = name.trim_end_matches("_bucket");
            assert!(
                served.contains(&format!("# TYPE {family} ")),
                "{file} reads {name}, which /metrics does not serve"
            );
        }
    }
    let (ok, said) = promtool(&after);
    assert!(ok, "promtool: {said}\n{after}");
    assert_eq!(
        sample(&after, "spinbench_station_state{state=\"idle\"}"),
        Some(1.0),
        "{after}"
    );
    assert!(
        sample(&after, "spinbench_store_write_seconds_count").unwrap_or(0.0) >= 1.0,
        "{after}"
    );
    // After the run no instrument is live and no slot's
    // temperature is current.
    assert!(
        !after.contains("spinbench_slot_temperature_celsius{slot="),
        "{after}"
    );
    assert_eq!(
        sample(&after, "spinbench_instruments_live"),
        Some(0.0),
        "{after}"
    );
    assert!(
        sample(
            &after,
            "spinbench_http_requests_total{route=\"/api/status\",status=\"200\"}"
        )
        .unwrap_or(0.0)
            >= 1.0,
        "{after}"
    );
}
