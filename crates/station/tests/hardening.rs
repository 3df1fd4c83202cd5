//! Hardening, round three (issue 27): each test names its item.

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
fn item_14_a_device_or_a_fifo_as_the_tls_certificate_is_refused_at_once() {
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
fn item_12_serve_refuses_to_start_on_a_store_it_cannot_write() {
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
fn item_23_a_calibration_from_the_future_or_of_no_device_is_refused() {
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
fn item_22_an_admin_may_retest_past_an_overdue_device_with_a_reason() {
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
