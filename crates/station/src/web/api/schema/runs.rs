//! The bodies of runs: starting, designing, retesting and resuming one,
//! its answer to a prompt, its listing, detail and results, an
//! instrument's history and an exclusion made after the run.

use super::{OutcomeName, StoredRunState};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use utoipa::ToSchema;

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
    #[schema(value_type = Option<super::Wording>)]
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

/// `GET /api/runs/{id}/retest`: what a retest would take and do, before it starts.
#[derive(Debug, Serialize, ToSchema)]
pub struct RetestOffer {
    /// The run it would retest.
    pub retest_of: String,
    /// The serials it would test again (a clear fail is set aside).
    pub serials: Vec<String>,
    /// The levels per mounting the data may add, measured until the
    /// verdict is certain (`None`: the plan measures its levels only).
    pub sequential_levels_per_mounting: Option<u32>,
    /// For each inconclusive instrument: what would decide it.
    pub advice: Vec<RetestAdviceRow>,
}

/// What a retest can do for one inconclusive instrument.
#[derive(Debug, Serialize, ToSchema)]
pub struct RetestAdviceRow {
    /// The instrument.
    pub serial: String,
    /// Its slot (from 1).
    pub slot: i64,
    /// The judged value [µg/g²].
    pub value_ug_per_g2: f64,
    /// Its U95 [µg/g²].
    #[serde(rename = "U95")]
    pub u95_ug_per_g2: f64,
    /// The limit [µg/g²].
    pub limit_ug_per_g2: f64,
    /// The U95 under which the same value is decided: its distance from
    /// the limit [µg/g²].
    pub deciding_u95_ug_per_g2: f64,
    /// Its levels off the curve, as `P 40 g`.
    pub off_curve: Vec<String>,
    /// The retest's predicted K2 U95 for it [µg/g²] (`None`: no prediction).
    pub predicted_u95_ug_per_g2: Option<f64>,
    /// Whether the retest is predicted to decide it (`None`: not known).
    pub can_decide: Option<bool>,
    /// The runs it came out inconclusive in, this one included.
    pub inconclusive_runs: i64,
    /// All of it in one English line.
    pub text: String,
}

impl From<&spinbench_engine::retest::RetestAdvice> for RetestAdviceRow {
    fn from(a: &spinbench_engine::retest::RetestAdvice) -> RetestAdviceRow {
        RetestAdviceRow {
            serial: a.serial.clone(),
            slot: i64::try_from(a.slot).unwrap_or(i64::MAX),
            value_ug_per_g2: a.value_ug_per_g2,
            u95_ug_per_g2: a.u95_ug_per_g2,
            limit_ug_per_g2: a.limit_ug_per_g2,
            deciding_u95_ug_per_g2: a.deciding_u95_ug_per_g2,
            off_curve: a
                .off_curve
                .iter()
                .map(|l| format!("{} {} g", l.mount, l.g))
                .collect(),
            predicted_u95_ug_per_g2: a.predicted_u95_ug_per_g2,
            can_decide: a.can_decide,
            inconclusive_runs: i64::try_from(a.inconclusive_runs).unwrap_or(i64::MAX),
            text: a.text(),
        }
    }
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
    /// The reasons' stable codes, in order, to filter on (`k2_over_limit`,
    /// `noisy`, …; the record's codes, whatever the language).
    pub reason_codes: Vec<String>,
    /// What the verdict judged (`None` for a record made before the
    /// decision was recorded).
    pub judged: Option<JudgedValue>,
    /// The instrument's own K2 of both mountings (the same on each of its
    /// rows) [µg/g²].
    pub instrument_k2_ug_per_g2: Option<f64>,
    /// Its U95 [µg/g²].
    #[serde(rename = "instrument_k2_U95")]
    pub instrument_k2_u95_ug_per_g2: Option<f64>,
}

/// What an instrument's verdict judged, beside its outcome.
#[derive(Debug, Serialize, ToSchema)]
pub struct JudgedValue {
    /// The quantity judged: `K2` (the instrument's own, both mountings) or
    /// `k2_max` (the larger mounting's k2).
    #[schema(value_type = MeasurandName)]
    pub measurand: String,
    /// Its value (`None`: not measured, e.g. K2 without both mountings) [µg/g²].
    pub value_ug_per_g2: Option<f64>,
    /// Its expanded uncertainty at 95 % [µg/g²].
    #[serde(rename = "U95")]
    pub u95_ug_per_g2: Option<f64>,
    /// The plan's limit on it [µg/g²].
    pub limit_ug_per_g2: f64,
    /// The decision rule: `guarded` or `simple`.
    #[schema(value_type = DecisionRuleName)]
    pub rule: String,
}

impl From<spinbench_engine::Judged> for JudgedValue {
    fn from(j: spinbench_engine::Judged) -> JudgedValue {
        JudgedValue {
            measurand: j.measurand.name().to_string(),
            value_ug_per_g2: j.value_ug_per_g2,
            u95_ug_per_g2: j.u95_ug_per_g2,
            limit_ug_per_g2: j.limit_ug_per_g2,
            rule: j.rule.name().to_string(),
        }
    }
}

/// The quantity a verdict judges ([`spinbench_engine::plan::Measurand`];
/// documentation of its names, held together with it by a test).
#[derive(Debug, Clone, Copy, Serialize, ToSchema)]
pub enum MeasurandName {
    /// The instrument's own K2 of both mountings.
    #[serde(rename = "K2")]
    K2,
    /// The larger mounting's k2.
    #[serde(rename = "k2_max")]
    K2Max,
}

/// How a value with its U95 is judged against the limit
/// ([`spinbench_engine::plan::DecisionRule`]; held together by a test).
#[derive(Debug, Clone, Copy, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum DecisionRuleName {
    /// Pass only when |value| + U95 is within the limit, fail only when
    /// |value| − U95 is beyond it.
    Guarded,
    /// The value alone against the limit.
    Simple,
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
    /// The larger |k2| of its mountings, a figure: the verdict judged
    /// `judged` [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// What its verdict judged (`None` for a record made before the
    /// decision was recorded).
    pub judged: Option<JudgedValue>,
    /// Its reasons' stable codes, in order.
    pub reason_codes: Vec<String>,
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
#[derive(Debug, Clone, Copy, Serialize, Deserialize, ToSchema)]
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

/// A retest's or a resume's options (the body may be empty).
#[derive(Debug, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RetestRequest {
    /// Start although a device is overdue for calibration (an admin), with
    /// this reason (recorded in the audit log).
    #[schema(max_length = 500, pattern = "^[^\\x00-\\x1f\\x7f-\\x9f]*$")]
    pub override_overdue: Option<String>,
}
