//! The typed event stream: everything the engine does, as it happens. The
//! CLI, the journal, the store and the web UI's hub subscribe to it; none
//! of them reaches into the drivers. No event is dropped: a subscriber that
//! cannot take one holds the run until it can (see the executor's `fanout`).

use crate::plan::{CompiledPlan, Fixture};
use crate::record::{PointRecord, UnitRecord};
use serde::{Deserialize, Serialize};
use spinbench_analysis::Mount;
use std::collections::BTreeMap;

/// What a text of an event says, as a catalogue key and the values the text
/// was made from, by name, so a page in another language words it itself:
/// the web UI fills `web.say.<key>`, word-valued values
/// through `web.arg.<name>.<value>`. The event's own text stays English.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Wording {
    /// The key (`step.level`, `notice.table_noisy`, `fault.interlock_open`).
    pub key: String,
    /// The values, by name (numbers as shown, words as codes).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub args: BTreeMap<String, String>,
}

impl Wording {
    /// A wording without values.
    pub fn new(key: &str) -> Wording {
        Wording {
            key: key.to_string(),
            args: BTreeMap::new(),
        }
    }

    /// The same wording with one more named value.
    #[must_use]
    pub fn with(mut self, name: &str, value: impl ToString) -> Wording {
        self.args.insert(name.to_string(), value.to_string());
        self
    }
}

/// A run's state (the table is data: [`crate::executor::state::TRANSITIONS`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunState {
    /// Created, nothing moved.
    Idle,
    /// Executing steps.
    Running,
    /// Waiting for the operator.
    Prompting,
    /// Held between steps by the operator; the ports are still read.
    Paused,
    /// Bringing the hardware to the safe state.
    Stopping,
    /// Finished normally.
    Completed,
    /// Ended by a fault, in the safe state.
    Faulted,
    /// Ended by the operator, in the safe state.
    Aborted,
}

impl RunState {
    /// Every state, in the order of the table.
    pub const ALL: [RunState; 8] = [
        RunState::Idle,
        RunState::Running,
        RunState::Prompting,
        RunState::Paused,
        RunState::Stopping,
        RunState::Completed,
        RunState::Faulted,
        RunState::Aborted,
    ];

    /// Its name, as serde, the store and the API write it (`completed`).
    pub fn as_str(self) -> &'static str {
        match self {
            RunState::Idle => "idle",
            RunState::Running => "running",
            RunState::Prompting => "prompting",
            RunState::Paused => "paused",
            RunState::Stopping => "stopping",
            RunState::Completed => "completed",
            RunState::Faulted => "faulted",
            RunState::Aborted => "aborted",
        }
    }

    /// Whether the run has ended in it (completed, faulted or aborted).
    pub fn is_ended(self) -> bool {
        matches!(
            self,
            RunState::Completed | RunState::Faulted | RunState::Aborted
        )
    }
}

impl std::fmt::Display for RunState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A text that names no run state.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("'{0}' is not a run state")]
pub struct NotARunState(pub String);

impl std::str::FromStr for RunState {
    type Err = NotARunState;
    fn from_str(text: &str) -> Result<RunState, NotARunState> {
        RunState::ALL
            .into_iter()
            .find(|s| s.as_str() == text)
            .ok_or_else(|| NotARunState(text.to_string()))
    }
}

/// One event.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum Event {
    /// A run began (or resumed) with this plan.
    RunStarted {
        /// Run identifier.
        run_id: String,
        /// Station name.
        station: String,
        /// The compiled plan.
        plan: Box<CompiledPlan>,
        /// True when continuing from a journal.
        resumed: bool,
        /// The station config (TOML) the run uses, as a snapshot.
        #[serde(default)]
        station_config: String,
    },
    /// The devices answered who they are (at the start of a run).
    Identified {
        /// Every device that answered.
        devices: Vec<DeviceIdentity>,
    },
    /// The run's state changed.
    StateChanged {
        /// New state.
        state: RunState,
    },
    /// A step began.
    StepStarted {
        /// Step index.
        index: usize,
        /// Of this many.
        of: usize,
        /// What it is.
        label: String,
        /// The label as a key and values (journals before it: none).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        wording: Option<Wording>,
    },
    /// A step finished.
    StepDone {
        /// Step index.
        index: usize,
    },
    /// Once per one-second window: the rate and every instrument's output.
    Values {
        /// Station time [s] (counter-module windows).
        time_s: f64,
        /// Measured rate [deg/s].
        rate_deg_s: f64,
        /// Demanded rate [deg/s].
        demand_deg_s: f64,
        /// True while the rate is within tolerance.
        on_speed: bool,
        /// dF per slot [Hz] (`None`: no output).
        outputs_hz: Vec<Option<f64>>,
        /// Each slot's latest temperature [°C] (`None`: none reported);
        /// empty in journals made before temperatures were kept.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        temperatures_c: Vec<Option<f64>>,
    },
    /// Waiting for stability or averaging at a level.
    Progress {
        /// "settling" or "averaging".
        phase: String,
        /// Values collected.
        done: u32,
        /// Values wanted.
        of: u32,
    },
    /// The tumble reading of one instrument.
    TumbleDone {
        /// Slot (0-based).
        slot: usize,
        /// Input axis up?
        up: bool,
        /// Mean output [Hz].
        output_hz: f64,
        /// Standard error of the mean [Hz] (0 in journals made before it was kept).
        #[serde(default)]
        standard_error_hz: f64,
    },
    /// A reading of a four-position tumble's extra positions: the input
    /// axis horizontal, gravity along the cross axis that is vertical on
    /// the centrifuge (as on the arm, or inverted).
    CrossTumbleDone {
        /// Slot (0-based).
        slot: usize,
        /// As on the arm (else inverted).
        as_on_arm: bool,
        /// Mean output [Hz].
        output_hz: f64,
        /// Standard error of the mean [Hz].
        standard_error_hz: f64,
    },
    /// The radius of one instrument in one mounting (method.md (6)–(8)).
    RadiusDone {
        /// Slot (0-based).
        slot: usize,
        /// Mounting.
        mount: Mount,
        /// Drawing radius [m].
        drawing_radius_m: f64,
        /// Radius found [m].
        radius_m: f64,
        /// Its relative standard uncertainty from the readings' noise [ppm]
        /// (0 in journals made before it was kept).
        #[serde(default)]
        reading_u_ppm: f64,
    },
    /// An averaged point of every measured instrument at one level.
    PointDone {
        /// Step index.
        step: usize,
        /// The points, one per measured slot.
        points: Vec<PointRecord>,
    },
    /// An instrument was failed and left out of further measurement.
    UnitFailed {
        /// Slot (0-based).
        slot: usize,
        /// Why.
        reason: String,
        /// Its stable code (`other` in journals written before codes existed).
        #[serde(default)]
        code: crate::record::ReasonCode,
        /// The values in its text, by name (see [`crate::Reason::args`]).
        #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
        args: std::collections::BTreeMap<String, String>,
    },
    /// The operator is asked to do something.
    Prompt {
        /// What to do.
        text: String,
        /// The fixture asked of each slot.
        fixtures: Vec<Option<Fixture>>,
    },
    /// The operator answered.
    PromptAnswered {
        /// Continue (true) or abort.
        proceed: bool,
        /// Who answered (an operator, or the simulator).
        by: String,
    },
    /// Every few seconds: the hardware's health for the status panel.
    Health {
        /// Instrument supply outputs 1 and 2: (volts, amperes).
        supply: Vec<(f64, f64)>,
        /// Interlocks closed (the table may move).
        interlocks_closed: bool,
        /// Each counter module's link and window counters.
        modules: Vec<ModuleHealth>,
        /// The chamber controller's busy replies ridden in this run (none
        /// without a chamber).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        chamber_busy_replies: Option<u64>,
    },
    /// Something the operator should know; the run goes on.
    Notice {
        /// What happened and what the station did about it.
        message: String,
        /// The message as a key and values.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        wording: Option<Wording>,
    },
    /// A fault: the run goes to the safe state.
    Fault {
        /// Why.
        reason: String,
        /// Why, as a key and values.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        wording: Option<Wording>,
    },
    /// One instrument's result.
    UnitResult {
        /// The record.
        record: Box<UnitRecord>,
    },
    /// The run ended.
    RunFinished {
        /// Final state.
        state: RunState,
        /// Why, if not completed.
        reason: Option<String>,
        /// Why, as a key and values: the wording of the fault that ended the
        /// run (what making safe found after it is in `reason` only).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        wording: Option<Wording>,
    },
}

impl Event {
    /// Its name as its serialised form tags it (`state_changed`).
    pub fn name(&self) -> &'static str {
        match self {
            Event::RunStarted { .. } => "run_started",
            Event::Identified { .. } => "identified",
            Event::StateChanged { .. } => "state_changed",
            Event::StepStarted { .. } => "step_started",
            Event::StepDone { .. } => "step_done",
            Event::Values { .. } => "values",
            Event::Progress { .. } => "progress",
            Event::TumbleDone { .. } => "tumble_done",
            Event::CrossTumbleDone { .. } => "cross_tumble_done",
            Event::RadiusDone { .. } => "radius_done",
            Event::PointDone { .. } => "point_done",
            Event::UnitFailed { .. } => "unit_failed",
            Event::Prompt { .. } => "prompt",
            Event::PromptAnswered { .. } => "prompt_answered",
            Event::Health { .. } => "health",
            Event::Notice { .. } => "notice",
            Event::Fault { .. } => "fault",
            Event::UnitResult { .. } => "unit_result",
            Event::RunFinished { .. } => "run_finished",
        }
    }
}

/// A subscriber could not take an event: what and why, in words that tell
/// the operator what failed (the run holds and offers the event again; the
/// text goes into the hold's notice and, past the hold limit, the fault).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{problem}")]
pub struct SinkError {
    /// What failed ("store …: cannot record the point_done event: …").
    pub problem: String,
}

impl From<String> for SinkError {
    fn from(problem: String) -> Self {
        SinkError { problem }
    }
}

/// A subscriber to the event stream.
pub trait EventSink {
    /// Receive one event. An error holds the run (state Paused, the ports
    /// still read) and the same event is offered again every second until it
    /// is taken, the run is aborted, or the hold limit passes (a fault).
    fn emit(&mut self, event: &Event) -> Result<(), SinkError>;
}

impl<F: FnMut(&Event)> EventSink for F {
    fn emit(&mut self, event: &Event) -> Result<(), SinkError> {
        self(event);
        Ok(())
    }
}

/// A counter module's counters since the run's start.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ModuleHealth {
    /// Valid frames decoded.
    pub frames: u64,
    /// Frames rejected for a bad CRC.
    pub bad_crc: u64,
    /// Frames rejected for a bad tail byte.
    pub bad_tail: u64,
    /// Ticks lost in sequence gaps.
    pub lost_ticks: u64,
    /// Times the port was reopened.
    pub reconnects: u64,
}

/// What a device is in the station. Written and read as its name
/// (`centrifuge`, `fmu 1` … `fmu 64`, `instrument supply`, `module supply`),
/// in the event stream, the store and the equipment register alike.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum DeviceRole {
    /// The rate table and its controller.
    Centrifuge,
    /// Frequency-counter module N (1-based, as its label on the rack).
    Fmu(u8),
    /// The supply that powers the instruments.
    InstrumentSupply,
    /// The supply that powers the modules.
    ModuleSupply,
}

/// The most frequency-counter modules a station names ([`DeviceRole::Fmu`]).
pub const MAX_FMU_ROLES: u8 = 64;

impl DeviceRole {
    /// Its name (`fmu 3`).
    pub fn name(self) -> String {
        match self {
            DeviceRole::Centrifuge => "centrifuge".into(),
            DeviceRole::Fmu(n) => format!("fmu {n}"),
            DeviceRole::InstrumentSupply => "instrument supply".into(),
            DeviceRole::ModuleSupply => "module supply".into(),
        }
    }

    /// Its kind without a number, for a catalogue key (`fmu`, `instrument_supply`).
    pub fn kind(self) -> &'static str {
        match self {
            DeviceRole::Centrifuge => "centrifuge",
            DeviceRole::Fmu(_) => "fmu",
            DeviceRole::InstrumentSupply => "instrument_supply",
            DeviceRole::ModuleSupply => "module_supply",
        }
    }
}

impl std::fmt::Display for DeviceRole {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

/// A text that names no device role; says the names.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "'{0}' is not a device role: centrifuge, fmu 1 … fmu {MAX_FMU_ROLES}, instrument supply or module supply"
)]
pub struct NotADeviceRole(pub String);

impl std::str::FromStr for DeviceRole {
    type Err = NotADeviceRole;
    /// A role's exact name; anything else (a typo would leave a real device
    /// unregistered while the register looks kept) is refused, saying the names.
    fn from_str(text: &str) -> Result<DeviceRole, NotADeviceRole> {
        match text {
            "centrifuge" => return Ok(DeviceRole::Centrifuge),
            "instrument supply" => return Ok(DeviceRole::InstrumentSupply),
            "module supply" => return Ok(DeviceRole::ModuleSupply),
            _ => {}
        }
        text.strip_prefix("fmu ")
            .and_then(|n| n.parse::<u8>().ok())
            .filter(|n| (1..=MAX_FMU_ROLES).contains(n) && text == format!("fmu {n}"))
            .map(DeviceRole::Fmu)
            .ok_or_else(|| NotADeviceRole(text.to_string()))
    }
}

impl TryFrom<String> for DeviceRole {
    type Error = NotADeviceRole;
    fn try_from(text: String) -> Result<DeviceRole, NotADeviceRole> {
        text.parse()
    }
}

impl From<DeviceRole> for String {
    fn from(role: DeviceRole) -> String {
        role.name()
    }
}

/// One device's identity, as it reported it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceIdentity {
    /// What it is in the station.
    pub role: DeviceRole,
    /// What it said (`*IDN?`, the controller's identification, the module's firmware id),
    /// or why it could not say.
    pub identity: String,
}

#[cfg(test)]
mod tests {
    use super::{Event, RunState};

    #[test]
    fn an_events_name_is_its_serialised_tag() {
        for event in [
            Event::StepDone { index: 2 },
            Event::StateChanged {
                state: RunState::Paused,
            },
            Event::Notice {
                message: "m".into(),
                wording: None,
            },
        ] {
            let json = serde_json::to_value(&event).expect("an event serialises");
            assert_eq!(json["event"], event.name(), "{event:?}");
        }
    }
}
