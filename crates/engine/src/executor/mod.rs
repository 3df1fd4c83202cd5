//! The one executor: runs a compiled plan's steps against the hardware
//! traits, emits events, and always ends in the safe state.
//!
//! This module holds the run loop ([`Executor::run`]) and its one end
//! (`finish`). The executor is made of parts, each owning its fields and
//! kept in a room of its own:
//!
//! | module | part or job |
//! |---|---|
//! | [`state`] | the run-state table as data; every change of state goes through it |
//! | `fanout` | `Fanout`: the subscribers and the state machine; every event to every subscriber, hold and retry when one cannot take it |
//! | `ports` | `Acquisition`: the counter modules' accumulators, windows and temperatures, paired into one second of the station with the per-second safety checks |
//! | `soak` | `ChamberState`: the chamber's setpoint and purge, and the soak |
//! | `units` | `UnitState`: each slot's readings, calibrations, points and failure |
//! | `rating` | the speed bounded by the measured radius: the configured radius checked at 1 g, every commanded rate under the fixtures' rating |
//! | `resume` | `Progress`: the steps done, restored from a journal |
//! | `safety` | `SafeOutcome`: the safe state, the confirmed stop, the stop keeper |
//! | [`stability`] | the stability statistics (pure functions) |
//! | `dwell` | the settle-and-average loop around them |
//! | `steps` | one handler per kind of step |
//! | [`sequential`] | `Deciding`: measuring until the verdict is certain, the level chosen by the data |
//! | `judge` | the run's units into records, through [`crate::judgement`]'s plain functions |
//!
//! Time is counted in counter-module windows (one second of ticks each), so
//! the same code runs against hardware and against a faster-than-real-time
//! simulator. Data are taken only at stable speed (method.md §3.3).

mod dwell;
mod fanout;
mod judge;
mod keeper;
mod ports;
mod rating;
mod resume;
mod safety;
pub mod sequential;
mod soak;
pub mod stability;
pub mod state;
mod steps;
mod units;
mod walk;

pub use crate::bench::Bench;
pub use keeper::{KEEP_RETRY, unconfirmed_safe_devices};
use safety::HandedToStopKeeper;
pub use safety::{STOP_NOT_CONFIRMED, keep_stopping, unconfirmed_stops};
pub use steps::{label, wording};

use crate::abort::AbortFlag;
use crate::config::StationConfig;
use crate::event::{DeviceIdentity, DeviceRole, Event, EventSink, RunState, Wording};
use crate::plan::{CompiledPlan, Fixture};
use crate::record::{Reason, ReasonCode, UnitRecord};
use spinbench_devices::DeviceError;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

/// Scale factor assumed before the tumble has measured it [Hz/g].
const NOMINAL_K1_HZ_PER_G: f64 = 100.0;

use fanout::Fanout;
use ports::Acquisition;
use resume::Progress;
use safety::SafeOutcome;
use soak::ChamberState;
use state::Trigger;
use units::UnitState;

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
    /// The plan has temperatures and the station no chamber (refused when compiled).
    #[error("the plan has temperatures_c but the station has no [chamber]")]
    NoChamber,
    /// The chamber raised an alarm.
    #[error(
        "the chamber raised alarm word {word:#06x} at {air_c:.1} °C (setpoint {setpoint_c} °C); the run was stopped and the chamber sent to the laboratory's temperature with the purge on (check the chamber)"
    )]
    ChamberAlarm {
        /// The controller's alarm word.
        word: u16,
        /// The air temperature then [°C].
        air_c: f64,
        /// The setpoint [°C].
        setpoint_c: f64,
    },
    /// An instrument reported a temperature above the station's limit.
    #[error(
        "slot {slot} reported {celsius:.2} °C, above temperature.instrument_max_c = {limit_c} °C; the run was stopped (check the instrument and the chamber)"
    )]
    OverTemperature {
        /// Slot (1-based).
        slot: usize,
        /// The temperature it reported [°C].
        celsius: f64,
        /// The limit [°C].
        limit_c: f64,
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
    /// A change of run state that the table does not have (a defect).
    #[error(transparent)]
    State(#[from] state::Refused),
    /// A level that cannot be turned into a rate (plan or station values).
    #[error("{0}")]
    Rate(String),
    /// The instruments' measured radius is not the configured arm's.
    #[error(
        "the instruments' measured radius is {measured_m:.4} m (median), the configured arm.radius_m {configured_m} m: \
         more than {tolerance_pct} % apart, so every level's g would be wrong; the table was stopped before the first level \
         (correct [arm] radius_m and start the run again)"
    )]
    RadiusMismatch {
        /// The median of the radii measured in the pass [m].
        measured_m: f64,
        /// The configured drawing radius [m].
        configured_m: f64,
        /// The tolerance [%].
        tolerance_pct: f64,
    },
    /// A level would put more g on a fixture than it is rated for.
    #[error(
        "{g_nominal:.2} g would put {applied_g:.2} g on slot {slot} at its radius of {radius_m:.4} m, \
         above its rating arm.max_g = {max_g} g; the table was stopped (lower the plan's range)"
    )]
    OverRating {
        /// The level, at the drawing radius [g].
        g_nominal: f64,
        /// The acceleration it would apply at the largest known radius [g].
        applied_g: f64,
        /// The slot of that radius (1-based).
        slot: usize,
        /// The largest known radius [m].
        radius_m: f64,
        /// The fixtures' rating [g].
        max_g: f64,
    },
}

impl EngineError {
    /// Why, as a catalogue key (`fault.<kind>`) and the values of its text
    /// (a text that comes whole from elsewhere, such as a driver's, as `detail`).
    pub fn wording(&self) -> Wording {
        match self {
            EngineError::Device(e) => Wording::new("fault.device").with("detail", e),
            EngineError::ModuleSilent { module, seconds } => Wording::new("fault.module_silent")
                .with("module", module)
                .with("seconds", format!("{seconds:.1}")),
            EngineError::InterlockOpen => Wording::new("fault.interlock_open"),
            EngineError::SupplyTripped { volts } => {
                Wording::new("fault.supply_tripped").with("volts", format!("{volts:.2}"))
            }
            EngineError::NoChamber => Wording::new("fault.no_chamber"),
            EngineError::ChamberAlarm {
                word,
                air_c,
                setpoint_c,
            } => Wording::new("fault.chamber_alarm")
                .with("word", format!("{word:#06x}"))
                .with("air", format!("{air_c:.1}"))
                .with("setpoint", setpoint_c),
            EngineError::OverTemperature {
                slot,
                celsius,
                limit_c,
            } => Wording::new("fault.over_temperature")
                .with("slot", slot)
                .with("temperature", format!("{celsius:.2}"))
                .with("limit", limit_c),
            EngineError::NotStable(detail) => {
                Wording::new("fault.not_stable").with("detail", detail)
            }
            EngineError::Aborted(by) => Wording::new("fault.aborted").with("by", by),
            EngineError::Power(detail) => Wording::new("fault.power").with("detail", detail),
            EngineError::Sink(detail) => Wording::new("fault.sink").with("detail", detail),
            EngineError::NoUnits => Wording::new("fault.no_units"),
            EngineError::State(e) => Wording::new("fault.state").with("detail", e),
            EngineError::Rate(detail) => Wording::new("fault.rate").with("detail", detail),
            EngineError::RadiusMismatch {
                measured_m,
                configured_m,
                tolerance_pct,
            } => Wording::new("fault.radius_mismatch")
                .with("measured", format!("{measured_m:.4}"))
                .with("configured", configured_m)
                .with("tolerance", tolerance_pct),
            EngineError::OverRating {
                g_nominal,
                applied_g,
                slot,
                radius_m,
                max_g,
            } => Wording::new("fault.over_rating")
                .with("g", format!("{g_nominal:.2}"))
                .with("applied", format!("{applied_g:.2}"))
                .with("slot", slot)
                .with("radius", format!("{radius_m:.4}"))
                .with("max_g", max_g),
        }
    }
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

/// One second of the whole station.
#[derive(Debug, Clone)]
struct Window {
    time_s: f64,
    rate_deg_s: f64,
    /// dF per slot, `None` when missing or from an incomplete window.
    outputs: Vec<Option<f64>>,
    /// (f1, f2) per slot.
    resonators: Vec<(Option<f64>, Option<f64>)>,
    /// Each slot's latest reported temperature [°C].
    temperatures_c: Vec<Option<f64>>,
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
    /// The chamber and the instruments' supply confirmed their safe state
    /// (purge on, setpoint at ambient, rails off). When false the reason
    /// says which was not, and a keeper tries again while the process lives.
    pub safe_devices_confirmed: bool,
}

/// The executor.
pub struct Executor<'a> {
    station: &'a StationConfig,
    plan: CompiledPlan,
    bench: Bench,
    operator: Box<dyn Operator + 'a>,
    options: RunOptions,
    /// Each slot's instrument: its readings, calibrations, points, failure.
    units: Vec<UnitState>,
    /// Which steps are done (a resumed run skips them).
    progress: Progress,
    /// The counter modules' data: accumulators, windows, temperatures.
    acquisition: Acquisition,
    /// The chamber as the run left it (setpoint, purge).
    chamber: ChamberState,
    /// The rate the table was last commanded to [°/s] (the per-second
    /// checks read the interlocks only while it is not zero).
    demand_deg_s: f64,
    /// What the safe state at the end confirmed.
    safe: SafeOutcome,
    /// The subscribers and the run-state table they are told of.
    fanout: Fanout<'a>,
    /// The passes whose rounds of deciding are over.
    deciding: sequential::Deciding,
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
        Executor {
            station,
            plan,
            bench,
            operator,
            options,
            units: vec![UnitState::default(); slots],
            progress: Progress::default(),
            acquisition: Acquisition::new(station, slots),
            chamber: ChamberState::default(),
            demand_deg_s: 0.0,
            safe: SafeOutcome::default(),
            fanout: Fanout::default(),
            deciding: sequential::Deciding::default(),
        }
    }

    /// Subscribe to the event stream.
    pub fn subscribe(&mut self, sink: impl EventSink + 'a) {
        self.fanout.sinks.push(Box::new(sink));
    }

    /// Change the state through the table ([`state::TRANSITIONS`]) and say
    /// so; a transition not in the table is refused (an error, nothing changes).
    fn set_state(&mut self, trigger: Trigger) -> Result<(), EngineError> {
        let state = self.fanout.machine.fire(trigger)?;
        self.emit(Event::StateChanged { state })
    }

    fn live(&self, slot: usize) -> bool {
        self.plan.serials[slot].is_some() && self.units[slot].failed.is_none()
    }

    fn fail_unit(&mut self, slot: usize, reason: Reason) -> Result<(), EngineError> {
        let (code, why) = (reason.code, reason.text.clone());
        if self.units[slot].failed.is_none() {
            self.units[slot].failed = Some(reason.clone());
            self.emit(Event::UnitFailed {
                slot,
                reason: reason.text,
                code: reason.code,
                args: reason.args,
            })?;
        }
        if (0..self.units.len()).all(|s| !self.live(s)) {
            return Err(EngineError::NoUnits);
        }
        // An instrument that went silent during a step: the operator
        // decides whether the run goes on without it (its result incomplete)
        // or ends, to reseat it and resume.
        if code == ReasonCode::NoOutput {
            let serial = self.plan.serials[slot].clone().unwrap_or_default();
            let text = format!(
                "{serial} (slot {}) went silent: {}. Its result will be incomplete. \
                 Go on without it, or abort the run (the table stops first) to reseat its \
                 connector, then resume the run",
                slot + 1,
                why
            );
            self.ask_operator(&text, &[])?;
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
        // An abort stops the asking: with devices that do not answer, each
        // question takes a whole command's time.
        let abort = self.options.abort.clone();
        let asked = |f: &mut dyn FnMut() -> Result<String, DeviceError>| {
            if abort.is_set() {
                "(not asked: the run was aborted)".to_string()
            } else {
                crate::bounds::device_reply(&f().unwrap_or_else(|e| format!("(no answer: {e})")))
            }
        };
        let mut devices = vec![DeviceIdentity {
            role: DeviceRole::Centrifuge,
            identity: asked(&mut || self.bench.centrifuge.identify()),
        }];
        for (m, module) in self.bench.modules.iter_mut().enumerate() {
            devices.push(DeviceIdentity {
                role: DeviceRole::Fmu(u8::try_from(m + 1).unwrap_or(u8::MAX)),
                identity: asked(&mut || {
                    module
                        .status()
                        .map(|s| format!("firmware {:#06x}", s.firmware_id))
                }),
            });
        }
        devices.push(DeviceIdentity {
            role: DeviceRole::InstrumentSupply,
            identity: asked(&mut || self.bench.instrument_supply.identify()),
        });
        if let Some(supply) = self.bench.module_supply.as_mut() {
            devices.push(DeviceIdentity {
                role: DeviceRole::ModuleSupply,
                identity: asked(&mut || supply.identify()),
            });
        }
        self.emit(Event::Identified { devices })?;
        if self.options.abort.is_set() {
            return Err(EngineError::Aborted(self.options.abort.by()));
        }
        Ok(())
    }

    /// Run the plan to the end (or to a fault or abort) and return the records.
    pub fn run(&mut self) -> RunSummary {
        let started = self.emit(Event::RunStarted {
            run_id: self.options.run_id.clone(),
            station: self.station.station.clone(),
            plan: Box::new(self.plan.clone()),
            resumed: self.progress.resumed,
            station_config: self.options.station_config_toml.clone(),
        });
        let result = started
            .and_then(|()| self.identify())
            .and_then(|()| self.set_state(Trigger::Start))
            .and_then(|()| self.execute_steps());
        self.finish(result)
    }

    /// An error's wording; an abort a web user asked for names the user
    /// apart (`fault.aborted_web`), so another language words the source.
    fn worded(&self, e: &EngineError) -> Wording {
        match (e, self.options.abort.user()) {
            (EngineError::Aborted(_), Some(user)) => {
                Wording::new("fault.aborted_web").with("user", user)
            }
            _ => e.wording(),
        }
    }

    /// The run's one end, whatever ended it: the fault said, the safe
    /// state, the records, the last state change and `RunFinished`. What
    /// the end itself could not do (a state change the table refused, an
    /// event a subscriber would not take after its hold) is not discarded:
    /// it is said in the run's reason.
    fn finish(&mut self, result: Result<(), EngineError>) -> RunSummary {
        let mut end_problems: Vec<String> = Vec::new();
        let (mut state, reason) = match &result {
            Ok(()) => (RunState::Completed, None),
            Err(EngineError::Aborted(_)) => (
                RunState::Aborted,
                result.as_ref().err().map(ToString::to_string),
            ),
            Err(e) => (RunState::Faulted, Some(e.to_string())),
        };
        if let (Some(r), Err(e)) = (&reason, &result)
            && let Err(not_said) = self.emit(Event::Fault {
                reason: r.clone(),
                wording: Some(self.worded(e)),
            })
        {
            end_problems.push(format!("the fault could not be recorded: {not_said}"));
        }
        if let Err(refused) = self.set_state(Trigger::End) {
            end_problems.push(format!("ending: {refused}"));
        }
        let safe_problems = self.safe_state();
        if !self.safe.stop_confirmed {
            if let Err(not_said) = self.emit(Event::Fault {
                reason: safe_problems[0].clone(),
                wording: Some(Wording::new("fault.not_safe").with("detail", &safe_problems[0])),
            }) {
                end_problems.push(format!(
                    "the safe state's fault could not be recorded: {not_said}"
                ));
            }
            let centrifuge =
                std::mem::replace(&mut self.bench.centrifuge, Box::new(HandedToStopKeeper));
            keep_stopping(centrifuge);
            if state == RunState::Completed {
                state = RunState::Faulted;
            }
        }
        let complete = result.is_ok();
        // The reason's wording: the fault's (what making safe found after it
        // is in the text only), else what making safe found.
        let wording = match &result {
            Err(e) => Some(self.worded(e)),
            Ok(()) if !safe_problems.is_empty() => {
                Some(Wording::new("fault.not_safe").with("detail", safe_problems.join("; ")))
            }
            Ok(()) => None,
        };
        let reason = match (reason, safe_problems.is_empty()) {
            (r, true) => r,
            (Some(r), false) => Some(format!(
                "{r}; while making safe: {}",
                safe_problems.join("; ")
            )),
            (None, false) => Some(format!("while making safe: {}", safe_problems.join("; "))),
        };
        let records = self.records(complete, reason.as_deref());
        // A table that changed since the runs this one was to pool with is
        // said once, before the results it corrected.
        if let Some(change) = records
            .iter()
            .find_map(|r| r.table_signature.as_ref()?.change.clone())
            && let Err(not_said) = self.emit(judge::table_change_notice(&change))
        {
            end_problems.push(format!("the table-change notice: {not_said}"));
        }
        for r in &records {
            if let Err(not_said) = self.emit(Event::UnitResult {
                record: Box::new(r.clone()),
            }) {
                end_problems.push(format!(
                    "slot {}'s result could not be recorded: {not_said}",
                    r.slot + 1
                ));
            }
        }
        if let Err(refused) = self.set_state(match state {
            RunState::Completed => Trigger::Completed,
            RunState::Aborted => Trigger::Aborted,
            _ => Trigger::Faulted,
        }) {
            end_problems.push(format!("the last state change: {refused}"));
        }
        // What the end could not do, and what a subscriber missed while
        // another's write was held, in the run's reason (nothing dropped).
        end_problems.append(&mut self.fanout.missed);
        if self.fanout.missed_more > 0 {
            end_problems.push(format!(
                "and {} more events missed by a subscriber",
                self.fanout.missed_more
            ));
        }
        let reason = match (reason, end_problems.is_empty()) {
            (r, true) => r,
            (Some(r), false) => Some(format!("{r}; at the end: {}", end_problems.join("; "))),
            (None, false) => Some(format!("at the end: {}", end_problems.join("; "))),
        };
        // The last event: a subscriber that cannot take it after its hold
        // has its own record of why (the store's outbox keeps it, the
        // journal is read back on resume); the summary says it too.
        let reason = match self.emit(Event::RunFinished {
            state,
            reason: reason.clone(),
            wording,
        }) {
            Ok(()) => reason,
            Err(not_said) => Some(format!(
                "{}the end could not be recorded: {not_said}",
                reason.map(|r| r + "; ").unwrap_or_default()
            )),
        };
        RunSummary {
            state,
            reason,
            records,
            duration_s: self.acquisition.windows as f64,
            dropped_windows: self.acquisition.dropped_windows,
            stop_confirmed: self.safe.stop_confirmed,
            safe_devices_confirmed: self.safe.safe_devices_confirmed,
        }
    }
}
