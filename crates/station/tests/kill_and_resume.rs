//! Crash recovery: `spinbench run --simulate` is killed (SIGKILL) at random
//! moments and continued with `--resume`; the final points must be the same
//! points as an uninterrupted run's (same levels, directions and slots, none
//! lost or doubled), and every point journaled before the kill must come
//! through unchanged.

mod common;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

fn spinbench() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spinbench"))
}

fn the_run_dir(data: &Path) -> Option<PathBuf> {
    std::fs::read_dir(data.join("runs"))
        .ok()?
        .flatten()
        .map(|e| e.path())
        .next()
}

/// (slot, mount, g_nominal, direction) of every point, and the points themselves.
fn points(dir: &Path) -> Vec<(u64, String, String, String, Value)> {
    let text = std::fs::read_to_string(dir.join("results.json")).expect("results.json");
    let records: Vec<Value> = serde_json::from_str(&text).expect("json");
    let mut out = Vec::new();
    for r in records {
        for p in r["points"].as_array().cloned().unwrap_or_default() {
            out.push((
                p["slot"].as_u64().unwrap_or(99),
                p["mount"].to_string(),
                p["g_nominal"].to_string(),
                p["direction"].to_string(),
                p,
            ));
        }
    }
    out.sort_by(|a, b| (a.0, &a.1, &a.3, &a.2).cmp(&(b.0, &b.1, &b.3, &b.2)));
    out
}

/// Points completed (PointDone followed by its StepDone) before the first resume.
fn journaled_before_kill(dir: &Path) -> Vec<(i64, Value)> {
    let text = std::fs::read_to_string(dir.join("journal.jsonl")).expect("journal");
    let mut events: Vec<Value> = Vec::new();
    for line in text.lines() {
        let Ok(e) = serde_json::from_str::<Value>(line) else {
            continue;
        };
        if e["event"] == "run_started" && e["resumed"] == true {
            break;
        }
        events.push(e);
    }
    let done: Vec<u64> = events
        .iter()
        .filter(|e| e["event"] == "step_done")
        .filter_map(|e| e["index"].as_u64())
        .collect();
    events
        .iter()
        .filter(|e| {
            e["event"] == "point_done" && e["step"].as_u64().is_some_and(|s| done.contains(&s))
        })
        .flat_map(|e| {
            let step = e["step"].as_i64().unwrap_or(-1);
            e["points"]
                .as_array()
                .cloned()
                .unwrap_or_default()
                .into_iter()
                .map(move |p| (step, p))
        })
        .collect()
}

#[test]
fn killed_runs_resume_with_no_point_lost_or_doubled() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("K")).expect("plan");

    // The uninterrupted run, and how long it takes.
    let data0 = dir.path().join("data0");
    let start = Instant::now();
    let status = spinbench()
        .args(["run", "--simulate", "--quiet", "--seed", "5", "--data"])
        .arg(&data0)
        .arg(&plan)
        .stdout(Stdio::null())
        .status()
        .expect("run");
    assert!(status.success());
    let full = start.elapsed();
    let reference = points(&the_run_dir(&data0).expect("run dir"));
    assert_eq!(
        reference.len(),
        3 * 2 * 13,
        "3 instruments × 2 mountings × 13 points"
    );

    let mut rng = ChaCha8Rng::seed_from_u64(2026);
    let mut resumed_trials = 0;
    let mut stored_checks = 0;
    let mut replayed_trials = 0;
    // Kill times are drawn from the reference run's length, and a loaded
    // machine makes runs slower or faster than that one: trials go on until
    // ten have been killed mid-run (at most 48: on a loaded machine many
    // kills land before the run has stored anything, or after its end).
    for trial in 0..48 {
        if stored_checks >= 10 && resumed_trials >= 10 {
            break;
        }
        let data = dir.path().join(format!("data{}", trial + 1));
        let kill_after = full.mul_f64(rng.random_range(0.1..0.8));
        let mut child = spinbench()
            .args(["run", "--simulate", "--quiet", "--seed", "5", "--data"])
            .arg(&data)
            .arg(&plan)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn");
        std::thread::sleep(kill_after);
        let finished_already = child.try_wait().ok().flatten().is_some();
        let _ = child.kill(); // SIGKILL
        let _ = child.wait();
        let Some(run_dir) = the_run_dir(&data) else {
            continue;
        };
        if finished_already || !run_dir.join("journal.jsonl").exists() {
            continue;
        }
        let before = journaled_before_kill(&run_dir);
        let run_id = run_dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        // Kill during write: the store opens and is sound. The points the
        // outbox still held in memory died with the process (the journal,
        // synced first, has them): the resume below writes them, and the
        // store must then hold every point the journal completed.
        let db = data.join("spinbench.db");
        if db.exists() {
            let store = spinbench_store::Store::open(&db).expect("the store opens after SIGKILL");
            assert_eq!(
                store.integrity_check().expect("integrity check"),
                "ok",
                "trial {trial}"
            );
            stored_checks += 1;
        }
        let out = spinbench()
            .args(["run", "--simulate", "--quiet", "--seed", "5", "--resume"])
            .arg(&run_dir)
            .arg(&plan)
            .output()
            .expect("resume");
        let stderr = String::from_utf8_lossy(&out.stderr);
        if stderr.contains("already completed") {
            continue;
        }
        if !out.status.success() {
            let journal =
                std::fs::read_to_string(run_dir.join("journal.jsonl")).unwrap_or_default();
            let telling: Vec<&str> = journal
                .lines()
                .filter(|l| {
                    l.contains("unit_failed")
                        || l.contains("run_started")
                        || l.contains("\"fault\"")
                })
                .map(|l| if l.len() > 300 { &l[..300] } else { l })
                .collect();
            panic!(
                "trial {trial} (killed after {kill_after:?}): resume failed: {stderr}\njournal: {telling:#?}"
            );
        }
        resumed_trials += 1;
        // The resumed run finished in its own store, with each point once,
        // every point the journal completed before the kill among them.
        let store = spinbench_store::Store::open(&data.join("spinbench.db")).expect("store");
        let stored = store.point_keys(&run_id).expect("keys");
        for p in &before {
            let key = (p.0, p.1["slot"].as_i64().unwrap_or(-1));
            assert!(
                stored.contains(&key),
                "trial {trial}: point {key:?} completed in the journal before the kill is missing from the store"
            );
        }
        assert_eq!(
            store.point_keys(&run_id).expect("keys").len(),
            reference.len(),
            "trial {trial}: points in the store"
        );
        assert_eq!(
            store.run(&run_id).expect("run").map(|r| r.state),
            Some(spinbench_store::StoredState::Completed),
            "trial {trial}"
        );
        let got = points(&run_dir);
        let keys =
            |v: &[(u64, String, String, String, Value)]| -> Vec<(u64, String, String, String)> {
                v.iter()
                    .map(|(a, b, c, d, _)| (*a, b.clone(), c.clone(), d.clone()))
                    .collect()
            };
        if keys(&got) != keys(&reference) {
            let results = std::fs::read_to_string(run_dir.join("results.json")).unwrap_or_default();
            let units: Vec<String> = serde_json::from_str::<Vec<Value>>(&results)
                .unwrap_or_default()
                .iter()
                .map(|r| {
                    format!(
                        "{}: {} points, {}",
                        r["serial"],
                        r["points"].as_array().map_or(0, Vec::len),
                        r["reasons"]
                    )
                })
                .collect();
            panic!(
                "trial {trial} (killed after {kill_after:?}): different points; units: {units:#?}\nresume stderr: {stderr}"
            );
        }
        for (_, p) in &before {
            assert!(
                got.iter().any(|g| &g.4 == p),
                "trial {trial}: a point journaled before the kill changed or vanished: {p}"
            );
        }
        // The raw capture survived the kill: the replay finds every stored
        // value (of the killed and of the resumed process) bit for bit.
        let replay = spinbench()
            .args(["replay", "--db"])
            .arg(data.join("spinbench.db"))
            .arg(&run_dir)
            .output()
            .expect("replay");
        let said = String::from_utf8_lossy(&replay.stdout);
        assert!(
            replay.status.success(),
            "trial {trial}: the replay of a resumed run failed: {said}{}",
            String::from_utf8_lossy(&replay.stderr)
        );
        replayed_trials += 1;
    }
    assert!(
        stored_checks >= 10,
        "the store was checked after only {stored_checks} kills"
    );
    assert!(
        resumed_trials >= 10,
        "only {resumed_trials} trials were killed mid-run"
    );
    assert_eq!(replayed_trials, resumed_trials);
}

#[test]
fn a_run_being_run_cannot_be_resumed_by_another_process() {
    // A second `--resume` of a run that a process is
    // running (here the first run itself, at real time) is refused: the
    // run's directory is locked, so the journal never gets a second record.
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("L")).expect("plan");
    let data = dir.path().join("data");
    // The virtual bench at real time: the first run lasts minutes.
    let bench = dir.path().join("bench.toml");
    std::fs::write(&bench, "speed = 1.0\n").expect("bench");
    let mut first = spinbench()
        .args(["run", "--simulate", "--quiet", "--bench"])
        .arg(&bench)
        .arg("--data")
        .arg(&data)
        .arg(&plan)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn");
    let until = Instant::now() + std::time::Duration::from_secs(30);
    let run_dir = loop {
        if let Some(d) = the_run_dir(&data).filter(|d| d.join("journal.jsonl").exists()) {
            break d;
        }
        assert!(Instant::now() < until, "the first run did not start");
        std::thread::sleep(std::time::Duration::from_millis(100));
    };
    let second = spinbench()
        .args(["run", "--simulate", "--quiet", "--resume"])
        .arg(&run_dir)
        .arg(&plan)
        .output()
        .expect("resume");
    let _ = first.kill();
    let _ = first.wait();
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert!(
        !second.status.success(),
        "a second process resumed a running run"
    );
    assert!(stderr.contains("being run by another process"), "{stderr}");
    // Once the first process is gone, the run can be resumed.
    let third = spinbench()
        .args(["run", "--simulate", "--quiet", "--resume"])
        .arg(&run_dir)
        .arg(&plan)
        .stdout(Stdio::null())
        .output()
        .expect("resume");
    assert!(
        third.status.success(),
        "{}",
        String::from_utf8_lossy(&third.stderr)
    );
}

/// A run is continued only on its own station: not under
/// another station's name, and never on the virtual bench when it was
/// recorded on hardware (nor the other way round). Nothing is run.
#[test]
fn a_run_is_resumed_only_on_its_own_station_and_bench() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("R")).expect("plan");
    let data = dir.path().join("data");
    let mut child = spinbench()
        .args(["run", "--simulate", "--quiet", "--seed", "5", "--data"])
        .arg(&data)
        .arg(&plan)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn");
    // Killed once its journal has started the run.
    let until = Instant::now() + std::time::Duration::from_secs(60);
    let run_dir = loop {
        if let Some(d) = the_run_dir(&data).filter(|d| {
            std::fs::read_to_string(d.join("journal.jsonl"))
                .is_ok_and(|j| j.contains("run_started"))
        }) {
            break d;
        }
        assert!(Instant::now() < until, "no run started in 60 s");
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let _ = child.kill();
    let _ = child.wait();
    let recorded = std::fs::read_to_string(run_dir.join("station.toml")).expect("station.toml");
    assert!(recorded.contains("simulated = true"), "{recorded}");
    let journal_before = std::fs::read(run_dir.join("journal.jsonl")).expect("journal");
    let resume = |extra: &[&str]| {
        let out = spinbench()
            .args(["run", "--quiet", "--data"])
            .arg(&data)
            .arg("--resume")
            .arg(&run_dir)
            .args(extra)
            .arg(&plan)
            .output()
            .expect("resume");
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    // Another station's name (its own config, the bench's devices).
    let other = dir.path().join("other.toml");
    std::fs::write(
        &other,
        recorded.replace(
            "station = \"spinbench virtual bench\"",
            "station = \"line 2\"",
        ),
    )
    .expect("other station");
    let (ok, err) = resume(&["--simulate", "--station", other.to_str().expect("utf-8")]);
    assert!(
        !ok && err
            .contains("recorded on station 'spinbench virtual bench', this is station 'line 2'"),
        "{err}"
    );
    // Another arm: every level's speed and the g of its points would change.
    let other_arm = dir.path().join("other-arm.toml");
    assert!(recorded.contains("radius_m = 0.8"), "{recorded}");
    std::fs::write(
        &other_arm,
        recorded.replacen("radius_m = 0.8", "radius_m = 0.5", 1),
    )
    .expect("another arm");
    let (ok, err) = resume(&[
        "--simulate",
        "--station",
        other_arm.to_str().expect("utf-8"),
    ]);
    assert!(
        !ok && err.contains("[arm] is not what the run was recorded with"),
        "{err}"
    );
    // An overdue device: a resume moves the table, so it is refused as a
    // new run is, naming the override.
    let db = data.join("spinbench.db");
    let set = spinbench()
        .args(["equipment", "set", "centrifuge", "--identity", "CT 1"])
        .args(["--certificate", "K-1", "--calibrated", "2020-01-01"])
        .args([
            "--due",
            "2021-01-01",
            "--station",
            "spinbench virtual bench",
        ])
        .arg("--db")
        .arg(&db)
        .output()
        .expect("equipment set");
    assert!(
        set.status.success(),
        "{}",
        String::from_utf8_lossy(&set.stderr)
    );
    let (ok, err) = resume(&["--simulate"]);
    assert!(
        !ok && err.contains("overdue") && err.contains("--override-overdue"),
        "{err}"
    );
    // A run recorded on hardware is not continued on the virtual bench.
    std::fs::write(
        run_dir.join("station.toml"),
        recorded.replace("simulated = true\n", ""),
    )
    .expect("as if recorded on hardware");
    let recorded_hw = std::fs::read_to_string(run_dir.join("station.toml")).expect("toml");
    std::fs::write(
        run_dir.join("station.toml"),
        recorded_hw.replace("name = \"sim-table\"", "name = \"CT-500\""),
    )
    .expect("a hardware centrifuge");
    let (ok, err) = resume(&["--simulate"]);
    assert!(
        !ok && err.contains("recorded on station hardware") && err.contains("virtual bench"),
        "{err}"
    );
    // Nothing was run: the journal is as the kill left it.
    assert_eq!(
        std::fs::read(run_dir.join("journal.jsonl")).expect("journal"),
        journal_before
    );
}
