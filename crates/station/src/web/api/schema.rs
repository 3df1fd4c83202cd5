//! The API's bodies as types (issue 17, part 1): every request a handler
//! parses and every JSON answer it sends is one of these, and the OpenAPI
//! document's schemas are derived from the same types (utoipa), so the
//! document cannot say one thing while the server does another. Deep
//! records of the engine (a plan, an exclusion, a board slot) travel as
//! JSON objects, described as such.

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

/// A file's bytes (a PDF or XLSX report): documented as a string of
/// format `binary`, so a generated client hands back the bytes as a file.
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
    #[schema(value_type = Option<Object>)]
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
    #[schema(value_type = Option<Object>)]
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

/// A report's format.
#[derive(Debug, ToSchema)]
#[schema(rename_all = "lowercase")]
pub enum ReportFormatName {
    /// PDF, for signing.
    Pdf,
    /// One HTML page.
    Html,
    /// A workbook.
    Xlsx,
    /// The summary table.
    Csv,
}

/// `POST /api/runs`.
#[derive(Debug, Deserialize, ToSchema)]
pub struct StartRun {
    /// The plan's name (`GET /api/plans`).
    #[schema(pattern = "^[A-Za-z0-9_-]{1,64}$")]
    pub plan: String,
    /// Serials by slot (`"1": "P:SN-1"`), replacing the plan's.
    #[serde(default)]
    pub serials: BTreeMap<String, String>,
    /// An admin's reason to start although a device is overdue for
    /// calibration (in the audit log).
    #[serde(default)]
    #[schema(max_length = 500, pattern = "^[^\\x00-\\x1f\\x7f-\\x9f]*$")]
    pub override_overdue: Option<String>,
    /// Design the plan's levels, readings on the way down and dwell for
    /// this K2 U95 [µg/g²] when the run starts (`levels = "auto"`), from
    /// the station's model of its own runs (`POST /api/plans/{name}/design`
    /// shows the design first).
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub target_k2_u95_ug_per_g2: Option<f64>,
}

/// `POST /api/plans/{name}/design`.
#[derive(Debug, Deserialize, ToSchema)]
pub struct DesignRequest {
    /// The K2 U95 to reach [µg/g²].
    #[schema(exclusive_minimum = 0.0, maximum = 1e6)]
    pub target_k2_u95_ug_per_g2: f64,
    /// The serials by slot the run will test (`"1": "SN-1"`; the plan's
    /// when empty): their number sizes the range of the run's median U95.
    #[serde(default)]
    pub serials: BTreeMap<String, String>,
}

/// A designed plan and its prediction beside the published plan's.
#[derive(Debug, Serialize, ToSchema)]
pub struct DesignReply {
    /// The levels [g].
    pub levels_g: Vec<f64>,
    /// The levels read again on the way down [g].
    pub down_levels_g: Vec<f64>,
    /// One-second values per reading.
    pub dwell_s: u32,
    /// Predicted K2 U95 of the median instrument [µg/g²].
    pub k2_u95_ug_per_g2: f64,
    /// The range a run's median K2 U95 falls in with 80 % probability
    /// [µg/g²] (none before the station has learned its instruments' spread).
    pub k2_u95_run_range_ug_per_g2: Option<[f64; 2]>,
    /// The instruments the range is for (the request's serials, else the
    /// plan's; 0: as many as the station's past runs had).
    pub instruments: usize,
    /// Predicted centrifuge time of the level steps [s].
    pub centrifuge_time_s: f64,
    /// The published plan's predicted K2 U95 [µg/g²] (none when its levels to the range are too few).
    pub published_k2_u95_ug_per_g2: Option<f64>,
    /// The published plan's predicted centrifuge time [s].
    pub published_centrifuge_time_s: Option<f64>,
    /// Where the station's model came from.
    pub model_source: String,
    /// Why the plan may not decide, before anything moves (the predicted
    /// U95 of the judged quantity against its limit); none when it can.
    pub decision_warning: Option<String>,
    /// The same as a wording (`{key, args}`, the catalogue's
    /// `say.plan.decision.*`), for the page's language.
    #[schema(value_type = Option<Object>)]
    pub decision_wording: Option<spinbench_engine::event::Wording>,
}

/// A run started, answered, paused, resumed or aborted.
#[derive(Debug, Serialize, ToSchema)]
pub struct RunId {
    /// The run.
    pub run_id: String,
}

/// `POST /api/runs/{id}/retest`'s answer.
#[derive(Debug, Serialize, ToSchema)]
pub struct RetestStarted {
    /// The new run.
    pub run_id: String,
    /// The run it retests.
    pub retest_of: String,
    /// The serials retested.
    pub serials: Vec<String>,
}

/// `POST /api/run/prompt`.
#[derive(Debug, Deserialize, ToSchema)]
pub struct PromptAnswer {
    /// Done as asked (true) or abort the run (false).
    pub proceed: bool,
}

/// One run in `GET /api/runs`.
#[derive(Debug, Serialize, ToSchema)]
pub struct RunEntry {
    /// Run identifier.
    pub id: String,
    /// Its readable label, `2026-11-24 · station 1 · #7` (the id for a run
    /// stored before labels were given).
    pub label: String,
    /// Station name.
    pub station: String,
    /// Its state.
    #[schema(value_type = StoredRunState)]
    pub state: spinbench_store::StoredState,
    /// Why it ended, when not completed.
    pub reason: Option<String>,
    /// Unix time it started [s].
    pub started_at: i64,
    /// Instruments with results.
    pub units: i64,
    /// Points stored.
    pub points: i64,
    /// The run it retests, if a retest.
    pub retest_of: Option<String>,
}

impl From<&spinbench_store::RunRow> for RunEntry {
    fn from(r: &spinbench_store::RunRow) -> RunEntry {
        RunEntry {
            id: r.id.clone(),
            label: r.label(),
            station: r.station.clone(),
            state: r.state,
            reason: r.reason.clone(),
            started_at: r.started_at,
            units: r.units,
            points: r.points,
            retest_of: r.retest_of.clone(),
        }
    }
}

/// One instrument and mounting of a run's results.
#[derive(Debug, Serialize, ToSchema)]
pub struct ResultRow {
    /// Serial number.
    pub serial: String,
    /// Slot (1-based).
    pub slot: i64,
    /// P or N (empty when not measured).
    pub mount: String,
    /// Found radius [m].
    pub radius_m: Option<f64>,
    /// Drawing radius [m].
    pub drawing_radius_m: Option<f64>,
    /// Bias [g].
    pub k0_g: Option<f64>,
    /// Scale factor [Hz/g].
    pub k1_hz_per_g: Option<f64>,
    /// k2 [µg/g²].
    pub k2_ug_per_g2: Option<f64>,
    /// Half-width of k2's 95 % interval [µg/g²].
    pub k2_ci95_half_ug_per_g2: Option<f64>,
    /// k2's expanded uncertainty (GUM, 95 %) [µg/g²].
    #[serde(rename = "k2_U95")]
    pub k2_u95_ug_per_g2: Option<f64>,
    /// k3 [µg/g³].
    pub k3_ug_per_g3: Option<f64>,
    /// The larger |k2| of the mountings [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// Scale-factor nonlinearity [ppm].
    pub sf_nonlinearity_ppm: Option<f64>,
    /// Asymmetry [ppm].
    pub asymmetry_ppm: Option<f64>,
    /// Hysteresis [µg].
    pub hysteresis_ug: Option<f64>,
    /// `pass`, `marginal`, `fail`, `inconclusive` or `incomplete`.
    #[schema(value_type = OutcomeName)]
    pub outcome: String,
    /// Why, in the user's language.
    pub reasons: String,
}

/// `GET /api/runs/{id}`.
#[derive(Debug, Serialize, ToSchema)]
pub struct RunDetail {
    /// The run as listed.
    #[serde(flatten)]
    pub run: RunEntry,
    /// The runs that retest it.
    pub retested_by: Vec<String>,
    /// Its serials a retest would take.
    pub to_retest: Vec<String>,
    /// Every instrument and mounting.
    pub results: Vec<ResultRow>,
    /// Its report downloads.
    pub reports: Vec<String>,
}

/// One test of a serial number.
#[derive(Debug, Serialize, ToSchema)]
pub struct UnitTest {
    /// The run.
    pub run_id: String,
    /// Slot (1-based).
    pub slot: i64,
    /// Its outcome.
    #[schema(value_type = OutcomeName)]
    pub outcome: String,
    /// k2_max [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
}

/// `GET /api/units/{serial}`.
#[derive(Debug, Serialize, ToSchema)]
pub struct UnitHistory {
    /// The serial number.
    pub serial: String,
    /// Every test of it, oldest first.
    pub tests: Vec<UnitTest>,
}

/// A mounting: P (input axis toward the spin axis) or N.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
pub enum MountName {
    /// Input axis toward the spin axis.
    P,
    /// Input axis away from it.
    N,
}

/// `POST /api/runs/{id}/exclusions`.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ExcludeLevel {
    /// The instrument.
    #[schema(max_length = 200)]
    pub serial: String,
    /// Its mounting.
    #[schema(value_type = MountName)]
    pub mount: spinbench_analysis::Mount,
    /// The level [g], as the plan names it.
    #[schema(minimum = 0.0, maximum = 1000.0)]
    pub g: f64,
    /// Why it is left out (not blank).
    #[schema(
        min_length = 1,
        max_length = 500,
        pattern = "^[^\\x00-\\x1f\\x7f-\\x9f]*[^\\s\\x00-\\x1f\\x7f-\\x9f][^\\x00-\\x1f\\x7f-\\x9f]*$"
    )]
    pub reason: String,
}

/// Its answer: the instrument reduced and graded again.
#[derive(Debug, Serialize, ToSchema)]
pub struct Excluded {
    /// The run.
    pub run_id: String,
    /// The instrument.
    pub serial: String,
    /// Its new outcome.
    #[schema(value_type = OutcomeName)]
    pub outcome: String,
    /// Its new k2_max [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// Every level left out of it (who, which, why, how many readings).
    #[schema(value_type = Vec<Object>)]
    pub exclusions: serde_json::Value,
}

/// One point of a control chart.
#[derive(Debug, Serialize, ToSchema)]
pub struct ChartPoint {
    /// Its run.
    pub run_id: String,
    /// Its serial (empty for a per-run figure).
    pub serial: String,
    /// Its value, in the chart's unit.
    pub value: f64,
}

/// A Western Electric rule broken.
#[derive(Debug, Serialize, ToSchema)]
pub struct ChartViolation {
    /// The point (1-based) that completes it.
    pub point: usize,
    /// Its run.
    pub run_id: String,
    /// Its run's label (`2026-11-24 · station 1 · #7`), as people name runs.
    pub run_label: String,
    /// The instrument of the point (empty on a radius chart).
    pub serial: String,
    /// The rule (`beyond3_sigma`, …).
    pub rule: String,
    /// The rule in words, in the user's language.
    pub says: String,
}

/// One control chart.
#[derive(Debug, Serialize, ToSchema)]
pub struct ChartReply {
    /// What it charts (`k2_max`, `radius slot 2 P`, …).
    pub quantity: String,
    /// Its unit.
    pub unit: String,
    /// The fixture position (slot), for a radius chart.
    pub slot: Option<usize>,
    /// Points that set its limits.
    pub baseline: usize,
    /// Centre line.
    pub centre: Option<f64>,
    /// σ̂ (from the mean moving range).
    pub sigma: Option<f64>,
    /// A rule is broken.
    pub flagged: bool,
    /// Its points, in time order.
    pub points: Vec<ChartPoint>,
    /// The rules broken.
    pub violations: Vec<ChartViolation>,
    /// The chart as SVG.
    pub svg: Option<String>,
}

/// First-pass yield of a run or a day.
#[derive(Debug, Serialize, ToSchema)]
pub struct YieldRow {
    /// The run or the day.
    pub label: String,
    /// Serials tested for the first time.
    pub first_tests: usize,
    /// Of those, passed.
    pub first_passes: usize,
    /// The fraction (none without first tests).
    #[serde(rename = "yield")]
    pub fraction: Option<f64>,
}

/// `GET /api/control-charts`.
#[derive(Debug, Serialize, ToSchema)]
pub struct ChartsReply {
    /// Limits from the first this many runs.
    pub baseline_runs: usize,
    /// Runs in the store.
    pub runs: usize,
    /// Every chart.
    pub charts: Vec<ChartReply>,
    /// First-pass yield per run.
    pub yield_by_run: Vec<YieldRow>,
    /// First-pass yield per day.
    pub yield_by_day: Vec<YieldRow>,
}

/// The centrifuge's signature the station has learned (docs/method.md §6).
#[derive(Debug, Serialize, ToSchema)]
pub struct SignatureReply {
    /// The run whose signature this is (none: nothing learned yet).
    pub run_id: Option<String>,
    /// The runs it rests on (0: nothing learned yet).
    pub runs: usize,
    /// The instruments of that run it rests on.
    pub instruments: usize,
    /// The sharp resonances, each at one level, corrected whole.
    pub spikes: Vec<SignatureSpike>,
    /// What it rests on and what it corrected, in the user's language.
    pub text: String,
    /// Its plot (SVG), when learned.
    pub svg: Option<String>,
}

/// A sharp resonance of the table.
#[derive(Debug, Serialize, ToSchema)]
pub struct SignatureSpike {
    /// The level [g].
    pub g: f64,
    /// Its error of the applied acceleration [µg].
    pub height_ug: f64,
}

/// One device of the equipment register.
#[derive(Debug, Serialize, ToSchema)]
pub struct EquipmentEntry {
    /// The station it belongs to (this server's: each station of a fleet
    /// keeps its own register).
    pub station: String,
    /// Its role (`centrifuge`, `fmu 1`, `instrument supply`, …).
    pub role: String,
    /// Identity as registered.
    pub identity: Option<String>,
    /// Calibration certificate.
    pub certificate: Option<String>,
    /// Calibrated on (YYYY-MM-DD).
    pub calibrated_on: Option<String>,
    /// Due on (YYYY-MM-DD).
    pub due_on: Option<String>,
    /// Who registered it.
    pub updated_by: Option<String>,
    /// `valid`, `due soon`, `overdue` or `not in the register`.
    pub status: String,
    /// The identity the station read from the device in its newest run
    /// (its `*IDN?` answer, a module's firmware): offered to an engineer
    /// to register it; absent before the station's first run.
    pub read_identity: Option<String>,
}

/// `PUT /api/equipment/{role}`.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SetEquipment {
    /// Make, model, serial (not blank, no control characters).
    #[schema(
        min_length = 1,
        max_length = 200,
        pattern = "^[^\\x00-\\x1f\\x7f-\\x9f]*[^\\s\\x00-\\x1f\\x7f-\\x9f][^\\x00-\\x1f\\x7f-\\x9f]*$"
    )]
    pub identity: String,
    /// Certificate number (not blank, no control characters).
    #[schema(
        min_length = 1,
        max_length = 200,
        pattern = "^[^\\x00-\\x1f\\x7f-\\x9f]*[^\\s\\x00-\\x1f\\x7f-\\x9f][^\\x00-\\x1f\\x7f-\\x9f]*$"
    )]
    pub certificate: String,
    /// YYYY-MM-DD, 1970 to 2200.
    #[schema(
        pattern = "^(19[7-9][0-9]|2[01][0-9][0-9]|2200)-(0[1-9]|1[0-2])-(0[1-9]|1[0-9]|2[0-8])$"
    )]
    pub calibrated_on: String,
    /// YYYY-MM-DD, after `calibrated_on`.
    #[schema(
        pattern = "^(19[7-9][0-9]|2[01][0-9][0-9]|2200)-(0[1-9]|1[0-2])-(0[1-9]|1[0-9]|2[0-8])$"
    )]
    pub due_on: String,
}

/// Its answer.
#[derive(Debug, Serialize, ToSchema)]
pub struct EquipmentSaved {
    /// The device.
    pub role: String,
    /// Its new due date.
    pub due_on: String,
}

/// One user.
#[derive(Debug, Serialize, ToSchema)]
pub struct UserEntry {
    /// Name.
    pub name: String,
    /// Role.
    pub role: String,
    /// Unix time it was made [s].
    pub created_at: i64,
}

/// `POST /api/users`.
#[derive(Debug, Deserialize, ToSchema)]
pub struct NewUser {
    /// Lower-case ASCII letters, digits, `.`, `_`, `-`, `@`, with at least one letter or digit.
    #[schema(max_length = 64, pattern = "^[a-z0-9._@-]*[a-z0-9][a-z0-9._@-]*$")]
    pub name: String,
    /// Its role.
    #[schema(value_type = crate::web::auth::Role)]
    pub role: String,
    /// At least 8 characters.
    #[schema(min_length = 8, max_length = 1024)]
    pub password: String,
}

/// A change of a user (an admin): role and/or password; either may be left out.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ChangeUser {
    /// The new role.
    #[schema(value_type = Option<crate::web::auth::Role>)]
    pub role: Option<String>,
    /// The new password, at least 8 characters.
    #[schema(min_length = 8, max_length = 1024)]
    pub password: Option<String>,
}

/// Its answer.
#[derive(Debug, Serialize, ToSchema)]
pub struct UserAdded {
    /// Name.
    pub name: String,
    /// Role.
    pub role: String,
}

/// One entry of the audit log.
#[derive(Debug, Serialize, ToSchema)]
pub struct AuditEntry {
    /// Its number.
    pub seq: i64,
    /// Unix time [s].
    pub at: i64,
    /// Who.
    pub who: String,
    /// What.
    pub action: String,
    /// The details.
    pub detail: String,
}

/// One station of the fleet (every station writing into this store).
#[derive(Debug, Serialize, ToSchema)]
pub struct FleetStation {
    /// The station's id (its config's `station`).
    pub station: String,
    /// `idle`, `running`, `waiting`, `faulted` or `offline` (no heartbeat
    /// for 10 s).
    #[schema(value_type = FleetStationState)]
    pub state: String,
    /// `server` (a `spinbench serve`) or `command line` (seen only through
    /// the runs of `spinbench run`, so never heard between runs).
    pub kind: String,
    /// Its current run (absent when offline).
    pub run_id: Option<String>,
    /// That run's label (`2026-11-24 · station 1 · #7`), as people name it.
    pub run_label: Option<String>,
    /// Steps done of the current run.
    pub steps_done: Option<i64>,
    /// Steps in the current run.
    pub steps_total: Option<i64>,
    /// Where its web UI answers.
    pub address: Option<String>,
    /// When it was last heard [Unix s].
    pub last_seen: i64,
    /// Instruments graded today (UTC) in first tests.
    pub tested_today: i64,
    /// Of them, passed.
    pub passed_today: i64,
    /// First-pass yield today (passed over tested), absent with none tested.
    pub first_pass_yield: Option<f64>,
    /// Its latest run's instruments by outcome (pass, marginal, fail,
    /// inconclusive, incomplete: how many of each; absent ones are 0).
    #[schema(value_type = std::collections::BTreeMap<String, i64>)]
    pub last_run_outcomes: std::collections::BTreeMap<String, i64>,
    /// This is the station of the server answering.
    pub this_station: bool,
}

/// A retest's or a resume's options (the body may be empty).
#[derive(Debug, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RetestRequest {
    /// Start although a device is overdue for calibration (an admin), with
    /// this reason (recorded in the audit log).
    #[schema(max_length = 500, pattern = "^[^\\x00-\\x1f\\x7f-\\x9f]*$")]
    pub override_overdue: Option<String>,
}
