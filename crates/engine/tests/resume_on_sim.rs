//! A resumed run is measured in the run's thermal state: after a break the
//! instruments are cold, so the warm-up is run again before the first
//! measured step, and said (on the virtual bench, restarted as after a
//! power cut).

mod common;

use spinbench_analysis::Mount;
use spinbench_engine::event::{Event, RunState};
use spinbench_engine::plan::Step;
use spinbench_engine::{PointRecord, TestPlan};
use spinbench_sim::SimConfig;
use spinbench_sim::serve::{RunningBench, ServeOptions};

/// The warm-up [s]: five of the virtual instruments' self-heating time
/// constants (120 s), so they are within 0.03 °C of their running state.
const WARMUP_S: f64 = 600.0;

fn plan() -> TestPlan {
    TestPlan::from_toml(&format!(
        r#"
        range_g = 20
        levels = [0, 1, 5, 10, 15, 20]
        passes = ["P", "N"]
        warmup_s = {WARMUP_S}
        dwell = {{ seconds = 3 }}
        stability = {{ hold_s = 3 }}
        [serials]
        1 = "T1"
        2 = "T2"
        3 = "T3"
        "#
    ))
    .expect("plan")
}

/// A fresh bench: the instruments unpowered and at the laboratory's
/// temperature (they heat by 4 °C with a 120 s time constant once powered).
fn bench() -> RunningBench {
    let sim = SimConfig {
        modules: 1,
        speed: 0.0,
        ..SimConfig::default()
    };
    RunningBench::start(sim, ServeOptions::default()).expect("bench")
}

fn points(events: &[Event]) -> Vec<&PointRecord> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::PointDone { points, .. } => Some(points),
            _ => None,
        })
        .flatten()
        .collect()
}

#[test]
fn a_resumed_run_warms_up_again_and_measures_in_the_runs_thermal_state() {
    let bench = bench();
    let steps = common::steps_of(&bench, &plan());
    // Killed in mounting N's first level, mounting P measured whole.
    let mount_n = steps
        .iter()
        .rposition(|s| matches!(s, Step::Mount { .. }))
        .expect("a mounting");
    let first_n_level = (mount_n..steps.len())
        .find(|&i| matches!(steps[i], Step::Level { .. }))
        .expect("a level in N");
    let (first, journal) = common::run_plan(&bench, &plan(), None, Some(first_n_level));
    assert_eq!(first.state, RunState::Aborted, "{:?}", first.reason);
    bench.shutdown();
    let bench = self::bench();
    let (resumed, events) = common::run_plan(&bench, &plan(), Some(&journal), None);
    assert_eq!(resumed.state, RunState::Completed, "{:?}", resumed.reason);
    // Said on the record.
    assert!(
        events.iter().any(
            |e| matches!(e, Event::Notice { message, .. } if message.contains("warm up again"))
        ),
        "no notice of the second warm-up"
    );
    // Each instrument's first point after the resume at the temperature it
    // was measured at in mounting P, not the laboratory's.
    let before = points(&journal);
    let after = points(&events);
    for slot in 0..3 {
        let p: Vec<f64> = before
            .iter()
            .filter(|q| q.slot == slot && q.mount == Mount::P)
            .filter_map(|q| q.temperature_c)
            .collect();
        assert!(!p.is_empty(), "slot {slot}: no temperatures in P");
        let (low, high) = p
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), t| {
                (l.min(*t), h.max(*t))
            });
        let first_after = after
            .iter()
            .find(|q| q.slot == slot)
            .and_then(|q| q.temperature_c)
            .expect("a resumed point with a temperature");
        assert!(
            (low - 0.2..=high + 0.2).contains(&first_after),
            "slot {slot}: first resumed point at {first_after:.3} °C, P measured at {low:.3}–{high:.3} °C"
        );
    }
}
