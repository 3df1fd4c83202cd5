//! The plan's `[sequential]` on the virtual bench (real pseudo-terminals,
//! production drivers): the levels the data add beside an instrument's own
//! activity dip, mirrored in the other mounting, one notice per pass, and a
//! run killed inside a round resumed from its journal with no level lost or
//! measured twice.

mod common;

use spinbench_analysis::{Direction, Mount};
use spinbench_engine::event::{Event, RunState};
use spinbench_engine::plan::Step;
use spinbench_engine::{RunSummary, StationConfig, TestPlan};
use spinbench_sim::SimConfig;
use spinbench_sim::config::DipConfig;
use spinbench_sim::serve::{RunningBench, ServeOptions};
use spinbench_sim::station::station_toml;
use std::collections::BTreeSet;

/// The planned levels [g]: 5 g apart, so a level halfway between two is
/// 2.5 g from each (the least spacing a chosen level keeps).
const PLANNED_G: [f64; 6] = [0.0, 1.0, 5.0, 10.0, 15.0, 20.0];

/// Levels chosen by the data per mounting.
const BUDGET: usize = 3;

fn plan() -> TestPlan {
    TestPlan::from_toml(&format!(
        r#"
        range_g = 20
        levels = {PLANNED_G:?}
        passes = ["P", "N"]
        warmup_s = 0
        dwell = {{ seconds = 3 }}
        stability = {{ hold_s = 3 }}
        anomalies = "own"
        [limits]
        k2_max_ug_per_g2 = 20
        decide_on = "K2"
        [sequential]
        max_levels_per_pass = {BUDGET}
        [serials]
        1 = "D1"
        2 = "C2"
        3 = "C3"
        4 = "C4"
        5 = "C5"
        6 = "C6"
        "#
    ))
    .expect("plan")
}

/// One module of six; the instrument in slot 1 meets an activity dip of
/// 3,000 µg at 15 g in mounting P (its resonator 1), nowhere in N.
fn bench() -> RunningBench {
    let mut sim = SimConfig {
        modules: 1,
        speed: 0.0,
        ..SimConfig::default()
    };
    sim.instruments.dips.push(DipConfig {
        module: 0,
        slot: 0,
        resonator: 1,
        at_g: Some(15.0),
        at_hz: None,
        size_ug: 3_000.0,
        width_g: 0.5,
    });
    RunningBench::start(sim, ServeOptions::default()).expect("bench")
}

/// Run the plan on `bench` ([`common::run_plan`]).
fn run(
    bench: &RunningBench,
    journal: Option<&[Event]>,
    abort_in_step: Option<usize>,
) -> (RunSummary, Vec<Event>) {
    common::run_plan(bench, &plan(), journal, abort_in_step)
}

/// The levels slot 0-based `slot` was measured at in `mount` that the
/// plan did not name [g].
fn added_levels(summary: &RunSummary, slot: usize, mount: Mount) -> Vec<f64> {
    let mut gs: Vec<f64> = summary.records[slot]
        .points
        .iter()
        .filter(|p| p.mount == mount)
        .map(|p| p.g_nominal.abs())
        .filter(|g| !PLANNED_G.iter().any(|m| (m - g).abs() < 0.05))
        .collect();
    gs.sort_by(f64::total_cmp);
    gs
}

/// Every (mounting, level, direction) of every instrument measured once.
fn assert_each_point_once(summary: &RunSummary) {
    for r in &summary.records {
        let mut seen = BTreeSet::new();
        for p in &r.points {
            let key = (
                p.mount == Mount::P,
                (p.g_nominal.abs() * 10.0).round() as i64,
                p.direction == Direction::Up,
            );
            assert!(seen.insert(key), "{}: {key:?} measured twice", r.serial);
        }
    }
}

fn deciding_notices(events: &[Event]) -> Vec<(String, String)> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Notice {
                message,
                wording: Some(w),
            } if w.key.starts_with("notice.deciding") => Some((w.key.clone(), message.clone())),
            _ => None,
        })
        .collect()
}

#[test]
fn levels_are_added_beside_an_instruments_own_dip_and_mirrored_in_the_other_mounting() {
    let plan = plan();
    let station_bench = bench();
    let station =
        StationConfig::from_toml(&station_toml(&station_bench, "")).expect("station config");
    let steps = plan.compile(&station).expect("compiles").steps;
    // The budget's rounds follow each pass's levels, before the next mounting.
    for pass in 0..2 {
        let rounds: Vec<usize> = steps
            .iter()
            .enumerate()
            .filter(|(_, s)| matches!(s, Step::Decide { pass: p, .. } if *p == pass))
            .map(|(i, _)| i)
            .collect();
        assert_eq!(rounds.len(), BUDGET, "pass {pass}: {steps:?}");
        let last_level = steps
            .iter()
            .rposition(|s| matches!(s, Step::Level { pass: p, .. } if *p == pass))
            .expect("levels");
        assert!(rounds.iter().all(|&i| i > last_level), "{steps:?}");
    }

    let (summary, events) = run(&station_bench, None, None);
    assert_eq!(summary.state, RunState::Completed, "{:?}", summary.reason);
    assert_each_point_once(&summary);
    // Slot 1's dip at 15 g is met in P only: the data ask for support beside
    // it, halfway to a neighbour, never nearer than 2.5 g to a measured level.
    let p_added = added_levels(&summary, 0, Mount::P);
    assert!(
        p_added.iter().any(|g| (g - 15.0).abs() <= 2.5 + 1e-9),
        "no level beside 15 g in P: {p_added:?}"
    );
    assert!(p_added.len() <= BUDGET, "{p_added:?}");
    for g in &p_added {
        for other in PLANNED_G.iter().chain(p_added.iter().filter(|o| *o != g)) {
            assert!((g - other).abs() >= 2.5 - 1e-9, "{g} g beside {other} g");
        }
    }
    // Every level added in P is measured in N too, for every instrument, so
    // the table still cancels from K2.
    for slot in 0..6 {
        let n_added = added_levels(&summary, slot, Mount::N);
        for g in &p_added {
            assert!(
                n_added.iter().any(|n| (n - g).abs() < 0.05),
                "slot {}: {g} g added in P, not in N ({n_added:?})",
                slot + 1
            );
        }
    }
    // One notice per pass, naming the levels it added.
    let notices = deciding_notices(&events);
    assert_eq!(notices.len(), 2, "{notices:?}");
    assert!(
        notices[0].1.contains(&format!("{}", p_added[0])),
        "{notices:?} against {p_added:?}"
    );
    // The instrument is still reduced on its own: its K2 exists and its
    // record names the level of P it set aside.
    let r = &summary.records[0];
    let analysis = r.analysis.as_ref().expect("analysis");
    assert!(
        analysis.joint.is_some(),
        "no K2 for the dipped instrument: {:?}",
        r.reasons
    );
    assert!(
        analysis
            .rule_exclusions
            .iter()
            .any(|e| e.mount == Mount::P && (e.g - 15.0).abs() < 0.05),
        "15 g in P not set aside: {:?}",
        analysis.rule_exclusions
    );
    station_bench.shutdown();
}

#[test]
fn a_run_killed_inside_a_round_resumes_with_no_level_lost_or_measured_twice() {
    let bench = bench();
    let steps = common::steps_of(&bench, &plan());
    // The second round of mounting P.
    let round = steps
        .iter()
        .position(|s| matches!(s, Step::Decide { pass: 0, round: 1 }))
        .expect("a second round in P");
    let (first, journal) = run(&bench, None, Some(round));
    assert_eq!(first.state, RunState::Aborted, "{:?}", first.reason);
    assert!(
        journal
            .iter()
            .any(|e| matches!(e, Event::StepDone { index } if *index == round - 1)),
        "the first round did not end before the abort"
    );
    // The station's process ends with the run; the bench is started again
    // (the same instruments, the table at rest), as after a power cut.
    bench.shutdown();
    let bench = self::bench();
    let (resumed, events) = run(&bench, Some(&journal), None);
    assert_eq!(resumed.state, RunState::Completed, "{:?}", resumed.reason);
    assert_each_point_once(&resumed);
    // The first round's level is kept from before the kill; the torn one
    // is measured in the resumed run.
    let before: BTreeSet<i64> = journal
        .iter()
        .filter_map(|e| match e {
            Event::PointDone { step, points } if *step == round - 1 => points
                .first()
                .map(|p| (p.g_nominal.abs() * 10.0).round() as i64),
            _ => None,
        })
        .collect();
    assert_eq!(before.len(), 1, "{before:?}");
    let p_added = added_levels(&resumed, 0, Mount::P);
    for g in &before {
        assert!(
            p_added.iter().any(|a| ((a * 10.0).round() as i64) == *g),
            "{g} (tenths of a g) lost: {p_added:?}"
        );
    }
    assert!(
        events
            .iter()
            .any(|e| matches!(e, Event::StepStarted { index, .. } if *index == round)),
        "the torn round was not done again"
    );
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, Event::StepStarted { index, .. } if *index == round - 1)),
        "the finished round was measured again"
    );
    bench.shutdown();
}
