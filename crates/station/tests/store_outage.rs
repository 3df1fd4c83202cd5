//! The run never waits on the store: `spinbench run` drives a
//! separate `spinbench sim` (real PTYs) and writes to a PostgreSQL server
//! of the test's own, which is restarted, or paused (SIGSTOP: a stall, as a
//! network partition without a reset), in the middle of the run.

use std::process::Command;
use std::time::{Duration, Instant};

#[path = "common/bench.rs"]
mod bench;
#[path = "common/postgres.rs"]
mod postgres;
use bench::{Operated, Sim, start_sim};
use postgres::Cluster;

/// A PostgreSQL of the test's own, a `spinbench sim` and a run of the
/// 20-g plan on them, operated until it says `line` (None without a
/// PostgreSQL: the test is skipped).
fn running_to(line: &str) -> Option<(Cluster, tempfile::TempDir, Sim, Operated)> {
    let db = Cluster::start()?;
    let dir = tempfile::tempdir().expect("tempdir");
    let sim = start_sim("10");
    let mut run = start_run(dir.path(), &sim, &db.url);
    assert!(
        run.operate_until(&sim, Duration::from_secs(120), |l| l.contains(line)),
        "the run never reached {line}:\n{}",
        run.transcript()
    );
    Some((db, dir, sim, run))
}

/// A run of the 20-g plan on `sim` writing to `url`, in `dir`.
fn start_run(dir: &std::path::Path, sim: &Sim, url: &str) -> Operated {
    Operated::run_on(
        dir,
        sim,
        "outage test",
        "",
        &bench::plan_to_20g("OUT", ""),
        &["--db".as_ref(), url.as_ref()],
    )
}

/// The instruments' points the journal of the only run under `data`
/// recorded (a point of the plan is one per instrument: two).
fn journal_points(data: &std::path::Path) -> usize {
    let runs = data.join("runs");
    let run = std::fs::read_dir(&runs)
        .expect("runs")
        .flatten()
        .next()
        .expect("a run directory")
        .path();
    std::fs::read_to_string(run.join("journal.jsonl"))
        .expect("journal")
        .lines()
        .filter(|l| l.contains("\"event\":\"point_done\""))
        .count()
        * 2
}

#[test]
fn a_postgres_restart_in_the_middle_of_a_run_loses_nothing() {
    let Some((db, dir, sim, mut run)) = running_to("5 g Up") else {
        return;
    };
    db.restart();
    let status = run
        .wait(&sim, Duration::from_secs(240))
        .unwrap_or_else(|| panic!("the run did not end:\n{}", run.transcript()));
    assert!(status.success(), "{}", run.transcript());
    assert!(
        !run.seen.iter().any(|l| l.contains("held")),
        "the run was held:\n{}",
        run.transcript()
    );
    // Everything is in the store: the run completed, every point, both results.
    let store =
        spinbench_store::Store::connect(&spinbench_store::StoreTarget::Postgres(db.url.clone()))
            .expect("store");
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 1);
    assert_eq!(runs[0].state.as_str(), "completed", "{:?}", runs[0].reason);
    let points = store.points(&runs[0].id).expect("points").len();
    assert!(points > 0);
    assert_eq!(points, journal_points(&dir.path().join("data")));
    assert_eq!(store.results(&runs[0].id).expect("results").len(), 2);
    assert!(store.value_count(&runs[0].id).expect("values") > 0);
}

#[test]
fn a_stalled_postgres_neither_stops_the_measuring_nor_the_abort() {
    let Some((db, dir, sim, mut run)) = running_to("5 g Up") else {
        return;
    };
    db.pause();
    // The run goes on measuring with the database stalled: the next level.
    assert!(
        run.operate_until(&sim, Duration::from_secs(60), |l| l.contains("10 g Up")),
        "the run stopped measuring while the database stalled:\n{}",
        run.transcript()
    );
    // SIGTERM: the safe state whatever the database does, the process ends.
    std::thread::sleep(Duration::from_millis(1500));
    assert!(
        Command::new("kill")
            .args(["-TERM", &run.run.id().to_string()])
            .status()
            .expect("kill")
            .success()
    );
    let signalled = Instant::now();
    let status = run
        .wait(&sim, Duration::from_secs(60))
        .unwrap_or_else(|| panic!("no exit within 60 s of SIGTERM:\n{}", run.transcript()));
    let took = signalled.elapsed();
    eprintln!(
        "stall: spinbench run exited {:.1} s after SIGTERM",
        took.as_secs_f64()
    );
    assert!(!status.success());
    assert!(took < Duration::from_secs(30), "took {took:?}");
    let (rate, rails) = sim.read_back();
    assert!(rate.abs() < 0.05, "the table turns at {rate} deg/s");
    assert!(rails.iter().all(|v| v.abs() < 0.5), "rails at {rails:?}");
    // What the store did not take is kept, and written once it is back.
    let data = dir.path().join("data");
    let left = std::fs::read_dir(data.join("runs"))
        .expect("runs")
        .flatten()
        .any(|e| {
            e.path()
                .join(spinbench_store::outbox::OUTBOX_FILE)
                .is_file()
        });
    assert!(left, "no outbox file kept:\n{}", run.transcript());
    db.resume();
    let store =
        spinbench_store::Store::connect(&spinbench_store::StoreTarget::Postgres(db.url.clone()))
            .expect("store");
    let recovered = spinbench_station::recovery::recover(&data, "outage test", &store);
    assert_eq!(recovered.caught_up.len(), 1, "{recovered:?}");
    assert!(recovered.problems.is_empty(), "{recovered:?}");
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 1);
    assert_eq!(runs[0].state.as_str(), "aborted", "{:?}", runs[0].reason);
    assert!(
        runs[0]
            .reason
            .as_deref()
            .unwrap_or_default()
            .contains("SIGTERM"),
        "{:?}",
        runs[0].reason
    );
    assert_eq!(
        store.points(&runs[0].id).expect("points").len(),
        journal_points(&data)
    );
}

#[test]
fn a_minute_of_a_stalled_postgres_under_a_run_loses_nothing() {
    let Some((db, dir, sim, mut run)) = running_to("1 g Up") else {
        return;
    };
    db.pause();
    let paused = Instant::now();
    // The run measures on through the minute: two more levels at least.
    assert!(
        run.operate_until(&sim, Duration::from_secs(60), |l| l.contains("10 g Up")),
        "the run stopped measuring while the database stalled:\n{}",
        run.transcript()
    );
    let measured_by_s = paused.elapsed().as_secs_f64();
    std::thread::sleep(Duration::from_secs(60).saturating_sub(paused.elapsed()));
    db.resume();
    let status = run
        .wait(&sim, Duration::from_secs(300))
        .unwrap_or_else(|| panic!("the run did not end:\n{}", run.transcript()));
    eprintln!(
        "stalled 60 s; 10 g measured {measured_by_s:.0} s into the stall; the run ended {:.0} s after the pause began",
        paused.elapsed().as_secs_f64()
    );
    assert!(status.success(), "{}", run.transcript());
    let store =
        spinbench_store::Store::connect(&spinbench_store::StoreTarget::Postgres(db.url.clone()))
            .expect("store");
    let runs = store.runs().expect("runs");
    assert_eq!(runs[0].state.as_str(), "completed", "{:?}", runs[0].reason);
    assert_eq!(
        store.points(&runs[0].id).expect("points").len(),
        journal_points(&dir.path().join("data"))
    );
    assert_eq!(store.results(&runs[0].id).expect("results").len(), 2);
}
