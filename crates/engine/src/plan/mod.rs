//! Test plans (TOML) and their compilation into a list of steps: a plan is
//! data, and one executor ([`crate::executor`]) runs any list of steps.
//!
//! ```toml
//! name = "batch 47"
//! range_g = 70            # levels 0, 1, 5, 10, … 70 (method.md §3.3) unless `levels` is given
//! # levels = "auto"       # or designed by the station for a K2 U95 target:
//! # target_k2_u95_ug_per_g2 = 4.5
//! passes = ["P", "N"]     # mountings, in order (a serial "P:SN1" or "N:SN1" fixes its slot's mounting)
//! [serials]
//! 1 = "SN2601"            # slot number (1-based: module 1 slots 1–6, module 2 slots 7–12, …)
//! [dwell]
//! seconds = 10
//! [limits]
//! k2_max_ug_per_g2 = 20   # the k2 limit [µg/g²]
//! decide_on = "K2"        # the instrument's own K2 (default) or "k2_max" (published convention)
//! ```

mod compile;
pub use compile::MAX_EXCLUSION_REASON_CHARS;
mod designed;
mod step;
pub use step::{Fixture, Step};
#[cfg(test)]
mod tests;
mod validate;

use crate::config::StationConfig;
use serde::{Deserialize, Serialize};
use spinbench_analysis::{Direction, ModelOrder, Mount, centrifuge, points};
use std::collections::BTreeMap;

/// The plan as written.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TestPlan {
    /// Name of the test.
    #[serde(default = "default_name")]
    pub name: String,
    /// Operator's name, recorded with the run.
    #[serde(default)]
    pub operator: String,
    /// Serial number per slot (1-based); `P:` or `N:` fixes the slot's mounting.
    pub serials: BTreeMap<String, String>,
    /// Range m [g] (default 70).
    #[serde(default = "default_range")]
    pub range_g: f64,
    /// Explicit levels [g], ascending from 0 (default: 0, 1, 5, then every
    /// 5 g to m), or `"auto"`: the station designs them, with the dwell and
    /// the readings on the way down, for `target_k2_u95_ug_per_g2`
    /// ([`TestPlan::designed`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub levels: Option<LevelTable>,
    /// Visit the levels up and then back down (default true).
    #[serde(default = "default_true")]
    pub up_down: bool,
    /// The levels read again on the way down [g], a subset of the levels
    /// below the top (absent: every one, when `up_down`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub down_levels: Option<Vec<f64>>,
    /// The K2 U95 a designed plan (`levels = "auto"`) is to reach [µg/g²].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_k2_u95_ug_per_g2: Option<f64>,
    /// The plan's predicted K2 U95 and centrifuge time, from the station's
    /// model of its own runs, written by the station when the run starts
    /// ([`TestPlan::with_prediction`]); the reports set the achieved beside it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prediction: Option<PlanPrediction>,
    /// Mountings to run, in order (default: as the serials' prefixes say, else P).
    #[serde(default)]
    pub passes: Vec<Mount>,
    /// Chamber temperatures at which the range test runs [°C] (absent: the
    /// room, no chamber). Each pass visits them in turn, soaked as `[soak]`
    /// says, in the order [`crate::soak::visiting_order`] gives.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub temperatures_c: Vec<f64>,
    /// When a chamber temperature counts as reached.
    #[serde(default, skip_serializing_if = "crate::soak::SoakConfig::is_default")]
    pub soak: crate::soak::SoakConfig,
    /// Tumble positions: 2 (IA up, IA down; method.md (5)) or 4 (also the
    /// two with gravity along the cross axis that is vertical on the arm, as
    /// on the arm and inverted, which measure the cross-axis sensitivity and
    /// take it out of the radius). Default 2.
    #[serde(default = "default_tumble_positions")]
    pub tumble_positions: u8,
    /// Warm-up after power-on [s] (default 60).
    #[serde(default = "default_warmup")]
    pub warmup_s: f64,
    /// Model order (default 3).
    #[serde(default = "default_order")]
    pub order: u8,
    /// How long to average at each level.
    #[serde(default)]
    pub dwell: DwellConfig,
    /// When the speed and the outputs count as stable.
    #[serde(default)]
    pub stability: StabilityConfig,
    /// Pass/fail limits.
    #[serde(default)]
    pub limits: Limits,
    /// Levels an engineer leaves out of the reduction, each with a reason
    /// (recorded in every record it touches, and in the reports).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub exclusions: Vec<PlanExclusion>,
    /// What the reduction does with a level it finds off the curve:
    /// `"flag"` (the default: kept, named, its misfit in the budget as model
    /// inadequacy), `"exclude"` (left out automatically, named in the
    /// record and the report, the change in the budget) or `"own"` (the
    /// shipped plans': left out when flagged in one mounting only, the
    /// instrument's own dip; kept when flagged in both, the table's);
    /// [`spinbench_analysis::AnomalyRule`].
    #[serde(default, skip_serializing_if = "is_default_rule")]
    pub anomalies: spinbench_analysis::AnomalyRule,
    /// The run this one retests (its failed, inconclusive and flagged
    /// instruments, [`crate::retest`]); absent for a first test.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retest_of: Option<String>,
    /// Measure until the verdict is certain: after each mounting's planned
    /// levels, while the instruments are still mounted, levels chosen by
    /// the data for the instruments still undecided ([`SequentialConfig`];
    /// absent: only the planned levels).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sequential: Option<SequentialConfig>,
}

/// The plan's `[sequential]` table: the rule and the budget of the levels
/// the station adds after a mounting's planned ones (docs/method.md §6,
/// "Measure until the verdict is certain").
///
/// The rule: an instrument is undecided when its verdict is inconclusive
/// (in the last mounting; in an earlier one, before K2 exists, when a level
/// is off its curve there). What would decide it is support beside the
/// level off its curve, so that the reductions with and without that
/// level agree: the level halfway to each measured neighbour. Each round
/// measures the one such level that serves the most undecided
/// instruments, then judges again; the rounds stop when no instrument is
/// undecided, no level would serve one, or the budget is spent.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SequentialConfig {
    /// The budget: at most this many added levels per mounting (1 to
    /// [`crate::bounds::MAX_SEQUENTIAL_LEVELS`]); each takes one planned
    /// level's settling and dwell.
    pub max_levels_per_pass: u32,
}

/// The `levels` key: a list, or `"auto"` (designed by the station).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(untagged)]
pub enum LevelTable {
    /// Explicit levels [g], ascending from 0.
    List(Vec<f64>),
    /// `"auto"`: designed for the plan's `target_k2_u95_ug_per_g2`.
    Auto(AutoLevels),
}

/// The word `auto` of `levels = "auto"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AutoLevels {
    /// Designed by the station.
    Auto,
}

/// A plan's prediction, and how it was made.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PlanPrediction {
    /// Predicted K2 U95 of the median instrument [µg/g²].
    pub k2_u95_ug_per_g2: f64,
    /// Predicted centrifuge time of the level steps, every pass [s].
    pub centrifuge_time_s: f64,
    /// The published plan's on the same model, for comparison (none when
    /// the published levels to the range are too few to fit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub published_k2_u95_ug_per_g2: Option<f64>,
    /// The published plan's centrifuge time [s].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub published_centrifuge_time_s: Option<f64>,
    /// The target, when the plan was designed [µg/g²].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_k2_u95_ug_per_g2: Option<f64>,
    /// The range the run's median K2 U95 falls in with probability
    /// [`spinbench_analysis::design::RUN_RANGE_PROBABILITY`] (its
    /// instruments' anomalies differ; none without a learned spread) [µg/g²].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k2_u95_run_range_ug_per_g2: Option<[f64; 2]>,
    /// Runs the station's model was learned from (0: the defaults of a station with no history).
    pub model_runs: usize,
    /// The most centrifuge time the plan's `[sequential]` levels can add,
    /// every pass, on top of `centrifuge_time_s` [s]: each added level
    /// settled from anywhere in the range, then its dwell (none: no
    /// `[sequential]`, or a record written before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sequential_centrifuge_time_max_s: Option<f64>,
}

/// A level left out of the reduction by the plan.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PlanExclusion {
    /// Only this serial number (absent: every instrument).
    #[serde(default)]
    pub serial: Option<String>,
    /// The mounting.
    pub mount: Mount,
    /// The level [g], one of the plan's levels.
    pub g: f64,
    /// Why (required).
    pub reason: String,
}

fn is_default_rule(rule: &spinbench_analysis::AnomalyRule) -> bool {
    *rule == spinbench_analysis::AnomalyRule::default()
}

fn default_name() -> String {
    "centrifuge test".into()
}

fn default_range() -> f64 {
    70.0
}

fn default_true() -> bool {
    true
}

fn default_warmup() -> f64 {
    60.0
}

fn default_tumble_positions() -> u8 {
    2
}

fn default_order() -> u8 {
    3
}

/// Averaging at each level: n one-second values, or adaptive between bounds.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct DwellConfig {
    /// One-second values per point (default 10; the published station's n).
    pub seconds: u32,
    /// Adaptive dwell: stop once every instrument's standard error of the
    /// mean is at most this [µg] (None = fixed dwell).
    pub sem_target_ug: Option<f64>,
    /// Fewest values of an adaptive dwell.
    pub min_seconds: u32,
    /// Most values of an adaptive dwell.
    pub max_seconds: u32,
}

impl Default for DwellConfig {
    fn default() -> Self {
        DwellConfig {
            seconds: 10,
            sem_target_ug: None,
            min_seconds: 5,
            max_seconds: 30,
        }
    }
}

/// Stability criteria (method.md §3.3: data only at stable speed).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct StabilityConfig {
    /// Rate within this of the demand [ppm] counts as on speed.
    pub rate_tolerance_ppm: f64,
    /// Seconds the rate must stay on speed before data are taken.
    pub hold_s: u32,
    /// Largest acceptable drift of an output over the hold [µg/s] (a slope
    /// test; the slope must also be significant, at a 1 % chance per look
    /// over all the instruments that noise alone stops the settling).
    pub drift_limit_ug_per_s: f64,
    /// Longest wait for stability at a level before the run faults [s].
    pub max_settle_s: u32,
    /// Restarts of a point after rate excursions before the run faults.
    pub max_restarts: u32,
    /// An instrument whose 1-s values scatter more than this is failed as noisy [µg].
    pub noise_limit_ug: f64,
    /// Largest change of an instrument's temperature during a point's
    /// averaging [°C]: a point over it is measured again (up to
    /// `max_restarts`), then kept and flagged. Absent: not checked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temperature_change_max_c: Option<f64>,
}

impl Default for StabilityConfig {
    fn default() -> Self {
        StabilityConfig {
            rate_tolerance_ppm: 20.0,
            hold_s: 5,
            drift_limit_ug_per_s: 3.0,
            max_settle_s: 180,
            max_restarts: 5,
            noise_limit_ug: 300.0,
            temperature_change_max_c: None,
        }
    }
}

/// Pass/fail limits, one per figure; a figure without a limit is reported only.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Limits {
    /// The k2 limit [µg/g²]: the largest |value| of the quantity
    /// `decide_on` names (the instrument's K2 by default; with
    /// `decide_on = "k2_max"`, the larger |k2| of the two mountings).
    pub k2_max_ug_per_g2: f64,
    /// Which quantity the k2 limit is held against (method.md §6): `"K2"`,
    /// the instrument's own second-order term (the default), or
    /// `"k2_max"`, the published station's convention.
    pub decide_on: Measurand,
    /// Scale-factor nonlinearity from the best straight line [ppm FS].
    pub nonlinearity_max_ppm_fs: Option<f64>,
    /// |Scale-factor asymmetry| between P and N [ppm].
    pub asymmetry_max_ppm: Option<f64>,
    /// |Hysteresis| [µg].
    pub hysteresis_max_ug: Option<f64>,
    /// Above this fraction of a limit the result is marginal.
    pub marginal_fraction: f64,
    /// How a value with an uncertainty is judged against its limit.
    pub decision_rule: DecisionRule,
}

/// Which quantity a k2 limit judges (docs/method.md §6, (15)); a plan's
/// `limits.decide_on` key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
pub enum Measurand {
    /// The instrument's own K2 = (k2_P − k2_N)/2 with its U95 (both
    /// mountings): what the instrument is, the table's common part
    /// cancelled. Needs both mountings; without them nothing is decided.
    #[default]
    #[serde(rename = "K2")]
    K2,
    /// The published station's k2_max: the larger |k2| of the two
    /// mountings, each with its own U95. It carries the centrifuge's common
    /// part (c′ of (15)), so it judges the table as well as the instrument.
    #[serde(rename = "k2_max")]
    K2Max,
}

impl Measurand {
    /// Its name in plans, records and reports: `K2` or `k2_max`.
    pub fn name(self) -> &'static str {
        match self {
            Measurand::K2 => "K2",
            Measurand::K2Max => "k2_max",
        }
    }

    /// What it is, for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Measurand::K2 => {
                "the instrument's own K2 = (k2_P − k2_N)/2 of both mountings (docs/method.md (15)), the centrifuge's common part cancelled"
            }
            Measurand::K2Max => {
                "k2_max, the larger |k2| of the two mountings (the published convention; it carries the centrifuge's common part, docs/method.md (15))"
            }
        }
    }
}

impl std::str::FromStr for Measurand {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text.trim() {
            "K2" => Ok(Measurand::K2),
            "k2_max" => Ok(Measurand::K2Max),
            other => Err(format!(
                "decide_on = '{other}': write \"K2\" (the instrument's own) or \"k2_max\" (the published convention)"
            )),
        }
    }
}

/// What a k2 verdict judged: the quantity, its limit and the rule; in every
/// record, so a reader never has to guess what was held against what.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
pub struct Decision {
    /// The quantity judged.
    pub measurand: Measurand,
    /// Its limit [µg/g²].
    pub limit_ug_per_g2: f64,
    /// The decision rule.
    pub rule: DecisionRule,
}

impl Limits {
    /// The k2 decision these limits make.
    pub fn decision(&self) -> Decision {
        Decision {
            measurand: self.decide_on,
            limit_ug_per_g2: self.k2_max_ug_per_g2,
            rule: self.decision_rule,
        }
    }
}

/// How a value with an uncertainty is judged against its limit (method.md §6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DecisionRule {
    /// Guarded acceptance (ISO 14253-1, ILAC-G8): pass only when
    /// |value| + U95 ≤ limit, fail only when |value| − U95 > limit,
    /// otherwise inconclusive (retest advised).
    #[default]
    Guarded,
    /// Simple acceptance: the value alone against the limit (the published
    /// method's), said so in every record and report.
    Simple,
}

/// A value judged against its limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Within the limit (guarded: with its whole interval).
    Pass,
    /// Passes, but within the marginal band of the limit.
    Marginal,
    /// The interval straddles the limit (guarded only).
    Inconclusive,
    /// Beyond the limit (guarded: with its whole interval).
    Fail,
}

impl DecisionRule {
    /// Its serde name: `guarded` or `simple`.
    pub fn name(self) -> &'static str {
        match self {
            DecisionRule::Guarded => "guarded",
            DecisionRule::Simple => "simple",
        }
    }

    /// Judge |value| against `limit`, with its expanded uncertainty `u95`
    /// when known; above `marginal_fraction`·limit a pass is marginal.
    /// Guarded without an uncertainty cannot decide: inconclusive. A value
    /// or limit that is not a number is never a pass (inconclusive).
    pub fn decide(
        self,
        value: f64,
        u95: Option<f64>,
        limit: f64,
        marginal_fraction: f64,
    ) -> Verdict {
        if !(value.is_finite() && limit.is_finite()) {
            return Verdict::Inconclusive;
        }
        let v = value.abs();
        let (low, high) = match (self, u95) {
            (DecisionRule::Simple, _) => (v, v),
            (DecisionRule::Guarded, Some(u)) if u.is_finite() && u >= 0.0 => (v - u, v + u),
            (DecisionRule::Guarded, _) => return Verdict::Inconclusive,
        };
        if low > limit {
            Verdict::Fail
        } else if high > limit {
            Verdict::Inconclusive
        } else if high > marginal_fraction * limit {
            Verdict::Marginal
        } else {
            Verdict::Pass
        }
    }

    /// Judge the larger |value| of several (one per mounting, k2_max) against
    /// `limit`: the limit is on the maximum, so under the guarded rule the
    /// result passes only when every value passes with its own U95, fails
    /// when any fails with its own, and is otherwise inconclusive — the
    /// worst of the values' verdicts. Returns it with the index of the value
    /// that decided it. No values: inconclusive.
    pub fn decide_all(
        self,
        values: &[(f64, Option<f64>)],
        limit: f64,
        marginal_fraction: f64,
    ) -> (Verdict, Option<usize>) {
        let rank = |v: Verdict| match v {
            Verdict::Pass => 0,
            Verdict::Marginal => 1,
            Verdict::Inconclusive => 2,
            Verdict::Fail => 3,
        };
        let mut worst: Option<(Verdict, usize, f64)> = None;
        for (i, &(value, u95)) in values.iter().enumerate() {
            let verdict = self.decide(value, u95, limit, marginal_fraction);
            let better = match worst {
                None => true,
                Some((w, _, wv)) => {
                    rank(verdict) > rank(w) || (rank(verdict) == rank(w) && value.abs() > wv)
                }
            };
            if better {
                worst = Some((verdict, i, value.abs()));
            }
        }
        match worst {
            Some((verdict, i, _)) => (verdict, Some(i)),
            None => (Verdict::Inconclusive, None),
        }
    }

    /// How reports name the rule.
    pub fn describe(self) -> &'static str {
        match self {
            DecisionRule::Guarded => {
                "guarded acceptance (ISO 14253-1, ILAC-G8): pass only when |value| + U95 is within the limit, fail only when |value| − U95 is beyond it, otherwise inconclusive (retest)"
            }
            DecisionRule::Simple => {
                "simple acceptance: the value alone against the limit, its uncertainty not considered"
            }
        }
    }
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            k2_max_ug_per_g2: 20.0,
            decide_on: Measurand::K2,
            nonlinearity_max_ppm_fs: None,
            asymmetry_max_ppm: None,
            hysteresis_max_ug: None,
            marginal_fraction: 0.9,
            decision_rule: DecisionRule::Guarded,
        }
    }
}

/// A plan that cannot run on this station; names the key and what to do.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("test plan: {key}: {problem}")]
pub struct PlanError {
    /// The key.
    pub key: String,
    /// What is wrong.
    pub problem: String,
}

/// A compiled plan: the steps, and per pass the mounting of each slot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CompiledPlan {
    /// The plan as written.
    pub plan: TestPlan,
    /// Serial number per slot (without the mounting prefix); `None` = empty slot.
    pub serials: Vec<Option<String>>,
    /// Per pass, the mounting of each slot (`None` = not measured in that pass).
    pub passes: Vec<Vec<Option<Mount>>>,
    /// The steps, in order.
    pub steps: Vec<Step>,
    /// Model order.
    #[serde(skip)]
    pub order: ModelOrder,
    /// What past runs on this centrifuge measured of its signature, pooled
    /// with the run's own before its points are corrected (the station
    /// reads it from its store; `None`: the run learns alone).
    #[serde(skip)]
    pub table_prior: Option<spinbench_analysis::table_signature::Prior>,
}

impl Default for TestPlan {
    /// The defaults of a plan file (no serials yet): 0–70 g, the published
    /// levels up and down, mounting P, 60 s warm-up, order 3, 10-s dwell.
    fn default() -> Self {
        TestPlan {
            name: default_name(),
            operator: String::new(),
            serials: BTreeMap::new(),
            range_g: default_range(),
            levels: None,
            up_down: true,
            down_levels: None,
            target_k2_u95_ug_per_g2: None,
            prediction: None,
            passes: Vec::new(),
            tumble_positions: default_tumble_positions(),
            temperatures_c: Vec::new(),
            soak: crate::soak::SoakConfig::default(),
            warmup_s: default_warmup(),
            order: default_order(),
            dwell: DwellConfig::default(),
            stability: StabilityConfig::default(),
            limits: Limits::default(),
            exclusions: Vec::new(),
            anomalies: Default::default(),
            retest_of: None,
            sequential: None,
        }
    }
}

impl TestPlan {
    /// Parse TOML text.
    /// Parse TOML text and check every number against its bound
    /// ([`TestPlan::validate`]).
    pub fn from_toml(text: &str) -> Result<TestPlan, PlanError> {
        let plan: TestPlan = toml::from_str(text).map_err(|e| PlanError {
            key: "(file)".into(),
            problem: e.to_string(),
        })?;
        plan.validate()?;
        Ok(plan)
    }

    /// The ascending level table [g] (the published one for `"auto"`,
    /// which [`TestPlan::designed`] replaces before the plan compiles).
    pub fn level_table(&self) -> Vec<f64> {
        match &self.levels {
            Some(LevelTable::List(l)) => l.clone(),
            _ => points::published_levels(self.range_g),
        }
    }
}
