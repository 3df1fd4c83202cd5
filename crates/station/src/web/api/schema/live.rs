//! The typed parts of `GET /api/status` that the engine sends as its own
//! records (a board slot, a wording, a module's counters, the plan's
//! prediction and what the run achieved, a fixture). Each type here only
//! documents the engine's serialised form: the engine does not know the
//! web, so it derives no schema. They are held to what is sent by the web
//! tests, which check every `/api/status` answer against the document;
//! each refuses a field it does not list (`additionalProperties: false`),
//! so a field the engine adds fails those tests until it is documented.

use super::{MountName, OutcomeName};
use serde::Serialize;
use std::collections::BTreeMap;
use utoipa::ToSchema;

/// What a text says, as a catalogue key and its values by name, so a page
/// words it in its own language (the engine's `Wording`).
#[derive(Debug, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Wording {
    /// The catalogue key (`step.level`, `notice.table_noisy`, …).
    pub key: String,
    /// The values, by name (numbers as shown, words as codes); absent
    /// when none.
    #[serde(default)]
    pub args: Option<BTreeMap<String, String>>,
}

/// A counter module's counters since the run's start.
#[derive(Debug, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ModuleCounters {
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

/// What a slot is doing.
#[derive(Debug, Clone, Copy, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum SlotPhaseName {
    /// Not in the step being taken (or the run has not begun).
    Waiting,
    /// Warming up after power-on.
    Warming,
    /// At 1 g for the tumble.
    Tumble,
    /// At 1 g at R0 while its radius is found.
    Radius,
    /// At a level, waiting for the rate and the outputs to be stable.
    Settling,
    /// At a level, averaging.
    Averaging,
    /// Measured and graded.
    Done,
    /// Left out: its output too noisy.
    Noisy,
    /// Left out (dead, drifting, over temperature …).
    Failed,
}

/// One slot of the board (the engine's `board::SlotState`).
#[derive(Debug, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct BoardSlot {
    /// Slot (from 1, as on the fixtures).
    pub slot: usize,
    /// Serial number.
    pub serial: String,
    /// The mounting of the pass being measured (or last measured).
    pub mount: Option<MountName>,
    /// What it is doing.
    pub phase: SlotPhaseName,
    /// Latest one-second output [Hz].
    pub output_hz: Option<f64>,
    /// Latest temperature [°C].
    pub temperature_c: Option<f64>,
    /// Points taken.
    pub points: usize,
    /// Points it takes in the whole plan.
    pub points_planned: usize,
    /// k2 per mounting fitted so far, each `[mounting, k2 µg/g², U95 or
    /// null]`.
    #[schema(value_type = Vec<Vec<serde_json::Value>>)]
    pub k2_ug_per_g2: Vec<(MountName, f64, Option<f64>)>,
    /// K2 once both mountings are measured: `[value µg/g², U95 or null]`.
    pub big_k2_ug_per_g2: Option<Vec<Option<f64>>>,
    /// The outcome once graded.
    pub outcome: Option<OutcomeName>,
    /// Why it was left out (English).
    pub reason: Option<String>,
    /// The reason's stable code (`k2_over_limit`, `noisy`, …), absent
    /// when none.
    #[serde(default)]
    pub reason_code: Option<String>,
    /// The values of the reason's text, by name; absent when none.
    #[serde(default)]
    pub reason_args: Option<BTreeMap<String, String>>,
}

/// A plan's prediction and how it was made (the engine's `PlanPrediction`).
#[derive(Debug, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Prediction {
    /// Predicted K2 U95 of the median instrument [µg/g²].
    pub k2_u95_ug_per_g2: f64,
    /// Predicted centrifuge time of the level steps, every pass [s].
    pub centrifuge_time_s: f64,
    /// The published plan's K2 U95 on the same model [µg/g²], if it fits.
    #[serde(default)]
    pub published_k2_u95_ug_per_g2: Option<f64>,
    /// The published plan's centrifuge time [s].
    #[serde(default)]
    pub published_centrifuge_time_s: Option<f64>,
    /// The target, when the plan was designed [µg/g²].
    #[serde(default)]
    pub target_k2_u95_ug_per_g2: Option<f64>,
    /// The range `[low, high]` the run's median K2 U95 falls in with 80 %
    /// probability [µg/g²] (absent without a learned spread).
    #[serde(default)]
    pub k2_u95_run_range_ug_per_g2: Option<[f64; 2]>,
    /// Runs the station's model was learned from (0: the defaults).
    pub model_runs: usize,
    /// The most centrifuge time the plan's `[sequential]` levels can add,
    /// every pass [s].
    #[serde(default)]
    pub sequential_centrifuge_time_max_s: Option<f64>,
}

/// What a run achieved, beside its prediction (the engine's `Achieved`).
#[derive(Debug, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AchievedFigures {
    /// Median K2 U95 over the instruments that have one [µg/g²].
    pub k2_u95_ug_per_g2: Option<f64>,
    /// Centrifuge time of the level steps, every pass [s].
    pub centrifuge_time_s: Option<f64>,
}

/// The fixture a prompt asks of a slot, as the engine names it: `"Up"`,
/// `"Down"`, `{"Arm": "P"}` or `{"Crosswise": {"as_on_arm": true}}`. Each
/// shape a named schema of its own, so that a generated client has a type
/// for each.
#[derive(Debug, Serialize, ToSchema)]
#[serde(untagged)]
pub enum FixtureName {
    /// On the bench, input axis up or down.
    Bench(BenchFixture),
    /// On the arm.
    Arm(ArmFixture),
    /// On the bench, input axis horizontal.
    Crosswise(CrosswiseFixture),
}

/// On the bench, input axis up or down.
#[derive(Debug, Clone, Copy, Serialize, ToSchema)]
pub enum BenchFixture {
    /// Input axis up.
    Up,
    /// Input axis down.
    Down,
}

/// On the arm, mounting P or N: `{"Arm": "P"}`.
#[derive(Debug, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ArmFixture {
    /// The mounting.
    #[serde(rename = "Arm")]
    pub arm: MountName,
}

/// On the bench, input axis horizontal: `{"Crosswise": {"as_on_arm": true}}`.
#[derive(Debug, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CrosswiseFixture {
    /// How gravity lies along the cross axis.
    #[serde(rename = "Crosswise")]
    pub crosswise: Crosswise,
}

/// Gravity along the cross axis that is vertical on the arm.
#[derive(Debug, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Crosswise {
    /// As on the arm (else upside down).
    pub as_on_arm: bool,
}
