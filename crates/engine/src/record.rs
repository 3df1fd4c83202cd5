//! Per-instrument records (OpenHTF's "every unit under test gets its own
//! record with an outcome").

use serde::{Deserialize, Serialize};
use spinbench_analysis::unit::UnitAnalysis;
use spinbench_analysis::{Direction, Mount};
use std::collections::BTreeMap;

/// One averaged point of one instrument.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointRecord {
    /// Slot (0-based).
    pub slot: usize,
    /// Mounting.
    pub mount: Mount,
    /// Nominal level [g].
    pub g_nominal: f64,
    /// Ascending or descending.
    pub direction: Direction,
    /// Acceleration applied at this instrument's own radius, method.md (9) [g].
    pub g_applied: f64,
    /// Mean measured rate during the dwell [deg/s].
    pub rate_deg_s: f64,
    /// Mean dF [Hz].
    pub output_hz: f64,
    /// Standard deviation of the one-second values [Hz].
    pub std_hz: f64,
    /// Number of one-second values.
    pub n: u32,
    /// Station time of the first and last value [s].
    pub time_s: [f64; 2],
    /// The chamber's setpoint while the point was taken [°C] (absent: no chamber).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setpoint_c: Option<f64>,
    /// Mean of the instrument's temperature over the point's values [°C]
    /// (as its counter module reports it; absent when it reports none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature_c: Option<f64>,
    /// Its change over the point: highest minus lowest [°C].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature_change_c: Option<f64>,
    /// Mean f1 + f2 [Hz], the resonators' common mode: a thermal proxy
    /// (it moves with temperature, hardly with acceleration).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resonator_sum_hz: Option<f64>,
    /// Its change over the point: highest minus lowest, relative [ppm].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resonator_sum_change_ppm: Option<f64>,
    /// Taken while the temperature changed by more than the plan's
    /// `stability.temperature_change_max_c` and it could not be measured
    /// again within `max_restarts`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub temperature_unsettled: bool,
}

/// Pass, fail, marginal, inconclusive (the interval straddles a limit), or
/// incomplete (never graded).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Within the limits.
    Pass,
    /// Within the limits but close to them.
    Marginal,
    /// Outside the limits, dead, noisy, or not measurable.
    Fail,
    /// Under the guarded decision rule (ISO 14253-1, ILAC-G8) the interval
    /// value ± U straddles a limit: neither pass nor fail; retest advised.
    Inconclusive,
    /// The run ended (aborted, faulted) before this instrument's part of
    /// the plan was done: not graded, the reasons say why.
    Incomplete,
}

/// The stable code of a reason (its serde name is what is stored and sent).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ReasonCode {
    /// No output from its resonators at the alive check.
    Dead,
    /// No output during a measuring step.
    NoOutput,
    /// Its own one-second scatter above `stability.noise_limit_ug`.
    Noisy,
    /// Its output kept drifting while the others settled.
    Drifting,
    /// The tumble could not calibrate it.
    TumbleFailed,
    /// Its radius could not be found.
    RadiusFailed,
    /// No point was taken.
    NoPoints,
    /// Its points could not be reduced.
    CannotReduce,
    /// |k2| above its limit.
    K2OverLimit,
    /// |k2| within the marginal band of its limit.
    K2NearLimit,
    /// |k2| ± U95 straddles its limit (guarded decision rule): retest.
    K2Inconclusive,
    /// Scale-factor nonlinearity above its limit.
    NonlinearityOverLimit,
    /// Nonlinearity within the marginal band.
    NonlinearityNearLimit,
    /// |Asymmetry| above its limit.
    AsymmetryOverLimit,
    /// |Asymmetry| within the marginal band.
    AsymmetryNearLimit,
    /// |Hysteresis| above its limit.
    HysteresisOverLimit,
    /// |Hysteresis| within the marginal band.
    HysteresisNearLimit,
    /// The model order has no k2 to judge.
    NoK2,
    /// A note of the reduction (a secondary result left out, and why).
    AnalysisNote,
    /// The run ended before its part of the plan was done.
    Incomplete,
    /// Points were taken while its temperature moved more than the plan allows.
    TemperatureUnsettled,
    /// It reported a temperature above the station's limit: the run stopped.
    OverTemperature,
    /// Anything else (and every reason of a record written before codes existed).
    #[default]
    Other,
}

/// One reason of an outcome: its code, its text (English) and the values
/// its text was made from, by name, so a report in another language words it
/// from the catalogue's `reason.<code>`. Reads a bare text
/// (as records written before codes existed hold) with the code `other`,
/// and a coded reason written before arguments existed with none.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(from = "ReasonStored")]
pub struct Reason {
    /// The stable code.
    pub code: ReasonCode,
    /// The text, for people (English).
    pub text: String,
    /// The values in the text, by name (numbers as shown, words as codes).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub args: BTreeMap<String, String>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum ReasonStored {
    Coded {
        code: ReasonCode,
        text: String,
        #[serde(default)]
        args: BTreeMap<String, String>,
    },
    Text(String),
}

impl From<ReasonStored> for Reason {
    fn from(stored: ReasonStored) -> Reason {
        match stored {
            ReasonStored::Coded { code, text, args } => Reason { code, text, args },
            ReasonStored::Text(text) => Reason {
                code: ReasonCode::Other,
                text,
                args: BTreeMap::new(),
            },
        }
    }
}

impl Reason {
    /// A reason with its code.
    pub fn new(code: ReasonCode, text: impl Into<String>) -> Reason {
        Reason {
            code,
            text: text.into(),
            args: BTreeMap::new(),
        }
    }

    /// The same reason with one more named value of its text.
    #[must_use]
    pub fn with(mut self, name: &str, value: impl ToString) -> Reason {
        self.args.insert(name.to_string(), value.to_string());
        self
    }

    /// Its code's serde name (`k2_over_limit`), the catalogue's key after `reason.`.
    pub fn code_name(&self) -> String {
        serde_json::to_value(self.code)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_else(|| "other".to_string())
    }
}

/// A reason reads as its text (`reason.contains("noisy")`).
impl std::ops::Deref for Reason {
    type Target = str;
    fn deref(&self) -> &str {
        &self.text
    }
}

/// Reasons join as texts (`record.reasons.join("; ")`).
impl std::borrow::Borrow<str> for Reason {
    fn borrow(&self) -> &str {
        &self.text
    }
}

impl std::fmt::Display for Reason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.text)
    }
}

impl Outcome {
    /// Every outcome.
    pub const ALL: [Outcome; 5] = [
        Outcome::Pass,
        Outcome::Marginal,
        Outcome::Fail,
        Outcome::Incomplete,
        Outcome::Inconclusive,
    ];

    /// Its serde name, as stored and shown: `pass`, `marginal`, `fail`, `incomplete`.
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Pass => "pass",
            Outcome::Marginal => "marginal",
            Outcome::Fail => "fail",
            Outcome::Incomplete => "incomplete",
            Outcome::Inconclusive => "inconclusive",
        }
    }

    /// The outcome of its serde name.
    pub fn parse(name: &str) -> Option<Outcome> {
        Outcome::ALL.into_iter().find(|o| o.as_str() == name)
    }
}

impl std::fmt::Display for Outcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
    }
}

impl PointRecord {
    /// The point as the reduction takes it.
    pub fn point(&self) -> spinbench_analysis::Point {
        spinbench_analysis::Point {
            mount: self.mount,
            g_nominal: self.g_nominal,
            g_applied: self.g_applied,
            output: self.output_hz,
            direction: Some(self.direction),
        }
    }
}

/// Everything the station found for one instrument.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnitRecord {
    /// Slot (0-based).
    pub slot: usize,
    /// Serial number.
    pub serial: String,
    /// Tumble bias k0' [Hz] and scale factor k1' [Hz/g] (method.md (5)).
    pub tumble: Option<[f64; 2]>,
    /// Sensitivity to gravity across the input axis, from a four-position
    /// tumble [µg/g] (taken out of the radius; `None` with two positions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cross_axis_ug_per_g: Option<f64>,
    /// Drawing radius R0 [m].
    pub drawing_radius_m: f64,
    /// Radius found per mounting [m].
    pub radius_m: BTreeMap<Mount, f64>,
    /// Each radius's relative standard uncertainty from its readings' noise [ppm].
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub radius_reading_u_ppm: BTreeMap<Mount, f64>,
    /// The averaged points.
    pub points: Vec<PointRecord>,
    /// The reduction (fits, figures), when it could be made.
    pub analysis: Option<UnitAnalysis>,
    /// The larger |k2| of the mountings [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// Pass, fail, marginal or incomplete.
    pub outcome: Outcome,
    /// Why, when not a plain pass: a stable code (for a line's MES to
    /// filter on) beside the text for people.
    pub reasons: Vec<Reason>,
    /// The decision rule the outcome was judged by (`None` in records made
    /// before the rule was recorded: those compared the value alone).
    #[serde(default)]
    pub decision_rule: Option<crate::plan::DecisionRule>,
    /// What the k2 verdict judged: the quantity (K2 or k2_max), its limit
    /// and the rule (`None` in records made before it was recorded: those
    /// judged k2_max).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decision: Option<crate::plan::Decision>,
    /// The centrifuge's signature learned from the run's instruments that
    /// corrected its points' applied acceleration (`None`: none learned,
    /// or a record made before the station learned its centrifuge).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table_signature: Option<spinbench_analysis::table_signature::TableSignature>,
    /// Its figures at each chamber temperature of the plan (absent without temperatures).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub at_temperatures: Vec<spinbench_analysis::temperature::AtTemperature>,
    /// Its temperature coefficients of k0, k1 and K2, with U95.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature_coefficients: Option<spinbench_analysis::temperature::TemperatureCoefficients>,
    /// The plan's exclusions that removed readings of this instrument (each
    /// with its reason, who, and how many readings).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub exclusions: Vec<spinbench_analysis::exclusion::LevelExclusion>,
}

impl UnitRecord {
    /// The stand-in for a stored record this release cannot read: the
    /// instrument's slot, serial, outcome and k2_max as the store's columns
    /// hold them, no figures, and one reason that says why (a report of
    /// the run still shows its other instruments).
    pub fn unreadable(
        slot: usize,
        serial: &str,
        outcome: Outcome,
        k2_max_ug_per_g2: Option<f64>,
        why: &str,
    ) -> UnitRecord {
        UnitRecord {
            slot,
            serial: serial.to_string(),
            tumble: None,
            cross_axis_ug_per_g: None,
            drawing_radius_m: 0.0,
            radius_m: BTreeMap::new(),
            radius_reading_u_ppm: BTreeMap::new(),
            points: Vec::new(),
            analysis: None,
            k2_max_ug_per_g2,
            outcome,
            reasons: vec![Reason {
                code: ReasonCode::Other,
                text: format!(
                    "its stored record cannot be read by this release ({why}): its figures are not shown; the store keeps the record as it was written"
                ),
                args: BTreeMap::new(),
            }],
            decision_rule: None,
            decision: None,
            table_signature: None,
            at_temperatures: Vec::new(),
            temperature_coefficients: None,
            exclusions: Vec::new(),
        }
    }
}

/// What an instrument's k2 verdict judged: the quantity, its value and
/// U95 as measured, the limit and the rule. The one reading of them every
/// surface shows beside the outcome.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Judged {
    /// The quantity judged.
    pub measurand: crate::plan::Measurand,
    /// Its value (`None` when it was not measured: K2 without both
    /// mountings) [µg/g²].
    pub value_ug_per_g2: Option<f64>,
    /// Its expanded uncertainty at 95 % (`None` when not known) [µg/g²].
    pub u95_ug_per_g2: Option<f64>,
    /// The plan's limit on it [µg/g²].
    pub limit_ug_per_g2: f64,
    /// The decision rule.
    pub rule: crate::plan::DecisionRule,
}

impl Judged {
    /// One line for a table or a log: `K2 +9.603 ± 1.108 µg/g² (limit 20,
    /// guarded)`; a value not measured reads `not measured`.
    pub fn text(&self) -> String {
        let value = match (self.value_ug_per_g2, self.u95_ug_per_g2) {
            (Some(v), Some(u)) => format!("{v:+.3} ± {u:.3} µg/g²"),
            (Some(v), None) => format!("{v:+.3} µg/g² (no U95)"),
            (None, _) => "not measured".to_string(),
        };
        format!(
            "{} {value} (limit {}, {})",
            self.measurand.name(),
            self.limit_ug_per_g2,
            self.rule.name()
        )
    }
}

impl UnitRecord {
    /// What its verdict judged, as [`Judged::text`] says it; a record made
    /// before the decision was recorded judged k2_max, and says so.
    pub fn judged_text(&self) -> String {
        match self.judged() {
            Some(j) => j.text(),
            None => self.k2_max_ug_per_g2.map_or_else(
                || "k2_max not measured".to_string(),
                |k| format!("k2_max {k:.3} µg/g² (limit not recorded)"),
            ),
        }
    }

    /// What its verdict judged; `None` for a record made before the
    /// decision was recorded (it does not say its limit).
    pub fn judged(&self) -> Option<Judged> {
        let decision = self.decision?;
        let analysis = self.analysis.as_ref();
        let (value, u95) = match decision.measurand {
            crate::plan::Measurand::K2 => {
                let joint = analysis.and_then(|a| a.joint.as_ref());
                (
                    joint.map(|j| j.k2_even_ug_per_g2),
                    joint.and_then(|j| j.k2_even_u95),
                )
            }
            crate::plan::Measurand::K2Max => {
                let u95 = analysis
                    .and_then(|a| a.fits.get(&a.k2_max_mount?))
                    .and_then(|f| f.uncertainty.as_ref())
                    .and_then(|u| u.k2_ug_per_g2.as_ref())
                    .map(|u| u.u95);
                (self.k2_max_ug_per_g2, u95)
            }
        };
        Some(Judged {
            measurand: decision.measurand,
            value_ug_per_g2: value,
            u95_ug_per_g2: u95,
            limit_ug_per_g2: decision.limit_ug_per_g2,
            rule: decision.rule,
        })
    }

    /// The stable codes of its reasons, in order (for a line's MES): each
    /// code's serde name, as stored.
    pub fn reason_codes(&self) -> Vec<String> {
        self.reasons
            .iter()
            .filter_map(|r| match serde_json::to_value(r.code) {
                Ok(serde_json::Value::String(name)) => Some(name),
                _ => None,
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outcome_names_are_their_serde_names() {
        for o in Outcome::ALL {
            let json = serde_json::to_string(&o).expect("json");
            assert_eq!(json, format!("\"{}\"", o.as_str()));
            assert_eq!(Outcome::parse(o.as_str()), Some(o));
        }
        assert_eq!(Outcome::parse("PASS"), None);
    }

    #[test]
    fn reasons_carry_a_code_and_old_texts_read_as_other() {
        let r = Reason::new(
            ReasonCode::K2OverLimit,
            "|k2| 21 µg/g² above the limit 20 µg/g²",
        );
        let json = serde_json::to_string(&r).expect("json");
        assert!(json.contains(r#""code":"k2_over_limit""#), "{json}");
        assert_eq!(serde_json::from_str::<Reason>(&json).expect("back"), r);
        let old: Reason = serde_json::from_str(r#""noisy: 400 µg""#).expect("old text");
        assert_eq!(old.code, ReasonCode::Other);
        assert!(old.contains("noisy"));
        assert_eq!(
            [r, old].join("; "),
            "|k2| 21 µg/g² above the limit 20 µg/g²; noisy: 400 µg"
        );
    }
}
