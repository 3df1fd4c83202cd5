//! Whatever ends the process, the table stops: `spinbench run` drives a
//! separate `spinbench sim` process through the real drivers (real PTYs),
//! answers its prompts as an operator would (remounting through the bench's
//! control socket), and is sent SIGTERM, SIGHUP or SIGINT while the table
//! spins. After the station exits, this test reads the controller's rate
//! and the rails through the same drivers, and the run's record from the
//! store.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

#[path = "common/bench.rs"]
mod bench;
use bench::{Operated, start_sim};

/// Run a plan against a separate bench, signal the station at a level,
/// and check the table, the rails and the record afterwards.
fn signal_while_spinning(signal: &str, name: &str) {
    let dir = tempfile::tempdir().expect("tempdir");
    let sim = start_sim("10");
    let data = dir.path().join("data");
    let mut run = Operated::run_on(
        dir.path(),
        &sim,
        "signal test",
        "",
        &bench::plan_to_20g("SIG", ""),
        &[],
    );
    // The operator: remount as asked, press Enter; wait for a level above 1 g.
    let spinning = run.operate_until(&sim, Duration::from_secs(120), |l| l.contains("10 g Up"));
    assert!(
        spinning,
        "the run never reached 10 g:\n{}",
        run.transcript()
    );
    // Let the table reach speed, then the signal.
    std::thread::sleep(Duration::from_millis(1500));
    let kill = Command::new("kill")
        .args([&format!("-{signal}"), &run.run.id().to_string()])
        .status()
        .expect("kill");
    assert!(kill.success());
    let ended = Instant::now();
    let status = run.wait(&sim, Duration::from_secs(60));
    let status = status.unwrap_or_else(|| {
        panic!(
            "spinbench run did not exit within 60 s of {name} ({:.0} s)",
            ended.elapsed().as_secs_f64()
        )
    });
    assert!(!status.success(), "an aborted run is not a success");
    assert!(
        run.seen.iter().any(|l| l.contains(name)),
        "the signal is named on screen:\n{}",
        run.transcript()
    );

    // The station is gone: its ports are free, read the devices ourselves.
    let (rate, rails) = sim.read_back();
    assert!(
        rate.abs() < 0.05,
        "the table still turns at {rate} deg/s after {name}"
    );
    for (ch, volts) in rails.iter().enumerate() {
        assert!(
            volts.abs() < 0.5,
            "rail {} at {volts} V after {name}",
            ch + 1
        );
    }
    check_recorded(&data, name);
}

/// The store says `aborted`, naming the signal.
fn check_recorded(data: &Path, name: &str) {
    let store = spinbench_store::Store::open_read_only(&spinbench_store::StoreTarget::File(
        data.join("spinbench.db"),
    ))
    .expect("store");
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 1);
    assert_eq!(runs[0].state.as_str(), "aborted", "{:?}", runs[0].reason);
    let reason = runs[0].reason.clone().unwrap_or_default();
    assert!(reason.contains(name), "{reason}");
    for r in store.results(&runs[0].id).expect("results") {
        assert_eq!(r.outcome.as_str(), "incomplete", "{}", r.serial);
    }
}

#[test]
fn sigterm_stops_the_table_switches_off_and_records_the_signal() {
    signal_while_spinning("TERM", "SIGTERM");
}

#[test]
fn sighup_stops_the_table_switches_off_and_records_the_signal() {
    signal_while_spinning("HUP", "SIGHUP");
}

#[test]
fn sigint_stops_the_table_switches_off_and_records_the_signal() {
    signal_while_spinning("INT", "SIGINT");
}
