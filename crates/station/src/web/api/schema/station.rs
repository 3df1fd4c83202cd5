//! The bodies of the session, the languages, the station's status and
//! config, the plans, and the names every other body shares (run states,
//! outcomes, errors).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use utoipa::ToSchema;

/// A run's state on the station now, as `/api/status` and the event
/// stream send it (the engine's [`spinbench_engine::RunState`]; this type
/// only documents its names, a test holds the two together).
#[derive(Debug, Clone, Copy, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum LiveRunState {
    /// Created, nothing moved.
    Idle,
    /// Executing steps.
    Running,
    /// Waiting for the operator.
    Prompting,
    /// Held between steps by the operator.
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

/// A stored run's state ([`spinbench_store::StoredState`]; documentation
/// of its names, held together with it by a test).
#[derive(Debug, Clone, Copy, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum StoredRunState {
    /// A process runs it.
    Running,
    /// Finished normally.
    Completed,
    /// Ended by a fault, in the safe state.
    Faulted,
    /// Ended by the operator, in the safe state.
    Aborted,
    /// Its process ended without finishing it (a crash, a power cut).
    Interrupted,
}

/// An instrument's outcome ([`spinbench_engine::Outcome`]; documentation
/// of its names, held together with it by a test).
#[derive(Debug, Clone, Copy, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum OutcomeName {
    /// Within the limit.
    Pass,
    /// Within the limit but close to it.
    Marginal,
    /// Outside the limit, dead, noisy or not measurable.
    Fail,
    /// The interval straddles the limit: neither pass nor fail.
    Inconclusive,
    /// Not graded: the run ended before the instrument's part was done.
    Incomplete,
}

/// A station's state in the fleet.
#[derive(Debug, Clone, Copy, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum FleetStationState {
    /// No run.
    Idle,
    /// A run is active.
    Running,
    /// A run waits for the operator's answer to a prompt.
    Waiting,
    /// Its last run faulted (until the next starts).
    Faulted,
    /// No heartbeat for 10 s.
    Offline,
}

/// A file's bytes (a PDF or XLSX report): in the document, its media type
/// with no schema (OpenAPI 3.1's raw bytes; `doc::raw_bytes_without_schema`).
#[derive(Debug, ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct BinaryFile(pub Vec<u8>);

/// Every error: what went wrong and what to do.
#[derive(Debug, Serialize, ToSchema)]
pub struct ErrorBody {
    /// What went wrong, and what to do about it (English).
    pub error: String,
    /// For the errors an operator meets: `error` as a catalogue key and
    /// its values (`{"key": "error.overdue", "args": {…}}`), so a page
    /// words it in the user's language.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<super::Wording>)]
    pub wording: Option<spinbench_engine::event::Wording>,
}

/// `POST /api/login`.
#[derive(Debug, Deserialize, ToSchema)]
pub struct Login {
    /// User name (lower-case ASCII letters, digits, `.`, `_`, `-`).
    #[schema(max_length = 64)]
    pub user: String,
    /// Password.
    #[schema(max_length = 1024)]
    pub password: String,
}

/// A logged-in session (the login's answer; `GET /api/session` adds the language).
#[derive(Debug, Serialize, ToSchema)]
pub struct SessionReply {
    /// User name.
    pub user: String,
    /// Role.
    pub role: crate::web::auth::Role,
    /// The token to send in `X-CSRF-Token` with every change.
    pub csrf: String,
    /// The user's language (`en` or `zh-CN`), on `GET /api/session`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub language: Option<String>,
}

/// `PUT /api/session/language`, and its answer.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Language {
    /// `en` or `zh-CN` (the server also takes `zh`, `zh-Hans`, `en-GB`, …).
    #[schema(value_type = LanguageTag)]
    pub language: String,
}

/// A language the station speaks.
#[derive(Debug, ToSchema)]
pub enum LanguageTag {
    /// English.
    #[schema(rename = "en")]
    En,
    /// Simplified Chinese.
    #[schema(rename = "zh-CN")]
    ZhCn,
}

/// `GET /api/i18n/{language}`: the page's words.
#[derive(Debug, Serialize, ToSchema)]
pub struct Catalogue {
    /// The language given (`en` or `zh-CN`).
    pub language: String,
    /// Key → text.
    pub words: BTreeMap<String, String>,
}

/// `GET /api/status`: the station now.
#[derive(Debug, Serialize, ToSchema)]
pub struct StatusReply {
    /// What the engine's events say (run, step, rate, supplies, board, …).
    #[serde(flatten)]
    pub snapshot: crate::web::hub::StatusSnapshot,
    /// The active run, if any.
    pub active: Option<String>,
    /// Served by the virtual bench.
    pub simulated: bool,
    /// The station's name.
    pub station: String,
    /// How the station's database is doing.
    pub store: StoreHealthReply,
}

/// The station's database as this server sees it: its heartbeat's writes
/// and the running (or last) run's outbox.
#[derive(Debug, Serialize, ToSchema)]
pub struct StoreHealthReply {
    /// The last writes were taken.
    pub up: bool,
    /// The run's events waiting to be written.
    pub queue_events: u64,
    /// How long the oldest of them has waited [s].
    pub queue_age_s: f64,
    /// The last failure's message (empty when none).
    pub last_error: String,
}

/// One plan in `GET /api/plans`.
#[derive(Debug, Serialize, ToSchema)]
pub struct PlanEntry {
    /// Its name (the file `DATA/plans/NAME.toml`).
    pub name: String,
    /// Its TOML text.
    pub text: String,
    /// The plan's own title (`name = …` inside it).
    pub title: String,
    /// Its serials by slot (`"1": "SN-001"`).
    pub serials: BTreeMap<String, String>,
    /// Why it cannot be read, if it cannot.
    pub problem: Option<String>,
    /// What it measures and whether it can decide, for the New-run form
    /// (absent for a plan that cannot be read or designed).
    pub summary: Option<PlanSummary>,
}

/// A plan at a glance: its range, levels, mountings, limit and rule, and
/// what it predicts on the station's defaults.
#[derive(Debug, Serialize, ToSchema)]
pub struct PlanSummary {
    /// The range: the highest level [g].
    pub range_g: f64,
    /// How many levels it steps through per mounting.
    pub levels: usize,
    /// The mountings measured (`P`, `N`).
    pub passes: Vec<String>,
    /// The quantity its verdict judges (`K2`, `k2_max`).
    pub measurand: String,
    /// Its limit [µg/g²].
    pub limit_ug_per_g2: f64,
    /// The decision rule (`guarded`, `simple`).
    pub rule: String,
    /// The predicted K2 U95 [µg/g²] on the station's defaults.
    pub k2_u95_ug_per_g2: Option<f64>,
    /// The predicted centrifuge time [s].
    pub centrifuge_time_s: Option<f64>,
    /// Whether the plan can decide: false when the prediction is wider
    /// than the limit allows or the measurand cannot be had (then
    /// `decision_warning` says why).
    pub can_decide: bool,
    /// Why it may not decide (English; the form shows its own words).
    pub decision_warning: Option<String>,
    /// The same as a wording (`{key, args}`, the catalogue's
    /// `say.plan.decision.*`), for the page's language.
    #[schema(value_type = Option<super::Wording>)]
    pub decision_wording: Option<spinbench_engine::event::Wording>,
}

/// `GET /api/plans`.
#[derive(Debug, Serialize, ToSchema)]
pub struct PlansReply {
    /// The station's slots.
    pub slots: usize,
    /// Every plan, by name.
    pub plans: Vec<PlanEntry>,
}

/// `PUT /api/plans/{name}`'s answer.
#[derive(Debug, Serialize, ToSchema)]
pub struct PlanSaved {
    /// The plan's name.
    pub name: String,
    /// Always true.
    pub saved: bool,
}

/// `PUT /api/station`'s answer.
#[derive(Debug, Serialize, ToSchema)]
pub struct Saved {
    /// Always true.
    pub saved: bool,
}

/// `GET /api/station`.
#[derive(Debug, Serialize, ToSchema)]
pub struct StationReply {
    /// The station's name.
    pub name: String,
    /// Its slots.
    pub slots: usize,
    /// The virtual bench.
    pub simulated: bool,
    /// Its config (TOML).
    pub toml: String,
}
