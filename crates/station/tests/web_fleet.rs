//! The fleet: two `spinbench serve --simulate` stations on one
//! PostgreSQL store run a test each at the same time; each server lists
//! both stations and both runs; the fleet view follows them from running to
//! idle to offline; a user removed on one server is refused on the other
//! within 5 s and their event stream there ends; neither server panics.

#[path = "common/web.rs"]
mod web;

use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::time::{Duration, Instant};
use web::{Backend, Client, add_user, serve_logged, share_store};

/// Each station's state in `/api/fleet`.
fn fleet(c: &mut Client) -> BTreeMap<String, String> {
    c.get_json("/api/fleet", 200)
        .as_array()
        .expect("a list")
        .iter()
        .map(|s| {
            (
                s["station"].as_str().unwrap_or("").to_string(),
                s["state"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect()
}

/// Poll the fleet until `want` holds (at most `seconds`).
fn wait_fleet(
    c: &mut Client,
    seconds: u64,
    what: &str,
    want: impl Fn(&BTreeMap<String, String>) -> bool,
) {
    let until = Instant::now() + Duration::from_secs(seconds);
    loop {
        let now = fleet(c);
        if want(&now) {
            return;
        }
        assert!(
            Instant::now() < until,
            "the fleet is not {what} after {seconds} s: {now:?}"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
fn two_stations_on_one_postgresql_run_at_once_and_see_each_other() {
    let a_dir = tempfile::tempdir().expect("tempdir");
    let b_dir = tempfile::tempdir().expect("tempdir");
    Backend::Postgres.prepare(a_dir.path());
    share_store(a_dir.path(), b_dir.path());
    add_user(a_dir.path(), "admin", "admin", "admin-password");
    add_user(a_dir.path(), "op", "operator", "op-password");
    add_user(a_dir.path(), "op2", "operator", "op2-password");
    for dir in [a_dir.path(), b_dir.path()] {
        std::fs::create_dir_all(dir.join("plans")).expect("plans");
        std::fs::write(
            dir.join("plans").join("fleet.toml"),
            web::short_plan("fleet test", &[]),
        )
        .expect("plan");
    }
    let logs = tempfile::tempdir().expect("tempdir");
    let (a_log, b_log) = (logs.path().join("a.log"), logs.path().join("b.log"));
    let a = serve_logged(a_dir.path(), "0", &["--name", "station-a"], &a_log);
    let b = serve_logged(b_dir.path(), "0", &["--name", "station-b"], &b_log);
    let mut op_a = Client::login(&a, "op", "op-password");
    let mut op_b = Client::login(&b, "op", "op-password");

    // A test on each, at the same time.
    let mut runs = Vec::new();
    for (c, serial) in [(&mut op_a, "FA-1"), (&mut op_b, "FB-1")] {
        let r = c.send(
            "POST",
            "/api/runs",
            Some(&json!({"plan": "fleet", "serials": {"1": serial}}).to_string()),
        );
        assert_eq!(r.status, 201, "{:?}", r.json());
        runs.push(r.json()["run_id"].as_str().expect("run id").to_string());
    }
    // Running, or waiting for the operator at a prompt (
    // a station waiting is shown as waiting, not running).
    let busy = |s: Option<&String>| matches!(s.map(String::as_str), Some("running" | "waiting"));
    wait_fleet(&mut op_a, 20, "both running", |f| {
        busy(f.get("station-a")) && busy(f.get("station-b"))
    });
    wait_fleet(&mut op_a, 20, "A waiting at its first prompt", |f| {
        f.get("station-a").map(String::as_str) == Some("waiting")
    });
    // Answer both stations' prompts until both runs end.
    let until = Instant::now() + Duration::from_secs(300);
    let mut done = [false, false];
    while done != [true, true] {
        assert!(Instant::now() < until, "the runs did not end in 300 s");
        for (k, c) in [&mut op_a, &mut op_b].into_iter().enumerate() {
            if done[k] {
                continue;
            }
            let s = c.get_json("/api/status", 200);
            if s["active"].is_null() && s["run_id"] == runs[k].as_str() {
                assert_eq!(s["state"], "completed", "station {k}: {s}");
                done[k] = true;
            } else if s["prompt"].is_string() {
                let r = c.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
                assert!(matches!(r.status, 200 | 409), "{:?}", r.json());
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    wait_fleet(&mut op_b, 20, "both idle", |f| {
        f.get("station-a").map(String::as_str) == Some("idle")
            && f.get("station-b").map(String::as_str) == Some("idle")
    });
    // Each row counts its latest run's outcomes (one
    // instrument each), as the run's own results say.
    for (k, row) in op_b
        .get_json("/api/fleet", 200)
        .as_array()
        .expect("a list")
        .iter()
        .filter(|s| s["station"] == "station-a" || s["station"] == "station-b")
        .enumerate()
    {
        let counts = row["last_run_outcomes"].as_object().expect("outcomes");
        let total: i64 = counts.values().filter_map(Value::as_i64).sum();
        assert_eq!(total, 1, "row {k}: {row}");
        let run = &runs[usize::from(row["station"] == "station-b")];
        let detail = op_b.get_json(&format!("/api/runs/{run}"), 200);
        let outcome = detail["results"][0]["outcome"]
            .as_str()
            .unwrap_or("?")
            .to_string();
        assert_eq!(
            counts.get(&outcome).and_then(Value::as_i64),
            Some(1),
            "{row} {detail}"
        );
    }
    // Each server lists both runs, each with its own station and records,
    // and each station keeps its own raw data.
    for c in [&mut op_a, &mut op_b] {
        let listed: Vec<Value> = c
            .get_json("/api/runs", 200)
            .as_array()
            .cloned()
            .unwrap_or_default();
        for (run, station) in runs.iter().zip(["station-a", "station-b"]) {
            let row = listed
                .iter()
                .find(|r| r["id"] == run.as_str())
                .unwrap_or_else(|| panic!("{run} not listed: {listed:?}"));
            assert_eq!(row["station"], station, "{row}");
            let detail = c.get_json(&format!("/api/runs/{run}"), 200);
            assert_eq!(
                detail["results"].as_array().map(Vec::len),
                Some(2),
                "{detail}"
            );
        }
        let stations = c.get_json("/api/fleet", 200);
        let yields: Vec<i64> = stations
            .as_array()
            .expect("a list")
            .iter()
            .map(|s| s["tested_today"].as_i64().unwrap_or(-1))
            .collect();
        assert_eq!(yields, [1, 1], "one instrument each: {stations}");
    }
    // History by station; control charts per centrifuge (this server's by
    // default, another's when asked).
    let only_a = op_b.get_json("/api/runs?station=station-a", 200);
    let ids: Vec<&str> = only_a
        .as_array()
        .expect("a list")
        .iter()
        .filter_map(|r| r["id"].as_str())
        .collect();
    assert_eq!(ids, [runs[0].as_str()], "{only_a}");
    // The list one page at a time: the next page is the Link header's.
    let first = op_b.send("GET", "/api/runs?limit=1", None);
    assert_eq!(first.status, 200);
    let page = first.json();
    assert_eq!(page.as_array().map(Vec::len), Some(1), "{page}");
    let link = first.link.clone().expect("a Link to the next page");
    let next = link
        .strip_prefix('<')
        .and_then(|l| l.split_once('>'))
        .map(|(path, rel)| {
            assert!(rel.contains("rel=\"next\""), "{link}");
            path.to_string()
        })
        .expect("<path>; rel=\"next\"");
    let second = op_b.send("GET", &next, None);
    assert_eq!(second.status, 200);
    assert!(
        second.link.is_none(),
        "no page after the last: {:?}",
        second.link
    );
    let mut both: Vec<String> = [page, second.json()]
        .iter()
        .filter_map(|p| p[0]["id"].as_str().map(str::to_string))
        .collect();
    both.sort();
    let mut all: Vec<String> = runs.iter().map(|r| r.to_string()).collect();
    all.sort();
    assert_eq!(both, all, "every run once over the two pages");
    for bad in [
        "/api/runs?limit=0",
        "/api/runs?limit=1001",
        "/api/runs?after=yesterday",
        "/api/runs?after=12.x%20y",
        "/api/control-charts?runs=0",
    ] {
        assert_eq!(op_b.send("GET", bad, None).status, 400, "{bad}");
    }
    for (c, station) in [(&mut op_a, "station-a"), (&mut op_b, "station-b")] {
        let charts = c.get_json("/api/control-charts", 200);
        assert_eq!(charts["runs"], 1, "{station}: {charts}");
        let other = if station == "station-a" {
            "station-b"
        } else {
            "station-a"
        };
        let theirs = c.get_json(&format!("/api/control-charts?station={other}"), 200);
        assert_eq!(theirs["runs"], 1, "{other}: {theirs}");
        let none = c.get_json("/api/control-charts?station=nobody", 200);
        assert_eq!(none["runs"], 0, "{none}");
    }
    for (dir, run) in [(a_dir.path(), &runs[0]), (b_dir.path(), &runs[1])] {
        let raw = dir.join("runs").join(run).join("raw");
        let bytes: u64 = std::fs::read_dir(&raw)
            .unwrap_or_else(|e| panic!("{}: {e}", raw.display()))
            .filter_map(|e| e.ok()?.metadata().ok())
            .map(|m| m.len())
            .sum();
        assert!(bytes > 0, "{}: no raw data", raw.display());
    }

    // B's run is retested on B, not on A.
    let r = op_a.send("POST", &format!("/api/runs/{}/retest", runs[1]), None);
    assert_eq!(r.status, 409, "{:?}", r.json());
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("recorded by station 'station-b'")),
        "{:?}",
        r.json()
    );

    // A user removed on B: refused on A within 5 s, their stream on A ended.
    let mut op2_a = Client::login(&a, "op2", "op2-password");
    let cookie = op2_a.cookie.clone().expect("cookie");
    let base = a.base.clone();
    let stream = std::thread::spawn(move || {
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .build()
            .into();
        let response = agent
            .get(format!("{base}/api/events"))
            .header("Cookie", &cookie)
            .call()
            .expect("events");
        assert_eq!(response.status().as_u16(), 200);
        let mut bytes = 0usize;
        for line in BufReader::new(response.into_body().into_reader()).lines() {
            match line {
                Ok(l) => bytes += l.len(),
                Err(_) => break,
            }
        }
        (Instant::now(), bytes)
    });
    std::thread::sleep(Duration::from_millis(500));
    let mut admin_b = Client::login(&b, "admin", "admin-password");
    assert_eq!(admin_b.send("DELETE", "/api/users/op2", None).status, 204);
    let removed = Instant::now();
    loop {
        let r = op2_a.send("GET", "/api/status", None);
        if r.status == 401 {
            break;
        }
        assert!(
            removed.elapsed() < Duration::from_secs(5),
            "a user removed on B still works on A after {:?}",
            removed.elapsed()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let refused_after = removed.elapsed();
    let (ended, _) = stream.join().expect("the stream's reader");
    assert!(
        ended.duration_since(removed) < Duration::from_secs(5),
        "the removed user's event stream on A ended {:?} after the removal",
        ended.duration_since(removed)
    );
    eprintln!(
        "removed on B: refused on A after {refused_after:?}, stream ended after {:?}",
        ended.duration_since(removed)
    );

    // B stops: A's fleet view shows it offline.
    b.terminate();
    wait_fleet(&mut op_a, 20, "B offline", |f| {
        f.get("station-b").map(String::as_str) == Some("offline")
            && f.get("station-a").map(String::as_str) == Some("idle")
    });
    // An offline row has no run fields; an admin retires
    // it (audited); a live station is not retired.
    let rows = op_a.get_json("/api/fleet", 200);
    let b_row = rows
        .as_array()
        .expect("a list")
        .iter()
        .find(|s| s["station"] == "station-b")
        .cloned()
        .expect("station-b listed");
    assert!(
        b_row["run_id"].is_null() && b_row["steps_done"].is_null(),
        "{b_row}"
    );
    // Offline is not retired: another install does not take B's name (its
    // runs, register and yield) until an admin retires B.
    let d_dir = tempfile::tempdir().expect("tempdir");
    share_store(a_dir.path(), d_dir.path());
    let (ok, err) = serve_refused(d_dir.path(), &["--name", "station-b"]);
    assert!(
        !ok && err.contains("already holds the name 'station-b'") && err.contains("retires"),
        "{err}"
    );
    let mut admin_a = Client::login(&a, "admin", "admin-password");
    assert_eq!(
        op_a.send("DELETE", "/api/fleet/station-b", None).status,
        403
    );
    let r = admin_a.send("DELETE", "/api/fleet/station-a", None);
    assert_eq!(r.status, 409, "{:?}", r.json());
    let r = admin_a.send("DELETE", "/api/fleet/station-b", None);
    assert_eq!(r.status, 200, "{:?}", r.json());
    assert!(!fleet(&mut op_a).contains_key("station-b"));
    let audit = admin_a.get_json("/api/audit", 200);
    assert!(
        audit
            .as_array()
            .expect("rows")
            .iter()
            .any(|e| e["action"] == "retire station" && e["detail"] == "station-b"),
        "{audit}"
    );
    drop(a);
    drop(b);
    for log in [&a_log, &b_log] {
        let text = std::fs::read_to_string(log).unwrap_or_default();
        assert!(!text.contains("panicked"), "{}:\n{text}", log.display());
    }
}

/// `spinbench serve` that is expected not to start: its exit status and
/// standard error (it must end by itself within 60 s).
fn serve_refused(data: &std::path::Path, extra: &[&str]) -> (bool, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["serve", "--simulate", "--bind", "127.0.0.1:0", "--data"])
        .arg(data)
        .arg("--db")
        .arg(web::store_of(data))
        .args(extra)
        .output()
        .expect("spinbench serve");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn stations_of_one_store_keep_their_names_and_registers() {
    stations_keep_their_names_and_registers_on(Backend::Sqlite);
}

#[test]
fn postgres_item_1_and_2_stations_of_one_store_keep_their_names_and_registers() {
    stations_keep_their_names_and_registers_on(Backend::Postgres);
}

/// Station B's register is not station A's (A's
/// overdue centrifuge neither blocks B nor counts as B's calibration); a
/// second install under a live station's name is refused at start, naming
/// the holder and how to rename; the first keeps its fleet row.
fn stations_keep_their_names_and_registers_on(backend: Backend) {
    let a_dir = tempfile::tempdir().expect("tempdir");
    let b_dir = tempfile::tempdir().expect("tempdir");
    let c_dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(a_dir.path());
    share_store(a_dir.path(), b_dir.path());
    share_store(a_dir.path(), c_dir.path());
    add_user(a_dir.path(), "eng", "engineer", "eng-password");
    let logs = tempfile::tempdir().expect("tempdir");
    let a = serve_logged(
        a_dir.path(),
        "0",
        &["--name", "station-a"],
        &logs.path().join("a.log"),
    );
    let b = serve_logged(
        b_dir.path(),
        "0",
        &["--name", "station-b"],
        &logs.path().join("b.log"),
    );
    let mut eng_a = Client::login(&a, "eng", "eng-password");
    let mut eng_b = Client::login(&b, "eng", "eng-password");

    // Item 1: A's centrifuge registered overdue is A's alone.
    let overdue = json!({"identity": "CT-A", "certificate": "K-A", "calibrated_on": "2020-01-01", "due_on": "2021-01-01"});
    let r = eng_a.send(
        "PUT",
        "/api/equipment/centrifuge",
        Some(&overdue.to_string()),
    );
    assert_eq!(r.status, 200, "{:?}", r.json());
    let status_of = |c: &mut Client| -> (String, String, Option<String>) {
        let list = c.get_json("/api/equipment", 200);
        let centrifuge = list
            .as_array()
            .expect("a list")
            .iter()
            .find(|e| e["role"] == "centrifuge")
            .cloned()
            .expect("the centrifuge");
        (
            centrifuge["station"].as_str().unwrap_or("").to_string(),
            centrifuge["status"].as_str().unwrap_or("").to_string(),
            centrifuge["certificate"].as_str().map(str::to_string),
        )
    };
    assert_eq!(
        status_of(&mut eng_a),
        ("station-a".into(), "overdue".into(), Some("K-A".into()))
    );
    assert_eq!(
        status_of(&mut eng_b),
        ("station-b".into(), "not in the register".into(), None),
        "station B shows station A's centrifuge"
    );
    // B registers its own; A's stays overdue.
    let valid = json!({"identity": "CT-B", "certificate": "K-B", "calibrated_on": "2025-01-01", "due_on": "2099-01-01"});
    let r = eng_b.send("PUT", "/api/equipment/centrifuge", Some(&valid.to_string()));
    assert_eq!(r.status, 200, "{:?}", r.json());
    assert_eq!(status_of(&mut eng_a).1, "overdue");
    assert_eq!(status_of(&mut eng_b).1, "valid");

    // Item 2: a second install under A's name does not start, and says
    // who holds the name and how to rename.
    let (ok, err) = serve_refused(c_dir.path(), &["--name", "station-a"]);
    assert!(!ok, "a second 'station-a' started");
    assert!(
        err.contains("already holds the name 'station-a'") && err.contains("--name"),
        "{err}"
    );
    // A keeps its fleet row.
    let rows = eng_b.get_json("/api/fleet", 200);
    let a_row = rows
        .as_array()
        .expect("a list")
        .iter()
        .find(|s| s["station"] == "station-a")
        .cloned()
        .expect("station-a in the fleet");
    assert_eq!(a_row["state"], "idle", "{a_row}");
    assert_eq!(a_row["kind"], "server", "{a_row}");
    assert!(
        a_row["address"]
            .as_str()
            .is_some_and(|addr| addr.starts_with(&a.base)),
        "{a_row}"
    );
    // A copied DATA/station-id: a second process of A's identity is refused.
    std::fs::copy(
        a_dir.path().join("station-id"),
        c_dir.path().join("station-id"),
    )
    .expect("copy A's identity");
    let (ok, err) = serve_refused(c_dir.path(), &["--name", "station-a"]);
    assert!(
        !ok && err.contains("was copied") && err.contains("Remove"),
        "{err}"
    );
    std::fs::remove_file(c_dir.path().join("station-id")).expect("rm");
    // A name that looks like a fleet station's is refused.
    for like in ["Station-A", "station-\u{0430}"] {
        let (ok, err) = serve_refused(c_dir.path(), &["--name", like]);
        assert!(
            !ok && err.contains("looks like the fleet's station 'station-a'"),
            "{like}: {err}"
        );
    }
    // A name with an invisible character is refused (item 7).
    let (ok, err) = serve_refused(c_dir.path(), &["--name", "station\u{200B}-a"]);
    assert!(!ok && err.contains("invisible character"), "{err}");
    // The register follows the identity, not the name: B stopped and
    // retired, another install takes the name "station-b" with a register
    // of its own; B's entry is kept under B's identity.
    let mut b = b;
    b.terminate();
    assert!(
        b.wait_exit(Duration::from_secs(60)).is_some(),
        "B did not stop"
    );
    let store = spinbench_store::Store::connect(&spinbench_store::StoreTarget::parse(
        &web::store_of(a_dir.path()).to_string_lossy(),
    ))
    .expect("store");
    assert!(store.retire_station("station-b", "admin").expect("retire"));
    let c = serve_logged(
        c_dir.path(),
        "0",
        &["--name", "station-b"],
        &logs.path().join("c.log"),
    );
    let mut eng_c = Client::login(&c, "eng", "eng-password");
    assert_eq!(
        status_of(&mut eng_c),
        ("station-b".into(), "not in the register".into(), None),
        "the new station-b shows the retired one's centrifuge"
    );
    let kept: Vec<_> = store
        .equipment(None)
        .expect("register")
        .into_iter()
        .filter(|e| e.station.starts_with("station-b (retired, identity "))
        .map(|e| e.certificate)
        .collect();
    assert_eq!(kept, ["K-B"], "B's entry kept under its identity");
    drop((a, c));
}
