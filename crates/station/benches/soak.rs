//! A long life: runs back to back through `spinbench
//! serve` on the virtual bench (fast-forwarded), on an SQLite file and on
//! PostgreSQL, with a browser's event stream open all along and the
//! operator's status polled throughout. Measured between the first tenth
//! of the runs and the last: the server's resident memory, its open file
//! descriptors, the p99 of `GET /api/status`, and the store's growth per
//! run. Prints `bench: <name> = <value> <unit>` lines and fails when the
//! memory, the descriptors or the latency climb, or the store grows faster
//! than the runs.
//!
//! Run: `cargo bench -p spinbench-station --bench soak` (100 runs per back
//! end; PostgreSQL from `SPINBENCH_TEST_POSTGRES`, as `scripts/test` starts
//! it, else SQLite only). Under `cargo test` it makes 2 runs on each.

use serde_json::{Value, json};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const PLAN: &str = "name = \"soak\"\nrange_g = 10\nlevels = [0, 1, 2, 4, 6, 8, 10]\npasses = [\"P\"]\n\
                    warmup_s = 0\ndwell = { seconds = 3 }\nstability = { hold_s = 3 }\n\
                    [serials]\n1 = \"SOAK-1\"\n2 = \"SOAK-2\"\n";

fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(30)))
        .build()
        .into()
}

/// A logged-in user of the server.
struct Session {
    base: String,
    cookie: String,
    csrf: String,
}

impl Session {
    fn login(base: &str) -> Session {
        let mut r = agent()
            .post(format!("{base}/api/login"))
            .send_json(json!({"user": "soak", "password": "soak-password"}))
            .expect("login");
        let cookie = r
            .headers()
            .get("set-cookie")
            .and_then(|v| v.to_str().ok())
            .and_then(|c| c.split(';').next())
            .expect("cookie")
            .to_string();
        let login: Value = r.body_mut().read_json().expect("json");
        Session {
            base: base.to_string(),
            cookie,
            csrf: login["csrf"].as_str().expect("csrf").to_string(),
        }
    }

    fn post(&self, path: &str, body: Value) -> (u16, Value) {
        let mut r = agent()
            .post(format!("{}{path}", self.base))
            .header("Cookie", &self.cookie)
            .header("X-CSRF-Token", &self.csrf)
            .send_json(&body)
            .expect("post");
        (
            r.status().as_u16(),
            r.body_mut().read_json().unwrap_or(Value::Null),
        )
    }

    /// `GET /api/status` and how long it took [ms].
    fn status(&self) -> (Value, f64) {
        let t0 = Instant::now();
        let v = agent()
            .get(format!("{}/api/status", self.base))
            .header("Cookie", &self.cookie)
            .call()
            .ok()
            .and_then(|mut r| r.body_mut().read_json().ok())
            .unwrap_or(Value::Null);
        (v, t0.elapsed().as_secs_f64() * 1000.0)
    }
}

/// `/proc/PID/status`'s VmRSS [MB].
fn rss_mb(pid: u32) -> f64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// Open file descriptors of a process.
fn fds(pid: u32) -> usize {
    std::fs::read_dir(format!("/proc/{pid}/fd")).map_or(0, |d| d.count())
}

/// The p99 of some latencies [ms].
fn p99(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(((v.len() as f64 * 0.99).ceil() as usize).saturating_sub(1))
        .copied()
        .unwrap_or(f64::NAN)
}

/// The store's size now [bytes]: the SQLite file with its log, or the
/// PostgreSQL database's.
fn store_bytes(db: &str) -> f64 {
    if db.starts_with("postgres") {
        postgres::Client::connect(db, postgres::NoTls)
            .ok()
            .and_then(|mut c| {
                c.query_one("SELECT pg_database_size(current_database())", &[])
                    .ok()
            })
            .map_or(f64::NAN, |r| r.get::<_, i64>(0) as f64)
    } else {
        ["", "-wal"]
            .iter()
            .map(|s| std::fs::metadata(format!("{db}{s}")).map_or(0, |m| m.len()) as f64)
            .sum()
    }
}

fn serve(data: &Path, db: &str) -> (Child, String) {
    let mut server = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args([
            "serve",
            "--simulate",
            "--sim-speed",
            "0",
            "--bind",
            "127.0.0.1:0",
            "--data",
        ])
        .arg(data)
        .args(["--db", db])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("serve");
    let mut lines = BufReader::new(server.stdout.take().expect("stdout")).lines();
    let base = loop {
        let line = lines.next().expect("the server's address").expect("line");
        if let Some(rest) = line.split("http://").nth(1) {
            break format!("http://{}", rest.split('/').next().expect("address"));
        }
    };
    std::thread::spawn(move || for _ in lines {});
    (server, base)
}

/// What one tenth of the soak looked like.
#[derive(Debug, Default, Clone)]
struct Window {
    rss_mb: f64,
    fds: usize,
    status_ms: Vec<f64>,
    store_bytes: f64,
}

fn soak(backend: &str, db: &str, data: &Path, runs: usize) {
    let add = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["user", "add", "soak", "--role", "operator", "--db", db])
        .env("SPINBENCH_PASSWORD", "soak-password")
        .output()
        .expect("user add");
    assert!(
        add.status.success(),
        "{}",
        String::from_utf8_lossy(&add.stderr)
    );
    std::fs::create_dir_all(data.join("plans")).expect("plans");
    std::fs::write(data.join("plans").join("soak.toml"), PLAN).expect("plan");
    let (server, base) = serve(data, db);
    let pid = server.id();
    // Stopped however the soak ends (a failed assertion included).
    struct Stop(Child);
    impl Drop for Stop {
        fn drop(&mut self) {
            let _ = Command::new("kill")
                .args(["-TERM", &self.0.id().to_string()])
                .status();
            let _ = self.0.wait();
        }
    }
    let _server = Stop(server);
    let session = Arc::new(Session::login(&base));
    // The browser: an event stream open all along, read and discarded.
    let stop = Arc::new(AtomicBool::new(false));
    let stream_events = Arc::new(Mutex::new(0usize));
    {
        let (session, stop, seen) = (session.clone(), stop.clone(), stream_events.clone());
        std::thread::spawn(move || {
            let streaming: ureq::Agent = ureq::Agent::config_builder()
                .http_status_as_error(false)
                .build()
                .into();
            let Ok(response) = streaming
                .get(format!("{}/api/events", session.base))
                .header("Cookie", &session.cookie)
                .call()
            else {
                return;
            };
            for line in BufReader::new(response.into_body().into_reader()).lines() {
                if stop.load(Ordering::Relaxed) || line.is_err() {
                    break;
                }
                if let Ok(mut n) = seen.lock() {
                    *n += 1;
                }
            }
        });
    }
    let tenth = (runs / 10).max(1);
    let mut windows: Vec<Window> = Vec::new();
    let mut window = Window::default();
    let start_bytes = store_bytes(db);
    let started = Instant::now();
    let mut completed = 0;
    for run in 0..runs {
        let (code, reply) = session.post("/api/runs", json!({"plan": "soak"}));
        assert_eq!(code, 201, "run {run}: {reply}");
        let until = Instant::now() + Duration::from_secs(300);
        loop {
            let (s, ms) = session.status();
            window.status_ms.push(ms);
            if s["active"].is_null() && s["state"].is_string() && s["run_id"].is_string() {
                if s["state"] == "completed" {
                    completed += 1;
                }
                break;
            }
            if s["prompt"].is_string() {
                session.post("/api/run/prompt", json!({"proceed": true}));
            }
            assert!(
                Instant::now() < until,
                "run {run} did not end in 300 s: {s}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        if (run + 1) % tenth == 0 {
            window.rss_mb = rss_mb(pid);
            window.fds = fds(pid);
            window.store_bytes = store_bytes(db);
            windows.push(std::mem::take(&mut window));
            eprintln!(
                "soak {backend}: {} runs in {:.0} s, {:.1} MB, {} fds",
                run + 1,
                started.elapsed().as_secs_f64(),
                rss_mb(pid),
                fds(pid)
            );
        }
    }
    stop.store(true, Ordering::Relaxed);
    assert_eq!(completed, runs, "every run completes");
    assert!(
        *stream_events.lock().expect("count") > runs,
        "the browser's event stream stayed open"
    );
    let (first, last) = (
        windows.first().cloned().unwrap_or_default(),
        windows.last().cloned().unwrap_or_default(),
    );
    let per_run = |from: f64, to: f64, n: usize| (to - from) / n.max(1) as f64 / 1024.0;
    let first_kb_per_run = per_run(start_bytes, first.store_bytes, tenth);
    let rest = runs.saturating_sub(tenth);
    let rest_kb_per_run = per_run(first.store_bytes, last.store_bytes, rest);
    println!("bench: soak_{backend}_runs = {runs} runs");
    println!(
        "bench: soak_{backend}_rss_first_tenth = {:.1} MB",
        first.rss_mb
    );
    println!(
        "bench: soak_{backend}_rss_last_tenth = {:.1} MB",
        last.rss_mb
    );
    println!("bench: soak_{backend}_fds_first_tenth = {} fds", first.fds);
    println!("bench: soak_{backend}_fds_last_tenth = {} fds", last.fds);
    println!(
        "bench: soak_{backend}_status_p99_first_tenth = {:.1} ms",
        p99(&first.status_ms)
    );
    println!(
        "bench: soak_{backend}_status_p99_last_tenth = {:.1} ms",
        p99(&last.status_ms)
    );
    println!("bench: soak_{backend}_store_first_tenth = {first_kb_per_run:.1} KiB/run");
    println!("bench: soak_{backend}_store_rest = {rest_kb_per_run:.1} KiB/run");
    if windows.len() >= 10 {
        // Flat: the memory within 30 MB, no descriptor more than a handful,
        // the latency within 3× (plus 20 ms of a busy machine), the store
        // growing per run within 2× of its first tenth's rate (PostgreSQL
        // grows in pages and extents: its rate is compared over the rest).
        assert!(
            last.rss_mb - first.rss_mb < 30.0,
            "{backend}: memory grew {:.1} → {:.1} MB",
            first.rss_mb,
            last.rss_mb
        );
        assert!(
            last.fds <= first.fds + 5,
            "{backend}: descriptors {} → {}",
            first.fds,
            last.fds
        );
        assert!(
            p99(&last.status_ms) < 3.0 * p99(&first.status_ms) + 20.0,
            "{backend}: status p99 {:.1} → {:.1} ms",
            p99(&first.status_ms),
            p99(&last.status_ms)
        );
        assert!(
            rest_kb_per_run < 2.0 * first_kb_per_run.max(16.0),
            "{backend}: the store grew {rest_kb_per_run:.1} KiB/run after {first_kb_per_run:.1} KiB/run"
        );
    }
}

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let runs = if measuring { 100 } else { 2 };
    let dir = tempfile::tempdir().expect("tempdir");
    let sqlite = dir.path().join("sqlite");
    std::fs::create_dir_all(&sqlite).expect("data");
    let db = sqlite.join("spinbench.db");
    soak("sqlite", db.to_str().expect("utf-8"), &sqlite, runs);
    match spinbench_store::testing::postgres_url() {
        Ok(admin) => {
            let url = spinbench_store::testing::fresh_postgres_database(&admin)
                .expect("a fresh PostgreSQL database");
            let pg = dir.path().join("postgres");
            std::fs::create_dir_all(&pg).expect("data");
            soak("postgres", &url, &pg, runs);
        }
        Err(why) => eprintln!("soak: PostgreSQL skipped: {why}"),
    }
}
