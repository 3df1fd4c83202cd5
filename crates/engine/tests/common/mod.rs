//! The harness the engine's tests on the virtual bench share: a plan run
//! on a bench, resumed from a journal, aborted inside a chosen step.

// Each test binary uses its own part of the harness.
#![allow(dead_code)]

use spinbench_engine::event::Event;
use spinbench_engine::{AbortFlag, Executor, RunOptions, RunSummary, StationConfig, TestPlan};
use spinbench_sim::serve::RunningBench;
use spinbench_sim::station::{SimOperator, station_toml};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The run options of a test: `abort` and `pause` the test's own.
pub fn options(abort: &AbortFlag, pause: &Arc<AtomicBool>) -> RunOptions {
    RunOptions {
        run_id: "test".into(),
        abort: abort.clone(),
        pause: pause.clone(),
        module_silence: Duration::from_secs(2),
        station_config_toml: String::new(),
        sink_hold_limit: Duration::from_secs(600),
    }
}

/// The steps `plan` compiles to on `bench`'s station.
pub fn steps_of(bench: &RunningBench, plan: &TestPlan) -> Vec<spinbench_engine::plan::Step> {
    let station = StationConfig::from_toml(&station_toml(bench, "")).expect("station config");
    plan.compile(&station).expect("compiles").steps
}

/// Run `plan` on `bench`, after `journal` when resuming; abort once the
/// step `abort_in_step` has run for 5 one-second values. The summary and
/// every event.
pub fn run_plan(
    bench: &RunningBench,
    plan: &TestPlan,
    journal: Option<&[Event]>,
    abort_in_step: Option<usize>,
) -> (RunSummary, Vec<Event>) {
    let station = StationConfig::from_toml(&station_toml(bench, "")).expect("station config");
    let compiled = plan.compile(&station).expect("plan fits the station");
    let events = Arc::new(Mutex::new(Vec::new()));
    let abort = AbortFlag::new();
    let options = options(&abort, &Arc::new(AtomicBool::new(false)));
    let mut ex = Executor::new(
        &station,
        compiled,
        station.connect().expect("connect the bench's devices"),
        Box::new(SimOperator::new(bench, true)),
        options,
    );
    if let Some(past) = journal {
        ex.restore(past);
    }
    let sink = events.clone();
    let mut in_step: Option<u64> = None;
    ex.subscribe(move |e: &Event| {
        match e {
            Event::StepStarted { index, .. } if Some(*index) == abort_in_step => in_step = Some(0),
            Event::Values { .. } => {
                if let Some(n) = in_step.as_mut() {
                    *n += 1;
                    if *n >= 5 {
                        abort.request("the test");
                    }
                }
            }
            _ => {}
        }
        if let Ok(mut v) = sink.lock() {
            v.push(e.clone());
        }
    });
    let summary = ex.run();
    let events = events.lock().map(|v| v.clone()).unwrap_or_default();
    (summary, events)
}
