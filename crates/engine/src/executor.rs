//! The one executor: runs a compiled plan's steps against the hardware
//! traits, emits events, and always ends in the safe state.
//!
//! Run states (an explicit table):
//!
//! | from | event | to |
//! |---|---|---|
//! | Idle | start | Running |
//! | Running | operator prompt | Prompting → Running |
//! | Running | pause (between steps) | Paused → Running on resume |
//! | Running, Prompting | a write fails (store, journal) | Paused → Running once it succeeds |
//! | Paused (write failing) | hold limit passes | Stopping → Faulted |
//! | Running | last step done | Stopping → Completed |
//! | Running, Prompting | fault (device lost, interlock, over-current, no stability) | Stopping → Faulted |
//! | Running, Prompting | abort (Ctrl-C, operator) | Stopping → Aborted |
//!
//! Time is counted in counter-module windows (one second of ticks each), so
//! the same code runs against hardware and against a faster-than-real-time
//! simulator. Data are taken only at stable speed (method.md §3.3).

use crate::abort::AbortFlag;
use crate::config::StationConfig;
use crate::event::{DeviceIdentity, Event, EventSink, ModuleHealth, RunState};
use crate::plan::{CompiledPlan, Fixture, Step};
use crate::record::{Outcome, PointRecord, UnitRecord};
use spinbench_analysis::radius::RadiusCalibration;
use spinbench_analysis::tumble::TumbleCalibration;
use spinbench_analysis::unit::{AnalysisOptions, UnitPoints, analyze_unit};
use spinbench_analysis::{Mount, Point, UG_PER_G, centrifuge};
use spinbench_devices::{Centrifuge, CounterModule, DeviceError, DeviceErrorKind, PowerSupply};
use spinbench_wire::fmu::{INSTRUMENTS_PER_MODULE, WindowAccumulator, WindowConfig, WindowValue};
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Scale factor assumed before the tumble has measured it [Hz/g].
const NOMINAL_K1_HZ_PER_G: f64 = 100.0;

/// What every screen and record says when the centrifuge did not confirm its stop.
pub const STOP_NOT_CONFIRMED: &str = "stop not confirmed: check the centrifuge";
/// Times the stop is commanded at the end of a run before it counts as unconfirmed.
const STOP_ATTEMPTS: usize = 3;
/// How often an unconfirmed stop is commanded again, for as long as the process lives.
const STOP_RETRY: Duration = Duration::from_secs(2);

/// A table counts as at rest below this rate [deg/s].
const AT_REST_DEG_S: f64 = 0.05;
/// Resonator frequencies outside this range mean a dead or miswired input [Hz].
const RESONATOR_RANGE_HZ: (f64, f64) = (5_000.0, 200_000.0);

/// The hardware of a station.
pub struct Bench {
    /// The centrifuge.
    pub centrifuge: Box<dyn Centrifuge>,
    /// The counter modules, in slot order.
    pub modules: Vec<Box<dyn CounterModule>>,
    /// The instruments' ±15 V supply (outputs 1 and 2).
    pub instrument_supply: Box<dyn PowerSupply>,
    /// The modules' supply, if the station switches it.
    pub module_supply: Option<Box<dyn PowerSupply>>,
}

/// An operator's answer to a prompt.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Answer {
    /// Continue (true) or abort the run.
    pub proceed: bool,
    /// Who answered.
    pub by: String,
}

/// Whoever answers prompts: the terminal, the web UI, or the simulator.
pub trait Operator {
    /// Ask the operator to do `text` (mount the instruments as `fixtures`)
    /// and wait for the answer.
    fn ask(&mut self, text: &str, fixtures: &[Option<Fixture>]) -> Answer;

    /// Put the question without waiting, when this operator can be polled:
    /// the engine then keeps reading the counter modules (nothing overruns
    /// while a person walks to the centrifuge) and calls
    /// [`poll_answer`](Self::poll_answer). The default asks and waits.
    fn post(&mut self, text: &str, fixtures: &[Option<Fixture>]) -> Option<Answer> {
        Some(self.ask(text, fixtures))
    }

    /// The answer to the posted question, waiting at most `wait`.
    fn poll_answer(&mut self, wait: Duration) -> Option<Answer> {
        let _ = wait;
        None
    }
}

/// Why a run ended early.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EngineError {
    /// A device failed.
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// A counter module sent no data within the deadline.
    #[error("counter module {module} sent no data for {seconds:.1} s; check its cable and supply")]
    ModuleSilent {
        /// Module index (1-based).
        module: usize,
        /// Wall-clock seconds of silence.
        seconds: f64,
    },
    /// The interlocks opened while the table was commanded to move.
    #[error(
        "the centrifuge interlocks opened; the table was stopped (close the door and reset the interlocks)"
    )]
    InterlockOpen,
    /// The instrument supply lost its output (over-current trip).
    #[error(
        "the instrument supply output dropped to {volts:.2} V (over-current trip?); check for a shorted instrument"
    )]
    SupplyTripped {
        /// Measured output voltage.
        volts: f64,
    },
    /// The rate or the outputs did not become stable.
    #[error("{0}")]
    NotStable(String),
    /// The operator or Ctrl-C aborted the run.
    #[error("aborted by {0}")]
    Aborted(String),
    /// The supply current does not match the instruments powered.
    #[error("{0}")]
    Power(String),
    /// An event subscriber (e.g. the journal) failed.
    #[error("{0}")]
    Sink(String),
    /// Nothing left to measure.
    #[error("every instrument has failed; nothing left to measure")]
    NoUnits,
}

/// Options of a run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Run identifier.
    pub run_id: String,
    /// Set to abort (Ctrl-C or a signal ending the process, the operator).
    pub abort: AbortFlag,
    /// While set, the run holds between steps (the ports are still read).
    pub pause: Arc<AtomicBool>,
    /// Wall-clock deadline for a counter module's silence.
    pub module_silence: Duration,
    /// The station config's text, stored with the run as a snapshot.
    pub station_config_toml: String,
    /// How long a run is held while a subscriber (the store) cannot write
    /// before it faults into the safe state.
    pub sink_hold_limit: Duration,
}

#[derive(Debug, Clone, Default)]
struct UnitState {
    up: Option<f64>,
    down: Option<f64>,
    cal: Option<TumbleCalibration>,
    radius: BTreeMap<Mount, f64>,
    points: Vec<PointRecord>,
    failed: Option<String>,
}

/// One second of the whole station.
#[derive(Debug, Clone)]
struct Window {
    time_s: f64,
    rate_deg_s: f64,
    /// dF per slot, `None` when missing or from an incomplete window.
    outputs: Vec<Option<f64>>,
    /// (f1, f2) per slot.
    resonators: Vec<(Option<f64>, Option<f64>)>,
}

/// The summary of a finished run.
#[derive(Debug, Clone)]
pub struct RunSummary {
    /// Final state.
    pub state: RunState,
    /// Why it did not complete, if so.
    pub reason: Option<String>,
    /// One record per instrument.
    pub records: Vec<UnitRecord>,
    /// Station time the run took [s].
    pub duration_s: f64,
    /// One-second windows dropped to keep the counter modules aligned in time.
    pub dropped_windows: u64,
    /// The centrifuge controller acknowledged the stop at the end of the run.
    /// When false the reason says [`STOP_NOT_CONFIRMED`], and a thread keeps
    /// commanding the stop for as long as the process lives.
    pub stop_confirmed: bool,
}

/// The executor.
pub struct Executor<'a> {
    station: &'a StationConfig,
    plan: CompiledPlan,
    bench: Bench,
    operator: Box<dyn Operator + 'a>,
    sinks: Vec<Box<dyn EventSink + 'a>>,
    options: RunOptions,
    units: Vec<UnitState>,
    completed: BTreeSet<usize>,
    resumed: bool,
    accumulators: Vec<WindowAccumulator>,
    pending: Vec<VecDeque<WindowValue>>,
    last_data: Vec<Instant>,
    windows: u64,
    demand_deg_s: f64,
    streaming: bool,
    /// Windows dropped to keep the modules aligned in time.
    dropped_windows: u64,
    /// The instrument supply's output 1 at its last safety check: (volts, amperes).
    supply_first: (f64, f64),
    /// The controller acknowledged the last stop command.
    stop_confirmed: bool,
}

impl<'a> Executor<'a> {
    /// An executor for `plan` on `bench`.
    pub fn new(
        station: &'a StationConfig,
        plan: CompiledPlan,
        bench: Bench,
        operator: Box<dyn Operator + 'a>,
        options: RunOptions,
    ) -> Self {
        let slots = plan.serials.len();
        let accumulators = station
            .fmu
            .iter()
            .map(|f| {
                WindowAccumulator::new(WindowConfig {
                    mode: f.mode.into(),
                    reference_hz: f.reference_hz,
                    ..WindowConfig::default()
                })
            })
            .collect();
        let modules = station.fmu.len();
        Executor {
            station,
            plan,
            bench,
            operator,
            sinks: Vec::new(),
            options,
            units: vec![UnitState::default(); slots],
            completed: BTreeSet::new(),
            resumed: false,
            accumulators,
            pending: vec![VecDeque::new(); modules],
            last_data: vec![Instant::now(); modules],
            windows: 0,
            demand_deg_s: 0.0,
            streaming: false,
            dropped_windows: 0,
            supply_first: (0.0, 0.0),
            stop_confirmed: false,
        }
    }

    /// Subscribe to the event stream.
    pub fn subscribe(&mut self, sink: impl EventSink + 'a) {
        self.sinks.push(Box::new(sink));
    }

    /// Restore what a journal says was done, so [`run`](Self::run) continues
    /// after the last completed step with no point lost or repeated.
    pub fn restore(&mut self, events: &[Event]) {
        self.resumed = true;
        let mut last_points: BTreeMap<usize, &Vec<PointRecord>> = BTreeMap::new();
        // Station time goes on from where the journal ends, so the resumed
        // run's one-second values never take the times of the first's.
        let mut last_time_s: f64 = 0.0;
        for e in events {
            match e {
                Event::Values { time_s, .. } => {
                    last_time_s = last_time_s.max(*time_s);
                }

                Event::StepDone { index } => {
                    self.completed.insert(*index);
                }
                Event::TumbleDone {
                    slot,
                    up,
                    output_hz,
                } => {
                    if let Some(u) = self.units.get_mut(*slot) {
                        if *up {
                            u.up = Some(*output_hz);
                        } else {
                            u.down = Some(*output_hz);
                        }
                        if let (Some(up), Some(down)) = (u.up, u.down) {
                            u.cal = TumbleCalibration::from_up_down(up, down).ok();
                        }
                    }
                }
                Event::RadiusDone {
                    slot,
                    mount,
                    radius_m,
                    ..
                } => {
                    if let Some(u) = self.units.get_mut(*slot) {
                        u.radius.insert(*mount, *radius_m);
                    }
                }
                Event::PointDone { step, points } => {
                    for p in points.iter() {
                        last_time_s = last_time_s.max(p.time_s[1]);
                    }
                    // A step killed between its PointDone and StepDone is redone
                    // and journals its point again: only the last one counts.
                    last_points.insert(*step, points);
                }
                Event::UnitFailed { slot, reason } => {
                    if let Some(u) = self.units.get_mut(*slot) {
                        u.failed = Some(reason.clone());
                    }
                }
                _ => {}
            }
        }
        if last_time_s.is_finite() && last_time_s > 0.0 {
            self.windows = last_time_s.ceil() as u64;
        }
        // A point is whole only with its StepDone; a torn step is redone.
        for (step, points) in last_points {
            if self.completed.contains(&step) {
                for p in points {
                    if let Some(u) = self.units.get_mut(p.slot) {
                        u.points.push(p.clone());
                    }
                }
            }
        }
    }

    /// Go on counting station time after `time_s` (on resume: the last
    /// one-second value the store holds of the run), so no value of the
    /// resumed run takes the time of one already stored.
    pub fn continue_time_after(&mut self, time_s: f64) {
        if time_s.is_finite() && time_s > 0.0 {
            self.windows = self.windows.max(time_s.ceil() as u64);
        }
    }

    fn emit(&mut self, event: Event) -> Result<(), EngineError> {
        for i in 0..self.sinks.len() {
            if let Err(problem) = self.sinks[i].emit(&event) {
                self.hold_for_sink(i, &event, problem)?;
            }
        }
        Ok(())
    }

    /// A subscriber (the store, the journal) could not take an event: nothing
    /// is dropped. The run is held (state Paused; the ports are still read,
    /// the table keeps its commanded rate) and the same event is offered again
    /// every second, until it is taken (the run goes on), the operator aborts,
    /// or [`RunOptions::sink_hold_limit`] passes (a fault: safe state).
    fn hold_for_sink(
        &mut self,
        failed: usize,
        event: &Event,
        problem: String,
    ) -> Result<(), EngineError> {
        fn tell_others(sinks: &mut [Box<dyn EventSink + '_>], failed: usize, e: &Event) {
            for (j, sink) in sinks.iter_mut().enumerate() {
                if j != failed {
                    let _ = sink.emit(e);
                }
            }
        }
        tell_others(
            &mut self.sinks,
            failed,
            &Event::Notice {
                message: format!(
                    "{problem}; the run is held (paused) and the write is tried again every second \
                     — fix the database or abort"
                ),
            },
        );
        tell_others(
            &mut self.sinks,
            failed,
            &Event::StateChanged {
                state: RunState::Paused,
            },
        );
        let held = Instant::now();
        let mut last = problem;
        loop {
            if self.options.abort.is_set() {
                return Err(EngineError::Aborted(format!(
                    "the operator while a write was failing ({last})"
                )));
            }
            if held.elapsed() > self.options.sink_hold_limit {
                return Err(EngineError::Sink(format!(
                    "{last} (held {:.0} s, sink_hold_limit)",
                    held.elapsed().as_secs_f64()
                )));
            }
            self.drain_ports(Duration::from_secs(1));
            match self.sinks[failed].emit(event) {
                Ok(()) => break,
                Err(e) => last = e,
            }
        }
        tell_others(
            &mut self.sinks,
            failed,
            &Event::Notice {
                message: "the write succeeded; nothing was lost and the run goes on".into(),
            },
        );
        tell_others(
            &mut self.sinks,
            failed,
            &Event::StateChanged {
                state: RunState::Running,
            },
        );
        // The failed subscriber missed the notice; it gets the state.
        let _ = self.sinks[failed].emit(&Event::StateChanged {
            state: RunState::Running,
        });
        Ok(())
    }

    /// Read every module's port for `time` without using the data beyond
    /// keeping each module's freshest window (a held run must not let the
    /// ports overrun).
    fn drain_ports(&mut self, time: Duration) {
        let until = Instant::now() + time;
        while Instant::now() < until {
            for m in 0..self.bench.modules.len() {
                let Ok(got) =
                    self.bench.modules[m].receive(Instant::now() + Duration::from_millis(5))
                else {
                    continue;
                };
                if !got.is_empty() {
                    self.last_data[m] = Instant::now();
                }
                for msg in got {
                    let closed = self.accumulators[m].push(&msg);
                    self.pending[m].extend(closed);
                }
                while self.pending[m].len() > 1 {
                    self.pending[m].pop_front();
                    self.dropped_windows += 1;
                }
            }
            if !self.streaming {
                std::thread::sleep(Duration::from_millis(20));
            }
        }
    }

    fn set_state(&mut self, state: RunState) -> Result<(), EngineError> {
        self.emit(Event::StateChanged { state })
    }

    fn live(&self, slot: usize) -> bool {
        self.plan.serials[slot].is_some() && self.units[slot].failed.is_none()
    }

    fn fail_unit(&mut self, slot: usize, reason: String) -> Result<(), EngineError> {
        if self.units[slot].failed.is_none() {
            self.units[slot].failed = Some(reason.clone());
            self.emit(Event::UnitFailed { slot, reason })?;
        }
        if (0..self.units.len()).all(|s| !self.live(s)) {
            return Err(EngineError::NoUnits);
        }
        Ok(())
    }

    /// The sign of the instrument's scale factor from its tumble (+1 before it).
    fn k1_sign(&self, slot: usize) -> f64 {
        self.units[slot]
            .cal
            .map_or(1.0, |c| c.scale_factor.signum())
    }

    fn k1(&self, slot: usize) -> f64 {
        self.units[slot]
            .cal
            .map_or(NOMINAL_K1_HZ_PER_G, |c| c.scale_factor.abs())
    }

    /// Ask every device who it is, for the run's record; a device that cannot
    /// say is recorded with the reason (the run's own checks decide whether it can work).
    fn identify(&mut self) -> Result<(), EngineError> {
        let say =
            |r: Result<String, DeviceError>| r.unwrap_or_else(|e| format!("(no answer: {e})"));
        let mut devices = vec![DeviceIdentity {
            role: "centrifuge".into(),
            identity: say(self.bench.centrifuge.identify()),
        }];
        for (m, module) in self.bench.modules.iter_mut().enumerate() {
            devices.push(DeviceIdentity {
                role: format!("fmu {}", m + 1),
                identity: say(module
                    .status()
                    .map(|s| format!("firmware {:#06x}", s.firmware_id))),
            });
        }
        devices.push(DeviceIdentity {
            role: "instrument supply".into(),
            identity: say(self.bench.instrument_supply.identify()),
        });
        if let Some(supply) = self.bench.module_supply.as_mut() {
            devices.push(DeviceIdentity {
                role: "module supply".into(),
                identity: say(supply.identify()),
            });
        }
        self.emit(Event::Identified { devices })
    }

    /// Run the plan to the end (or to a fault or abort) and return the records.
    pub fn run(&mut self) -> RunSummary {
        let started = self.emit(Event::RunStarted {
            run_id: self.options.run_id.clone(),
            station: self.station.station.clone(),
            plan: Box::new(self.plan.clone()),
            resumed: self.resumed,
            station_config: self.options.station_config_toml.clone(),
        });
        let result = started
            .and_then(|()| self.identify())
            .and_then(|()| self.set_state(RunState::Running))
            .and_then(|()| self.execute_steps());
        let (mut state, reason) = match &result {
            Ok(()) => (RunState::Completed, None),
            Err(EngineError::Aborted(_)) => (
                RunState::Aborted,
                result.as_ref().err().map(ToString::to_string),
            ),
            Err(e) => (RunState::Faulted, Some(e.to_string())),
        };
        if let Some(r) = &reason {
            let _ = self.emit(Event::Fault { reason: r.clone() });
        }
        let _ = self.set_state(RunState::Stopping);
        let safe_problems = self.safe_state();
        if !self.stop_confirmed {
            let _ = self.emit(Event::Fault {
                reason: safe_problems[0].clone(),
            });
            let centrifuge =
                std::mem::replace(&mut self.bench.centrifuge, Box::new(HandedToStopKeeper));
            keep_stopping(centrifuge);
            if state == RunState::Completed {
                state = RunState::Faulted;
            }
        }
        let complete = result.is_ok();
        let reason = match (reason, safe_problems.is_empty()) {
            (r, true) => r,
            (Some(r), false) => Some(format!(
                "{r}; while making safe: {}",
                safe_problems.join("; ")
            )),
            (None, false) => Some(format!("while making safe: {}", safe_problems.join("; "))),
        };
        let records = self.records(complete, reason.as_deref());
        for r in &records {
            let _ = self.emit(Event::UnitResult {
                record: Box::new(r.clone()),
            });
        }
        let _ = self.set_state(state);
        let _ = self.emit(Event::RunFinished {
            state,
            reason: reason.clone(),
        });
        RunSummary {
            state,
            reason,
            records,
            duration_s: self.windows as f64,
            dropped_windows: self.dropped_windows,
            stop_confirmed: self.stop_confirmed,
        }
    }

    fn execute_steps(&mut self) -> Result<(), EngineError> {
        let steps = self.plan.steps.clone();
        // On resume: the first step still to do, and the mounting it needs.
        let first_todo = (0..steps.len()).find(|i| !self.completed.contains(i));
        let remount = first_todo.and_then(|t| {
            (0..t)
                .rev()
                .find(|&i| matches!(steps[i], Step::Mount { .. }))
        });
        for (index, step) in steps.iter().enumerate() {
            let setup = matches!(step, Step::PowerOn | Step::CheckAlive);
            let needed = !self.completed.contains(&index)
                || (self.resumed && (setup || Some(index) == remount));
            if !needed {
                continue;
            }
            if self.options.abort.is_set() {
                return Err(EngineError::Aborted(self.options.abort.by()));
            }
            if self.options.pause.load(Ordering::Relaxed) {
                self.set_state(RunState::Paused)?;
                while self.options.pause.load(Ordering::Relaxed) {
                    if self.options.abort.is_set() {
                        return Err(EngineError::Aborted(self.options.abort.by()));
                    }
                    if self.streaming {
                        // Keep reading (and keep the safety checks running) while held.
                        self.next_window()?;
                    } else {
                        std::thread::sleep(Duration::from_millis(10));
                    }
                }
                self.set_state(RunState::Running)?;
            }
            self.emit(Event::StepStarted {
                index,
                of: steps.len(),
                label: label(step),
            })?;
            match step {
                Step::PowerOn => self.power_on()?,
                Step::CheckAlive => self.check_alive()?,
                Step::WarmUp { seconds } => self.warm_up(*seconds)?,
                Step::Mount { fixtures } => self.mount(fixtures)?,
                Step::Tumble { up } => self.tumble(*up)?,
                Step::Radius { pass } => self.radius(*pass)?,
                Step::Level {
                    pass,
                    g_nominal,
                    direction,
                } => self.level(index, *pass, *g_nominal, *direction)?,
                Step::Stop => self.command_rate(0.0)?,
            }
            self.emit(Event::StepDone { index })?;
        }
        Ok(())
    }

    fn power_on(&mut self) -> Result<(), EngineError> {
        let p = &self.station.power;
        if let Some(m) = &mut self.bench.module_supply {
            m.set_output(1, true)?;
        }
        for ch in [1, 2] {
            self.bench
                .instrument_supply
                .configure(ch, p.rail_volts, p.rail_current_limit_a)?;
            self.bench.instrument_supply.set_output(ch, true)?;
        }
        for (m, module) in self.bench.modules.iter_mut().enumerate() {
            let mask = (0..INSTRUMENTS_PER_MODULE)
                .filter(|s| {
                    self.plan
                        .serials
                        .get(m * INSTRUMENTS_PER_MODULE + s)
                        .is_some_and(Option::is_some)
                })
                .fold(0u8, |mask, s| mask | (1 << s));
            module.set_power(mask)?;
            module.start(self.station.fmu[m].mode.into())?;
        }
        self.streaming = true;
        self.bench.centrifuge.reset_interlocks()?;
        self.bench.centrifuge.arm()?;
        let now = Instant::now();
        self.last_data.iter_mut().for_each(|t| *t = now);
        Ok(())
    }

    fn check_alive(&mut self) -> Result<(), EngineError> {
        let mut seen: Vec<u32> = vec![0; self.units.len()];
        for _ in 0..3 {
            let w = self.next_window()?;
            for (slot, (f1, f2)) in w.resonators.iter().enumerate() {
                let ok = |f: &Option<f64>| {
                    f.is_some_and(|f| (RESONATOR_RANGE_HZ.0..=RESONATOR_RANGE_HZ.1).contains(&f))
                };
                if ok(f1) && ok(f2) {
                    seen[slot] += 1;
                }
            }
        }
        // The instruments' total current on the +15 V rail.
        let powered = self.plan.serials.iter().filter(|s| s.is_some()).count() as f64;
        let expected = powered * self.station.power.instrument_current_a;
        let amps = self.bench.instrument_supply.measure(1)?.amps;
        if expected > 0.0 && !(0.5 * expected..=1.5 * expected).contains(&amps) {
            return Err(EngineError::Power(format!(
                "the instruments draw {amps:.3} A on the +15 V rail, expected about {expected:.3} A \
                 ({powered} × power.instrument_current_a); check the relays and the wiring"
            )));
        }
        for (slot, &count) in seen.iter().enumerate() {
            if self.live(slot) && count == 0 {
                self.fail_unit(
                    slot,
                    "no output from its resonators: dead, unpowered or not connected".into(),
                )?;
            }
        }
        Ok(())
    }

    fn warm_up(&mut self, seconds: f64) -> Result<(), EngineError> {
        let n = seconds.ceil() as u32;
        for i in 0..n {
            self.next_window()?;
            self.emit(Event::Progress {
                phase: "warm-up".into(),
                done: i + 1,
                of: n,
            })?;
        }
        Ok(())
    }

    fn mount(&mut self, fixtures: &[Option<Fixture>]) -> Result<(), EngineError> {
        // The table must be at rest before anyone touches it.
        self.command_rate(0.0)?;
        let mut waited = 0;
        while self.next_window()?.rate_deg_s.abs() > AT_REST_DEG_S {
            waited += 1;
            if waited > self.plan.plan.stability.max_settle_s {
                return Err(EngineError::NotStable(
                    "the table did not come to rest for remounting".into(),
                ));
            }
        }
        let text = mount_text(fixtures);
        self.set_state(RunState::Prompting)?;
        self.emit(Event::Prompt {
            text: text.clone(),
            fixtures: fixtures.to_vec(),
        })?;
        let mut answer = self.operator.post(&text, fixtures);
        while answer.is_none() {
            if self.options.abort.is_set() {
                return Err(EngineError::Aborted(self.options.abort.by()));
            }
            // Keep the ports read while the person works.
            self.drain_ports(Duration::from_millis(100));
            answer = self.operator.poll_answer(Duration::from_millis(50));
        }
        let answer = answer.unwrap_or(Answer {
            proceed: false,
            by: "nobody".into(),
        });
        self.emit(Event::PromptAnswered {
            proceed: answer.proceed,
            by: answer.by.clone(),
        })?;
        self.set_state(RunState::Running)?;
        if !answer.proceed {
            return Err(EngineError::Aborted(answer.by));
        }
        Ok(())
    }

    fn command_rate(&mut self, rate_deg_s: f64) -> Result<(), EngineError> {
        if rate_deg_s == 0.0 {
            self.bench.centrifuge.stop()?;
        } else {
            self.bench.centrifuge.set_rate(rate_deg_s)?;
        }
        self.demand_deg_s = rate_deg_s;
        Ok(())
    }

    /// Wait for stability, then average; returns the dwell's windows. An
    /// instrument whose output keeps drifting while the rate holds (and the
    /// others settle) fails and leaves `slots`; the others go on.
    fn acquire(&mut self, slots: &mut Vec<usize>) -> Result<Vec<Window>, EngineError> {
        let st = self.plan.plan.stability;
        let dwell = self.plan.plan.dwell;
        let mut restarts = 0;
        // The slope test runs on every instrument at once: its critical t
        // keeps the chance that noise alone holds the station at 1 % per
        // look (Bonferroni over the instruments; at least 3). With one
        // fixed t = 3 and 96 instruments, some instrument's noise looked
        // like drift nearly every second and a level never settled.
        let looks = slots.len().max(1) as f64;
        let t_crit = spinbench_analysis::model::student_t_quantile(
            1.0 - 0.01 / looks / 2.0,
            (st.hold_s as usize).saturating_sub(2),
        )
        .map_or(3.0, |t| t.max(3.0));
        'settle: loop {
            // Settle: the rate on speed for the hold time, then no output drifting.
            let mut hold: Vec<Window> = Vec::new();
            let mut waited = 0;
            // The instruments the last full hold found drifting.
            let mut drifting: Vec<usize> = Vec::new();
            loop {
                let w = self.next_window()?;
                waited += 1;
                self.emit(Event::Progress {
                    phase: "settling".into(),
                    done: hold.len() as u32,
                    of: st.hold_s,
                })?;
                if self.on_speed(w.rate_deg_s) {
                    hold.push(w);
                } else {
                    hold.clear();
                }
                if hold.len() >= st.hold_s as usize {
                    drifting = slots
                        .iter()
                        .copied()
                        .filter(|&s| self.drifting(s, &hold, t_crit))
                        .collect();
                    if drifting.is_empty() {
                        break;
                    }
                    hold.remove(0);
                }
                if waited > st.max_settle_s {
                    if !drifting.is_empty() && drifting.len() < slots.len() {
                        for &s in &drifting {
                            self.fail_unit(
                                s,
                                format!(
                                    "its output kept drifting for {} s at {:.3} deg/s (more than stability.drift_limit_ug_per_s = {} µg/s)",
                                    st.max_settle_s, self.demand_deg_s, st.drift_limit_ug_per_s
                                ),
                            )?;
                        }
                        slots.retain(|s| !drifting.contains(s));
                        drifting.clear();
                        waited = 0;
                        continue;
                    }
                    return Err(EngineError::NotStable(format!(
                        "no stable speed and outputs within {} s at {:.3} deg/s (stability.max_settle_s)",
                        st.max_settle_s, self.demand_deg_s
                    )));
                }
            }
            // Average: n values, a rate excursion discards and restarts the point.
            let mut values: Vec<Window> = Vec::new();
            let target_n = if dwell.sem_target_ug.is_some() {
                dwell.max_seconds
            } else {
                dwell.seconds
            };
            while (values.len() as u32) < target_n {
                let w = self.next_window()?;
                if !self.on_speed(w.rate_deg_s) {
                    restarts += 1;
                    if restarts > st.max_restarts {
                        return Err(EngineError::NotStable(format!(
                            "the rate left its tolerance {restarts} times while averaging at {:.3} deg/s",
                            self.demand_deg_s
                        )));
                    }
                    continue 'settle;
                }
                values.push(w);
                self.emit(Event::Progress {
                    phase: "averaging".into(),
                    done: values.len() as u32,
                    of: target_n,
                })?;
                if let Some(target) = dwell.sem_target_ug
                    && values.len() as u32 >= dwell.min_seconds
                    && slots
                        .iter()
                        .all(|&s| self.sem_ug(s, &values).is_none_or(|sem| sem <= target))
                {
                    break;
                }
            }
            return Ok(values);
        }
    }

    fn on_speed(&self, rate_deg_s: f64) -> bool {
        let d = self.demand_deg_s;
        let tol = (d.abs() * self.plan.plan.stability.rate_tolerance_ppm * 1e-6).max(AT_REST_DEG_S);
        (rate_deg_s - d).abs() <= tol
    }

    /// The slope test: a drift above the limit and significant at `t_crit`.
    fn drifting(&self, slot: usize, hold: &[Window], t_crit: f64) -> bool {
        let y: Vec<f64> = hold.iter().filter_map(|w| w.outputs[slot]).collect();
        if y.len() < 3 {
            return false;
        }
        let n = y.len() as f64;
        let xbar = (n - 1.0) / 2.0;
        let ybar = y.iter().sum::<f64>() / n;
        let sxx: f64 = (0..y.len()).map(|i| (i as f64 - xbar).powi(2)).sum();
        let sxy: f64 = y
            .iter()
            .enumerate()
            .map(|(i, v)| (i as f64 - xbar) * (v - ybar))
            .sum();
        let slope = sxy / sxx;
        let rss: f64 = y
            .iter()
            .enumerate()
            .map(|(i, v)| (v - ybar - slope * (i as f64 - xbar)).powi(2))
            .sum();
        let se = (rss / (n - 2.0) / sxx).sqrt();
        let slope_ug = slope.abs() / self.k1(slot) * UG_PER_G;
        slope_ug > self.plan.plan.stability.drift_limit_ug_per_s && slope.abs() > t_crit * se
    }

    /// Each instrument's own 1-s scatter [µg], robust to what every
    /// instrument feels: the part of the output the measured rate explains
    /// (the applied acceleration of each window from its rate, (9)) is
    /// removed, so the tail of the table's settling within the rate
    /// tolerance is not taken for instrument noise; the common mode (median
    /// deviation per window) of the instruments on the same counter module is
    /// removed when there are at least three (their windows are the same
    /// ticks by construction); and the scatter is estimated from successive
    /// differences (σ = std(Δ)/√2), which ignores slow trends. A rate reading
    /// is one instant of a ripple, so the smaller of the scatter with and
    /// without the rate correction is taken.
    fn instrument_noise_ug(
        &self,
        pass: usize,
        slots: &[usize],
        values: &[Window],
    ) -> BTreeMap<usize, f64> {
        let raw = self.scatter_ug(pass, slots, values, false);
        let corrected = self.scatter_ug(pass, slots, values, true);
        raw.into_iter()
            .map(|(s, a)| (s, corrected.get(&s).map_or(a, |&b| a.min(b))))
            .collect()
    }

    fn scatter_ug(
        &self,
        pass: usize,
        slots: &[usize],
        values: &[Window],
        rate_corrected: bool,
    ) -> BTreeMap<usize, f64> {
        let g = self.station.g_local_m_s2;
        let mut out = BTreeMap::new();
        let mut by_module: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
        for &s in slots {
            by_module
                .entry(s / INSTRUMENTS_PER_MODULE)
                .or_default()
                .push(s);
        }
        for group in by_module.values() {
            // Series in g, per slot, over the windows where every slot of the group has a value.
            let windows: Vec<&Window> = values
                .iter()
                .filter(|w| group.iter().all(|&s| w.outputs[s].is_some()))
                .collect();
            if windows.len() < 3 {
                continue;
            }
            let series: Vec<Vec<f64>> = group
                .iter()
                .map(|&s| {
                    let mount = self.plan.passes[pass][s].unwrap_or(Mount::P);
                    let radius = self.units[s]
                        .radius
                        .get(&mount)
                        .copied()
                        .unwrap_or_else(|| self.station.drawing_radius_m(s));
                    windows
                        .iter()
                        .filter_map(|w| {
                            let y = w.outputs[s]? / self.k1(s);
                            if !rate_corrected {
                                return Some(y);
                            }
                            let rate = w.rate_deg_s.to_radians();
                            // method.md (9), signed by the mounting and the scale factor.
                            let sign = mount.input_sign() * self.k1_sign(s);
                            Some(y - sign * rate * rate * radius / g)
                        })
                        .collect()
                })
                .collect();
            let common: Vec<f64> = (0..windows.len())
                .map(|t| {
                    if group.len() < 3 {
                        return 0.0;
                    }
                    let mut dev: Vec<f64> = series.iter().map(|y| y[t] - mean_std(y).0).collect();
                    dev.sort_by(f64::total_cmp);
                    dev[dev.len() / 2]
                })
                .collect();
            for (k, &s) in group.iter().enumerate() {
                let own: Vec<f64> = series[k].iter().zip(&common).map(|(y, c)| y - c).collect();
                let diffs: Vec<f64> = own.windows(2).map(|d| d[1] - d[0]).collect();
                let (_, std_diff) = mean_std(&diffs);
                out.insert(s, std_diff / std::f64::consts::SQRT_2 * UG_PER_G);
            }
        }
        out
    }

    fn sem_ug(&self, slot: usize, values: &[Window]) -> Option<f64> {
        let y: Vec<f64> = values.iter().filter_map(|w| w.outputs[slot]).collect();
        if y.len() < 2 {
            return None;
        }
        let (mean, std) = mean_std(&y);
        let _ = mean;
        Some(std / (y.len() as f64).sqrt() / self.k1(slot) * UG_PER_G)
    }

    fn tumble(&mut self, up: bool) -> Result<(), EngineError> {
        self.command_rate(0.0)?;
        let mut slots: Vec<usize> = (0..self.units.len()).filter(|&s| self.live(s)).collect();
        let values = self.acquire(&mut slots)?;
        for slot in slots {
            let y: Vec<f64> = values.iter().filter_map(|w| w.outputs[slot]).collect();
            if y.is_empty() {
                self.fail_unit(
                    slot,
                    format!(
                        "no output during the IA-{} tumble reading",
                        if up { "up" } else { "down" }
                    ),
                )?;
                continue;
            }
            let (mean, _) = mean_std(&y);
            let u = &mut self.units[slot];
            if up {
                u.up = Some(mean);
            } else {
                u.down = Some(mean);
            }
            self.emit(Event::TumbleDone {
                slot,
                up,
                output_hz: mean,
            })?;
            let u = &self.units[slot];
            if let (Some(a), Some(b)) = (u.up, u.down) {
                match TumbleCalibration::from_up_down(a, b) {
                    Ok(cal) => self.units[slot].cal = Some(cal),
                    Err(e) => self.fail_unit(slot, format!("tumble: {e}"))?,
                }
            }
        }
        Ok(())
    }

    fn radius(&mut self, pass: usize) -> Result<(), EngineError> {
        let g = self.station.g_local_m_s2;
        let r0 = self.station.arm.radius_m;
        let w = centrifuge::rate_for_acceleration_rad_s(1.0, r0, g)
            .map_err(|e| EngineError::NotStable(e.to_string()))?;
        self.command_rate(w.to_degrees())?;
        let mut slots: Vec<usize> = (0..self.units.len())
            .filter(|&s| self.live(s) && self.plan.passes[pass][s].is_some())
            .collect();
        let values = self.acquire(&mut slots)?;
        let rate = values.iter().map(|w| w.rate_deg_s).sum::<f64>() / values.len().max(1) as f64;
        let w_meas = rate.to_radians();
        for slot in slots {
            let Some(mount) = self.plan.passes[pass][slot] else {
                continue;
            };
            let y: Vec<f64> = values.iter().filter_map(|w| w.outputs[slot]).collect();
            let Some(cal) = self.units[slot].cal else {
                continue;
            };
            if y.is_empty() {
                self.fail_unit(slot, "no output during the radius step".into())?;
                continue;
            }
            let (mean, _) = mean_std(&y);
            let r0_i = self.station.drawing_radius_m(slot);
            // method.md (6)–(8) at the measured rate: the rate applies ω²·R0/g at R0.
            let nominal_g = w_meas * w_meas * r0_i / g;
            match RadiusCalibration::from_reading(mean, &cal, r0_i, nominal_g, mount) {
                Ok(r) => {
                    self.units[slot].radius.insert(mount, r.radius_m);
                    self.emit(Event::RadiusDone {
                        slot,
                        mount,
                        drawing_radius_m: r0_i,
                        radius_m: r.radius_m,
                    })?;
                }
                Err(e) => self.fail_unit(slot, format!("radius in mounting {mount}: {e}"))?,
            }
        }
        Ok(())
    }

    fn level(
        &mut self,
        step: usize,
        pass: usize,
        g_nominal: f64,
        direction: spinbench_analysis::Direction,
    ) -> Result<(), EngineError> {
        let g = self.station.g_local_m_s2;
        let r0 = self.station.arm.radius_m;
        let w = centrifuge::rate_for_acceleration_rad_s(g_nominal, r0, g)
            .map_err(|e| EngineError::NotStable(e.to_string()))?;
        self.command_rate(w.to_degrees())?;
        let mut slots: Vec<usize> = (0..self.units.len())
            .filter(|&s| self.live(s) && self.plan.passes[pass][s].is_some())
            .collect();
        let noise_limit = self.plan.plan.stability.noise_limit_ug;
        let mut table_restarts = 0;
        let (values, own_noise) = loop {
            let values = self.acquire(&mut slots)?;
            let own_noise = self.instrument_noise_ug(pass, &slots, &values);
            // Every instrument scattering at once is the table (the tail of
            // its settling), not the instruments: measure the point again.
            let noisy = |s: &usize| own_noise.get(s).is_some_and(|&n| n > noise_limit);
            if slots.len() >= 2
                && slots.iter().all(noisy)
                && table_restarts < self.plan.plan.stability.max_restarts
            {
                table_restarts += 1;
                self.emit(Event::Notice {
                    message: format!(
                        "every instrument scattered more than {noise_limit} µg together at {g_nominal} g: \
                         the table, not the instruments; measuring the point again ({table_restarts})"
                    ),
                })?;
                continue;
            }
            break (values, own_noise);
        };
        let rate = values.iter().map(|w| w.rate_deg_s).sum::<f64>() / values.len().max(1) as f64;
        let w_meas = rate.to_radians();
        let mut points = Vec::new();
        for slot in slots {
            let Some(mount) = self.plan.passes[pass][slot] else {
                continue;
            };
            let y: Vec<f64> = values.iter().filter_map(|w| w.outputs[slot]).collect();
            if y.len() < 2 {
                self.fail_unit(slot, format!("no output at {g_nominal} g"))?;
                continue;
            }
            let (mean, std) = mean_std(&y);
            let std_ug = own_noise
                .get(&slot)
                .copied()
                .unwrap_or(std / self.k1(slot) * UG_PER_G);
            if std_ug > noise_limit {
                self.fail_unit(
                    slot,
                    format!("noisy: its own 1-s scatter is {std_ug:.0} µg at {g_nominal} g (limit {noise_limit} µg, stability.noise_limit_ug)"),
                )?;
                continue;
            }
            let radius = self.units[slot]
                .radius
                .get(&mount)
                .copied()
                .unwrap_or_else(|| self.station.drawing_radius_m(slot));
            points.push(PointRecord {
                slot,
                mount,
                g_nominal,
                direction,
                // method.md (9): each instrument's own radius.
                g_applied: w_meas * w_meas * radius / g,
                rate_deg_s: rate,
                output_hz: mean,
                std_hz: std,
                n: y.len() as u32,
                time_s: [
                    values.first().map_or(0.0, |w| w.time_s),
                    values.last().map_or(0.0, |w| w.time_s),
                ],
            });
        }
        for p in &points {
            self.units[p.slot].points.push(p.clone());
        }
        self.emit(Event::PointDone { step, points })
    }

    /// The next one-second window of every module, with the rate and the safety checks.
    fn next_window(&mut self) -> Result<Window, EngineError> {
        let modules = self.bench.modules.len();
        let mut values: Vec<Option<WindowValue>> = vec![None; modules];
        loop {
            if self.options.abort.is_set() {
                return Err(EngineError::Aborted(self.options.abort.by()));
            }
            for (m, value) in values.iter_mut().enumerate() {
                // Pair each module's freshest window: an older backlog would
                // put another moment beside the other modules' values.
                while self.pending[m].len() > 1 {
                    self.pending[m].pop_front();
                    self.dropped_windows += 1;
                }
                if value.is_none() {
                    *value = self.pending[m].pop_front();
                }
            }
            if values.iter().all(Option::is_some) {
                break;
            }
            // Drain every module on every pass: a port left unread overruns
            // (and a simulator pacing itself on the station's reads would wait).
            // Short waits: a long wait on one quiet module would leave the
            // others unread for its length.
            for m in 0..values.len() {
                let got =
                    self.bench.modules[m].receive(Instant::now() + Duration::from_millis(1))?;
                if !got.is_empty() {
                    self.last_data[m] = Instant::now();
                }
                for msg in got {
                    let closed = self.accumulators[m].push(&msg);
                    self.pending[m].extend(closed);
                }
                let silent = self.last_data[m].elapsed();
                if silent > self.options.module_silence {
                    return Err(EngineError::ModuleSilent {
                        module: m + 1,
                        seconds: silent.as_secs_f64(),
                    });
                }
            }
        }
        // Take in everything that has already arrived: after a pause the
        // ports hold a backlog, and the windows averaged must be of the same
        // moment as the rate polled below. Newer windows replace older ones.
        for (m, value) in values.iter_mut().enumerate() {
            loop {
                let got =
                    self.bench.modules[m].receive(Instant::now() + Duration::from_micros(300))?;
                if got.is_empty() {
                    break;
                }
                self.last_data[m] = Instant::now();
                for msg in got {
                    let closed = self.accumulators[m].push(&msg);
                    self.pending[m].extend(closed);
                }
            }
            if let Some(newest) = self.pending[m].pop_back() {
                self.dropped_windows += 1 + self.pending[m].len() as u64;
                self.pending[m].clear();
                *value = Some(newest);
            }
        }
        self.windows += 1;
        let rate = self.bench.centrifuge.read_rate()?;
        if self.demand_deg_s != 0.0 && !self.bench.centrifuge.read_interlocks()? {
            return Err(EngineError::InterlockOpen);
        }
        if self.windows.is_multiple_of(5) {
            let first = self.bench.instrument_supply.measure(1)?;
            if first.volts < 0.5 * self.station.power.rail_volts {
                return Err(EngineError::SupplyTripped { volts: first.volts });
            }
            self.supply_first = (first.volts, first.amps);
        }
        // The status panel's health every 20 s: two more device queries,
        // which cost wall time when the bench runs faster than real time.
        if self.windows.is_multiple_of(20) {
            let first = self.supply_first;
            let second = self.bench.instrument_supply.measure(2)?;
            let modules = self
                .bench
                .modules
                .iter()
                .zip(&self.accumulators)
                .map(|(module, acc)| {
                    let link = module.link_stats();
                    ModuleHealth {
                        frames: link.decoder.frames,
                        bad_crc: link.decoder.bad_crc,
                        bad_tail: link.decoder.bad_tail,
                        lost_ticks: acc.stats().lost_ticks,
                        reconnects: link.reconnects,
                    }
                })
                .collect();
            // Spinning, they were just read closed; at rest an unreadable
            // interlock shows as open.
            let interlocks_closed = self.demand_deg_s != 0.0
                || self.bench.centrifuge.read_interlocks().unwrap_or(false);
            self.emit(Event::Health {
                supply: vec![first, (second.volts, second.amps)],
                interlocks_closed,
                modules,
            })?;
        }
        let slots = self.units.len();
        let mut outputs = vec![None; slots];
        let mut resonators = vec![(None, None); slots];
        for (m, v) in values.into_iter().enumerate() {
            let Some(v) = v else { continue };
            for (k, inst) in v.instruments.iter().enumerate() {
                let slot = m * INSTRUMENTS_PER_MODULE + k;
                if slot < slots {
                    resonators[slot] = (inst.f1_hz, inst.f2_hz);
                    // A window with lost ticks is marked, never averaged as whole.
                    outputs[slot] = if v.is_complete() { inst.df_hz } else { None };
                }
            }
        }
        let window = Window {
            time_s: self.windows as f64,
            rate_deg_s: rate,
            outputs,
            resonators,
        };
        let on_speed = self.on_speed(rate);
        // The raw bytes of this second reach the capture's file before its
        // values reach the store: replay can check every stored value, even
        // of a run killed and resumed.
        for module in &mut self.bench.modules {
            module.flush_capture();
        }
        self.emit(Event::Values {
            time_s: window.time_s,
            rate_deg_s: rate,
            demand_deg_s: self.demand_deg_s,
            on_speed,
            outputs_hz: window.outputs.clone(),
        })?;
        Ok(window)
    }

    /// Controlled stop, streaming off, relays open, supplies off. Every
    /// action is tried; the problems are returned. The stop is commanded up
    /// to [`STOP_ATTEMPTS`] times; when the controller never acknowledges
    /// it, the first problem is [`STOP_NOT_CONFIRMED`] and `stop_confirmed`
    /// stays false (the caller keeps commanding it, see [`keep_stopping`]).
    fn safe_state(&mut self) -> Vec<String> {
        let mut problems = Vec::new();
        let mut last_stop_error = None;
        self.stop_confirmed = false;
        for attempt in 0..STOP_ATTEMPTS {
            // Confirmed: the stop was sent and the controller answers after
            // it (a dialect whose stop has no acknowledgement would
            // otherwise "succeed" into a controller that hears nothing).
            match stop_and_confirm(self.bench.centrifuge.as_mut()) {
                Ok(()) => {
                    self.stop_confirmed = true;
                    break;
                }
                Err(e) => {
                    last_stop_error = Some(e.to_string());
                    if attempt + 1 < STOP_ATTEMPTS {
                        std::thread::sleep(Duration::from_millis(200));
                    }
                }
            }
        }
        if !self.stop_confirmed {
            problems.push(format!(
                "{STOP_NOT_CONFIRMED} (the controller did not acknowledge the stop after {STOP_ATTEMPTS} tries: {}; \
                 the station keeps commanding it while this program runs)",
                last_stop_error.unwrap_or_default()
            ));
        }
        let mut note = |r: Result<(), DeviceError>| {
            if let Err(e) = r {
                problems.push(e.to_string());
            }
        };
        if self.stop_confirmed {
            note(self.bench.centrifuge.disarm());
        }
        for m in &mut self.bench.modules {
            if self.streaming {
                note(m.stop());
            }
            note(m.set_power(0));
        }
        for ch in [1, 2] {
            note(self.bench.instrument_supply.set_output(ch, false));
        }
        self.demand_deg_s = 0.0;
        problems
    }

    /// The steps of the plan that measure `slot` (tumble, radius, levels
    /// of the passes it takes part in) and were not all done.
    fn steps_left(&self, slot: usize) -> usize {
        self.plan
            .steps
            .iter()
            .enumerate()
            .filter(|(_, step)| match step {
                Step::Tumble { .. } => true,
                Step::Radius { pass } | Step::Level { pass, .. } => self
                    .plan
                    .passes
                    .get(*pass)
                    .and_then(|p| p.get(slot))
                    .is_some_and(Option::is_some),
                _ => false,
            })
            .filter(|(index, _)| !self.completed.contains(index))
            .count()
    }

    /// Fit every instrument and give each its record and outcome. An
    /// instrument whose part of the plan was not completed (`run_complete`
    /// false, and steps of its left) is [`Outcome::Incomplete`]: its points
    /// are fitted and kept, but never graded pass or fail.
    fn records(&self, run_complete: bool, run_reason: Option<&str>) -> Vec<UnitRecord> {
        let limits = self.plan.plan.limits;
        let mut out = Vec::new();
        for (slot, u) in self.units.iter().enumerate() {
            let Some(serial) = self.plan.serials[slot].clone() else {
                continue;
            };
            let mut reasons = Vec::new();
            let mut analysis = None;
            let mut k2_max = None;
            let mut outcome = Outcome::Fail;
            let left = if run_complete || u.failed.is_some() {
                0
            } else {
                self.steps_left(slot)
            };
            if left > 0 {
                outcome = Outcome::Incomplete;
                reasons.push(format!(
                    "incomplete: the run ended with {left} of this instrument's measuring steps not done ({})",
                    run_reason.unwrap_or("no reason recorded")
                ));
                if !u.points.is_empty()
                    && let Ok(a) = analyze_unit(
                        &UnitPoints {
                            unit: serial.clone(),
                            run: None,
                            points: point_list(&u.points),
                        },
                        AnalysisOptions {
                            order: self.plan.order,
                        },
                    )
                {
                    k2_max = a.k2_max_ug_per_g2;
                    analysis = Some(a);
                }
            } else if let Some(f) = &u.failed {
                reasons.push(f.clone());
            } else if u.points.is_empty() {
                reasons.push("no points were taken".into());
            } else {
                let input = UnitPoints {
                    unit: serial.clone(),
                    run: None,
                    points: point_list(&u.points),
                };
                match analyze_unit(
                    &input,
                    AnalysisOptions {
                        order: self.plan.order,
                    },
                ) {
                    Ok(a) => {
                        k2_max = a.k2_max_ug_per_g2;
                        // Each figure against its limit; the outcome is the worst.
                        let f = &a.figures;
                        let checks = [
                            ("|k2|", k2_max, Some(limits.k2_max_ug_per_g2), "µg/g²"),
                            (
                                "nonlinearity",
                                f.nonlinearity_ppm_fs,
                                limits.nonlinearity_max_ppm_fs,
                                "ppm FS",
                            ),
                            (
                                "|asymmetry|",
                                f.asymmetry_ppm.map(f64::abs),
                                limits.asymmetry_max_ppm,
                                "ppm",
                            ),
                            (
                                "|hysteresis|",
                                f.hysteresis_ug.map(f64::abs),
                                limits.hysteresis_max_ug,
                                "µg",
                            ),
                        ];
                        outcome = Outcome::Pass;
                        for (name, value, limit, unit) in checks {
                            let (Some(v), Some(l)) = (value, limit) else {
                                continue;
                            };
                            if v > l {
                                reasons.push(format!(
                                    "{name} {v:.3} {unit} above the limit {l} {unit}"
                                ));
                                outcome = Outcome::Fail;
                            } else if v > limits.marginal_fraction * l {
                                reasons.push(format!(
                                    "{name} {v:.3} {unit} within {:.0} % of the limit {l} {unit}",
                                    (1.0 - limits.marginal_fraction) * 100.0
                                ));
                                if outcome == Outcome::Pass {
                                    outcome = Outcome::Marginal;
                                }
                            }
                        }
                        if k2_max.is_none() {
                            reasons.push("the model order has no k2".into());
                        }
                        reasons.extend(a.notes.iter().cloned());
                        analysis = Some(a);
                    }
                    Err(e) => reasons.push(format!("cannot reduce: {e}")),
                }
            }
            out.push(UnitRecord {
                slot,
                serial,
                tumble: u.cal.map(|c| [c.bias_output, c.scale_factor]),
                drawing_radius_m: self.station.drawing_radius_m(slot),
                radius_m: u.radius.clone(),
                points: u.points.clone(),
                analysis,
                k2_max_ug_per_g2: k2_max,
                outcome,
                reasons,
            });
        }
        out
    }
}

/// The executor's stand-in for a centrifuge whose controller was handed to
/// [`keep_stopping`]: every command says where it went.
struct HandedToStopKeeper;

impl Centrifuge for HandedToStopKeeper {
    fn identify(&mut self) -> Result<String, DeviceError> {
        Err(self.refuse("*IDN?"))
    }
    fn arm(&mut self) -> Result<(), DeviceError> {
        Err(self.refuse("arm"))
    }
    fn reset_interlocks(&mut self) -> Result<(), DeviceError> {
        Err(self.refuse("reset interlocks"))
    }
    fn set_rate(&mut self, _rate_deg_s: f64) -> Result<(), DeviceError> {
        Err(self.refuse("set rate"))
    }
    fn read_rate(&mut self) -> Result<f64, DeviceError> {
        Err(self.refuse("read rate"))
    }
    fn read_interlocks(&mut self) -> Result<bool, DeviceError> {
        Err(self.refuse("read interlocks"))
    }
    fn stop(&mut self) -> Result<(), DeviceError> {
        Err(self.refuse("stop"))
    }
    fn disarm(&mut self) -> Result<(), DeviceError> {
        Err(self.refuse("disarm"))
    }
}

impl HandedToStopKeeper {
    fn refuse(&self, command: &str) -> DeviceError {
        DeviceError {
            device: "centrifuge".into(),
            command: command.into(),
            kind: DeviceErrorKind::Rejected(format!(
                "{STOP_NOT_CONFIRMED}; the controller is being sent the stop until it answers"
            )),
        }
    }
}

/// Command the stop and read the rate back: the stop counts as confirmed
/// only when the controller answers after it.
fn stop_and_confirm(centrifuge: &mut dyn Centrifuge) -> Result<(), DeviceError> {
    centrifuge.stop()?;
    centrifuge.read_rate().map(|_| ())
}

/// Keep commanding the stop of a centrifuge whose controller did not
/// acknowledge it, every [`STOP_RETRY`], on a thread of its own, for as
/// long as the process lives (or until it is acknowledged, said on stderr).
pub fn keep_stopping(mut centrifuge: Box<dyn Centrifuge>) {
    UNCONFIRMED_STOPS.fetch_add(1, Ordering::SeqCst);
    let spawned = std::thread::Builder::new()
        .name("centrifuge stop keeper".into())
        .spawn(move || {
            let since = Instant::now();
            loop {
                std::thread::sleep(STOP_RETRY);
                if stop_and_confirm(centrifuge.as_mut()).is_ok() {
                    let _ = centrifuge.disarm();
                    UNCONFIRMED_STOPS.fetch_sub(1, Ordering::SeqCst);
                    eprintln!(
                        "  centrifuge: the stop was acknowledged {:.0} s after the run ended",
                        since.elapsed().as_secs_f64()
                    );
                    return;
                }
            }
        });
    if let Err(e) = spawned {
        eprintln!(
            "  {STOP_NOT_CONFIRMED}: cannot start the thread that keeps commanding the stop: {e}"
        );
    }
}

/// Centrifuges of this process whose stop is still being commanded.
static UNCONFIRMED_STOPS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// How many centrifuges of this process have a stop not yet acknowledged
/// (a program about to exit waits while this is above zero).
pub fn unconfirmed_stops() -> usize {
    UNCONFIRMED_STOPS.load(Ordering::SeqCst)
}

/// The analysis' points of a unit's records.
fn point_list(records: &[PointRecord]) -> Vec<Point> {
    records
        .iter()
        .map(|p| Point {
            mount: p.mount,
            g_nominal: p.g_nominal,
            g_applied: p.g_applied,
            output: p.output_hz,
            direction: Some(p.direction),
        })
        .collect()
}

fn mean_std(y: &[f64]) -> (f64, f64) {
    let n = y.len() as f64;
    let mean = y.iter().sum::<f64>() / n;
    let var = if y.len() > 1 {
        y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    (mean, var.sqrt())
}

fn mount_text(fixtures: &[Option<Fixture>]) -> String {
    let kinds: BTreeSet<String> = fixtures
        .iter()
        .flatten()
        .map(|f| format!("{f:?}"))
        .collect();
    let describe = |f: &Fixture| match f {
        Fixture::Up => "on the tumble fixture, input axis UP".to_string(),
        Fixture::Down => "on the tumble fixture, input axis DOWN".to_string(),
        Fixture::Arm(Mount::P) => {
            "on the arm in mounting P (input axis toward the spin axis)".to_string()
        }
        Fixture::Arm(Mount::N) => {
            "on the arm in mounting N (input axis away from the spin axis)".to_string()
        }
    };
    match fixtures.iter().flatten().next() {
        Some(f) if kinds.len() == 1 => format!("Mount every instrument {}", describe(f)),
        _ => {
            let list: Vec<String> = fixtures
                .iter()
                .enumerate()
                .filter_map(|(i, f)| f.map(|f| format!("slot {}: {}", i + 1, describe(&f))))
                .collect();
            format!("Mount the instruments: {}", list.join("; "))
        }
    }
}

/// A short label of a step for progress display.
pub fn label(step: &Step) -> String {
    match step {
        Step::PowerOn => "power on".into(),
        Step::CheckAlive => "check instruments".into(),
        Step::WarmUp { seconds } => format!("warm-up {seconds:.0} s"),
        Step::Mount { fixtures } => mount_text(fixtures),
        Step::Tumble { up } => format!("tumble, input axis {}", if *up { "up" } else { "down" }),
        Step::Radius { pass } => format!("radius at 1 g (pass {})", pass + 1),
        Step::Level {
            pass,
            g_nominal,
            direction,
        } => format!("{g_nominal} g {direction:?} (pass {})", pass + 1),
        Step::Stop => "stop".into(),
    }
}
