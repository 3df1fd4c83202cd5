//! The engine against the virtual bench (real pseudo-terminals, production
//! drivers): a complete run, every safety path by fault injection, failed
//! instruments, abort, and the refusal of a plan beyond the limits.

mod common;

use spinbench_analysis::Mount;
use spinbench_engine::event::{Event, EventSink, RunState};
use spinbench_engine::plan::DecisionRule;
use spinbench_engine::{
    Bench, Executor, Outcome, ReasonCode, RunOptions, RunSummary, StationConfig, TestPlan,
};
use spinbench_sim::SimConfig;
use spinbench_sim::config::SlotRef;
use spinbench_sim::serve::{RunningBench, ServeOptions};
use spinbench_sim::station::{SimOperator, station_toml};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

fn station_for(bench: &RunningBench) -> StationConfig {
    StationConfig::from_toml(&station_toml(bench, "")).expect("the bench's station config is valid")
}

fn small_plan() -> TestPlan {
    TestPlan::from_toml(
        r#"
        range_g = 10
        levels = [0, 1, 2, 4, 6, 8, 10]
        passes = ["P"]
        warmup_s = 0
        dwell = { seconds = 3 }
        stability = { hold_s = 3 }
        limits = { decide_on = "k2_max" }
        [serials]
        1 = "A1"
        2 = "A2"
        3 = "A3"
        4 = "A4"
        5 = "A5"
        6 = "A6"
        7 = "B1"
        8 = "B2"
        9 = "B3"
        "#,
    )
    .expect("plan")
}

fn connect(station: &StationConfig) -> Bench {
    station.connect().expect("connect the bench's devices")
}

/// Run `plan` on a bench built from `sim`; returns the summary, the events and the bench.
fn run(
    sim: SimConfig,
    plan: TestPlan,
    abort_after_windows: Option<u64>,
) -> (RunSummary, Vec<Event>, RunningBench) {
    run_paused(sim, plan, abort_after_windows, None, &|_| {})
}

/// As `run`, pausing at window `pause.0` and resuming at window `pause.1` when given.
fn run_paused(
    sim: SimConfig,
    plan: TestPlan,
    abort_after_windows: Option<u64>,
    pause_windows: Option<(u64, u64)>,
    adjust_station: &dyn Fn(&mut StationConfig),
) -> (RunSummary, Vec<Event>, RunningBench) {
    run_prepared(
        sim,
        plan,
        abort_after_windows,
        pause_windows,
        adjust_station,
        &|_| {},
    )
}

/// As `run_paused`, with `before` given the bench before the run starts.
fn run_prepared(
    sim: SimConfig,
    plan: TestPlan,
    abort_after_windows: Option<u64>,
    pause_windows: Option<(u64, u64)>,
    adjust_station: &dyn Fn(&mut StationConfig),
    before: &dyn Fn(&RunningBench),
) -> (RunSummary, Vec<Event>, RunningBench) {
    // Virtual time in lockstep, unless a test asks for a faster-than-real
    // clock (lost bytes stall the lockstep: the station waits for a window
    // the bench never completes).
    let speed = if sim.speed > 1.0 { sim.speed } else { 0.0 };
    let bench =
        RunningBench::start(SimConfig { speed, ..sim }, ServeOptions::default()).expect("bench");
    before(&bench);
    let mut station = station_for(&bench);
    adjust_station(&mut station);
    let compiled = plan.compile(&station).expect("plan fits the station");
    let events = Arc::new(Mutex::new(Vec::new()));
    let abort = spinbench_engine::AbortFlag::new();
    let pause = Arc::new(AtomicBool::new(false));
    let unpause = pause.clone();
    let summary = {
        let options = common::options(&abort, &pause);
        let mut ex = Executor::new(
            &station,
            compiled,
            connect(&station),
            Box::new(SimOperator::new(&bench, true)),
            options,
        );
        let sink = events.clone();
        let mut windows = 0u64;
        ex.subscribe(move |e: &Event| {
            if matches!(e, Event::Values { .. }) {
                windows += 1;
                if let Some((at, until)) = pause_windows {
                    unpause.store(
                        windows >= at && windows < until,
                        std::sync::atomic::Ordering::Relaxed,
                    );
                }
                if abort_after_windows.is_some_and(|n| windows >= n) {
                    abort.request("the test");
                }
            }
            if let Ok(mut v) = sink.lock() {
                v.push(e.clone());
            }
        });
        ex.run()
    };
    let events = events.lock().map(|v| v.clone()).unwrap_or_default();
    (summary, events, bench)
}

/// The safe state: instrument rails off, relays open (except on a module
/// that no longer answers: its instruments are unpowered by the rails),
/// the table commanded to stop.
fn assert_safe_except(
    bench: &RunningBench,
    expect_table_stopped: bool,
    silent_module: Option<usize>,
) {
    bench.with_world(|w| {
        assert!(
            w.rails.outputs.iter().all(|o| !o.on),
            "instrument rails still on"
        );
        for m in (0..w.config().modules).filter(|m| Some(*m) != silent_module) {
            assert_eq!(
                w.relay_mask(m).unwrap_or(0),
                0,
                "module {m} relays still closed"
            );
        }
        if expect_table_stopped {
            assert!(
                w.table.demand_rad_s == 0.0 || !w.table.rate_mode || !w.table.interlocks_closed,
                "table still commanded to spin"
            );
        }
    });
}

fn assert_safe(bench: &RunningBench, expect_table_stopped: bool) {
    assert_safe_except(bench, expect_table_stopped, None);
}

fn reason(summary: &RunSummary) -> String {
    summary.reason.clone().unwrap_or_default()
}

#[test]
fn a_complete_run_measures_every_instrument() {
    let (summary, events, bench) = run(SimConfig::default(), small_plan(), None);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    assert_eq!(summary.records.len(), 9);
    for r in &summary.records {
        assert_eq!(r.points.len(), 13, "{}: {:?}", r.serial, r.reasons);
        assert!(r.radius_m.contains_key(&Mount::P));
        assert!(r.analysis.is_some());
        // The outcome follows k2_max ± its GUM U95 against the limit (20 µg/g²,
        // marginal above 18) under the default, guarded, rule.
        let k2 = r.k2_max_ug_per_g2.expect("k2_max");
        let a = r.analysis.as_ref().expect("analysis");
        // U95 of the GUM budget (Type A repeatability and the station's Type B).
        let u = a.fits[&a.k2_max_mount.expect("mount")]
            .uncertainty
            .as_ref()
            .and_then(|u| u.k2_ug_per_g2.as_ref())
            .expect("k2 budget")
            .u95;
        let want = if k2 - u > 20.0 {
            Outcome::Fail
        } else if k2 + u > 20.0 {
            Outcome::Inconclusive
        } else if k2 + u > 18.0 {
            Outcome::Marginal
        } else {
            Outcome::Pass
        };
        assert_eq!(r.outcome, want, "{}: {:?}", r.serial, r.reasons);
        assert_eq!(r.decision_rule, Some(DecisionRule::Guarded));
    }
    // Every point journaled once, every step once.
    let points = events
        .iter()
        .filter(|e| matches!(e, Event::PointDone { .. }))
        .count();
    assert_eq!(points, 13);
    assert!(events.iter().any(|e| matches!(
        e,
        Event::RunFinished {
            state: RunState::Completed,
            ..
        }
    )));
    assert_safe(&bench, true);
    bench.shutdown();
}

#[test]
fn safety_centrifuge_silence_faults_into_the_safe_state() {
    let mut sim = SimConfig::default();
    sim.faults.centrifuge_silent_at_s = Some(40.0);
    let (summary, events, bench) = run(sim, small_plan(), None);
    assert_eq!(summary.state, RunState::Faulted);
    // The stop cannot be confirmed: the record and every screen say so.
    assert!(!summary.stop_confirmed);
    assert!(
        reason(&summary).contains(spinbench_engine::executor::STOP_NOT_CONFIRMED),
        "{}",
        reason(&summary)
    );
    assert!(
        events
            .iter()
            .any(|e| matches!(e, Event::Fault { reason, .. }
        if reason.starts_with(spinbench_engine::executor::STOP_NOT_CONFIRMED)))
    );
    for r in &summary.records {
        assert_eq!(r.outcome, Outcome::Incomplete, "{}", r.serial);
    }
    // The stop goes on being commanded; once the controller answers again
    // it is acknowledged and the table is commanded to rest.
    assert!(spinbench_engine::executor::unconfirmed_stops() >= 1);
    bench.with_world(|w| w.end_centrifuge_silence());
    let until = std::time::Instant::now() + Duration::from_secs(20);
    while spinbench_engine::executor::unconfirmed_stops() > 0 {
        assert!(
            std::time::Instant::now() < until,
            "the stop was not commanded again once the controller answered"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_safe(&bench, true);
    assert!(
        reason(&summary).contains("centrifuge"),
        "{}",
        reason(&summary)
    );
    assert!(
        reason(&summary).contains("no reply"),
        "{}",
        reason(&summary)
    );
    assert_safe(&bench, false);
    bench.shutdown();
}

#[test]
fn safety_an_open_interlock_faults_into_the_safe_state() {
    let mut sim = SimConfig::default();
    sim.faults.interlock_open_at_s = Some(60.0);
    let (summary, _, bench) = run(sim, small_plan(), None);
    assert_eq!(summary.state, RunState::Faulted);
    assert!(
        reason(&summary).contains("interlocks opened"),
        "{}",
        reason(&summary)
    );
    assert_safe(&bench, true);
    bench.shutdown();
}

#[test]
fn safety_an_over_current_trip_faults_into_the_safe_state() {
    let mut sim = SimConfig::default();
    sim.faults.supply_trip_at_s = Some(50.0);
    let (summary, _, bench) = run(sim, small_plan(), None);
    assert_eq!(summary.state, RunState::Faulted);
    assert!(
        reason(&summary).contains("over-current"),
        "{}",
        reason(&summary)
    );
    assert_safe(&bench, true);
    bench.shutdown();
}

#[test]
fn safety_a_silent_counter_module_faults_into_the_safe_state() {
    let mut sim = SimConfig::default();
    sim.faults.module_silent = Some((1, 45.0));
    let (summary, _, bench) = run(sim, small_plan(), None);
    assert_eq!(summary.state, RunState::Faulted);
    assert!(
        reason(&summary).contains("counter module 2 sent no data"),
        "{}",
        reason(&summary)
    );
    assert_safe_except(&bench, true, Some(1));
    bench.shutdown();
}

#[test]
fn safety_a_plan_beyond_the_limits_is_refused_before_anything_moves() {
    let bench = RunningBench::start(SimConfig::default(), ServeOptions::default()).expect("bench");
    let mut station = station_for(&bench);
    station.arm.max_g = 1000.0;
    let mut plan = small_plan();
    plan.range_g = 150.0;
    plan.levels = None;
    let e = plan
        .compile(&station)
        .expect_err("above the rate limit")
        .to_string();
    assert!(
        e.contains("range_g") && e.contains("above the centrifuge's limit of 2400 deg/s"),
        "{e}"
    );
    let mut tight = station.clone();
    tight.arm.max_g = 8.0;
    station.arm.max_g = 100.0;
    let e = plan
        .compile(&station)
        .expect_err("above the fixtures' rating at 105 g")
        .to_string();
    assert!(e.contains("105 g") && e.contains("rated 100 g"), "{e}");
    let e = small_plan()
        .compile(&tight)
        .expect_err("above the fixtures' rating")
        .to_string();
    assert!(e.contains("rated 8 g"), "{e}");
    // Nothing was switched on.
    bench.with_world(|w| assert!(w.rails.outputs.iter().all(|o| !o.on) && !w.table.rate_mode));
    bench.shutdown();
}

#[test]
fn a_dead_and_a_noisy_instrument_are_incomplete_and_the_others_go_on() {
    let mut sim = SimConfig::default();
    sim.faults.dead_instruments = vec![SlotRef { module: 0, slot: 1 }];
    sim.faults.noisy_instruments = vec![SlotRef { module: 1, slot: 0 }];
    let (summary, _, bench) = run(sim, small_plan(), None);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let by_serial = |s: &str| {
        summary
            .records
            .iter()
            .find(|r| r.serial == s)
            .expect("record")
    };
    // It gave nothing to judge: never graded pass or fail.
    let dead = by_serial("A2");
    assert_eq!(dead.outcome, Outcome::Incomplete);
    assert!(
        dead.reasons.iter().any(|r| r.contains("no output")),
        "{:?}",
        dead.reasons
    );
    // Too noisy to take a point: as likely its cable as the instrument,
    // so not judged against the limits either.
    let noisy = by_serial("B1");
    assert_eq!(noisy.outcome, Outcome::Incomplete);
    assert!(
        noisy
            .reasons
            .iter()
            .any(|r| r.code == ReasonCode::Noisy && r.contains("scatter") && !r.contains("noisy:")),
        "{:?}",
        noisy.reasons
    );
    let good = by_serial("A1");
    assert_eq!(good.points.len(), 13);
    assert!(
        good.analysis.is_some()
            && good
                .reasons
                .iter()
                .all(|r| !r.contains("noisy") && !r.contains("no output"))
    );
    bench.shutdown();
}

#[test]
fn a_units_record_with_its_analysis_reads_back_as_the_same_type() {
    let (summary, _, bench) = run(SimConfig::default(), small_plan(), None);
    bench.shutdown();
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    for record in &summary.records {
        assert!(record.analysis.is_some());
        let json = serde_json::to_string(record).expect("serialize");
        let back: spinbench_engine::UnitRecord = serde_json::from_str(&json).expect("deserialize");
        // Everything the JSON carries comes back; the fitted polynomial is
        // derived again from the coefficients (it is not in the JSON).
        assert_eq!(serde_json::to_string(&back).expect("again"), json);
        let (a, b) = (
            record.analysis.as_ref().expect("analysis"),
            back.analysis.as_ref().expect("analysis read back"),
        );
        for (mount, fit) in &a.fits {
            let other = &b.fits[mount].fit;
            for g in [0.0, 10.0, 70.0] {
                let (x, y) = (fit.fit.predict(g), other.predict(g));
                assert!(
                    (x - y).abs() <= 1e-9 * x.abs().max(1.0),
                    "{mount} at {g} g: {x} vs {y}"
                );
            }
        }
    }
}

#[test]
fn an_abort_ends_in_the_safe_state() {
    // A dead and a noisy instrument too: in an aborted run none is graded.
    let mut sim = SimConfig::default();
    sim.faults.dead_instruments = vec![SlotRef { module: 0, slot: 1 }];
    sim.faults.noisy_instruments = vec![SlotRef { module: 1, slot: 0 }];
    let (summary, events, bench) = run(sim, small_plan(), Some(40));
    assert_eq!(summary.state, RunState::Aborted, "{}", reason(&summary));
    assert!(
        reason(&summary).contains("the test"),
        "{}",
        reason(&summary)
    );
    // Nothing of an unfinished plan is graded pass or fail.
    assert!(!summary.records.is_empty());
    for r in &summary.records {
        assert_eq!(
            r.outcome,
            Outcome::Incomplete,
            "{}: {:?}",
            r.serial,
            r.reasons
        );
        assert!(
            r.reasons.iter().any(|x| x.starts_with("incomplete:")),
            "{:?}",
            r.reasons
        );
    }
    assert!(summary.stop_confirmed);
    assert!(events.iter().any(|e| matches!(
        e,
        Event::RunFinished {
            state: RunState::Aborted,
            ..
        }
    )));
    assert_safe(&bench, true);
    bench.shutdown();
}

#[test]
fn a_paused_run_holds_between_steps_and_then_completes() {
    let (summary, events, bench) = run_paused(
        SimConfig::default(),
        small_plan(),
        None,
        Some((5, 15)),
        &|_| {},
    );
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let states: Vec<RunState> = events
        .iter()
        .filter_map(|e| match e {
            Event::StateChanged { state } => Some(state.to_owned()),
            _ => None,
        })
        .collect();
    let paused_at = states
        .iter()
        .position(|s| *s == RunState::Paused)
        .expect("the run paused");
    assert_eq!(states.get(paused_at + 1), Some(&RunState::Running));
    bench.shutdown();
}

#[test]
fn a_wrong_supply_current_stops_the_run_before_any_spin() {
    let bench = RunningBench::start(
        SimConfig {
            speed: 0.0,
            ..SimConfig::default()
        },
        ServeOptions::default(),
    )
    .expect("bench");
    let mut station = station_for(&bench);
    // The station believes each instrument draws 0.2 A; the bench's draw 0.04 A.
    station.power.instrument_current_a = 0.2;
    let compiled = small_plan().compile(&station).expect("plan");
    let options = RunOptions {
        run_id: "current".into(),
        abort: spinbench_engine::AbortFlag::new(),
        pause: Arc::new(AtomicBool::new(false)),
        module_silence: Duration::from_secs(2),
        station_config_toml: String::new(),
        sink_hold_limit: Duration::from_secs(600),
    };
    let summary = Executor::new(
        &station,
        compiled,
        connect(&station),
        Box::new(SimOperator::new(&bench, true)),
        options,
    )
    .run();
    assert_eq!(summary.state, RunState::Faulted);
    assert!(
        reason(&summary).contains("expected about 1.800 A"),
        "{}",
        reason(&summary)
    );
    assert_safe(&bench, true);
    bench.shutdown();
}

#[test]
fn every_figure_with_a_limit_decides_the_outcome() {
    let mut plan = small_plan();
    // A nonlinearity limit no instrument can meet (k2 alone bows the line by ~100 ppm FS at 10 g).
    plan.limits.nonlinearity_max_ppm_fs = Some(0.01);
    plan.limits.k2_max_ug_per_g2 = 1000.0;
    let (summary, _, bench) = run(SimConfig::default(), plan, None);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    for r in &summary.records {
        assert_eq!(r.outcome, Outcome::Fail, "{}: {:?}", r.serial, r.reasons);
        assert!(r.reasons.iter().any(|x| x.starts_with("nonlinearity") && x.contains("above the limit 0.01 ppm FS")), "{:?}", r.reasons);
    }
    bench.shutdown();
}

/// Refuses its first `left` point events, keeps the rest.
struct RefusingSink {
    left: u32,
    taken: Arc<Mutex<Vec<Event>>>,
}

impl EventSink for RefusingSink {
    fn emit(&mut self, e: &Event) -> Result<(), spinbench_engine::event::SinkError> {
        if matches!(e, Event::PointDone { .. }) && self.left > 0 {
            self.left -= 1;
            return Err(String::from("store test: the server went away").into());
        }
        if let Ok(mut v) = self.taken.lock() {
            v.push(e.clone());
        }
        Ok(())
    }
}

/// Run `small_plan` with a subscriber that refuses its first `refusals`
/// point events (as a store whose server went away would), beside a recorder.
fn run_with_refusing_sink(
    refusals: u32,
    hold_limit: Duration,
) -> (RunSummary, Vec<Event>, Vec<Event>) {
    run_with_refusing_sink_and(refusals, hold_limit, spinbench_engine::AbortFlag::new())
}

/// As [`run_with_refusing_sink`], watching `abort`.
fn run_with_refusing_sink_and(
    refusals: u32,
    hold_limit: Duration,
    abort: spinbench_engine::AbortFlag,
) -> (RunSummary, Vec<Event>, Vec<Event>) {
    run_with_refusing_sink_then(refusals, hold_limit, abort, None)
}

/// A boxed subscriber passed on to the executor.
struct Boxed(Box<dyn EventSink>);

impl EventSink for Boxed {
    fn emit(&mut self, e: &Event) -> Result<(), spinbench_engine::event::SinkError> {
        self.0.emit(e)
    }
}

/// As [`run_with_refusing_sink_and`], with `then` subscribed after the
/// refusing subscriber (the third).
fn run_with_refusing_sink_then(
    refusals: u32,
    hold_limit: Duration,
    abort: spinbench_engine::AbortFlag,
    then: Option<Box<dyn EventSink>>,
) -> (RunSummary, Vec<Event>, Vec<Event>) {
    let bench = RunningBench::start(
        SimConfig {
            speed: 0.0,
            ..SimConfig::default()
        },
        ServeOptions::default(),
    )
    .expect("bench");
    let station = station_for(&bench);
    let compiled = small_plan().compile(&station).expect("plan");
    let options = RunOptions {
        run_id: "refused".into(),
        abort,
        pause: Arc::new(AtomicBool::new(false)),
        module_silence: Duration::from_secs(2),
        station_config_toml: String::new(),
        sink_hold_limit: hold_limit,
    };
    let seen = Arc::new(Mutex::new(Vec::new()));
    let stored = Arc::new(Mutex::new(Vec::new()));
    let summary = {
        let mut ex = Executor::new(
            &station,
            compiled,
            connect(&station),
            Box::new(SimOperator::new(&bench, true)),
            options,
        );
        let recorder = seen.clone();
        ex.subscribe(move |e: &Event| {
            if let Ok(mut v) = recorder.lock() {
                v.push(e.clone());
            }
        });
        ex.subscribe(RefusingSink {
            left: refusals,
            taken: stored.clone(),
        });
        if let Some(then) = then {
            ex.subscribe(Boxed(then));
        }
        ex.run()
    };
    assert_safe(&bench, true);
    bench.shutdown();
    let seen = seen.lock().map(|v| v.clone()).unwrap_or_default();
    let stored = stored.lock().map(|v| v.clone()).unwrap_or_default();
    (summary, seen, stored)
}

#[test]
fn a_failed_write_holds_the_run_and_nothing_is_lost_once_it_succeeds() {
    let (summary, seen, stored) = run_with_refusing_sink(2, Duration::from_secs(600));
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let notices: Vec<&str> = seen
        .iter()
        .filter_map(|e| match e {
            Event::Notice { message, .. } => Some(message.as_str()),
            _ => None,
        })
        .collect();
    assert!(
        notices
            .iter()
            .any(|m| m.contains("the server went away") && m.contains("held")),
        "{notices:?}"
    );
    assert!(seen.contains(&Event::StateChanged {
        state: RunState::Paused
    }));
    // Every point the recorder saw reached the refusing subscriber too, in the same order.
    let points = |events: &[Event]| -> Vec<Event> {
        events
            .iter()
            .filter(|e| matches!(e, Event::PointDone { .. }))
            .cloned()
            .collect()
    };
    assert!(!points(&seen).is_empty());
    assert_eq!(
        points(&seen),
        points(&stored),
        "nothing lost, nothing doubled"
    );
}

#[test]
fn a_write_that_keeps_failing_faults_into_the_safe_state_after_the_hold_limit() {
    let (summary, _, stored) = run_with_refusing_sink(u32::MAX, Duration::from_secs(2));
    assert_eq!(summary.state, RunState::Faulted);
    assert!(
        reason(&summary).contains("the server went away"),
        "{}",
        reason(&summary)
    );
    assert!(!stored.iter().any(|e| matches!(e, Event::PointDone { .. })));
    // The run never claims a pass for a point the store did not take.
    assert!(stored.iter().all(|e| !matches!(
        e,
        Event::RunFinished {
            state: RunState::Completed,
            ..
        }
    )));
}

/// A second subscriber that refuses what it is told while the first one's
/// write is held (its notices, the held state): nothing is dropped in
/// silence, the run's reason says what it missed.
#[test]
fn what_a_second_subscriber_misses_during_a_hold_is_said_in_the_runs_reason() {
    /// Refuses what it is told of another subscriber's hold: the held
    /// notice and the held state.
    struct Flaky;
    impl EventSink for Flaky {
        fn emit(&mut self, e: &Event) -> Result<(), spinbench_engine::event::SinkError> {
            let of_the_hold = match e {
                Event::Notice { message, .. } => message.contains("the run is held"),
                Event::StateChanged { state } => *state == RunState::Paused,
                _ => false,
            };
            if of_the_hold {
                return Err(String::from("screen test: the browser went away").into());
            }
            Ok(())
        }
    }
    let (summary, _, _) = run_with_refusing_sink_then(
        1,
        Duration::from_secs(600),
        spinbench_engine::AbortFlag::new(),
        Some(Box::new(Flaky)),
    );
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let why = reason(&summary);
    assert!(
        why.contains("subscriber 3 missed notice: screen test: the browser went away")
            && why.contains("subscriber 3 missed state_changed"),
        "{why}"
    );
}

/// A signal that aborts a run held on a failing write is
/// named in the run's reason as the signal, not as "the operator".
#[test]
fn a_signal_during_a_held_write_is_recorded_as_the_signal() {
    let abort = spinbench_engine::AbortFlag::new();
    let later = abort.clone();
    let setter = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(1500));
        later.request("signal SIGTERM");
    });
    let (summary, _, _) = run_with_refusing_sink_and(u32::MAX, Duration::from_secs(600), abort);
    let _ = setter.join();
    assert_eq!(summary.state, RunState::Aborted, "{}", reason(&summary));
    assert!(
        reason(&summary).contains("signal SIGTERM while a write was failing")
            && !reason(&summary).contains("the operator"),
        "{}",
        reason(&summary)
    );
}

#[test]
fn an_instrument_that_never_settles_fails_and_the_others_go_on() {
    let mut sim = SimConfig::default();
    sim.faults.drifting_instruments = vec![SlotRef { module: 1, slot: 1 }];
    sim.faults.drift_ug_per_s = 200.0;
    let plan = TestPlan::from_toml(
        r#"
        range_g = 10
        levels = [0, 1, 2, 4, 6, 8, 10]
        passes = ["P"]
        warmup_s = 0
        dwell = { seconds = 3 }
        stability = { hold_s = 5, max_settle_s = 60 }
        [serials]
        1 = "A1"
        2 = "A2"
        7 = "B1"
        8 = "B2"
        "#,
    )
    .expect("plan");
    let (summary, _, bench) = run(sim, plan, None);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let drifting = summary
        .records
        .iter()
        .find(|r| r.serial == "B2")
        .expect("record");
    assert_eq!(drifting.outcome, Outcome::Fail);
    assert!(
        drifting.reasons.iter().any(|r| r.contains("kept drifting")),
        "{:?}",
        drifting.reasons
    );
    for serial in ["A1", "A2", "B1"] {
        let r = summary
            .records
            .iter()
            .find(|r| r.serial == serial)
            .expect("record");
        assert!(
            r.analysis.is_some() && !r.points.is_empty(),
            "{serial}: {:?}",
            r.reasons
        );
        assert!(
            r.reasons.iter().all(|x| !x.contains("drifting")),
            "{serial}"
        );
    }
    bench.shutdown();
}

#[test]
fn a_plan_exclusion_leaves_its_level_out_and_is_recorded_with_its_reason() {
    let mut plan = small_plan();
    plan.operator = "eng. Li".into();
    plan.exclusions.push(spinbench_engine::plan::PlanExclusion {
        serial: Some("A2".into()),
        mount: Mount::P,
        g: 6.0,
        reason: "fixture rattled at 6 g".into(),
    });
    let (summary, _events, bench) = run(SimConfig::default(), plan, None);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    for r in &summary.records {
        let fit = &r.analysis.as_ref().expect("analysis").fits[&Mount::P].fit;
        let has_6g = fit.residuals.iter().any(|x| x.g_nominal == 6.0);
        if r.serial == "A2" {
            assert!(!has_6g, "A2 was fitted with the excluded level");
            let e = &r.exclusions[0];
            assert_eq!(
                (e.g, e.reason.as_str(), e.by.as_str()),
                (6.0, "fixture rattled at 6 g", "eng. Li")
            );
            assert!(e.points_removed >= 1);
            // Its points are all kept in the record: nothing is deleted.
            assert!(r.points.iter().any(|p| p.g_nominal == 6.0));
        } else {
            assert!(has_6g && r.exclusions.is_empty(), "{}", r.serial);
        }
    }
    bench.shutdown();
}

#[test]
fn the_applied_acceleration_includes_the_earths_rate_at_the_stations_latitude() {
    let sim = SimConfig {
        latitude_deg: 60.0,
        ..SimConfig::default()
    };
    let (summary, _events, bench) = run(sim, small_plan(), None);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let station = station_for(&bench);
    assert_eq!(
        station.arm.latitude_deg,
        Some(60.0),
        "the bench's station config says where it stands"
    );
    let earth = 7.292_115e-5 * 60f64.to_radians().sin();
    let g = station.g_local_m_s2;
    let mut checked = 0;
    for r in &summary.records {
        let radius = r.radius_m[&Mount::P];
        for p in r.points.iter().filter(|p| p.rate_deg_s != 0.0) {
            let w = p.rate_deg_s.to_radians() + earth;
            let want = w * w * radius / g;
            assert!(
                (p.g_applied - want).abs() <= 1e-12 * want,
                "{} vs {want}",
                p.g_applied
            );
            checked += 1;
        }
    }
    assert!(checked > 50, "{checked} points checked");
    // A latitude that is none is refused, naming the key.
    let text = station_toml(&bench, "").replace("latitude_deg = 60", "latitude_deg = 91");
    bench.shutdown();
    let e = StationConfig::from_toml(&text).expect_err("latitude 91");
    assert!(e.to_string().contains("arm.latitude_deg"), "{e}");
}

/// Run `small_plan` in both mountings with `positions` tumble positions on
/// a bench whose instruments are 2000 µg/g sensitive across the axis (far
/// more than a good one), so gravity's part of the 1 g radius reading
/// (±2000 ppm, ±1.6 mm) stands far above the readings' noise.
fn run_cross_axis(positions: u8) -> (RunSummary, spinbench_sim::world::Truth) {
    let sim = SimConfig {
        instruments: spinbench_sim::config::PopulationConfig {
            cross_axis_max_ug_per_g: 2000.0,
            ..Default::default()
        },
        ..SimConfig::default()
    };
    let mut plan = small_plan();
    plan.passes = vec![Mount::P, Mount::N];
    plan.tumble_positions = positions;
    // Warmed up (5 time constants of the bench's 150 µg warm-up transient),
    // so the readings do not drift between the positions.
    plan.warmup_s = 600.0;
    let (summary, _, bench) = run(sim, plan, None);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let truth = bench.with_world(|w| w.truth());
    bench.shutdown();
    (summary, truth)
}

#[test]
fn a_four_position_tumble_takes_gravity_across_the_axis_out_of_the_radius() {
    let (two, truth) = run_cross_axis(2);
    let (four, _) = run_cross_axis(4);
    let slots = spinbench_wire::fmu::INSTRUMENTS_PER_MODULE;
    let mut large = 0;
    for (r2, r4) in two.records.iter().zip(&four.records) {
        let t = truth
            .instruments
            .iter()
            .find(|t| t.module * slots + t.slot == r4.slot)
            .expect("truth of the slot");
        let c = t.vba.cross_axis_ug_per_g;
        // Measured by the extra positions.
        let found = r4.cross_axis_ug_per_g.expect("four positions measure c");
        assert!((found - c).abs() < 20.0, "{}: c {found} vs {c}", r4.serial);
        assert!(r2.cross_axis_ug_per_g.is_none());
        for mount in [Mount::P, Mount::N] {
            let true_r = match mount {
                Mount::P => t.position.radius_p_m,
                Mount::N => t.position.radius_n_m,
            };
            let ppm = |r: &spinbench_engine::record::UnitRecord| {
                (r.radius_m[&mount] / true_r - 1.0) * 1e6
            };
            // Corrected: within the readings' noise; uncorrected: off by c,
            // with the mounting's sign.
            assert!(
                ppm(r4).abs() < 25.0,
                "{} {mount}: {} ppm",
                r4.serial,
                ppm(r4)
            );
            let expected = mount.input_sign() * c;
            assert!(
                (ppm(r2) - expected).abs() < 25.0,
                "{} {mount}: {} ppm, c {c}",
                r2.serial,
                ppm(r2)
            );
            // The readings' noise is in the budget, measured per instrument.
            let u = r4.radius_reading_u_ppm[&mount];
            assert!(u > 0.0 && u < 25.0, "{} {mount}: u {u} ppm", r4.serial);
        }
        large += usize::from(c.abs() > 500.0);
        // The unmeasured cross-axis bound enters the budget only without the
        // extra positions.
        let has_cross = |r: &spinbench_engine::record::UnitRecord| {
            let fit = &r.analysis.as_ref().expect("analysis").fits[&Mount::P];
            let k1 = fit
                .uncertainty
                .as_ref()
                .and_then(|u| u.k1.as_ref())
                .expect("k1 budget");
            k1.budget
                .iter()
                .any(|b| b.source == spinbench_analysis::uncertainty::Source::CrossAxis)
        };
        assert!(has_cross(r2) && !has_cross(r4), "{}", r4.serial);
    }
    assert!(
        large >= 3,
        "too few instruments with |c| > 500 µg/g to tell: {large}"
    );
}

#[test]
fn every_point_carries_the_instruments_temperature_and_the_one_second_values_too() {
    let (summary, events, bench) = run(SimConfig::default(), small_plan(), None);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let temperatures = bench.with_world(|w| w.instrument_temperature_c(0));
    bench.shutdown();
    for r in &summary.records {
        for p in &r.points {
            let t = p.temperature_c.expect("a temperature per point");
            // Ambient 23 °C plus up to 4 °C of self-heating.
            assert!((22.9..27.1).contains(&t), "{}: {t} °C", r.serial);
            assert!(
                p.temperature_change_c
                    .is_some_and(|d| (0.0..1.0).contains(&d))
            );
            let sum = p.resonator_sum_hz.expect("f1 + f2");
            assert!(sum > 1e4, "{}: f1 + f2 = {sum} Hz", r.serial);
            assert!(!p.temperature_unsettled);
        }
    }
    assert!((22.9..27.1).contains(&temperatures), "{temperatures}");
    let with_temperature = events
        .iter()
        .filter(|e| matches!(e, Event::Values { temperatures_c, .. } if temperatures_c.first().is_some_and(Option::is_some)))
        .count();
    assert!(
        with_temperature > 10,
        "one-second values with temperatures: {with_temperature}"
    );
}

#[test]
fn a_point_taken_while_the_temperature_moves_is_measured_again_then_flagged() {
    // The laboratory warms by 36 °C an hour (0.01 °C/s): every 3-s point moves
    // by more than the plan's 0.005 °C.
    let sim = SimConfig {
        ambient_drift_c_per_h: 36.0,
        ..SimConfig::default()
    };
    let mut plan = small_plan();
    plan.stability.temperature_change_max_c = Some(0.005);
    plan.stability.max_restarts = 1;
    let (summary, events, bench) = run(sim, plan, None);
    bench.shutdown();
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let again = events
        .iter()
        .filter(|e| matches!(e, Event::Notice { message, .. } if message.contains("temperature_change_max_c")))
        .count();
    assert!(again >= 7, "each level measured again once: {again}");
    for r in &summary.records {
        assert!(
            r.points.iter().all(|p| p.temperature_unsettled),
            "{}",
            r.serial
        );
        assert!(
            r.reasons
                .iter()
                .any(|x| x.code == spinbench_engine::ReasonCode::TemperatureUnsettled),
            "{}: {:?}",
            r.serial,
            r.reasons
        );
        assert_ne!(r.outcome, Outcome::Incomplete, "flagged, still graded");
    }
}

#[test]
fn an_instrument_over_its_temperature_limit_stops_the_run_in_the_safe_state() {
    // The instruments run at 23 °C and more; the station allows 20 °C.
    let (summary, events, bench) = run_paused(
        SimConfig::default(),
        small_plan(),
        None,
        None,
        &|s: &mut StationConfig| s.temperature.instrument_max_c = Some(20.0),
    );
    assert_eq!(summary.state, RunState::Faulted, "{}", reason(&summary));
    let why = reason(&summary);
    assert!(
        why.contains("slot 1") && why.contains("instrument_max_c"),
        "{why}"
    );
    assert!(
        events
            .iter()
            .any(|e| matches!(e, Event::RunFinished { .. }))
    );
    assert_safe(&bench, true);
    bench.shutdown();
}

#[test]
fn an_abort_sends_the_chamber_to_the_laboratorys_temperature_with_the_purge_on() {
    // The purge valve on the controller, then on a relay module of its own.
    for purge_on_relay in [false, true] {
        abort_with_the_chamber_cold(purge_on_relay);
    }
}

fn abort_with_the_chamber_cold(purge_on_relay: bool) {
    let sim = SimConfig {
        chamber: Some(spinbench_sim::chamber::ChamberSimConfig {
            purge_on_relay,
            ..Default::default()
        }),
        ..SimConfig::default()
    };
    // The operator had set the chamber cold and running before the run.
    let (summary, _, bench) = run_paused(sim, small_plan(), Some(40), None, &|s| {
        s.temperature.ambient_c = 24.0;
        if let Some(c) = &s.chamber {
            let mut chamber = c.connect().expect("chamber");
            chamber.set_setpoint_c(-40.0).expect("cold");
            chamber.set_running(true).expect("run");
        }
    });
    assert_eq!(summary.state, RunState::Aborted, "{}", reason(&summary));
    let (setpoint, purge) = bench.with_world(|w| {
        let c = w.chamber().expect("the bench has a chamber");
        (c.setpoint_c, c.purge)
    });
    assert_eq!(setpoint, 24.0, "to the laboratory's temperature");
    assert!(
        purge,
        "with the dry-air purge on (on a relay: {purge_on_relay})"
    );
    assert_safe(&bench, true);
    bench.shutdown();
}

/// A quick chamber: 30 °C/min, the instruments 20 s behind the air.
fn quick_chamber() -> spinbench_sim::chamber::ChamberSimConfig {
    spinbench_sim::chamber::ChamberSimConfig {
        heat_rate_c_per_min: 30.0,
        cool_rate_c_per_min: 30.0,
        overshoot_c: 0.2,
        settle_tau_s: 10.0,
        instrument_lag_s: 20.0,
        ..Default::default()
    }
}

/// A bench with `chamber` and the small plan at `temperatures`, soaked for
/// 20 s in ±0.5 °C.
fn chamber_run(
    chamber: spinbench_sim::chamber::ChamberSimConfig,
    temperatures: &[f64],
    max_soak_s: u32,
) -> (RunSummary, Vec<Event>, RunningBench) {
    let sim = SimConfig {
        chamber: Some(chamber),
        ..SimConfig::default()
    };
    let mut plan = small_plan();
    // Warmed up: the bench's 150 µg warm-up transient is not a temperature effect.
    plan.warmup_s = 600.0;
    plan.temperatures_c = temperatures.to_vec();
    plan.soak = spinbench_engine::soak::SoakConfig {
        tolerance_c: 0.5,
        window_s: 20,
        max_soak_s,
    };
    run(sim, plan, None)
}

#[test]
fn a_plan_with_temperatures_soaks_at_each_and_keeps_every_point_with_its_setpoint() {
    let (summary, events, bench) = chamber_run(quick_chamber(), &[40.0, 5.0], 1800);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let soaks: Vec<String> = events
        .iter()
        .filter_map(|e| match e {
            Event::StepStarted { label, .. } if label.starts_with("soak") => Some(label.clone()),
            _ => None,
        })
        .collect();
    // The reference first (nearest the room's 23 °C), where the radius is found.
    assert_eq!(
        soaks,
        ["soak the chamber at 40 °C", "soak the chamber at 5 °C"]
    );
    for r in &summary.records {
        for setpoint in [5.0, 40.0] {
            let at: Vec<&spinbench_engine::PointRecord> = r
                .points
                .iter()
                .filter(|p| p.setpoint_c == Some(setpoint))
                .collect();
            assert_eq!(at.len(), 13, "{}: points at {setpoint} °C", r.serial);
            let t = at[0].temperature_c.expect("measured");
            // The instruments run about 4 °C above the air they sit in.
            assert!(
                (t - setpoint - 4.0).abs() < 1.5,
                "{}: {t} °C at {setpoint} °C",
                r.serial
            );
        }
        assert!(
            r.reasons
                .iter()
                .any(|x| x.text.contains("reference temperature")),
            "{:?}",
            r.reasons
        );
        assert_ne!(r.outcome, Outcome::Incomplete);
    }
    // The temperature coefficients hold the bench's truth within their U95.
    let truth = bench.with_world(|w| w.truth());
    let slots = spinbench_wire::fmu::INSTRUMENTS_PER_MODULE;
    let mut held = 0;
    for r in &summary.records {
        let c = r
            .temperature_coefficients
            .expect("coefficients from two temperatures");
        assert_eq!(r.at_temperatures.len(), 2);
        let t = truth
            .instruments
            .iter()
            .find(|t| t.module * slots + t.slot == r.slot)
            .expect("truth");
        eprintln!(
            "{}: k0 {:.3}±{:.3} (true {:.3}) k1 {:.4}±{:.4} (true {:.4})",
            r.serial,
            c.k0_ug_per_c,
            c.k0_ug_per_c_u95,
            t.vba.temp_coeff_ug_per_c,
            c.k1_ppm_per_c,
            c.k1_ppm_per_c_u95,
            t.vba.k1_temp_coeff_ppm_per_c
        );
        held += usize::from((c.k0_ug_per_c - t.vba.temp_coeff_ug_per_c).abs() <= c.k0_ug_per_c_u95);
        held += usize::from(
            (c.k1_ppm_per_c - t.vba.k1_temp_coeff_ppm_per_c).abs() <= c.k1_ppm_per_c_u95,
        );
        assert!(c.k2_ug_per_g2_per_c.is_none(), "one mounting: no K2");
    }
    // Two temperatures leave no scatter to judge the line by, and the
    // bench's bias walk (5 µg/√h) between them is in no single fit's
    // uncertainty: about one in six falls just outside (≤ 1 % of the slope).
    // With three or more the Birge ratio takes it in (see the demo's coverage).
    assert!(held >= 14, "{held} of 18 coefficients within their U95");
    // The run ended in the safe state: the chamber back to the room, purge on.
    let (setpoint, purge) = bench.with_world(|w| {
        let c = w.chamber().expect("chamber");
        (c.setpoint_c, c.purge)
    });
    assert_eq!((setpoint, purge), (23.0, true));
    // A level left out after the run is graded again on the reference
    // temperature's points only, and the record keeps its temperature notes.
    let station = station_for(&bench);
    let mut plan = small_plan();
    plan.warmup_s = 600.0;
    plan.temperatures_c = vec![40.0, 5.0];
    let compiled = plan.compile(&station).expect("plan");
    let record = &summary.records[0];
    let after = spinbench_engine::judgement::exclude_after_run(
        record,
        &compiled,
        &station,
        spinbench_analysis::exclusion::LevelExclusion {
            unit: None,
            mount: Mount::P,
            g: 4.0,
            reason: "test".into(),
            by: "engineer".into(),
            points_removed: 0,
        },
    )
    .expect("re-graded");
    assert_eq!(
        after.exclusions[0].points_removed, 2,
        "4 g up and down at 40 °C"
    );
    let fit = &after.analysis.as_ref().expect("analysis").fits[&Mount::P].fit;
    assert_eq!(
        fit.points, 11,
        "the reference temperature's 13 points less two"
    );
    assert!(
        after
            .reasons
            .iter()
            .any(|x| x.text.contains("reference temperature")),
        "{:?}",
        after.reasons
    );
    bench.shutdown();
}

#[test]
fn chamber_faults_during_a_run_end_in_the_safe_state_with_the_reason() {
    use spinbench_sim::chamber::{ChamberFault, ChamberSimConfig};
    // A controller that falls silent during the soak.
    let (summary, _, bench) = chamber_run(
        ChamberSimConfig {
            fault: ChamberFault::Silent,
            fault_at_s: 30.0,
            ..quick_chamber()
        },
        &[40.0],
        1800,
    );
    assert_eq!(summary.state, RunState::Faulted, "{}", reason(&summary));
    assert!(
        reason(&summary).contains("sim-chamber"),
        "{}",
        reason(&summary)
    );
    // The silent chamber's safe state is not confirmed: said, and left to
    // the keeper.
    assert!(!summary.safe_devices_confirmed);
    assert!(
        reason(&summary).contains("chamber: purge on and setpoint to ambient")
            && reason(&summary).contains("tries again every 2 s"),
        "{}",
        reason(&summary)
    );
    assert!(spinbench_engine::executor::unconfirmed_safe_devices() >= 1);
    assert_safe(&bench, true);
    bench.shutdown();

    // A heater that runs away: the over-temperature alarm stops the run.
    let (summary, _, bench) = chamber_run(
        ChamberSimConfig {
            fault: ChamberFault::Runaway,
            fault_at_s: 30.0,
            ..quick_chamber()
        },
        &[30.0],
        1800,
    );
    assert_eq!(summary.state, RunState::Faulted, "{}", reason(&summary));
    assert!(
        reason(&summary).contains("alarm word"),
        "{}",
        reason(&summary)
    );
    assert_safe(&bench, true);
    let purge = bench.with_world(|w| w.chamber().map(|c| c.purge));
    assert_eq!(purge, Some(true), "the purge on in the safe state");
    bench.shutdown();

    // A chamber that cannot get there in time.
    let (summary, _, bench) = chamber_run(
        ChamberSimConfig {
            heat_rate_c_per_min: 0.5,
            ..quick_chamber()
        },
        &[60.0],
        120,
    );
    assert_eq!(summary.state, RunState::Faulted, "{}", reason(&summary));
    assert!(
        reason(&summary).contains("did not soak"),
        "{}",
        reason(&summary)
    );
    assert!(
        summary
            .records
            .iter()
            .all(|r| r.outcome == Outcome::Incomplete)
    );
    assert_safe(&bench, true);
    bench.shutdown();
}

#[test]
fn the_board_follows_every_slot_through_the_run() {
    use spinbench_engine::board::{SlotBoard, SlotPhase};
    use spinbench_engine::plan::Step;
    let mut plan = small_plan();
    plan.passes = vec![Mount::P, Mount::N];
    let (summary, events, bench) = run(SimConfig::default(), plan, None);
    bench.shutdown();
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let Some(Event::RunStarted { plan, .. }) = events.first() else {
        panic!("the run starts with RunStarted");
    };
    // The last level of the first pass.
    let end_of_p = plan
        .steps
        .iter()
        .rposition(|s| matches!(s, Step::Level { pass: 0, .. }))
        .expect("levels of pass 0");
    let mut board = SlotBoard::new();
    let mut seen_averaging = false;
    let mut after_p = None;
    for event in &events {
        board.apply(event);
        if board
            .slots()
            .iter()
            .any(|s| s.phase == SlotPhase::Averaging)
        {
            seen_averaging = true;
        }
        if matches!(event, Event::StepDone { index } if *index == end_of_p) {
            after_p = Some(board.slots().to_vec());
        }
    }
    assert!(seen_averaging, "slots were seen averaging at a level");
    // After the P pass each slot has its P k2 with a U95, no K2 yet.
    let after_p = after_p.expect("the P pass ended");
    assert_eq!(after_p.len(), 9);
    for s in &after_p {
        assert_eq!(
            s.k2_ug_per_g2.len(),
            1,
            "slot {}: {:?}",
            s.slot,
            s.k2_ug_per_g2
        );
        assert_eq!(s.k2_ug_per_g2[0].0, Mount::P);
        assert!(s.k2_ug_per_g2[0].2.is_some_and(|u| u > 0.0));
        assert!(s.big_k2_ug_per_g2.is_none());
        assert_eq!(s.points * 2, s.points_planned);
    }
    // At the end: graded, every point taken, k2 of both mountings and K2,
    // the board's outcome the record's.
    for s in board.slots() {
        let record = summary
            .records
            .iter()
            .find(|r| r.slot + 1 == s.slot)
            .expect("record");
        assert_eq!(s.phase, SlotPhase::Done);
        assert_eq!(s.outcome, Some(record.outcome));
        assert_eq!(s.points, s.points_planned);
        assert_eq!(s.k2_ug_per_g2.len(), 2);
        assert!(s.big_k2_ug_per_g2.is_some());
        assert!(s.temperature_c.is_some() && s.output_hz.is_some());
    }
}

#[test]
fn a_point_with_too_few_whole_values_is_measured_again_not_failed() {
    // Bytes lost on the counter modules' lines (as when a busy host reads its
    // ports late): a window with lost ticks is never averaged, and some 3-s
    // points get fewer than two whole values of an instrument. They are
    // measured again (a notice says so); no instrument is failed for "no output".
    // In lockstep: the same bytes are lost on every run, however loaded the
    // machine (in real time a slow run met the drops elsewhere).
    let mut sim = SimConfig {
        speed: 0.0,
        ..SimConfig::default()
    };
    sim.faults.byte_drop_rate = BYTE_DROP_RATE;
    let (summary, events, bench) = run(sim, small_plan(), None);
    bench.shutdown();
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let again = events
        .iter()
        .filter(|e| matches!(e, Event::Notice { message, .. } if message.contains("fewer than 2 whole one-second values")))
        .count();
    eprintln!("points measured again: {again}");
    assert!(again >= 1, "a point was measured again");
    for r in &summary.records {
        assert!(
            r.reasons
                .iter()
                .all(|x| x.code != spinbench_engine::ReasonCode::NoOutput),
            "{}: {:?}",
            r.serial,
            r.reasons
        );
        // Seven levels up, six down: every one measured.
        assert_eq!(r.points.len(), 13, "{}: every level measured", r.serial);
    }
}

/// Lost bytes per byte on the modules' lines in the test above.
const BYTE_DROP_RATE: f64 = 1.2e-5;

#[test]
fn an_error_another_program_left_in_a_supplys_queue_is_reported_and_the_run_completes() {
    // Another program's refused setting, still queued in the rails supply:
    // the station reads it, says so, clears it, and its own settings pass.
    let (summary, events, _bench) = run_prepared(
        SimConfig::default(),
        small_plan(),
        None,
        None,
        &|_| {},
        &|bench| {
            bench.with_world(|w| {
                let _ = w.rails.handle("VOLT 40", &[]);
            });
        },
    );
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let notice = events.iter().find_map(|e| match e {
        Event::Notice { message, .. } if message.contains("*CLS") => Some(message.clone()),
        _ => None,
    });
    assert!(
        notice.as_deref().is_some_and(|m| m.contains("-222")),
        "{notice:?}"
    );
}

#[test]
fn a_chamber_alarm_while_a_pass_measures_faults_the_run() {
    use spinbench_sim::chamber::{ChamberFault, ChamberSimConfig};
    // The heater runs away long after the soak, while the levels are measured.
    let (summary, events, bench) = chamber_run(
        ChamberSimConfig {
            fault: ChamberFault::Runaway,
            fault_at_s: 800.0,
            ..quick_chamber()
        },
        &[30.0],
        1800,
    );
    let points_before = events
        .iter()
        .filter(|e| matches!(e, Event::PointDone { .. }))
        .count();
    assert!(
        points_before > 0,
        "the alarm came before any level was measured"
    );
    assert_eq!(summary.state, RunState::Faulted, "{}", reason(&summary));
    assert!(
        reason(&summary).contains("alarm word"),
        "{}",
        reason(&summary)
    );
    // Not complete: nothing graded.
    for r in &summary.records {
        assert_eq!(
            r.outcome,
            Outcome::Incomplete,
            "{}: {:?}",
            r.serial,
            r.reasons
        );
    }
    assert!(summary.safe_devices_confirmed, "{}", reason(&summary));
    assert_safe(&bench, true);
    bench.shutdown();
}

#[test]
fn an_instrument_that_falls_silent_mid_run_is_put_to_the_operator_and_ends_incomplete() {
    let mut sim = SimConfig::default();
    // Slot 2 works loose after the tumble, while the levels are measured.
    sim.faults.instrument_silent_at = Some((SlotRef { module: 0, slot: 1 }, 120.0));
    let (summary, events, bench) = run(sim, small_plan(), None);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let asked: Vec<&String> = events
        .iter()
        .filter_map(|e| match e {
            Event::Prompt { text, .. } if text.contains("went silent") => Some(text),
            _ => None,
        })
        .collect();
    assert_eq!(asked.len(), 1, "{asked:?}");
    assert!(
        asked[0].contains("A2 (slot 2)") && asked[0].contains("reseat"),
        "{}",
        asked[0]
    );
    let silent = summary
        .records
        .iter()
        .find(|r| r.serial == "A2")
        .expect("record");
    assert_eq!(silent.outcome, Outcome::Incomplete, "{:?}", silent.reasons);
    assert!(!silent.points.is_empty(), "its points before are kept");
    let good = summary
        .records
        .iter()
        .find(|r| r.serial == "A1")
        .expect("record");
    assert_eq!(good.points.len(), 13);
    assert_ne!(good.outcome, Outcome::Incomplete);
    bench.shutdown();
}

/// The largest acceleration the run put on any position [g]: the table's
/// rate read back each second at the bench's true radii (the largest).
fn largest_applied_g(events: &[Event], bench: &RunningBench) -> f64 {
    let true_radius_m = bench.with_world(|w| {
        w.truth()
            .instruments
            .iter()
            .flat_map(|u| [u.position.radius_p_m, u.position.radius_n_m])
            .fold(0.0, f64::max)
    });
    events
        .iter()
        .filter_map(|e| match e {
            Event::Values { rate_deg_s, .. } => Some(*rate_deg_s),
            _ => None,
        })
        .map(|rate| rate.to_radians().powi(2) * true_radius_m / 9.80665)
        .fold(0.0, f64::max)
}

#[test]
fn safety_a_wrong_configured_radius_stops_the_run_at_1_g_before_any_level() {
    // Fixtures at 0.8 m rated 100 g, the config saying 0.5 m: a 70 g plan
    // passes the plan check (70 g at 0.5 m) and would put 112 g on them.
    let mut plan = small_plan();
    plan.range_g = 70.0;
    plan.levels = Some(spinbench_engine::plan::LevelTable::List(vec![
        0.0, 10.0, 20.0, 40.0, 55.0, 70.0,
    ]));
    let (summary, events, bench) = run_paused(SimConfig::default(), plan, None, None, &|s| {
        s.arm.radius_m = 0.5;
        s.arm.position_radius_m.clear();
        s.arm.max_g = 100.0;
    });
    assert_eq!(summary.state, RunState::Faulted, "{}", reason(&summary));
    let why = reason(&summary);
    assert!(
        why.contains("measured radius is 0.80") && why.contains("arm.radius_m 0.5 m"),
        "{why}"
    );
    assert!(
        !events.iter().any(|e| matches!(e, Event::PointDone { .. })),
        "no level was measured"
    );
    let applied = largest_applied_g(&events, &bench);
    assert!(applied < 2.0, "the table went to {applied:.2} g");
    assert_safe(&bench, true);
    bench.shutdown();
}

#[test]
fn safety_a_level_over_the_rating_at_the_measured_radius_is_never_spun() {
    // Every fixture 6 mm further out than drawn (within the radius
    // tolerance): 10 g at the drawing radius is 10.08 g on fixtures rated 10 g.
    let mut sim = SimConfig::default();
    sim.centrifuge.radius_scatter_mm = 0.0;
    sim.centrifuge.position_shifts_mm = vec![6.0; 18];
    let (summary, events, bench) = run_paused(sim, small_plan(), None, None, &|s| {
        s.arm.max_g = 10.0;
    });
    assert_eq!(summary.state, RunState::Faulted, "{}", reason(&summary));
    let why = reason(&summary);
    assert!(
        why.contains("10.00 g would put 10.0") && why.contains("arm.max_g = 10 g"),
        "{why}"
    );
    assert!(
        !events.iter().any(|e| matches!(e, Event::PointDone { .. })),
        "stopped at the radius step, before the first level"
    );
    let applied = largest_applied_g(&events, &bench);
    assert!(applied <= 10.0, "the table went to {applied:.3} g");
    assert_safe(&bench, true);
    bench.shutdown();
}

#[test]
fn one_instrument_far_from_its_drawing_radius_is_set_aside_and_the_run_goes_on() {
    let mut sim = SimConfig::default();
    sim.centrifuge.position_shifts_mm = vec![10.0];
    let (summary, _events, bench) = run(sim, small_plan(), None);
    assert_eq!(summary.state, RunState::Completed, "{}", reason(&summary));
    let first = &summary.records[0];
    let why: Vec<&str> = first.reasons.iter().map(|r| r.text.as_str()).collect();
    assert!(
        why.iter()
            .any(|t| t.contains("radius measured 0.809") && t.contains("check its fixture")),
        "{why:?}"
    );
    assert_eq!(first.outcome, Outcome::Incomplete);
    assert!(
        summary.records[1..]
            .iter()
            .all(|r| r.radius_m.contains_key(&Mount::P))
    );
    bench.shutdown();
}
