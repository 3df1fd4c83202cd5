//! HTTP latency under load: 50 clients, each with its own
//! session, asking `GET /api/runs` of one `spinbench serve --simulate` over
//! a store of 200 runs, on SQLite and (when `SPINBENCH_TEST_POSTGRES` names
//! a server) on PostgreSQL — every store call goes through the handlers'
//! blocking boundary. Prints the p50 and p99 latency and the throughput as
//! `bench: <name> = <value> <unit>` lines.
//!
//! Run: `cargo bench -p spinbench-station --bench http_runs`

use spinbench_engine::TestPlan;
use spinbench_engine::event::{Event, EventSink};
use spinbench_engine::plan::CompiledPlan;
use spinbench_store::{Store, StoreTarget};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Instant;

/// Clients and runs when measuring (a smoke run under `cargo test` takes 3 and 20).
const CLIENTS: usize = 50;
const RUNS: usize = 200;

fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into()
}

/// `RUNS` finished runs of 12 instruments in the store.
fn fill(target: &StoreTarget, runs: usize) {
    let store = Store::connect(target).expect("store");
    let mut sink = store.sink().expect("sink");
    for r in 0..runs {
        let plan = CompiledPlan {
            plan: TestPlan::default(),
            serials: (0..12).map(|i| Some(format!("H{r:03}-{i:02}"))).collect(),
            passes: Vec::new(),
            steps: Vec::new(),
            order: Default::default(),
            table_prior: None,
        };
        sink.emit(&Event::RunStarted {
            run_id: format!("run-bench-{r:04}"),
            station: "bench".into(),
            plan: Box::new(plan),
            resumed: false,
            station_config: String::new(),
        })
        .expect("run started");
    }
}

fn measure(name: &str, db: &str, data: &std::path::Path, measuring: bool) {
    let (clients, runs, requests_each) = if measuring {
        (CLIENTS, RUNS, 40)
    } else {
        (3, 20, 2)
    };
    fill(&StoreTarget::parse(db), runs);
    let add = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["user", "add", "bench", "--role", "operator", "--db", db])
        .env("SPINBENCH_PASSWORD", "bench-password")
        .output()
        .expect("user add");
    assert!(
        add.status.success(),
        "{}",
        String::from_utf8_lossy(&add.stderr)
    );
    let mut server = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args([
            "serve",
            "--simulate",
            "--bind",
            "127.0.0.1:0",
            "--db",
            db,
            "--data",
        ])
        .arg(data)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("serve");
    let stdout = server.stdout.take().expect("stdout");
    let mut lines = BufReader::new(stdout).lines();
    let base = loop {
        let line = lines.next().expect("the server's address").expect("a line");
        if let Some(rest) = line.split("http://").nth(1) {
            break format!("http://{}", rest.split('/').next().unwrap_or(""));
        }
    };
    std::thread::spawn(move || for _ in lines {});
    let cookies: Vec<String> = (0..clients)
        .map(|_| {
            let r = agent()
                .post(format!("{base}/api/login"))
                .send_json(serde_json::json!({"user": "bench", "password": "bench-password"}))
                .expect("login");
            let cookie = r
                .headers()
                .get("set-cookie")
                .and_then(|v| v.to_str().ok())
                .unwrap_or("")
                .split(';')
                .next()
                .unwrap_or("")
                .to_string();
            assert!(!cookie.is_empty(), "login refused");
            cookie
        })
        .collect();
    let start = Instant::now();
    let threads: Vec<_> = cookies
        .into_iter()
        .map(|cookie| {
            let base = base.clone();
            std::thread::spawn(move || {
                let agent = agent();
                (0..requests_each)
                    .map(|_| {
                        let one = Instant::now();
                        let mut r = agent
                            .get(format!("{base}/api/runs"))
                            .header("Cookie", &cookie)
                            .call()
                            .expect("GET /api/runs");
                        assert_eq!(r.status().as_u16(), 200);
                        let body = r.body_mut().read_to_string().expect("body");
                        assert!(body.contains("run-bench-0000"));
                        one.elapsed().as_secs_f64()
                    })
                    .collect::<Vec<f64>>()
            })
        })
        .collect();
    let mut latencies: Vec<f64> = threads
        .into_iter()
        .flat_map(|t| t.join().expect("a client"))
        .collect();
    let elapsed = start.elapsed().as_secs_f64();
    let _ = server.kill();
    let _ = server.wait();
    latencies.sort_by(f64::total_cmp);
    let at = |q: f64| latencies[((latencies.len() as f64 * q) as usize).min(latencies.len() - 1)];
    if !measuring {
        println!(
            "http bench smoke run ({name}): {} requests answered (no figures outside `cargo bench`)",
            latencies.len()
        );
        return;
    }
    println!(
        "{name}: {} requests by {clients} clients over {runs} runs in {elapsed:.1} s",
        latencies.len()
    );
    println!("bench: http_runs_{name}_p50 = {:.1} ms", at(0.50) * 1e3);
    println!("bench: http_runs_{name}_p99 = {:.1} ms", at(0.99) * 1e3);
    println!(
        "bench: http_runs_{name}_throughput = {:.0} requests/s",
        latencies.len() as f64 / elapsed
    );
}

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let dir = tempfile::tempdir().expect("tempdir");
    let sqlite = dir.path().join("sqlite");
    std::fs::create_dir_all(&sqlite).expect("dir");
    let db = sqlite.join("spinbench.db");
    measure("sqlite", db.to_str().expect("utf-8"), &sqlite, measuring);
    match spinbench_store::testing::postgres_url() {
        Ok(admin) => {
            let url = spinbench_store::testing::fresh_postgres_database(&admin).expect("database");
            let pg = dir.path().join("pg");
            std::fs::create_dir_all(&pg).expect("dir");
            measure("postgres", &url, &pg, measuring);
        }
        Err(e) => println!("postgres: not measured: {e}"),
    }
}
