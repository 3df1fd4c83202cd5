//! Hardening, round three: each test names its item.

mod common;
#[path = "common/web.rs"]
mod web;

use common::spinbench;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::os::unix::fs::PermissionsExt;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use web::{Client, add_user, serve};

#[test]
fn a_device_or_a_fifo_as_the_tls_certificate_is_refused_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let fifo = dir.path().join("cert.fifo");
    let made = Command::new("mkfifo").arg(&fifo).status().expect("mkfifo");
    assert!(made.success());
    for cert in ["/dev/zero", fifo.to_str().expect("utf-8")] {
        let started = Instant::now();
        let mut child = Command::new(env!("CARGO_BIN_EXE_spinbench"))
            .args([
                "serve",
                "--simulate",
                "--bind",
                "127.0.0.1:0",
                "--tls-cert",
                cert,
                "--tls-key",
                cert,
                "--data",
            ])
            .arg(dir.path().join("data"))
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("serve");
        let status = loop {
            if let Ok(Some(status)) = child.try_wait() {
                break status;
            }
            if started.elapsed() > Duration::from_secs(20) {
                let _ = child.kill();
                panic!("serve --tls-cert {cert} did not refuse within 20 s");
            }
            std::thread::sleep(Duration::from_millis(50));
        };
        let mut err = String::new();
        let _ = child
            .stderr
            .take()
            .expect("stderr")
            .read_to_string(&mut err);
        assert!(!status.success());
        assert!(err.contains("not a regular file"), "{cert}: {err}");
    }
}

/// Send `request` on a raw connection and read one answer's status line.
fn status_of(stream: &mut TcpStream) -> String {
    let mut buf = [0u8; 4096];
    let mut got = Vec::new();
    let _ = stream.set_read_timeout(Some(Duration::from_secs(10)));
    while !got.windows(4).any(|w| w == b"\r\n\r\n") {
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => got.extend_from_slice(&buf[..n]),
        }
    }
    let text = String::from_utf8_lossy(&got).into_owned();
    // The rest of this answer's body, by its length.
    let length: usize = text
        .lines()
        .find_map(|l| {
            l.to_ascii_lowercase()
                .strip_prefix("content-length:")
                .map(|v| v.trim().parse().unwrap_or(0))
        })
        .unwrap_or(0);
    let head_end = got
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .map_or(got.len(), |p| p + 4);
    let mut have = got.len() - head_end;
    while have < length {
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => have += n,
        }
    }
    text.lines().next().unwrap_or("").to_string()
}

#[test]
fn items_18_20_21_login_only_as_json_retest_reads_its_body_and_reasons_are_characters() {
    let dir = tempfile::tempdir().expect("tempdir");
    add_user(dir.path(), "eng", "engineer", "eng-password");
    let server = serve(dir.path(), "0");
    let addr = server.base.trim_start_matches("http://").to_string();

    // Item 20: a cross-site form's text/plain login is refused.
    let mut s = TcpStream::connect(&addr).expect("connect");
    let body = r#"{"user": "eng", "password": "eng-password"}"#;
    write!(
        s,
        "POST /api/login HTTP/1.1\r\nHost: x\r\nContent-Type: text/plain\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .expect("send");
    let line = status_of(&mut s);
    assert!(line.contains(" 415 "), "{line}");

    // Item 21: the retest route reads its body, so the connection serves
    // the next request.
    let mut eng = Client::login(&server, "eng", "eng-password");
    let cookie = eng.cookie.clone().expect("cookie");
    let csrf = eng.csrf.clone().expect("csrf");
    let mut s = TcpStream::connect(&addr).expect("connect");
    write!(
        s,
        "POST /api/runs/no-such-run/retest HTTP/1.1\r\nHost: x\r\nCookie: {cookie}\r\nX-CSRF-Token: {csrf}\r\nContent-Type: application/json\r\nContent-Length: 2\r\n\r\n{{}}"
    )
    .expect("send");
    let first = status_of(&mut s);
    assert!(first.contains(" 404 "), "{first}");
    write!(s, "GET /api/openapi.json HTTP/1.1\r\nHost: x\r\n\r\n").expect("send");
    let second = status_of(&mut s);
    assert!(
        second.contains(" 200 "),
        "the next request on the connection: {second}"
    );

    // Item 18: a reason with a control character is refused; 200 Chinese
    // characters (600 bytes) are not too long.
    let ask = |reason: &str| {
        serde_json::json!({"serial": "X", "mount": "P", "g": 10.0, "reason": reason}).to_string()
    };
    let r = eng.send(
        "POST",
        "/api/runs/no-such-run/exclusions",
        Some(&ask("bad\nline")),
    );
    assert_eq!(r.status, 400, "{:?}", r.json());
    let r = eng.send(
        "POST",
        "/api/runs/no-such-run/exclusions",
        Some(&ask(&"振".repeat(200))),
    );
    assert_eq!(
        r.status,
        404,
        "past the reason's check to the run: {:?}",
        r.json()
    );
    let r = eng.send(
        "POST",
        "/api/runs/no-such-run/exclusions",
        Some(&ask(&"振".repeat(501))),
    );
    assert_eq!(r.status, 400);
    // Nor a right-to-left override or a zero-width space.
    for odd in ["level \u{202E}01", "noisy\u{200B}"] {
        let r = eng.send("POST", "/api/runs/no-such-run/exclusions", Some(&ask(odd)));
        assert_eq!(r.status, 400, "{odd:?}: {:?}", r.json());
    }
}

#[test]
fn items_5_6_25_backups_are_private_never_inside_the_data_and_never_take_a_strays_log() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("H")).expect("plan");
    let (ok, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--quiet",
        "--data",
        data.to_str().expect("utf-8"),
        plan.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{err}");
    let db = data.join("spinbench.db");
    let db_s = db.to_str().expect("utf-8");

    // Item 5: inside the data directory (its runs) or beside the store: refused.
    for inside in [data.join("runs").join("backup"), data.join("backups")] {
        let (ok, _, err) = spinbench(&[
            "backup",
            inside.to_str().expect("utf-8"),
            "--db",
            db_s,
            "--data",
            data.to_str().expect("utf-8"),
        ]);
        assert!(!ok && err.contains("inside"), "{}: {err}", inside.display());
        assert!(!inside.exists(), "{} was made", inside.display());
    }

    // Item 25: a backup is the owner's alone.
    let backups = dir.path().join("backups");
    let (ok, _, err) = spinbench(&[
        "backup",
        backups.to_str().expect("utf-8"),
        "--db",
        db_s,
        "--data",
        data.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{err}");
    let mode =
        |p: &std::path::Path| std::fs::metadata(p).expect("meta").permissions().mode() & 0o777;
    assert_eq!(mode(&backups), 0o700);
    let mut files = 0;
    let mut stack = vec![backups.clone()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("dir").flatten() {
            let p = e.path();
            if p.is_dir() {
                assert_eq!(mode(&p), 0o700, "{}", p.display());
                stack.push(p);
            } else {
                assert_eq!(mode(&p) & 0o077, 0, "{} is readable by others", p.display());
                files += 1;
            }
        }
    }
    assert!(files >= 2, "the store and the runs' files");

    // Item 6: a restore beside a stray -wal (a store moved aside without
    // it) is refused, and the stray is left as it was.
    let backup_file = std::fs::read_dir(&backups)
        .expect("dir")
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "db"))
        .expect("the backup");
    let target = dir.path().join("restored.db");
    let wal = dir.path().join("restored.db-wal");
    std::fs::write(&wal, b"a moved store's last writes").expect("wal");
    let (ok, _, err) = spinbench(&[
        "restore",
        backup_file.to_str().expect("utf-8"),
        "--db",
        target.to_str().expect("utf-8"),
    ]);
    assert!(!ok && err.contains("-wal exists"), "{err}");
    assert_eq!(
        std::fs::read(&wal).expect("wal"),
        b"a moved store's last writes"
    );
    assert!(!target.exists());
}

#[test]
fn serve_refuses_to_start_on_a_store_it_cannot_write() {
    // A store this user can read but not write: on PostgreSQL, a database
    // user with SELECT only (root writes any file, so SQLite cannot show it
    // in a test run as root).
    let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = spinbench_store::testing::fresh_postgres_database(&admin).expect("a fresh database");
    spinbench_store::Store::connect(&spinbench_store::StoreTarget::Postgres(url.clone()))
        .expect("the schema made by its owner");
    let reader = format!("reader_{}", std::process::id());
    let mut c = postgres::Client::connect(&url, postgres::NoTls).expect("connect");
    c.batch_execute(&format!(
        "CREATE ROLE {reader} LOGIN; GRANT USAGE ON SCHEMA public TO {reader}; \
         GRANT SELECT ON ALL TABLES IN SCHEMA public TO {reader};"
    ))
    .expect("a read-only user");
    let read_only = url.replacen("://spinbench@", &format!("://{reader}@"), 1);
    let dir = tempfile::tempdir().expect("tempdir");
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args([
            "serve",
            "--simulate",
            "--bind",
            "127.0.0.1:0",
            "--db",
            &read_only,
            "--data",
        ])
        .arg(dir.path())
        .output()
        .expect("serve");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "serve started on a store it cannot write"
    );
    assert!(
        err.contains("by this user") && err.contains("permission denied"),
        "{err}"
    );
}

#[test]
fn a_calibration_from_the_future_or_of_no_device_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("spinbench.db");
    let db_s = db.to_str().expect("utf-8");
    let set = |role: &str, calibrated: &str, due: &str| {
        spinbench(&[
            "equipment",
            "set",
            role,
            "--identity",
            "X 1",
            "--certificate",
            "C-1",
            "--calibrated",
            calibrated,
            "--due",
            due,
            "--station",
            "A",
            "--db",
            db_s,
        ])
    };
    let (ok, _, err) = set("centrifuge", "2199-01-01", "2200-01-01");
    assert!(!ok && err.contains("after today"), "{err}");
    let (ok, _, err) = set("bogus role", "2025-01-01", "2027-01-01");
    assert!(!ok && err.contains("not a device"), "{err}");
    let (ok, _, err) = set("fmu 01", "2025-01-01", "2027-01-01");
    assert!(!ok, "{err}");
    let (ok, _, err) = set("fmu 2", "2025-01-01", "2027-01-01");
    assert!(ok, "{err}");
    // Item 24: an identity with a right-to-left override is refused.
    let (ok, _, err) = spinbench(&[
        "equipment",
        "set",
        "centrifuge",
        "--identity",
        "X\u{202E}1",
        "--certificate",
        "C-1",
        "--calibrated",
        "2025-01-01",
        "--due",
        "2027-01-01",
        "--station",
        "A",
        "--db",
        db_s,
    ]);
    assert!(!ok && err.contains("invisible character"), "{err}");

    // The same through the API.
    add_user(dir.path(), "eng", "engineer", "eng-password");
    let server = serve(dir.path(), "0");
    let mut eng = Client::login(&server, "eng", "eng-password");
    let body = serde_json::json!({"identity": "X 1", "certificate": "C-1", "calibrated_on": "2199-01-01", "due_on": "2200-01-01"});
    let r = eng.send("PUT", "/api/equipment/centrifuge", Some(&body.to_string()));
    assert_eq!(r.status, 400, "{:?}", r.json());
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("after today"))
    );
}

#[test]
fn an_admin_may_retest_past_an_overdue_device_with_a_reason() {
    let dir = tempfile::tempdir().expect("tempdir");
    add_user(dir.path(), "admin", "admin", "admin-password");
    add_user(dir.path(), "op", "operator", "op-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(
        dir.path().join("plans").join("tight.toml"),
        format!(
            "{}[limits]\nk2_max_ug_per_g2 = 0.001\n",
            web::short_plan("tight", &["T-1"])
        ),
    )
    .expect("plan");
    let server = serve(dir.path(), "0");
    let mut admin = Client::login(&server, "admin", "admin-password");
    // A run whose instrument fails the tight limit: something to retest.
    let r = admin.send("POST", "/api/runs", Some(r#"{"plan": "tight"}"#));
    assert_eq!(r.status, 201, "{:?}", r.json());
    let run_id = r.json()["run_id"].as_str().expect("run id").to_string();
    let until = Instant::now() + Duration::from_secs(120);
    loop {
        let s = admin.get_json("/api/status", 200);
        if s["active"].is_null() && s["run_id"] == run_id.as_str() {
            break;
        }
        if s["prompt"].is_string() {
            admin.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
        }
        assert!(Instant::now() < until, "the run did not end");
        std::thread::sleep(Duration::from_millis(100));
    }
    // The centrifuge overdue: a plain retest is refused, naming the override.
    let overdue = serde_json::json!({"identity": "C 1", "certificate": "K-1", "calibrated_on": "2020-01-01", "due_on": "2021-01-01"});
    let r = admin.send(
        "PUT",
        "/api/equipment/centrifuge",
        Some(&overdue.to_string()),
    );
    assert_eq!(r.status, 200, "{:?}", r.json());
    let path = format!("/api/runs/{run_id}/retest");
    let r = admin.send("POST", &path, None);
    assert_eq!(r.status, 409, "{:?}", r.json());
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("override_overdue"))
    );
    // An operator may not override.
    let mut op = Client::login(&server, "op", "op-password");
    let with_reason = r#"{"override_overdue": "calibration booked for Monday"}"#;
    assert_eq!(op.send("POST", &path, Some(with_reason)).status, 403);
    // The admin, with a reason: started, and the override is audited.
    let r = admin.send("POST", &path, Some(with_reason));
    assert_eq!(r.status, 201, "{:?}", r.json());
    let audit = admin.get_json("/api/audit", 200);
    assert!(
        audit.as_array().expect("a list").iter().any(|e| e["action"]
            == "override overdue calibration"
            && e["detail"]
                .as_str()
                .is_some_and(|d| d.contains("retest of") && d.contains("Monday"))),
        "{audit}"
    );
    let _ = admin.send("POST", "/api/run/abort", None);
}

/// Devices that take connections and never answer.
fn silent_devices() -> (String, std::thread::JoinHandle<()>) {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr").to_string();
    let held = std::thread::spawn(move || {
        let mut open = Vec::new();
        for stream in listener.incoming().flatten() {
            // Read nothing, answer nothing: hold the connection.
            open.push(stream);
        }
    });
    (addr, held)
}

#[test]
fn sigterm_with_silent_devices_ends_in_bounded_time_and_records_the_run() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (addr, _held) = silent_devices();
    // The longest a command may take: 5 s × 2 attempts (MAX_COMMAND_MS).
    let io = "io = { timeout_ms = 5000, retries = 1 }";
    let station = station_at(&addr, io);
    let station_path = dir.path().join("station.toml");
    std::fs::write(&station_path, station).expect("station");
    // What was accepted before: 10 s × 3 attempts per command.
    let slow = std::fs::read_to_string(&station_path)
        .expect("station")
        .replace(io, "io = { timeout_ms = 10000, retries = 2 }");
    let slow_path = dir.path().join("slow.toml");
    std::fs::write(&slow_path, slow).expect("slow station");
    let data = dir.path().to_str().expect("path");
    let (ok, _, refused) = spinbench(&[
        "serve",
        "--station",
        slow_path.to_str().expect("path"),
        "--data",
        data,
        "--bind",
        "127.0.0.1:0",
    ]);
    assert!(!ok);
    assert!(
        refused.contains("MAX_COMMAND_MS") && refused.contains("centrifuge.io"),
        "{refused}"
    );

    add_user(dir.path(), "op", "operator", "op-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(
        dir.path().join("plans").join("short.toml"),
        "name = \"short\"\nrange_g = 20\nlevels = [0, 1, 5, 10, 15, 20]\npasses = [\"P\"]\n\
         warmup_s = 0\ndwell = { seconds = 10 }\nstability = { hold_s = 3 }\n[serials]\n1 = \"Q-1\"\n",
    )
    .expect("plan");
    let mut server = web::serve_station(dir.path(), &station_path);
    let mut op = Client::login(&server, "op", "op-password");
    let r = op.send("POST", "/api/runs", Some(r#"{"plan": "short"}"#));
    assert_eq!(r.status, 201, "{:?}", r.json());
    // The station is asking its first silent device.
    std::thread::sleep(Duration::from_secs(3));
    let signalled = Instant::now();
    server.terminate();
    let status = server.wait_exit(Duration::from_secs(85));
    let took_s = signalled.elapsed().as_secs_f64();
    eprintln!("serve exited {took_s:.1} s after SIGTERM with silent devices");
    assert!(
        status.is_some(),
        "serve did not exit within 85 s of SIGTERM (the unit's TimeoutStopSec is 90)"
    );
    assert!(took_s < 75.0, "{took_s:.1} s");
    let store = spinbench_store::Store::open_read_only(&spinbench_store::StoreTarget::parse(
        &web::store_of(dir.path()).to_string_lossy(),
    ))
    .expect("store");
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 1);
    assert!(
        runs[0].state.as_str() == "aborted" || runs[0].state.as_str() == "faulted",
        "{} {:?}",
        runs[0].state,
        runs[0].reason
    );
    let reason = runs[0].reason.clone().unwrap_or_default();
    assert!(
        reason.contains("SIGTERM") && reason.contains("stop not confirmed: check the centrifuge"),
        "{reason}"
    );
}

#[test]
fn a_backup_leaves_out_a_run_being_run_and_refreshes_a_file_that_grew() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    std::fs::create_dir_all(&data).expect("data");
    add_user(&data, "eng", "engineer", "eng-password");
    let runs = data.join("runs");
    let (running, done) = (runs.join("run-2"), runs.join("run-1"));
    for (run, text) in [(&running, "{\"running\":1}\n"), (&done, "{\"done\":1}\n")] {
        std::fs::create_dir_all(run).expect("run dir");
        std::fs::write(run.join("journal.jsonl"), text).expect("journal");
    }
    // A process runs run-2: it holds its directory's lock.
    let lock = std::fs::File::open(&running).expect("open");
    lock.lock().expect("lock");
    let backup = dir.path().join("backup");
    let store = web::store_of(&data);
    let args = |b: &std::path::Path| {
        vec![
            "backup".to_string(),
            b.to_string_lossy().into_owned(),
            "--db".into(),
            store.to_string_lossy().into_owned(),
            "--data".into(),
            data.to_string_lossy().into_owned(),
        ]
    };
    let run = |a: Vec<String>| {
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        spinbench(&a)
    };
    let (ok, out, err) = run(args(&backup));
    assert!(ok, "{err}");
    assert!(
        out.contains("runs in progress") && out.contains("run-2"),
        "{out}"
    );
    assert!(backup.join("runs/run-1/journal.jsonl").is_file());
    assert!(!backup.join("runs/run-2").exists(), "a torn copy was taken");
    // The run ends; run-1 was resumed meanwhile and its journal grew.
    drop(lock);
    std::fs::write(
        done.join("journal.jsonl"),
        "{\"done\":1}\n{\"resumed\":1}\n",
    )
    .expect("grow");
    let (ok, out, err) = run(args(&backup));
    assert!(ok, "{err}");
    assert!(!out.contains("in progress"), "{out}");
    assert_eq!(
        std::fs::read_to_string(backup.join("runs/run-2/journal.jsonl")).expect("copied"),
        "{\"running\":1}\n"
    );
    assert_eq!(
        std::fs::read_to_string(backup.join("runs/run-1/journal.jsonl")).expect("copied"),
        "{\"done\":1}\n{\"resumed\":1}\n"
    );
}

/// A station config whose devices all sit at `addr` (never connected
/// until a run starts).
fn station_at(addr: &str, io: &str) -> String {
    let transport = format!("transport = {{ kind = \"tcp\", address = \"{addr}\" }}");
    format!(
        "[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\ninstrument_supply = \"rails\"\n\
         [centrifuge]\nname = \"table\"\nmax_rate_deg_s = 2400\n{transport}\n{io}\n\
         dialect = {{ kind = \"acutrol\" }}\n\
         [[fmu]]\nname = \"counters\"\n{transport}\n{io}\n\
         [[power_supply]]\nname = \"rails\"\nchannels = 2\n{transport}\n{io}\n"
    )
}

#[test]
fn a_station_config_that_cannot_be_written_is_not_applied_nor_audited() {
    let dir = tempfile::tempdir().expect("tempdir");
    let folder = dir.path().join("conf");
    std::fs::create_dir(&folder).expect("conf");
    let station_path = folder.join("station.toml");
    let first = station_at("127.0.0.1:9", "");
    std::fs::write(&station_path, &first).expect("station");
    add_user(dir.path(), "eng", "engineer", "eng-password");
    let server = web::serve_station(dir.path(), &station_path);
    let mut eng = Client::login(&server, "eng", "eng-password");
    let edited = first.replace("max_g = 100", "max_g = 90");
    // The name a running server holds is not changed under it.
    let renamed = format!("station = \"line 2\"\n{first}");
    let r = eng.send("PUT", "/api/station", Some(&renamed));
    assert_eq!(r.status, 409, "{:?}", r.json());
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("holds the station name") && e.contains("restart")),
        "{:?}",
        r.json()
    );
    // The file cannot be written (root included): its folder is moved
    // aside and its name taken by a plain file.
    let held = dir.path().join("conf-held");
    std::fs::rename(&folder, &held).expect("move the folder aside");
    std::fs::write(&folder, "").expect("blocker");
    let r = eng.send("PUT", "/api/station", Some(&edited));
    assert_eq!(r.status, 409, "{:?}", r.json());
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("nothing was changed")),
        "{:?}",
        r.json()
    );
    let now: serde_json::Value = eng.get_json("/api/station", 200);
    assert!(
        now["toml"]
            .as_str()
            .is_some_and(|t| !t.contains("max_g = 90")),
        "applied though not written: {now}"
    );
    assert_eq!(
        std::fs::read_to_string(held.join("station.toml")).expect("file"),
        first
    );
    let beside = std::fs::read_dir(&held).expect("conf").count();
    assert_eq!(beside, 1, "nothing is left beside the config");
    let audited = |action: &str| {
        let store = spinbench_store::Store::open_read_only(&spinbench_store::StoreTarget::parse(
            &web::store_of(dir.path()).to_string_lossy(),
        ))
        .expect("store");
        store
            .audit_log(100)
            .expect("audit")
            .iter()
            .filter(|a| a.action == action)
            .count()
    };
    assert_eq!(audited("save station config"), 0);
    // Once it can be written: written, in use, audited.
    std::fs::remove_file(&folder).expect("unblock");
    std::fs::rename(&held, &folder).expect("the folder back");
    let r = eng.send("PUT", "/api/station", Some(&edited));
    assert_eq!(r.status, 200, "{:?}", r.json());
    assert_eq!(
        std::fs::read_to_string(&station_path).expect("file"),
        edited
    );
    let now: serde_json::Value = eng.get_json("/api/station", 200);
    assert!(
        now["toml"]
            .as_str()
            .is_some_and(|t| t.contains("max_g = 90")),
        "{now}"
    );
    assert_eq!(audited("save station config"), 1);
}

#[test]
fn a_store_that_cannot_be_written_is_read_and_backups_are_out_of_wal() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    std::fs::create_dir_all(&data).expect("data");
    let db = data.join("spinbench.db");
    let db_s = db.to_str().expect("utf-8");
    let (ok, _, err) = spinbench(&["runs", "list", "--db", db_s]);
    assert!(!ok, "no store yet: {err}");
    add_user(&data, "eng", "engineer", "eng-password");
    // A WAL store whose -shm cannot be made (as on read-only media; root
    // included: the name is taken by a directory).
    std::fs::create_dir(data.join("spinbench.db-shm")).expect("shm blocker");
    let (ok, out, err) = spinbench(&["runs", "list", "--db", db_s]);
    assert!(ok, "a store that cannot be written is read: {err}");
    let _ = out;
    std::fs::remove_dir(data.join("spinbench.db-shm")).expect("unblock");
    // A backup is one file out of WAL mode (header byte 18: 1 rollback
    // journal, 2 WAL).
    let backup = dir.path().join("backup");
    let (ok, _, err) = spinbench(&["backup", backup.to_str().expect("utf-8"), "--db", db_s]);
    assert!(ok, "{err}");
    let file = std::fs::read_dir(&backup)
        .expect("backup dir")
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "db"))
        .expect("the backup file");
    let header = std::fs::read(&file).expect("read");
    assert_eq!(header[18], 1, "the backup is in WAL mode");
    assert!(!file.with_extension("db-wal").exists());
}

#[test]
fn items_23_17_a_station_may_require_registered_devices_and_an_unreachable_one_leaves_no_run() {
    let dir = tempfile::tempdir().expect("tempdir");
    let station_path = dir.path().join("station.toml");
    // Devices at an address nothing listens on (refused at once).
    let station = format!(
        "{}[equipment]\nrequire_registered = true\n",
        station_at("127.0.0.1:9", "")
    );
    std::fs::write(&station_path, station).expect("station");
    add_user(dir.path(), "op", "operator", "op-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(
        dir.path().join("plans").join("short.toml"),
        "name = \"short\"\nrange_g = 20\nlevels = [0, 1, 5, 10, 15, 20]\npasses = [\"P\"]\n\
         warmup_s = 0\ndwell = { seconds = 10 }\n[serials]\n1 = \"Q-1\"\n",
    )
    .expect("plan");
    let server = web::serve_station(dir.path(), &station_path);
    let mut op = Client::login(&server, "op", "op-password");
    let r = op.send("POST", "/api/runs", Some(r#"{"plan": "short"}"#));
    assert_eq!(r.status, 409, "{:?}", r.json());
    let error = r.json()["error"].as_str().unwrap_or_default().to_string();
    assert!(
        error.contains("centrifuge (not in the equipment register"),
        "{error}"
    );
    // Registered: the run is no longer held back; the hardware cannot be
    // reached (503), and no run directory is left behind (item 17).
    let db = web::store_of(dir.path());
    for role in ["centrifuge", "fmu 1", "instrument supply"] {
        let (ok, _, err) = spinbench(&[
            "equipment",
            "set",
            role,
            "--identity",
            "X 1",
            "--certificate",
            "C-1",
            "--calibrated",
            "2025-01-01",
            "--due",
            "2099-01-01",
            "--db",
            db.to_str().expect("utf-8"),
        ]);
        assert!(ok, "{role}: {err}");
    }
    let r = op.send("POST", "/api/runs", Some(r#"{"plan": "short"}"#));
    assert_eq!(r.status, 503, "{:?}", r.json());
    let runs = dir.path().join("runs");
    let left = std::fs::read_dir(&runs).map_or(0, |d| d.count());
    assert_eq!(left, 0, "a run directory was left in {}", runs.display());
    // The CLI likewise leaves none, and refuses to resume a completed run
    // before connecting anything.
    let plan = dir.path().join("plans").join("short.toml");
    let (ok, _, err) = spinbench(&[
        "run",
        plan.to_str().expect("utf-8"),
        "--station",
        station_path.to_str().expect("utf-8"),
        "--data",
        dir.path().to_str().expect("utf-8"),
        "--db",
        db.to_str().expect("utf-8"),
    ]);
    assert!(!ok, "{err}");
    assert_eq!(
        std::fs::read_dir(&runs).map_or(0, |d| d.count()),
        0,
        "{err}"
    );
    let done = runs.join("run-done");
    std::fs::create_dir_all(&done).expect("run dir");
    std::fs::copy(&plan, done.join("plan.toml")).expect("plan");
    let station_text = std::fs::read_to_string(&station_path).expect("station");
    let config = spinbench_engine::StationConfig::from_toml(&station_text).expect("station");
    let compiled =
        spinbench_engine::TestPlan::from_toml(&std::fs::read_to_string(&plan).expect("plan"))
            .expect("plan")
            .compile(&config)
            .expect("compiled");
    let journal = [
        spinbench_engine::Event::RunStarted {
            run_id: "run-done".into(),
            station: config.station.clone(),
            plan: Box::new(compiled),
            resumed: false,
            station_config: station_text,
        },
        spinbench_engine::Event::RunFinished {
            state: spinbench_engine::RunState::Completed,
            reason: None,
            wording: None,
        },
    ]
    .iter()
    .map(|e| serde_json::to_string(e).expect("event") + "\n")
    .collect::<String>();
    std::fs::write(done.join("journal.jsonl"), journal).expect("journal");
    let (ok, _, err) = spinbench(&[
        "run",
        plan.to_str().expect("utf-8"),
        "--station",
        station_path.to_str().expect("utf-8"),
        "--resume",
        done.to_str().expect("utf-8"),
        "--data",
        dir.path().to_str().expect("utf-8"),
        "--db",
        db.to_str().expect("utf-8"),
    ]);
    assert!(!ok && err.contains("already completed"), "{err}");
    assert!(
        !done.join("raw").exists(),
        "raw files started in a completed run"
    );
}

/// Run `sql` on the store `data`'s server keeps (an SQLite file or a
/// PostgreSQL database), as a DBA or a fault would.
fn store_sql(data: &std::path::Path, sqlite: &str, postgres: &str) {
    let target = web::store_of(data);
    let target = target.to_str().expect("utf-8");
    if target.starts_with("postgres") {
        let mut c = postgres::Client::connect(target, postgres::NoTls).expect("PostgreSQL");
        c.batch_execute(postgres).expect("the SQL");
    } else {
        let c = rusqlite::Connection::open(target).expect("SQLite");
        c.execute_batch(sqlite).expect("the SQL");
    }
}

#[test]
fn issue_39_item_6_nothing_is_done_that_cannot_be_audited() {
    nothing_is_done_that_cannot_be_audited_on(web::Backend::Sqlite);
}

#[test]
fn postgres_issue_39_item_6_nothing_is_done_that_cannot_be_audited() {
    nothing_is_done_that_cannot_be_audited_on(web::Backend::Postgres);
}

/// While the audit log refuses every entry (a trigger, as
/// a full or broken table would), a plan is not saved, a run is not
/// started and a prompt is not answered; each answer says nothing was
/// done. Once the log takes entries again, the same requests succeed and
/// are audited.
fn nothing_is_done_that_cannot_be_audited_on(backend: web::Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "eng", "engineer", "eng-password");
    add_user(dir.path(), "admin", "admin", "admin-password");
    let server = serve(dir.path(), "0");
    let mut eng = Client::login(&server, "eng", "eng-password");
    let mut admin = Client::login(&server, "admin", "admin-password");
    store_sql(
        dir.path(),
        "CREATE TRIGGER audit_refused BEFORE INSERT ON audit BEGIN SELECT RAISE(ABORT, 'audit refused'); END;",
        "CREATE FUNCTION audit_refused() RETURNS trigger LANGUAGE plpgsql AS $$ BEGIN RAISE EXCEPTION 'audit refused'; END $$;
         CREATE TRIGGER audit_refused BEFORE INSERT ON audit FOR EACH ROW EXECUTE FUNCTION audit_refused();",
    );
    let plan = web::short_plan("audited", &["AU-1"]);
    let r = eng.send("PUT", "/api/plans/audited", Some(&plan));
    assert!(r.status >= 500, "{} {:?}", r.status, r.json());
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("nothing was saved")),
        "{:?}",
        r.json()
    );
    let plans = dir.path().join("plans");
    assert!(
        !plans.join("audited.toml").exists(),
        "the plan was saved unaudited"
    );
    let r = eng.send("POST", "/api/runs", Some(r#"{"plan": "short"}"#));
    assert_eq!(r.status, 503, "{:?}", r.json());
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("nothing was started")),
        "{:?}",
        r.json()
    );
    assert!(
        eng.get_json("/api/status", 200)["active"].is_null(),
        "a run started unaudited"
    );
    let runs = dir.path().join("runs");
    assert_eq!(std::fs::read_dir(&runs).map_or(0, |d| d.count()), 0);
    // The log takes entries again: the same requests succeed, audited.
    store_sql(
        dir.path(),
        "DROP TRIGGER audit_refused;",
        "DROP TRIGGER audit_refused ON audit;",
    );
    let r = eng.send("PUT", "/api/plans/audited", Some(&plan));
    assert_eq!(r.status, 200, "{:?}", r.json());
    assert!(plans.join("audited.toml").exists());
    let log = admin.get_json("/api/audit", 200);
    assert!(
        log.as_array()
            .expect("rows")
            .iter()
            .any(|a| a["action"] == "save plan" && a["detail"] == "audited"),
        "{log}"
    );
}

/// A made-up session cookie is refused before the body is read: the
/// server answers 401 while the client has sent 10 bytes of a declared
/// 2 MiB body (before, it waited to buffer the whole body first), and
/// closes the connection.
#[test]
fn a_made_up_session_is_refused_before_its_body_is_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = serve(dir.path(), "0");
    let address = server.base.trim_start_matches("http://").to_string();
    let mut stream = TcpStream::connect(&address).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .expect("timeout");
    let body_bytes = 2 * 1024 * 1024 - 1;
    write!(
        stream,
        "POST /api/runs HTTP/1.1\r\nHost: {address}\r\nCookie: spinbench_session=made-up-{}\r\n\
         Content-Type: application/json\r\nContent-Length: {body_bytes}\r\n\r\n{{\"plan\": ",
        "0".repeat(40)
    )
    .expect("headers");
    let mut answer = [0u8; 1024];
    let started = Instant::now();
    let n = stream.read(&mut answer).expect("an answer before the body");
    let head = String::from_utf8_lossy(&answer[..n]).to_ascii_lowercase();
    assert!(head.starts_with("http/1.1 401"), "{head}");
    assert!(started.elapsed() < Duration::from_secs(5));
    // The unread body leaves the connection unusable: the answer says so,
    // so that a client's pool does not send its next request on it.
    assert!(head.contains("connection: close"), "{head}");
}
