//! A run folder's left-over file (`store-outbox.jsonl`: events a store had
//! not taken when the run's process ended) is never trusted whole: a forged
//! file in a completed run's folder, or in a folder holding another
//! station's run, changes nothing in the store and is set aside and
//! audited; two starts catching up one file write it once; a torn last line
//! is kept aside and the good lines written.

mod common;

use common::spinbench;
use spinbench_store::{Store, StoreTarget};
use std::path::{Path, PathBuf};

const OUTBOX: &str = "store-outbox.jsonl";

/// A completed simulated run in `data` (its own SQLite store): its folder.
fn a_completed_run(data: &Path, prefix: &str) -> PathBuf {
    let plan = data
        .parent()
        .expect("parent")
        .join(format!("{prefix}plan.toml"));
    std::fs::write(&plan, common::short_plan(prefix)).expect("plan");
    let (ok, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--quiet",
        "--data",
        data.to_str().expect("utf-8"),
        plan.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{err}");
    std::fs::read_dir(data.join("runs"))
        .expect("runs")
        .flatten()
        .map(|e| e.path())
        .find(|p| p.join("journal.jsonl").is_file())
        .expect("a run folder")
}

fn store_of(data: &Path) -> Store {
    Store::connect(&StoreTarget::File(data.join("spinbench.db"))).expect("store")
}

fn audited(store: &Store, action: &str) -> usize {
    store
        .audit_log(500)
        .expect("audit")
        .iter()
        .filter(|a| a.action == action)
        .count()
}

/// The journal's lines with `edit` applied to each.
fn journal_edited(run: &Path, edit: impl Fn(&str) -> String) -> String {
    std::fs::read_to_string(run.join("journal.jsonl"))
        .expect("journal")
        .lines()
        .map(|l| edit(l) + "\n")
        .collect()
}

#[test]
fn a_forged_left_over_file_changes_nothing_and_is_set_aside_and_audited() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let run = a_completed_run(&data, "LF-");
    let id = run.file_name().expect("id").to_string_lossy().into_owned();
    let store = store_of(&data);
    let before = store.run_record(&id).expect("read").expect("the run");
    // A point's output changed and the run's results again: never measured so.
    let forged = journal_edited(&run, |l| {
        if l.contains("\"event\":\"point_done\"") {
            l.replacen("\"output_hz\":", "\"output_hz\":1", 1)
        } else {
            l.to_string()
        }
    });
    std::fs::write(run.join(OUTBOX), forged).expect("forge");
    // The next start of the station looks at left-over files.
    a_completed_run(&data, "LG-");
    assert_eq!(
        store.run_record(&id).expect("read").expect("the run"),
        before,
        "the completed run's record changed"
    );
    assert!(!run.join(OUTBOX).exists());
    assert!(run.join(format!("{OUTBOX}.refused")).is_file());
    assert_eq!(audited(&store, "refuse left-over events"), 1);
    assert_eq!(audited(&store, "catch up left-over events"), 0);

    // Another station's run copied into a new folder of this station's,
    // with a left-over file of all its events: refused, not written.
    let other = data.join("runs").join("run-1700000000-0123456789ab");
    std::fs::create_dir_all(&other).expect("other");
    let theirs = journal_edited(&run, |l| {
        l.replace(&id, "run-1700000000-0123456789ab")
            .replace("spinbench virtual bench", "line 2")
    });
    std::fs::write(other.join("journal.jsonl"), &theirs).expect("journal");
    std::fs::write(other.join(OUTBOX), &theirs).expect("outbox");
    a_completed_run(&data, "LH-");
    assert!(
        store
            .run("run-1700000000-0123456789ab")
            .expect("read")
            .is_none(),
        "another station's run was written"
    );
    assert_eq!(audited(&store, "refuse left-over events"), 2);
}

#[test]
fn two_starts_catch_up_one_left_over_file_once_and_a_torn_tail_is_kept_aside() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let run = a_completed_run(&data, "LT-");
    let id = run.file_name().expect("id").to_string_lossy().into_owned();
    // A store that never took the run: the left-over file is all of it
    // (the journal's events), and its last line torn.
    std::fs::remove_file(data.join("spinbench.db")).expect("rm store");
    let mut left = journal_edited(&run, str::to_string);
    left.push_str("{\"event\":\"notice\",\"mess");
    std::fs::write(run.join(OUTBOX), left).expect("left-over file");
    let store = store_of(&data);
    assert!(store.run(&id).expect("read").is_none());
    let starts: Vec<_> = (0..2)
        .map(|_| {
            let data = data.clone();
            std::thread::spawn(move || {
                let store = store_of(&data);
                spinbench_station::recovery::recover(&data, "spinbench virtual bench", &store)
            })
        })
        .collect();
    let done: Vec<_> = starts
        .into_iter()
        .map(|t| t.join().expect("a start"))
        .collect();
    let caught: usize = done.iter().map(|d| d.caught_up.len()).sum();
    assert_eq!(caught, 1, "{done:?}");
    assert_eq!(audited(&store, "catch up left-over events"), 1);
    let record = store
        .run_record(&id)
        .expect("read")
        .expect("the run written");
    assert!(!record.points.is_empty());
    assert!(run.join(format!("{OUTBOX}.torn")).is_file());
    assert!(!run.join(OUTBOX).exists());
}
