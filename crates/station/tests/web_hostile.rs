//! `spinbench serve` on a plant network, tried as an attacker would:
//! failed logins bounded, throttled and audited; slow, idle and surplus
//! connections closed; and a SIGTERM while a run spins and a browser holds
//! the event stream stops the run first, then the streams, in bounded time.

#[path = "common/web.rs"]
mod web;

use serde_json::{Value, json};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};
use web::{Backend, Client, add_user, serve, serve_with};

fn login_body(user: &str, password: &str) -> String {
    json!({"user": user, "password": password}).to_string()
}

#[test]
fn failed_logins_are_bounded_throttled_and_audited() {
    let dir = tempfile::tempdir().expect("tempdir");
    add_user(dir.path(), "admin", "admin", "admin-password");
    add_user(dir.path(), "ana", "admin", "ana-password");
    let server = serve(dir.path(), "0");
    let mut anon = Client::new(&server);
    let db = dir.path().join("spinbench.db");
    let size = |p: &std::path::Path| {
        ["", "-wal"]
            .iter()
            .map(|s| std::fs::metadata(format!("{}{s}", p.display())).map_or(0, |m| m.len()))
            .sum::<u64>()
    };
    let before = size(&db);
    // Huge names: refused before anything is stored.
    let huge = login_body(&"x".repeat(1_900_000), "whatever");
    let addr = server.base.trim_start_matches("http://").to_string();
    for _ in 0..20 {
        // The server answers 413 and closes before the body is all sent.
        let status = post_raw(&addr, "/api/login", &huge);
        assert!(
            status.is_none_or(|s| s == 413 || s == 400),
            "status {status:?}"
        );
    }
    // A name that fits the body limit but cannot be a user's: a short prefix only.
    let long = "y".repeat(3_000);
    let r = anon.send("POST", "/api/login", Some(&login_body(&long, "whatever")));
    assert_eq!(r.status, 401);
    assert!(
        size(&db) < before + 200_000,
        "the store grew by {} bytes",
        size(&db) - before
    );
    // Guessing a password: locked after five failures, with Retry-After.
    for i in 0..5 {
        let r = anon.send("POST", "/api/login", Some(&login_body("admin", "guess")));
        assert_eq!(r.status, 401, "guess {i}");
    }
    let r = anon.send(
        "POST",
        "/api/login",
        Some(&login_body("admin", "admin-password")),
    );
    assert_eq!(r.status, 429, "{:?}", r.json());
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("try again")),
        "{:?}",
        r.json()
    );
    // Others still log in from the same address.
    let mut ana = Client::login(&server, "ana", "ana-password");
    let audit = ana.get_json("/api/audit", 200);
    let rows = audit.as_array().expect("audit rows");
    assert!(
        rows.iter().any(|r| r["action"] == "login locked"),
        "{audit}"
    );
    for r in rows {
        let who = r["who"].as_str().unwrap_or_default();
        assert!(who.len() < 200, "an audit entry of {} bytes", who.len());
    }
}

#[test]
fn the_retry_after_header_is_sent_with_429() {
    the_retry_after_header_is_sent_with_429_on(Backend::Sqlite);
}

#[test]
fn postgres_the_retry_after_header_is_sent_with_429() {
    the_retry_after_header_is_sent_with_429_on(Backend::Postgres);
}

fn the_retry_after_header_is_sent_with_429_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "admin", "admin", "admin-password");
    let server = serve(dir.path(), "0");
    for _ in 0..5 {
        let mut c = Client::new(&server);
        c.send("POST", "/api/login", Some(&login_body("admin", "guess")));
    }
    let mut stream = TcpStream::connect(server.base.trim_start_matches("http://")).expect("tcp");
    let body = login_body("admin", "guess");
    write!(
        stream,
        "POST /api/login HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
    .expect("send");
    let mut reply = String::new();
    stream.read_to_string(&mut reply).expect("reply");
    assert!(reply.starts_with("HTTP/1.1 429"), "{reply}");
    let retry = reply
        .lines()
        .find_map(|l| {
            l.to_ascii_lowercase()
                .strip_prefix("retry-after: ")
                .map(str::to_string)
        })
        .expect("Retry-After");
    assert!(
        retry
            .trim()
            .parse::<u64>()
            .is_ok_and(|s| (1..=60).contains(&s)),
        "{retry}"
    );
}

/// POST `body` on a connection of its own; the status, if an answer came.
fn post_raw(addr: &str, path: &str, body: &str) -> Option<u16> {
    let mut stream = TcpStream::connect(addr).expect("connect");
    let _ = stream.set_read_timeout(Some(Duration::from_secs(10)));
    let _ = write!(
        stream,
        "POST {path} HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    let _ = stream.write_all(body.as_bytes());
    let mut reply = Vec::new();
    let _ = stream.read_to_end(&mut reply);
    let text = String::from_utf8_lossy(&reply);
    text.split(' ').nth(1).and_then(|s| s.parse().ok())
}

/// True when the server closed the connection within `limit`.
fn closed_within(stream: &mut TcpStream, limit: Duration) -> bool {
    let until = Instant::now() + limit;
    let mut buf = [0u8; 4096];
    let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
    while Instant::now() < until {
        match stream.read(&mut buf) {
            Ok(0) => return true,
            // A 408 or similar before the close is fine; keep reading.
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(_) => return true,
        }
    }
    false
}

#[test]
fn slow_idle_and_surplus_connections_are_closed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = serve_with(
        dir.path(),
        "0",
        &[
            "--header-timeout-s",
            "1",
            "--idle-timeout-s",
            "2",
            "--max-connections",
            "40",
        ],
    );
    let addr = server.base.trim_start_matches("http://").to_string();
    let mut slow = Vec::new();
    let mut idle = Vec::new();
    for _ in 0..15 {
        let mut s = TcpStream::connect(&addr).expect("connect");
        s.write_all(b"GET /api/status HTTP/1.1\r\nHost: x\r\n")
            .expect("half a header");
        slow.push(s);
        idle.push(TcpStream::connect(&addr).expect("connect"));
    }
    // Over the cap: the newest are served, the oldest closed to make room
    // (a new client is never locked out).
    let mut surplus: Vec<TcpStream> = (0..20)
        .map(|_| TcpStream::connect(&addr).expect("connect"))
        .collect();
    let mut closed_oldest = 0;
    for s in slow.iter_mut().take(5).chain(idle.iter_mut().take(5)) {
        if closed_within(s, Duration::from_millis(500)) {
            closed_oldest += 1;
        }
    }
    assert_eq!(
        closed_oldest, 10,
        "the 10 oldest connections were not closed at once"
    );
    for (i, s) in surplus.iter_mut().enumerate() {
        s.write_all(b"GET /api/openapi.json HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
            .expect("a request");
        let mut reply = Vec::new();
        let _ = s.set_read_timeout(Some(Duration::from_secs(5)));
        let _ = s.read_to_end(&mut reply);
        assert!(
            reply.starts_with(b"HTTP/1.1 200"),
            "surplus connection {i} not served"
        );
    }
    for (i, s) in slow.iter_mut().enumerate() {
        assert!(
            closed_within(s, Duration::from_secs(5)),
            "slow-header connection {i} still open"
        );
    }
    for (i, s) in idle.iter_mut().enumerate() {
        assert!(
            closed_within(s, Duration::from_secs(5)),
            "idle connection {i} still open"
        );
    }
    // The server still serves.
    let mut c = Client::new(&server);
    assert_eq!(c.send("GET", "/api/openapi.json", None).status, 200);
}

#[test]
fn trickling_request_bodies_lock_no_one_out() {
    // 260 connections each send a login's headers with
    // Content-Length: 4000 and then one byte; a new client is still served
    // within 5 s, and a trickling body is cut off at the body deadline.
    let dir = tempfile::tempdir().expect("tempdir");
    let server = serve(dir.path(), "0");
    let addr = server.base.trim_start_matches("http://").to_string();
    let mut held: Vec<TcpStream> = Vec::new();
    for _ in 0..260 {
        let Ok(mut s) = TcpStream::connect(&addr) else {
            continue;
        };
        let _ = s.write_all(
            b"POST /api/login HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 4000\r\n\r\n{",
        );
        held.push(s);
    }
    let asked = Instant::now();
    let mut c = Client::new(&server);
    assert_eq!(c.send("GET", "/api/openapi.json", None).status, 200);
    assert!(
        asked.elapsed() < Duration::from_secs(5),
        "a new client waited {:?}",
        asked.elapsed()
    );
    // A trickler still open is answered 408 and closed once its body is
    // late. (Which are open depends on the order the server read their
    // headers: a full server closes the connections that sent no request
    // yet first, then the oldest without a session.)
    let open = (0..held.len())
        .rev()
        .find(|&k| !closed_within(&mut held[k], Duration::from_millis(20)))
        .expect("a trickler still open");
    let last = &mut held[open];
    let _ = last.write_all(b"\"");
    let mut reply = Vec::new();
    let _ = last.set_read_timeout(Some(Duration::from_secs(15)));
    let _ = last.read_to_end(&mut reply);
    assert!(
        reply.starts_with(b"HTTP/1.1 408"),
        "{}",
        String::from_utf8_lossy(&reply)
    );
}

#[test]
fn sigterm_stops_the_run_then_the_event_streams_in_bounded_time() {
    sigterm_stops_the_run_then_the_event_streams_in_bounded_time_on(Backend::Sqlite);
}

#[test]
fn postgres_sigterm_stops_the_run_then_the_event_streams_in_bounded_time() {
    sigterm_stops_the_run_then_the_event_streams_in_bounded_time_on(Backend::Postgres);
}

fn sigterm_stops_the_run_then_the_event_streams_in_bounded_time_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "op", "operator", "op-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(
        dir.path().join("plans").join("long.toml"),
        "name = \"long\"\nrange_g = 20\nlevels = [0, 1, 5, 10, 15, 20]\npasses = [\"P\"]\n\
         warmup_s = 0\ndwell = { seconds = 60 }\nstability = { hold_s = 3 }\n[serials]\n1 = \"T-1\"\n",
    )
    .expect("plan");
    let mut server = serve(dir.path(), "20");
    let mut op = Client::login(&server, "op", "op-password");
    let r = op.send("POST", "/api/runs", Some(r#"{"plan": "long"}"#));
    assert_eq!(r.status, 201, "{:?}", r.json());
    // Answer the prompts until the table turns.
    let until = Instant::now() + Duration::from_secs(120);
    loop {
        let s: Value = op.get_json("/api/status", 200);
        if s["rate_deg_s"].as_f64().is_some_and(|r| r > 100.0) {
            break;
        }
        if s["prompt"].is_string() {
            op.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
        }
        assert!(Instant::now() < until, "the table never turned: {s}");
        std::thread::sleep(Duration::from_millis(100));
    }
    // A browser holds the event stream.
    let mut stream = TcpStream::connect(server.base.trim_start_matches("http://")).expect("tcp");
    write!(
        stream,
        "GET /api/events HTTP/1.1\r\nHost: x\r\nCookie: {}\r\nAccept: text/event-stream\r\n\r\n",
        op.cookie.clone().unwrap_or_default()
    )
    .expect("events");
    let mut first = [0u8; 64];
    stream.read_exact(&mut first).expect("the stream flows");
    let signalled = Instant::now();
    let kill = std::process::Command::new("kill")
        .args(["-TERM", &server.pid().to_string()])
        .status()
        .expect("kill");
    assert!(kill.success());
    let status = server.wait_exit(Duration::from_secs(30));
    assert!(
        status.is_some(),
        "serve did not exit within 30 s of SIGTERM"
    );
    assert!(
        closed_within(&mut stream, Duration::from_secs(2)),
        "the event stream stayed open"
    );
    eprintln!(
        "serve exited {:.1} s after SIGTERM",
        signalled.elapsed().as_secs_f64()
    );
    let store = spinbench_store::Store::open_read_only(&spinbench_store::StoreTarget::parse(
        &web::store_of(dir.path()).to_string_lossy(),
    ))
    .expect("store");
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 1);
    assert_eq!(runs[0].state.as_str(), "aborted", "{:?}", runs[0].reason);
    assert!(
        runs[0]
            .reason
            .as_deref()
            .is_some_and(|r| r.contains("SIGTERM")),
        "{:?}",
        runs[0].reason
    );
}

#[test]
fn a_login_name_with_a_line_break_or_a_nul_is_refused_and_audited_escaped() {
    a_login_name_with_a_line_break_or_a_nul_is_refused_and_audited_escaped_on(Backend::Sqlite);
}

#[test]
fn postgres_a_login_name_with_a_line_break_or_a_nul_is_refused_and_audited_escaped() {
    a_login_name_with_a_line_break_or_a_nul_is_refused_and_audited_escaped_on(Backend::Postgres);
}

/// A refused login's name is written to the audit log with
/// its line break, NUL or right-to-left override as an escape (no forged
/// line, no reordered text), on both back ends (a NUL was a 500 on
/// PostgreSQL, with no entry).
fn a_login_name_with_a_line_break_or_a_nul_is_refused_and_audited_escaped_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "admin", "admin", "admin-password");
    let server = serve(dir.path(), "0");
    let mut anon = Client::new(&server);
    for name in ["adm\nFORGED", "adm\u{0}in", "adm\u{202E}in"] {
        let r = anon.send("POST", "/api/login", Some(&login_body(name, "whatever")));
        assert_eq!(r.status, 401, "{name:?}: {:?}", r.json());
    }
    let mut admin = Client::login(&server, "admin", "admin-password");
    let audit = admin.get_json("/api/audit", 200);
    let refused: Vec<String> = audit
        .as_array()
        .expect("audit rows")
        .iter()
        .filter(|r| r["action"] == "login refused")
        .map(|r| r["who"].as_str().unwrap_or_default().to_string())
        .collect();
    assert_eq!(refused.len(), 3, "{audit}");
    for who in &refused {
        assert!(
            !who.chars().any(|c| c.is_control() || c == '\u{202E}'),
            "{who:?}"
        );
    }
    assert!(
        refused.iter().any(|w| w == "adm\\u{a}FORGED"),
        "{refused:?}"
    );
    assert!(refused.iter().any(|w| w == "adm\\u{0}in"), "{refused:?}");
}

/// A flood of connections, header-less and
/// anonymous, on a full server closes them, not the operator's event
/// stream nor their status polls; and 2 MiB bodies sent to the login take
/// no memory (refused by their Content-Length, before a byte is read).
#[test]
fn a_connection_flood_spares_the_operators_stream_and_big_bodies_take_no_memory() {
    let dir = tempfile::tempdir().expect("tempdir");
    add_user(dir.path(), "op", "operator", "op-password");
    let server = serve_with(dir.path(), "0", &["--max-connections", "16"]);
    let addr = server.base.trim_start_matches("http://").to_string();
    let mut op = Client::login(&server, "op", "op-password");
    let mut stream = TcpStream::connect(&addr).expect("tcp");
    write!(
        stream,
        "GET /api/events HTTP/1.1\r\nHost: x\r\nCookie: {}\r\nAccept: text/event-stream\r\n\r\n",
        op.cookie.clone().unwrap_or_default()
    )
    .expect("events");
    let mut first = [0u8; 12];
    stream.read_exact(&mut first).expect("the stream answers");
    assert_eq!(&first, b"HTTP/1.1 200");
    let rss_kb = || {
        std::fs::read_to_string(format!("/proc/{}/status", server.pid()))
            .ok()
            .and_then(|s| {
                s.lines().find(|l| l.starts_with("VmRSS:")).and_then(|l| {
                    l.split_whitespace()
                        .nth(1)
                        .and_then(|v| v.parse::<u64>().ok())
                })
            })
            .expect("the server's resident memory")
    };
    let before_kb = rss_kb();
    // The flood: 60 connections that send nothing, 60 that ask anonymously
    // and keep their connection, 60 that send a 2 MiB login body.
    let mut held = Vec::new();
    let mut polls_failed = 0;
    let big = format!(
        "{{\"user\": \"{}\", \"password\": \"x\"}}",
        "x".repeat(2 * 1024 * 1024)
    );
    for round in 0..60 {
        held.push(TcpStream::connect(&addr).expect("connect"));
        let mut anon = TcpStream::connect(&addr).expect("connect");
        let _ = anon.write_all(b"GET /api/openapi.json HTTP/1.1\r\nHost: x\r\n\r\n");
        held.push(anon);
        let mut body = TcpStream::connect(&addr).expect("connect");
        let _ = write!(
            body,
            "POST /api/login HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
            big.len()
        );
        let _ = body.write_all(big.as_bytes());
        held.push(body);
        if round % 6 == 0 && op.send("GET", "/api/status", None).status != 200 {
            polls_failed += 1;
        }
    }
    assert_eq!(polls_failed, 0, "the operator's status polls failed");
    // The operator's stream is still open (it sends, or waits).
    let _ = stream.set_read_timeout(Some(Duration::from_millis(500)));
    let mut more = [0u8; 256];
    match stream.read(&mut more) {
        Ok(0) => panic!("the operator's event stream was closed by the flood"),
        Ok(_) => {}
        Err(e) => assert!(
            matches!(
                e.kind(),
                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
            ),
            "{e}"
        ),
    }
    let grown_mb = rss_kb().saturating_sub(before_kb) as f64 / 1024.0;
    assert!(grown_mb < 40.0, "the server grew by {grown_mb:.0} MB");
    eprintln!("bench: flood_server_growth = {grown_mb:.1} MB");
}

#[test]
fn concurrent_saves_of_one_plan_each_land_whole_and_audited() {
    concurrent_saves_of_one_plan_each_land_whole_and_audited_on(Backend::Sqlite);
}

#[test]
fn postgres_concurrent_saves_of_one_plan_each_land_whole_and_audited() {
    concurrent_saves_of_one_plan_each_land_whole_and_audited_on(Backend::Postgres);
}

/// 40 engineers' saves of one plan at once (each a different title): every
/// one answers 200 with its audit entry, the file in place is one of them
/// whole, and no temporary file is left beside it.
fn concurrent_saves_of_one_plan_each_land_whole_and_audited_on(backend: Backend) {
    const SAVES: usize = 40;
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "eng", "engineer", "eng-password");
    add_user(dir.path(), "admin", "admin", "admin-password");
    let server = serve(dir.path(), "0");
    let plans: Vec<String> = (0..SAVES)
        .map(|i| web::short_plan(&format!("crowded-{i:02}"), &["CR-1"]))
        .collect();
    let statuses: Vec<u16> = std::thread::scope(|scope| {
        let handles: Vec<_> = plans
            .iter()
            .map(|plan| {
                let server = &server;
                scope.spawn(move || {
                    let mut eng = Client::login(server, "eng", "eng-password");
                    eng.send("PUT", "/api/plans/crowded", Some(plan)).status
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a saving thread"))
            .collect()
    });
    assert!(statuses.iter().all(|s| *s == 200), "{statuses:?}");
    let folder = dir.path().join("plans");
    let text = std::fs::read_to_string(folder.join("crowded.toml")).expect("the plan");
    assert!(plans.contains(&text), "the file in place is no save whole");
    let beside: Vec<String> = std::fs::read_dir(&folder)
        .expect("plans")
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("saving"))
        .collect();
    assert!(beside.is_empty(), "left beside: {beside:?}");
    let mut admin = Client::login(&server, "admin", "admin-password");
    let log = admin.get_json("/api/audit", 200);
    let saved = log
        .as_array()
        .expect("rows")
        .iter()
        .filter(|a| a["action"] == "save plan" && a["detail"] == "crowded")
        .count();
    assert_eq!(saved, SAVES, "audit entries of the saves");
}
