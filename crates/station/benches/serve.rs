//! The web server with 96 instruments streaming to 5 browsers:
//! `spinbench serve --simulate` (16 counter modules, real time) runs a test
//! started through the API (its prompts answered through the API too);
//! then the station process's CPU (server, engine and virtual bench
//! together) is measured with no browser connected and with 5 event
//! streams open, and each one-second event's latency from the hub to the
//! browser (`published_ms` in the event) is collected.
//! Prints `bench: <name> = <value> <unit>` lines.
//!
//! Run: `cargo bench -p spinbench-station --bench serve`

use serde_json::{Value, json};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

#[path = "common/cpu.rs"]
mod cpu;
use cpu::cpu_seconds;

fn spinbench() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spinbench"))
}

fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into()
}

struct Session {
    base: String,
    cookie: String,
    csrf: String,
}

impl Session {
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

    fn get(&self, path: &str) -> Value {
        agent()
            .get(format!("{}{path}", self.base))
            .header("Cookie", &self.cookie)
            .call()
            .expect("get")
            .body_mut()
            .read_json()
            .unwrap_or(Value::Null)
    }
}

fn now_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1000.0)
}

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let (modules, window_s) = if measuring { (16, 20.0) } else { (1, 3.0) };
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path();
    let add = spinbench()
        .args(["user", "add", "bench", "--role", "operator", "--db"])
        .arg(data.join("spinbench.db"))
        .env("SPINBENCH_PASSWORD", "bench-password")
        .output()
        .expect("user add");
    assert!(
        add.status.success(),
        "{}",
        String::from_utf8_lossy(&add.stderr)
    );
    std::fs::write(data.join("bench.toml"), format!("modules = {modules}\n"))
        .expect("bench config");
    std::fs::create_dir_all(data.join("plans")).expect("plans");
    let serials: String = (1..=modules * 6)
        .map(|i| format!("{i} = \"B{i:03}\"\n"))
        .collect();
    std::fs::write(
        data.join("plans").join("bench.toml"),
        format!(
            "range_g = 20\nlevels = [0, 1, 5, 10, 15, 20]\npasses = [\"P\"]\nwarmup_s = 0\n[serials]\n{serials}"
        ),
    )
    .expect("plan");
    let mut server = spinbench()
        .args([
            "serve",
            "--simulate",
            "--sim-speed",
            "1",
            "--bind",
            "127.0.0.1:0",
            "--data",
        ])
        .arg(data)
        .arg("--sim-config")
        .arg(data.join("bench.toml"))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("serve");
    let pid = server.id();
    let mut lines = BufReader::new(server.stdout.take().expect("stdout")).lines();
    let base = loop {
        let line = lines.next().expect("the server's address").expect("line");
        if let Some(rest) = line.split("http://").nth(1) {
            break format!("http://{}", rest.split('/').next().expect("address"));
        }
    };
    std::thread::spawn(move || for _ in lines {});

    let mut r = agent()
        .post(format!("{base}/api/login"))
        .send_json(json!({"user": "bench", "password": "bench-password"}))
        .expect("login");
    let cookie = r
        .headers()
        .get("set-cookie")
        .and_then(|v| v.to_str().ok())
        .and_then(|c| c.split(';').next())
        .expect("cookie")
        .to_string();
    let login: Value = r.body_mut().read_json().expect("json");
    let session = Arc::new(Session {
        base: base.clone(),
        cookie,
        csrf: login["csrf"].as_str().expect("csrf").to_string(),
    });
    let (status, reply) = session.post("/api/runs", json!({"plan": "bench"}));
    assert_eq!(status, 201, "{reply}");
    // The operator's hands: answer each prompt.
    let stop = Arc::new(AtomicBool::new(false));
    {
        let (session, stop) = (session.clone(), stop.clone());
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                if session.get("/api/status")["prompt"].is_string() {
                    session.post("/api/run/prompt", json!({"proceed": true}));
                }
                std::thread::sleep(Duration::from_millis(300));
            }
        });
    }
    // Let the run settle into streaming.
    std::thread::sleep(Duration::from_secs(if measuring { 8 } else { 2 }));

    let cpu = |seconds: f64| {
        let (c0, t0) = (cpu_seconds(&pid.to_string()), Instant::now());
        std::thread::sleep(Duration::from_secs_f64(seconds));
        (cpu_seconds(&pid.to_string()) - c0) / t0.elapsed().as_secs_f64() * 100.0
    };
    let idle_cpu = cpu(window_s);

    let latencies = Arc::new(Mutex::new(Vec::<f64>::new()));
    let values_seen = Arc::new(Mutex::new(vec![0usize; 5]));
    for k in 0..5 {
        let (session, latencies, seen, stop) = (
            session.clone(),
            latencies.clone(),
            values_seen.clone(),
            stop.clone(),
        );
        std::thread::spawn(move || {
            let response = agent()
                .get(format!("{}/api/events", session.base))
                .header("Cookie", &session.cookie)
                .call()
                .expect("events");
            let reader = BufReader::new(response.into_body().into_reader());
            // The catch-up backlog comes first; count only what is published from now on.
            let connected = now_ms();
            let mut kind = String::new();
            for line in reader.lines() {
                let Ok(line) = line else { break };
                if stop.load(Ordering::Relaxed) {
                    break;
                }
                if let Some(k) = line.strip_prefix("event:") {
                    kind = k.trim().to_string();
                } else if let Some(d) = line.strip_prefix("data:")
                    && kind == "values"
                    && let Ok(v) = serde_json::from_str::<Value>(d.trim())
                    && let Some(at) = v["published_ms"].as_f64()
                    && at >= connected
                {
                    let late = now_ms() - at;
                    latencies.lock().map(|mut l| l.push(late)).ok();
                    seen.lock().map(|mut s| s[k] += 1).ok();
                }
            }
        });
    }
    let streaming_cpu = cpu(window_s);
    stop.store(true, Ordering::Relaxed);
    let mut l = latencies.lock().map(|l| l.clone()).unwrap_or_default();
    let seen = values_seen.lock().map(|s| s.clone()).unwrap_or_default();
    let _ = server.kill();
    let _ = server.wait();
    l.sort_by(f64::total_cmp);
    let pick = |q: f64| {
        l.get(((l.len() as f64 - 1.0) * q).round() as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    let instruments = modules * 6;
    println!(
        "{instruments} instruments, real time; one-second events received per browser: {seen:?}"
    );
    assert!(
        seen.iter().all(|&n| n > 0),
        "every browser got one-second values"
    );
    if !measuring {
        println!("serve bench smoke run (no figures outside `cargo bench`)");
        return;
    }
    println!("bench: serve_process_cpu_{instruments}_instruments_no_browser = {idle_cpu:.1} %");
    println!(
        "bench: serve_process_cpu_{instruments}_instruments_5_browsers = {streaming_cpu:.1} %"
    );
    println!(
        "bench: serve_event_latency_p50_{instruments}_instruments_5_browsers = {:.1} ms",
        pick(0.5)
    );
    println!(
        "bench: serve_event_latency_p99_{instruments}_instruments_5_browsers = {:.1} ms",
        pick(0.99)
    );
    println!(
        "bench: serve_event_latency_max_{instruments}_instruments_5_browsers = {:.1} ms",
        pick(1.0)
    );
}
