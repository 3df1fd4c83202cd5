//! Test plans (TOML) and their compilation into a list of steps: a plan is
//! data, and one executor ([`crate::executor`]) runs any list of steps.
//!
//! ```toml
//! name = "batch 47"
//! range_g = 70            # levels 0, 1, 5, 10, … 70 (method.md §3.3) unless `levels` is given
//! passes = ["P", "N"]     # mountings, in order (a serial "P:SN1" or "N:SN1" fixes its slot's mounting)
//! [serials]
//! 1 = "SN2601"            # slot number (1-based: module 1 slots 1–6, module 2 slots 7–12, …)
//! [dwell]
//! seconds = 10
//! [limits]
//! k2_max_ug_per_g2 = 20
//! ```

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
    /// Explicit levels [g], ascending from 0 (default: 0, 1, 5, then every 5 g to m).
    #[serde(default)]
    pub levels: Option<Vec<f64>>,
    /// Visit the levels up and then back down (default true).
    #[serde(default = "default_true")]
    pub up_down: bool,
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
    /// inadequacy) or `"exclude"` (left out automatically, named in the
    /// record and the report, the change in the budget);
    /// [`spinbench_analysis::AnomalyRule`].
    #[serde(default, skip_serializing_if = "is_default_rule")]
    pub anomalies: spinbench_analysis::AnomalyRule,
    /// The run this one retests (its failed, inconclusive and flagged
    /// instruments, [`crate::retest`]); absent for a first test.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retest_of: Option<String>,
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
    /// |k2| of the worse mounting must not exceed this [µg/g²].
    pub k2_max_ug_per_g2: f64,
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

/// The instrument mounting an operator is asked for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Fixture {
    /// On the bench, input axis up.
    Up,
    /// On the bench, input axis down.
    Down,
    /// On the arm, mounting P or N.
    Arm(Mount),
    /// On the bench, input axis horizontal, with gravity along the cross
    /// axis that is vertical on the arm: as on the arm, or inverted.
    Crosswise {
        /// As on the arm (else upside down).
        as_on_arm: bool,
    },
}

/// One step of a compiled plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Step {
    /// Switch the supplies and relays on, start streaming.
    PowerOn,
    /// Check each instrument draws current and its resonators are in range.
    CheckAlive,
    /// Wait for the instruments to warm up.
    WarmUp {
        /// Seconds of station time.
        seconds: f64,
    },
    /// Ask the operator to mount the instruments (per slot; `None` = leave).
    Mount {
        /// Requested fixture per slot.
        fixtures: Vec<Option<Fixture>>,
    },
    /// Record the 1 g outputs with the input axis up or down (method.md (5)).
    Tumble {
        /// Up (+1 g) or down (−1 g).
        up: bool,
    },
    /// Bring the chamber to a temperature and wait until it and the
    /// instruments have soaked (`[soak]`).
    Soak {
        /// Chamber setpoint [°C].
        setpoint_c: f64,
    },
    /// Record the output with the input axis horizontal and gravity along
    /// the cross axis that is vertical on the arm (four-position tumble).
    CrossTumble {
        /// As on the arm (else inverted).
        as_on_arm: bool,
    },
    /// Spin to 1 g at R0 and find each instrument's radius (method.md (6)–(8)).
    Radius {
        /// Pass number.
        pass: usize,
    },
    /// Take one averaged point at a level.
    Level {
        /// Pass number.
        pass: usize,
        /// Nominal level [g] at the drawing radius.
        g_nominal: f64,
        /// Ascending or descending.
        direction: Direction,
    },
    /// Controlled stop of the centrifuge.
    Stop,
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

    /// The ascending level table [g].
    pub fn level_table(&self) -> Vec<f64> {
        self.levels
            .clone()
            .unwrap_or_else(|| points::published_levels(self.range_g))
    }

    /// Check every number and name of the plan against its named bound
    /// ([`crate::bounds`]) before anything is allocated in proportion to
    /// it: finite, of the right sign, within the bound.
    pub fn validate(&self) -> Result<(), PlanError> {
        use crate::bounds::*;
        let at = |key: &str| {
            let key = key.to_string();
            move |problem: String| PlanError { key, problem }
        };
        for (key, text) in [("name", &self.name), ("operator", &self.operator)] {
            if text.chars().count() > MAX_NAME_CHARS || text.chars().any(char::is_control) {
                return Err(at(key)(format!(
                    "'{}': at most {MAX_NAME_CHARS} characters, no control characters (MAX_NAME_CHARS)",
                    shown(text)
                )));
            }
        }
        if let Some(id) = &self.retest_of
            && !crate::retest::is_run_id(id)
        {
            return Err(at("retest_of")(format!(
                "'{}' is not a run identifier (1 to 64 letters, digits, '-' or '_')",
                shown(id)
            )));
        }
        for (slot, serial) in &self.serials {
            if slot.len() > 8 {
                return Err(at("serials")(format!(
                    "'{}' is not a slot number",
                    shown(slot)
                )));
            }
            if serial.chars().count() > MAX_NAME_CHARS || serial.chars().any(char::is_control) {
                return Err(at(&format!("serials.{slot}"))(format!(
                    "'{}': at most {MAX_NAME_CHARS} characters, no control characters (MAX_NAME_CHARS)",
                    shown(serial)
                )));
            }
        }
        check_positive(self.range_g, MAX_LEVEL_G, "g", "MAX_LEVEL_G").map_err(at("range_g"))?;
        if let Some(levels) = &self.levels {
            if levels.len() > MAX_LEVELS {
                return Err(at("levels")(format!(
                    "{} levels; at most {MAX_LEVELS} (MAX_LEVELS)",
                    levels.len()
                )));
            }
            for (i, g) in levels.iter().enumerate() {
                check(*g, 0.0..=MAX_LEVEL_G, "g", "MAX_LEVEL_G")
                    .map_err(at(&format!("levels[{i}]")))?;
            }
        }
        check(self.warmup_s, 0.0..=MAX_WARMUP_S, "s", "MAX_WARMUP_S").map_err(at("warmup_s"))?;
        let d = &self.dwell;
        for (key, v, min) in [
            ("dwell.seconds", d.seconds, 2),
            ("dwell.min_seconds", d.min_seconds, 2),
            ("dwell.max_seconds", d.max_seconds, 2),
        ] {
            if !(min..=MAX_DWELL_S).contains(&v) {
                return Err(at(key)(format!(
                    "{v} s is outside {min} to {MAX_DWELL_S} s (MAX_DWELL_S)"
                )));
            }
        }
        if d.max_seconds < d.min_seconds {
            return Err(at("dwell")(format!(
                "max_seconds {} is below min_seconds {}",
                d.max_seconds, d.min_seconds
            )));
        }
        if let Some(t) = d.sem_target_ug {
            check_positive(t, MAX_UG, "µg", "MAX_UG").map_err(at("dwell.sem_target_ug"))?;
        }
        let s = &self.stability;
        check_positive(
            s.rate_tolerance_ppm,
            MAX_RATE_TOLERANCE_PPM,
            "ppm",
            "MAX_RATE_TOLERANCE_PPM",
        )
        .map_err(at("stability.rate_tolerance_ppm"))?;
        check_positive(s.drift_limit_ug_per_s, MAX_UG, "µg/s", "MAX_UG")
            .map_err(at("stability.drift_limit_ug_per_s"))?;
        check_positive(s.noise_limit_ug, MAX_UG, "µg", "MAX_UG")
            .map_err(at("stability.noise_limit_ug"))?;
        if let Some(c) = s.temperature_change_max_c {
            check_positive(
                c,
                MAX_TEMPERATURE_CHANGE_C,
                "°C",
                "MAX_TEMPERATURE_CHANGE_C",
            )
            .map_err(at("stability.temperature_change_max_c"))?;
        }
        for (key, v, min, max, bound) in [
            (
                "stability.hold_s",
                s.hold_s,
                3,
                MAX_SETTLE_S,
                "MAX_SETTLE_S",
            ),
            (
                "stability.max_settle_s",
                s.max_settle_s,
                1,
                MAX_SETTLE_S,
                "MAX_SETTLE_S",
            ),
            (
                "stability.max_restarts",
                s.max_restarts,
                0,
                MAX_RESTARTS,
                "MAX_RESTARTS",
            ),
        ] {
            if !(min..=max).contains(&v) {
                return Err(at(key)(format!("{v} is outside {min} to {max} ({bound})")));
            }
        }
        let l = &self.limits;
        check_positive(
            l.k2_max_ug_per_g2,
            MAX_FIGURE_LIMIT,
            "µg/g²",
            "MAX_FIGURE_LIMIT",
        )
        .map_err(at("limits.k2_max_ug_per_g2"))?;
        for (key, v, unit) in [
            (
                "limits.nonlinearity_max_ppm_fs",
                l.nonlinearity_max_ppm_fs,
                "ppm FS",
            ),
            ("limits.asymmetry_max_ppm", l.asymmetry_max_ppm, "ppm"),
            ("limits.hysteresis_max_ug", l.hysteresis_max_ug, "µg"),
        ] {
            if let Some(v) = v {
                check_positive(v, MAX_FIGURE_LIMIT, unit, "MAX_FIGURE_LIMIT").map_err(at(key))?;
            }
        }
        check(l.marginal_fraction, 0.0..=1.0, "", "a fraction")
            .map_err(at("limits.marginal_fraction"))?;
        Ok(())
    }

    /// Check the plan against the station and compile it into steps. This
    /// is where a plan that would exceed the centrifuge's rate limit or the
    /// fixtures' rating at any position is refused, before anything moves.
    pub fn compile(&self, station: &StationConfig) -> Result<CompiledPlan, PlanError> {
        let err = |key: &str, problem: String| {
            Err(PlanError {
                key: key.into(),
                problem,
            })
        };
        self.validate()?;
        if !self.temperatures_c.is_empty() {
            if station.chamber.is_none() {
                return err(
                    "temperatures_c",
                    "the station has no [chamber] to reach them; add one to the station config or leave temperatures_c out".into(),
                );
            }
            let (lo, hi) = spinbench_devices::chamber::SETPOINT_RANGE_C;
            if let Some(t) = self
                .temperatures_c
                .iter()
                .find(|t| !(t.is_finite() && (lo..=hi).contains(*t)))
            {
                return err(
                    "temperatures_c",
                    format!(
                        "{t} is not a chamber temperature from {lo} to {hi} °C (SETPOINT_RANGE_C)"
                    ),
                );
            }
            // A setpoint the station's own limit would stop the run at:
            // refused before anything moves, not faulted after a pass.
            if let Some(max) = station.temperature.instrument_max_c
                && let Some(t) = self.temperatures_c.iter().find(|t| **t >= max)
            {
                return err(
                    "temperatures_c",
                    format!(
                        "{t} °C reaches the station's temperature.instrument_max_c = {max} °C, which stops a run; leave it out or raise the limit if the instruments allow"
                    ),
                );
            }
            if self.temperatures_c.len() > crate::bounds::MAX_TEMPERATURES {
                return err(
                    "temperatures_c",
                    format!(
                        "{} temperatures; at most {} (MAX_TEMPERATURES)",
                        self.temperatures_c.len(),
                        crate::bounds::MAX_TEMPERATURES
                    ),
                );
            }
            if let Err((key, problem)) = self.soak.validate() {
                return err(&key, problem);
            }
        }
        if !matches!(self.tumble_positions, 2 | 4) {
            return err(
                "tumble_positions",
                format!(
                    "{} is not 2 (IA up, IA down) or 4 (also the two cross-axis positions)",
                    self.tumble_positions
                ),
            );
        }
        let order = ModelOrder::from_degree(self.order).ok_or_else(|| PlanError {
            key: "order".into(),
            problem: format!("{} is not 1, 2 or 3", self.order),
        })?;
        let levels = self.level_table();
        if levels.first() != Some(&0.0) {
            return err("levels", "the levels must start at 0 g".into());
        }
        if levels.iter().any(|g| !g.is_finite()) || levels.windows(2).any(|w| w[1] <= w[0]) {
            return err(
                "levels",
                "the levels must be finite and strictly ascending".into(),
            );
        }
        if levels.len() < 6 {
            return err(
                "levels",
                format!(
                    "{} levels; method.md §3.3 asks for at least 6 from 0 to m",
                    levels.len()
                ),
            );
        }
        for (i, e) in self.exclusions.iter().enumerate() {
            let key = format!("exclusions[{i}]");
            if e.reason.trim().is_empty() {
                return err(
                    &key,
                    "a reason is required: nothing is excluded without one".into(),
                );
            }
            if !levels.contains(&e.g) {
                return err(
                    &key,
                    format!("{} g is not one of the plan's levels {levels:?}", e.g),
                );
            }
            if let Some(serial) = &e.serial
                && !self.serials.values().any(|s| {
                    let s = s.trim();
                    s == serial
                        || s.strip_prefix("P:")
                            .or_else(|| s.strip_prefix("N:"))
                            .map(str::trim)
                            == Some(serial.as_str())
                })
            {
                return err(
                    &key,
                    format!("no instrument '{serial}' in the plan's serials"),
                );
            }
        }
        if levels.len() < usize::from(self.order) + 2 {
            return err(
                "levels",
                format!(
                    "{} levels cannot fit an order-{} model with a residual",
                    levels.len(),
                    self.order
                ),
            );
        }
        if self.dwell.seconds < 2
            || self.dwell.min_seconds < 2
            || self.dwell.max_seconds < self.dwell.min_seconds
        {
            return err(
                "dwell",
                "need seconds ≥ 2 and 2 ≤ min_seconds ≤ max_seconds".into(),
            );
        }
        if self.stability.hold_s < 3 {
            return err(
                "stability.hold_s",
                "the drift test needs at least 3 seconds of hold".into(),
            );
        }
        if !(self.limits.k2_max_ug_per_g2 > 0.0
            && (0.0..=1.0).contains(&self.limits.marginal_fraction))
        {
            return err(
                "limits",
                "need k2_max_ug_per_g2 > 0 and 0 ≤ marginal_fraction ≤ 1".into(),
            );
        }

        // Serials and their mountings.
        let slots = station.slots();
        let mut serials = vec![None; slots];
        let mut fixed: Vec<Option<Mount>> = vec![None; slots];
        for (key, serial) in &self.serials {
            let slot: usize = key
                .parse()
                .ok()
                .filter(|s| (1..=slots).contains(s))
                .ok_or_else(|| PlanError {
                    key: format!("serials.{key}"),
                    problem: format!("slots are numbered 1 to {slots}"),
                })?;
            // "01" or "+1" beside "1" would name one slot twice and one
            // instrument would be dropped without a word: only the plain
            // number names a slot.
            if key != &slot.to_string() {
                return err(
                    &format!("serials.{key}"),
                    format!("write the slot as {slot} (no sign, no leading zero)"),
                );
            }
            let (mount, bare) = match serial.split_once(':') {
                Some((m, rest)) => match Mount::parse(m) {
                    Some(mount) => (Some(mount), rest.trim()),
                    None => {
                        return err(
                            &format!("serials.{key}"),
                            format!("'{m}:' is not a mounting prefix; use P: or N:"),
                        );
                    }
                },
                None => (None, serial.trim()),
            };
            let normal = match crate::bounds::person_text(bare) {
                Ok(n) => n,
                Err(why) => return err(&format!("serials.{key}"), why),
            };
            let bare = normal.as_str();
            if bare.is_empty() {
                return err(
                    &format!("serials.{key}"),
                    "the serial number is empty".into(),
                );
            }
            // One instrument, one slot: its history must not mix two.
            if let Some(other) = serials.iter().position(|s| s.as_deref() == Some(bare)) {
                return err(
                    &format!("serials.{key}"),
                    format!(
                        "'{bare}' is already in slot {}; an instrument takes one slot",
                        other + 1
                    ),
                );
            }
            serials[slot - 1] = Some(bare.to_string());
            fixed[slot - 1] = mount;
        }
        if serials.iter().all(Option::is_none) {
            return err("serials", "no instrument in the plan".into());
        }
        let passes: Vec<Vec<Option<Mount>>> = if !self.passes.is_empty() {
            self.passes
                .iter()
                .map(|&m| {
                    (0..slots)
                        .map(|i| {
                            serials[i]
                                .as_ref()
                                .and(fixed[i].map_or(Some(m), |f| (f == m).then_some(m)))
                        })
                        .collect()
                })
                .collect()
        } else if serials
            .iter()
            .zip(&fixed)
            .all(|(s, f)| s.is_none() || f.is_some())
        {
            // Every serial carries its mounting: one mixed pass.
            vec![fixed.clone()]
        } else {
            vec![
                (0..slots)
                    .map(|i| serials[i].as_ref().and(Some(fixed[i].unwrap_or(Mount::P))))
                    .collect(),
            ]
        };
        // A pass nobody takes part in (every instrument's prefix fixes the
        // other mounting) is not spun: the table would run its levels for nothing.
        let passes: Vec<Vec<Option<Mount>>> = passes
            .into_iter()
            .filter(|p| p.iter().any(Option::is_some))
            .collect();

        // Safety: every level within the rate limit and every position within its rating.
        let max_rate = station.centrifuge.max_rate_deg_s().map_err(|e| PlanError {
            key: e.key,
            problem: e.problem,
        })?;
        let g = station.g_local_m_s2;
        let r0 = station.arm.radius_m;
        for &level in &levels {
            let w =
                centrifuge::rate_for_acceleration_rad_s(level, r0, g).map_err(|e| PlanError {
                    key: "levels".into(),
                    problem: e.to_string(),
                })?;
            if w.to_degrees() > max_rate {
                return err(
                    "range_g",
                    format!(
                        "{level} g needs {:.1} deg/s at R0 = {r0} m, above the centrifuge's limit of {max_rate} deg/s; lower the range",
                        w.to_degrees()
                    ),
                );
            }
            for i in 0..slots {
                let at = level * station.drawing_radius_m(i) / r0;
                if at > station.arm.max_g * 1.001 {
                    return err(
                        "range_g",
                        format!(
                            "{level} g puts {at:.2} g on position {} (rated {} g, arm.max_g); lower the range",
                            i + 1,
                            station.arm.max_g
                        ),
                    );
                }
            }
        }

        // The steps.
        let sequence = if self.up_down {
            points::up_down(&levels)
        } else {
            levels.clone()
        };
        let top = levels.last().copied().unwrap_or(0.0);
        let all = |f: Fixture| {
            serials
                .iter()
                .map(|s| s.as_ref().map(|_| f))
                .collect::<Vec<_>>()
        };
        let mut steps = vec![
            Step::PowerOn,
            Step::CheckAlive,
            Step::WarmUp {
                seconds: self.warmup_s.max(0.0),
            },
            Step::Mount {
                fixtures: all(Fixture::Up),
            },
            Step::Tumble { up: true },
            Step::Mount {
                fixtures: all(Fixture::Down),
            },
            Step::Tumble { up: false },
        ];
        if self.tumble_positions == 4 {
            for as_on_arm in [true, false] {
                steps.push(Step::Mount {
                    fixtures: all(Fixture::Crosswise { as_on_arm }),
                });
                steps.push(Step::CrossTumble { as_on_arm });
            }
        }
        let orders = crate::soak::visiting_order(
            &self.temperatures_c,
            passes.len(),
            station.temperature.ambient_c,
        );
        let reference =
            crate::soak::reference_c(&self.temperatures_c, station.temperature.ambient_c);
        for (p, pass) in passes.iter().enumerate() {
            steps.push(Step::Mount {
                fixtures: pass.iter().map(|m| m.map(Fixture::Arm)).collect(),
            });
            // Without temperatures: one visit at the room's.
            let temperatures: Vec<Option<f64>> = match orders.get(p) {
                Some(o) if !o.is_empty() => o.iter().copied().map(Some).collect(),
                _ => vec![None],
            };
            for setpoint in temperatures {
                if let Some(setpoint_c) = setpoint {
                    steps.push(Step::Soak { setpoint_c });
                }
                // The radius at the reference temperature (or the room's),
                // which each pass visits first (see `soak::visiting_order`).
                if setpoint == reference {
                    steps.push(Step::Radius { pass: p });
                }
                let mut passed_top = false;
                for &level in &sequence {
                    let direction = if passed_top {
                        Direction::Down
                    } else {
                        Direction::Up
                    };
                    if level == top {
                        passed_top = true;
                    }
                    steps.push(Step::Level {
                        pass: p,
                        g_nominal: level,
                        direction,
                    });
                }
                steps.push(Step::Stop);
            }
        }
        Ok(CompiledPlan {
            plan: self.clone(),
            serials,
            passes,
            steps,
            order,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_exclusion_needs_a_reason_a_level_of_the_plan_and_a_known_serial() {
        let station = station(1);
        let plan = |exclusion: &str| {
            TestPlan::from_toml(&format!(
                "range_g = 30\n[serials]\n1 = \"P:A\"\n[[exclusions]]\n{exclusion}\n"
            ))
            .expect("plan")
            .compile(&station)
        };
        assert!(plan("mount = \"P\"\ng = 5\nreason = \"resonance\"").is_ok());
        assert!(plan("serial = \"A\"\nmount = \"P\"\ng = 5\nreason = \"resonance\"").is_ok());
        let e = plan("mount = \"P\"\ng = 5\nreason = \" \"").expect_err("no reason");
        assert_eq!(e.key, "exclusions[0]");
        let e = plan("mount = \"P\"\ng = 7\nreason = \"r\"").expect_err("not a level");
        assert!(e.problem.contains("not one of the plan's levels"), "{e}");
        let e = plan("serial = \"Z\"\nmount = \"P\"\ng = 5\nreason = \"r\"").expect_err("serial");
        assert!(e.problem.contains("no instrument 'Z'"), "{e}");
    }

    #[test]
    fn the_decision_rules_at_their_boundaries() {
        use DecisionRule::{Guarded, Simple};
        let (limit, band) = (20.0, 0.9);
        let g = |v: f64, u: f64| Guarded.decide(v, Some(u), limit, band);
        // Guarded: pass only with the whole interval inside.
        assert_eq!(g(17.0, 3.0), Verdict::Marginal); // 20.0 ≤ 20: inside, in the band
        assert_eq!(g(17.0, 3.000_001), Verdict::Inconclusive);
        assert_eq!(g(14.0, 3.0), Verdict::Pass); // 17 ≤ 18 = 0.9 × 20
        assert_eq!(g(15.0, 3.000_001), Verdict::Marginal);
        // Fail only with the whole interval beyond.
        assert_eq!(g(23.0, 3.0), Verdict::Inconclusive); // 20.0 is not beyond 20
        assert_eq!(g(23.000_001, 3.0), Verdict::Fail);
        // The web UI's case: 12.6 ± 19.3 against 20 is not a pass.
        assert_eq!(g(12.6, 19.3), Verdict::Inconclusive);
        assert_eq!(g(-25.0, 1.0), Verdict::Fail);
        // Guarded with no uncertainty cannot decide.
        assert_eq!(
            Guarded.decide(1.0, None, limit, band),
            Verdict::Inconclusive
        );
        assert_eq!(
            Guarded.decide(1.0, Some(f64::NAN), limit, band),
            Verdict::Inconclusive
        );
        // Simple: the value alone.
        let s = |v: f64| Simple.decide(v, Some(19.3), limit, band);
        assert_eq!(s(12.6), Verdict::Pass);
        assert_eq!(s(18.0), Verdict::Pass);
        assert_eq!(s(18.000_001), Verdict::Marginal);
        assert_eq!(s(20.0), Verdict::Marginal);
        assert_eq!(s(20.000_001), Verdict::Fail);
        // The default is guarded, and a plan can say so either way.
        assert_eq!(Limits::default().decision_rule, Guarded);
        let plan =
            TestPlan::from_toml("[serials]\n1 = \"A\"\n[limits]\ndecision_rule = \"simple\"\n")
                .expect("plan");
        assert_eq!(plan.limits.decision_rule, Simple);
    }

    #[test]
    fn a_value_that_is_not_a_number_never_passes() {
        for rule in [DecisionRule::Guarded, DecisionRule::Simple] {
            for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                assert_eq!(
                    rule.decide(v, Some(0.1), 20.0, 0.9),
                    Verdict::Inconclusive,
                    "{rule:?} {v}"
                );
            }
            assert_eq!(
                rule.decide(1.0, Some(0.1), f64::NAN, 0.9),
                Verdict::Inconclusive
            );
        }
    }

    #[test]
    fn guarded_k2_max_needs_every_mounting_inside_the_limit() {
        use DecisionRule::Guarded;
        // Issue 30's case: P alone straddles the limit (15.99 + 5.39 > 20),
        // while the larger |k2| (N) is well inside: inconclusive, decided by P.
        let both = [(15.99, Some(5.39)), (-17.49, Some(0.10))];
        assert_eq!(
            Guarded.decide_all(&both, 20.0, 0.9),
            (Verdict::Inconclusive, Some(0))
        );
        // Every mounting inside with its U: the larger |k2| decides (marginal here).
        let inside = [(10.0, Some(1.0)), (-18.5, Some(1.0))];
        assert_eq!(
            Guarded.decide_all(&inside, 20.0, 0.9),
            (Verdict::Marginal, Some(1))
        );
        // Any mounting beyond with its U: fail.
        let beyond = [(25.0, Some(1.0)), (-1.0, Some(30.0))];
        assert_eq!(
            Guarded.decide_all(&beyond, 20.0, 0.9),
            (Verdict::Fail, Some(0))
        );
        assert_eq!(
            Guarded.decide_all(&[], 20.0, 0.9),
            (Verdict::Inconclusive, None)
        );
    }

    fn station(slots_modules: usize) -> StationConfig {
        let fmu: String = (0..slots_modules)
            .map(|i| format!("[[fmu]]\nname = \"f{i}\"\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n"))
            .collect();
        StationConfig::from_toml(&format!(
            "[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\ninstrument_supply = \"rails\"\n\
             [centrifuge]\nname = \"t\"\nmax_rate_deg_s = 2400\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n\
             dialect = {{ kind = \"acutrol\" }}\n{fmu}\
             [[power_supply]]\nname = \"rails\"\nchannels = 2\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n"
        ))
        .expect("station")
    }

    #[test]
    fn the_default_is_what_an_empty_plan_file_means() {
        let parsed = TestPlan::from_toml("[serials]\n1 = \"A\"").expect("plan");
        let mut default = TestPlan::default();
        default.serials.insert("1".into(), "A".into());
        assert_eq!(parsed, default);
    }

    #[test]
    fn prefixes_fix_mountings_and_passes_follow() {
        let st = station(2);
        let plan =
            TestPlan::from_toml("[serials]\n1 = \"P:A\"\n2 = \"N:B\"\n7 = \"P:C\"").expect("plan");
        let c = plan.compile(&st).expect("compile");
        // Every serial has a prefix: one mixed pass.
        assert_eq!(c.passes.len(), 1);
        assert_eq!(c.passes[0][0], Some(Mount::P));
        assert_eq!(c.passes[0][1], Some(Mount::N));
        assert_eq!(c.passes[0][2], None);
        assert_eq!(c.serials[1].as_deref(), Some("B"));
        // The published table up and down: 16 levels → 31 level steps.
        let levels = c
            .steps
            .iter()
            .filter(|s| matches!(s, Step::Level { .. }))
            .count();
        assert_eq!(levels, 31);
        let both =
            TestPlan::from_toml("passes = [\"P\", \"N\"]\n[serials]\n1 = \"A\"\n2 = \"N:B\"")
                .expect("plan");
        let c = both.compile(&st).expect("compile");
        assert_eq!(c.passes.len(), 2);
        assert_eq!(c.passes[0][1], None, "an N-only serial sits out the P pass");
        assert_eq!(c.passes[1][1], Some(Mount::N));
        // With only N-fixed instruments the P pass is not spun at all.
        let n_only = TestPlan::from_toml("passes = [\"P\", \"N\"]\n[serials]\n2 = \"N:B\"")
            .expect("plan")
            .compile(&st)
            .expect("compile");
        assert_eq!(n_only.passes.len(), 1);
        assert_eq!(n_only.passes[0][1], Some(Mount::N));
    }

    #[test]
    fn bad_plans_name_the_key() {
        let st = station(1);
        let cases = [
            (
                "[serials]\n9 = \"A\"",
                "serials.9: slots are numbered 1 to 6",
            ),
            (
                "[serials]\n1 = \"X:A\"",
                "serials.1: 'X:' is not a mounting prefix",
            ),
            (
                "[serials]\n1 = \"A\"\n2 = \"N:A\"",
                "serials.2: 'A' is already in slot 1",
            ),
            (
                "[serials]\n1 = \"P:\"",
                "serials.1: the serial number is empty",
            ),
            (
                "levels = [0, 1, 2]\n[serials]\n1 = \"A\"",
                "levels: 3 levels",
            ),
            (
                "levels = [0, 2, 1, 3, 4, 5]\n[serials]\n1 = \"A\"",
                "strictly ascending",
            ),
            (
                "order = 4\n[serials]\n1 = \"A\"",
                "order: 4 is not 1, 2 or 3",
            ),
            ("[serials]", "serials: no instrument"),
        ];
        for (text, want) in cases {
            let e = TestPlan::from_toml(text)
                .expect("parses")
                .compile(&st)
                .expect_err(text)
                .to_string();
            assert!(e.contains(want), "{text}: {e}");
        }
        let e = TestPlan::from_toml("rnage_g = 5")
            .expect_err("unknown key")
            .to_string();
        assert!(e.contains("rnage_g"), "{e}");
    }

    #[test]
    fn a_slot_written_two_ways_is_refused_not_dropped() {
        // Issue 27, item 11: "01" beside "1" named slot 1 twice; one
        // instrument was silently dropped.
        let station = station(1);
        for key in ["01", "+1", " 1"] {
            let text = format!("[serials]\n1 = \"A\"\n\"{key}\" = \"B\"\n");
            let plan = TestPlan::from_toml(&text).expect("plan");
            let e = plan.compile(&station).expect_err(key);
            assert_eq!(e.key, format!("serials.{key}"), "{e}");
        }
        let plan = TestPlan::from_toml("[serials]\n1 = \"A\"\n2 = \"B\"\n").expect("plan");
        assert!(plan.compile(&station).is_ok());
    }

    #[test]
    fn two_counter_modules_of_one_name_are_refused() {
        // Issue 27, item 28.
        let fmu =
            "[[fmu]]\nname = \"f\"\ntransport = { kind = \"tcp\", address = \"127.0.0.1:1\" }\n";
        let text = format!(
            "[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\ninstrument_supply = \"rails\"\n\
             [centrifuge]\nname = \"t\"\nmax_rate_deg_s = 2400\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n\
             dialect = {{ kind = \"acutrol\" }}\n{fmu}{fmu}\
             [[power_supply]]\nname = \"rails\"\nchannels = 2\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n"
        );
        let e = StationConfig::from_toml(&text).expect_err("two modules named f");
        assert!(e.to_string().contains("fmu[1].name"), "{e}");
    }

    #[test]
    fn a_temperature_the_station_would_stop_at_is_refused_before_anything_moves() {
        // Issue 27, item 16: 70 °C on a station with instrument_max_c = 40.
        let fmu =
            "[[fmu]]\nname = \"f\"\ntransport = { kind = \"tcp\", address = \"127.0.0.1:1\" }\n";
        let text = format!(
            "[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\ninstrument_supply = \"rails\"\n\
             [temperature]\ninstrument_max_c = 40\n\
             [chamber]\nname = \"c\"\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n\
             protocol = {{ kind = \"modbus-rtu\", unit_id = 1, setpoint = 100, process_value = 101, run = 102, alarms = 103, counts_per_c = 10 }}\n\
             [centrifuge]\nname = \"t\"\nmax_rate_deg_s = 2400\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n\
             dialect = {{ kind = \"acutrol\" }}\n{fmu}\
             [[power_supply]]\nname = \"rails\"\nchannels = 2\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n"
        );
        let station = StationConfig::from_toml(&text).expect("station");
        let hot =
            TestPlan::from_toml("temperatures_c = [25, 70]\n[serials]\n1 = \"A\"\n").expect("plan");
        let e = hot.compile(&station).expect_err("70 °C over a 40 °C limit");
        assert_eq!(e.key, "temperatures_c", "{e}");
        assert!(e.to_string().contains("instrument_max_c"), "{e}");
        let mild =
            TestPlan::from_toml("temperatures_c = [25, 35]\n[serials]\n1 = \"A\"\n").expect("plan");
        assert!(mild.compile(&station).is_ok());
    }

    #[test]
    fn look_alike_serials_are_one_serial_and_invisible_characters_are_refused() {
        // Issue 27, item 24: a fullwidth Ａ is A (so the second is refused
        // as the same instrument); a zero-width space or a right-to-left
        // override is refused, naming the character.
        let station = station(1);
        let plan = TestPlan::from_toml("[serials]\n1 = \"A1\"\n2 = \"\u{FF21}1\"\n").expect("plan");
        let e = plan.compile(&station).expect_err("A1 twice");
        assert!(e.to_string().contains("already in slot 1"), "{e}");
        for odd in ["A\u{200B}1", "\u{202E}A1"] {
            let text = format!("[serials]\n1 = \"{odd}\"\n");
            let plan = TestPlan::from_toml(&text).expect("plan");
            let e = plan.compile(&station).expect_err(odd);
            assert!(e.to_string().contains("invisible character"), "{e}");
        }
        let plan = TestPlan::from_toml("[serials]\n1 = \"\u{FF21}7\"\n").expect("plan");
        assert_eq!(
            plan.compile(&station).expect("plan").serials[0].as_deref(),
            Some("A7")
        );
    }
}
