//! Retest: from a finished run, a plan that tests again
//! only its instruments that failed, were inconclusive, were not fully
//! measured or were flagged, with the same serials, slots and plan, and
//! `retest_of` naming the original (the store keeps the link both ways).

use crate::executor::sequential::flagged_levels;
use crate::plan::{SequentialConfig, TestPlan};
use crate::record::{Outcome, ReasonCode, UnitRecord};
use serde::Serialize;
use spinbench_analysis::Mount;

/// The reasons that flag an instrument for a retest whatever its outcome.
pub const FLAGS: [ReasonCode; 2] = [ReasonCode::TemperatureUnsettled, ReasonCode::K2Inconclusive];

pub use crate::bounds::is_run_id;

/// Whether an instrument's record calls for a retest: inconclusive,
/// incomplete, or flagged by one of [`FLAGS`]. A plain fail does not: it
/// was decided against the limit with its U95, and the same instrument
/// measured again fails again; it is set aside, or retested on purpose
/// ([`may_retest`], [`RetestChoice::include_fails`]).
pub fn needs_retest(record: &UnitRecord) -> bool {
    matches!(record.outcome, Outcome::Inconclusive | Outcome::Incomplete)
        || record.reasons.iter().any(|r| FLAGS.contains(&r.code))
}

/// Whether an instrument may be named in a retest: one that needs it, or
/// a fail retested on purpose.
pub fn may_retest(record: &UnitRecord) -> bool {
    needs_retest(record) || record.outcome == Outcome::Fail
}

/// Which instruments a retest takes besides those that need one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RetestChoice {
    /// The plain fails too (an engineer who doubts the fixture or the
    /// cable); by default they are set aside.
    pub include_fails: bool,
}

impl RetestChoice {
    /// Whether the retest takes `record`.
    pub fn takes(self, record: &UnitRecord) -> bool {
        needs_retest(record) || (self.include_fails && record.outcome == Outcome::Fail)
    }
}

/// Why no retest plan could be made.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RetestError {
    /// Every instrument was decided (passed, marginal or failed) with
    /// nothing flagged.
    #[error(
        "nothing to retest in run {0}: every instrument was decided (pass or fail) with nothing flagged; a clear fail is set aside (retest it on purpose with --include-fails)"
    )]
    NothingToRetest(String),
    /// The run has no results yet.
    #[error("run {0} has no graded results yet: wait for it to finish, then retest it")]
    NotGraded(String),
    /// The run id is not one.
    #[error("'{0}' is not a run identifier")]
    BadRunId(String),
}

/// The plan that retests `run_id`: `original` with only the slots whose
/// records the `choice` takes, `retest_of` set, and the name marked.
pub fn retest_plan(
    run_id: &str,
    original: &TestPlan,
    records: &[UnitRecord],
    choice: RetestChoice,
) -> Result<(TestPlan, Vec<String>), RetestError> {
    if !is_run_id(run_id) {
        return Err(RetestError::BadRunId(run_id.chars().take(80).collect()));
    }
    if records.is_empty() {
        return Err(RetestError::NotGraded(run_id.to_string()));
    }
    let again: Vec<&UnitRecord> = records.iter().filter(|r| choice.takes(r)).collect();
    if again.is_empty() {
        return Err(RetestError::NothingToRetest(run_id.to_string()));
    }
    let mut plan = original.clone();
    // The same plan reproduces the same interval (the instrument's dips and
    // noise are its own): a retest measures until the verdict is certain,
    // and a designed one aims under what would decide the closest.
    if plan.sequential.is_none() && plan.temperatures_c.is_empty() {
        plan.sequential = Some(SequentialConfig {
            max_levels_per_pass: RETEST_SEQUENTIAL_LEVELS,
        });
    }
    if plan.is_auto()
        && let Some(closest) = again
            .iter()
            .filter_map(|r| judged(r).map(|j| j.deciding_u95()))
            .filter(|u| u.is_finite() && *u > 0.0)
            .min_by(f64::total_cmp)
    {
        let aim = RETEST_TARGET_FRACTION * closest;
        plan.target_k2_u95_ug_per_g2 = Some(
            plan.target_k2_u95_ug_per_g2
                .map_or(aim, |t| t.min(aim))
                .max(MIN_RETEST_TARGET_UG_PER_G2),
        );
    }
    // Plan slots are 1-based; a record's slot is 0-based.
    plan.serials.retain(|slot, _| {
        slot.parse::<usize>()
            .is_ok_and(|s| again.iter().any(|r| r.slot + 1 == s))
    });
    plan.retest_of = Some(run_id.to_string());
    if !plan.name.starts_with("retest of ") {
        plan.name = format!("retest of {}", plan.name)
            .chars()
            .take(crate::bounds::MAX_NAME_CHARS)
            .collect();
    }
    let serials = again.iter().map(|r| r.serial.clone()).collect();
    Ok((plan, serials))
}

/// The levels chosen by the data per mounting in a retest whose plan
/// had none (the shipped check's budget).
pub const RETEST_SEQUENTIAL_LEVELS: u32 = 12;

/// A designed retest aims its K2 U95 at this fraction of the closest
/// instrument's distance from the limit: the value it reproduces moves
/// by its own scatter too.
pub const RETEST_TARGET_FRACTION: f64 = 0.8;

/// The smallest K2 U95 a retest is designed for [µg/g²]: below it the
/// planner's model of the station (its noise and the table) is the
/// limit, not the dwell.
pub const MIN_RETEST_TARGET_UG_PER_G2: f64 = 0.2;

/// What was judged of an inconclusive instrument: the value, its U95
/// and the limit.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Judged {
    value_ug_per_g2: f64,
    u95_ug_per_g2: f64,
    limit_ug_per_g2: f64,
}

impl Judged {
    /// The U95 under which the same value is decided: its distance from
    /// the limit (the guarded rule grades when |value| ± U95 clears it).
    fn deciding_u95(&self) -> f64 {
        (self.value_ug_per_g2.abs() - self.limit_ug_per_g2).abs()
    }
}

/// The judged value of an inconclusive record, its U95 and its limit.
fn judged(record: &UnitRecord) -> Option<Judged> {
    if record.outcome != Outcome::Inconclusive {
        return None;
    }
    let j = record.judged()?;
    Some(Judged {
        value_ug_per_g2: j.value_ug_per_g2?,
        u95_ug_per_g2: j.u95_ug_per_g2?,
        limit_ug_per_g2: j.limit_ug_per_g2,
    })
}

/// A level an instrument's reduction found off its curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LevelOffCurve {
    /// The mounting.
    pub mount: Mount,
    /// The level [g].
    pub g: f64,
}

/// What a retest can do for one inconclusive instrument, said before it
/// runs: what would decide it, what widened its interval, and whether the
/// retest plan is predicted to get there (method.md §6).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RetestAdvice {
    /// The instrument.
    pub serial: String,
    /// Its slot (from 1).
    pub slot: usize,
    /// The judged value (K2 or k2_max, as the plan says) [µg/g²].
    pub value_ug_per_g2: f64,
    /// Its U95 in the run [µg/g²].
    pub u95_ug_per_g2: f64,
    /// The limit [µg/g²].
    pub limit_ug_per_g2: f64,
    /// The U95 under which the same value is decided: its distance from
    /// the limit [µg/g²].
    pub deciding_u95_ug_per_g2: f64,
    /// Its levels off the curve, where the retest adds levels beside.
    pub off_curve: Vec<LevelOffCurve>,
    /// The retest plan's predicted K2 U95 [µg/g²] (none: no prediction).
    pub predicted_u95_ug_per_g2: Option<f64>,
    /// Whether the retest is predicted to decide it, its value unchanged:
    /// its predicted U95 under the deciding one (none: no prediction).
    pub can_decide: Option<bool>,
    /// The runs it came out inconclusive in: this one and the runs it
    /// retests, one after the other (1: this run only).
    pub inconclusive_runs: usize,
}

impl RetestAdvice {
    /// The advice in English, one line.
    pub fn text(&self) -> String {
        let off = if self.off_curve.is_empty() {
            "no level off its curve".to_string()
        } else {
            let levels: Vec<String> = self
                .off_curve
                .iter()
                .map(|l| format!("{} {} g", l.mount, l.g))
                .collect();
            format!(
                "off its curve at {} (the retest adds levels beside)",
                levels.join(", ")
            )
        };
        let verdict = match (self.can_decide, self.predicted_u95_ug_per_g2) {
            (Some(true), Some(p)) => {
                format!("the retest's predicted U95 {p:.3} can decide it if its value holds")
            }
            (Some(false), Some(p)) => format!(
                "no retest this station runs is predicted to decide it (predicted U95 {p:.3}): judge it by review or set it aside"
            ),
            _ => "no prediction for the retest".to_string(),
        };
        let tries = if self.inconclusive_runs > 1 {
            format!(" (inconclusive in {} runs)", self.inconclusive_runs)
        } else {
            String::new()
        };
        format!(
            "{}{tries}: {:.3} ± {:.3} µg/g² against {}: decided by a U95 under {:.3}; {off}; {verdict}",
            self.serial,
            self.value_ug_per_g2,
            self.u95_ug_per_g2,
            self.limit_ug_per_g2,
            self.deciding_u95_ug_per_g2,
        )
    }
}

/// The advice for every inconclusive instrument of `records`, against the
/// retest plan's predicted K2 U95 (`predicted_u95`, from
/// [`TestPlan::designed`]). On the plan's own levels (`designed` false) an
/// instrument with no level off its curve gets its own U95 again: the
/// same levels reproduce it, and the levels the data add serve a dip.
pub fn retest_advice(
    records: &[UnitRecord],
    predicted_u95: Option<f64>,
    designed: bool,
) -> Vec<RetestAdvice> {
    records
        .iter()
        .filter_map(|r| {
            let j = judged(r)?;
            let off_curve = [Mount::P, Mount::N]
                .into_iter()
                .flat_map(|mount| {
                    flagged_levels(r, mount)
                        .into_iter()
                        .map(move |g| LevelOffCurve { mount, g })
                })
                .collect();
            let deciding = j.deciding_u95();
            let off_curve: Vec<LevelOffCurve> = off_curve;
            let predicted_u95 = if designed || !off_curve.is_empty() {
                predicted_u95
            } else {
                Some(j.u95_ug_per_g2)
            };
            Some(RetestAdvice {
                serial: r.serial.clone(),
                slot: r.slot + 1,
                value_ug_per_g2: j.value_ug_per_g2,
                u95_ug_per_g2: j.u95_ug_per_g2,
                limit_ug_per_g2: j.limit_ug_per_g2,
                deciding_u95_ug_per_g2: deciding,
                off_curve,
                predicted_u95_ug_per_g2: predicted_u95,
                can_decide: predicted_u95.map(|p| p < deciding),
                inconclusive_runs: 1,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Reason;

    fn record(slot: usize, serial: &str, outcome: Outcome, reasons: Vec<Reason>) -> UnitRecord {
        UnitRecord {
            slot,
            serial: serial.into(),
            tumble: None,
            cross_axis_ug_per_g: None,
            drawing_radius_m: 1.0,
            radius_m: Default::default(),
            radius_reading_u_ppm: Default::default(),
            points: Vec::new(),
            analysis: None,
            k2_max_ug_per_g2: None,
            outcome,
            reasons,
            decision_rule: None,
            decision: None,
            table_signature: None,
            at_temperatures: Vec::new(),
            temperature_coefficients: None,
            exclusions: Vec::new(),
        }
    }

    #[test]
    fn only_the_inconclusive_incomplete_and_flagged_are_tested_again_and_fails_on_purpose() {
        let plan = TestPlan::from_toml(
            "name = \"batch 7\"\n[serials]\n1 = \"P:A\"\n2 = \"P:B\"\n3 = \"N:C\"\n4 = \"D\"\n5 = \"E\"\n6 = \"F\"\n",
        )
        .expect("plan");
        let records = vec![
            record(0, "A", Outcome::Pass, vec![]),
            record(1, "B", Outcome::Fail, vec![]),
            record(2, "C", Outcome::Inconclusive, vec![]),
            record(3, "D", Outcome::Incomplete, vec![]),
            record(
                4,
                "E",
                Outcome::Pass,
                vec![Reason::new(ReasonCode::TemperatureUnsettled, "moved")],
            ),
            record(5, "F", Outcome::Marginal, vec![]),
        ];
        // The clear fail is set aside by default.
        let (again, serials) =
            retest_plan("run-1-ab", &plan, &records, RetestChoice::default()).expect("retest");
        assert_eq!(serials, ["C", "D", "E"]);
        let everyone = RetestChoice {
            include_fails: true,
        };
        let (again_with_fails, serials) =
            retest_plan("run-1-ab", &plan, &records, everyone).expect("retest");
        assert_eq!(serials, ["B", "C", "D", "E"]);
        assert!(again_with_fails.serials.contains_key("2"));
        let kept: Vec<(&str, &str)> = again
            .serials
            .iter()
            .map(|(k, v)| (k.as_str(), v.as_str()))
            .collect();
        // Same slots, same serials with their mountings.
        assert_eq!(kept, [("3", "N:C"), ("4", "D"), ("5", "E")]);
        assert_eq!(again.retest_of.as_deref(), Some("run-1-ab"));
        assert_eq!(again.name, "retest of batch 7");
        again.validate().expect("a valid plan");
        // Through TOML and back: the link survives.
        let text = toml::to_string(&again).expect("toml");
        assert_eq!(TestPlan::from_toml(&text).expect("parsed"), again);

        let decided = vec![
            record(0, "A", Outcome::Pass, vec![]),
            record(1, "B", Outcome::Fail, vec![]),
        ];
        assert_eq!(
            retest_plan("run-1-ab", &plan, &decided, RetestChoice::default()),
            Err(RetestError::NothingToRetest("run-1-ab".into()))
        );
        assert!(matches!(
            retest_plan("run-1-ab", &plan, &[], RetestChoice::default()),
            Err(RetestError::NotGraded(_))
        ));
        assert!(matches!(
            retest_plan("../etc", &plan, &records, RetestChoice::default()),
            Err(RetestError::BadRunId(_))
        ));
    }

    /// An instrument graded on points of both mountings, 0–70 g up and
    /// down: its K2 `k2_even` [µg/g²], ±60 µg of scatter, and an activity
    /// dip of `dip_ug` at 40 g in mounting P.
    fn graded(serial: &str, slot: usize, k2_even: f64, dip_ug: f64) -> UnitRecord {
        use spinbench_analysis::model::ieee1293_output;
        use spinbench_analysis::points::{infer_directions, published_levels, up_down};
        use spinbench_analysis::{AnalysisOptions, AnomalyRule, Point};
        let k1 = 46.5;
        let mut state: u64 = 7 + slot as u64;
        let mut points = Vec::new();
        for mount in [Mount::P, Mount::N] {
            let mut pass: Vec<Point> = up_down(&published_levels(70.0))
                .into_iter()
                .map(|g| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    let scatter = (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0;
                    let dip = if mount == Mount::P && g == 40.0 {
                        dip_ug
                    } else {
                        0.0
                    };
                    let k = [0.01, k1, k2_even * 1e-6, 0.05e-6];
                    Point {
                        mount,
                        g_nominal: g,
                        g_applied: g,
                        output: ieee1293_output(k, mount.input_sign() * g)
                            + k1 * (60.0 * scatter + dip) * 1e-6,
                        direction: None,
                    }
                })
                .collect();
            infer_directions(&mut pass);
            points.extend(pass);
        }
        let options = AnalysisOptions {
            anomalies: AnomalyRule::Flag,
            ..AnalysisOptions::default()
        };
        let limits = crate::plan::Limits::default();
        let g = crate::judgement::grade(serial, points, options, &limits, None);
        UnitRecord {
            analysis: g.analysis,
            k2_max_ug_per_g2: g.k2_max_ug_per_g2,
            outcome: g.outcome,
            reasons: g.reasons,
            decision: Some(limits.decision()),
            ..record(slot, serial, g.outcome, Vec::new())
        }
    }

    #[test]
    fn a_record_says_what_its_verdict_judged_in_one_reading() {
        let y = graded("Y", 1, 5.0, 0.0);
        let j = y.judged().expect("judged");
        assert_eq!(j.measurand, crate::plan::Measurand::K2);
        let (value, u95) = (
            j.value_ug_per_g2.expect("K2"),
            j.u95_ug_per_g2.expect("U95"),
        );
        assert!((value - 5.0).abs() <= u95, "{value} ± {u95}");
        assert_eq!(j.limit_ug_per_g2, 20.0);
        assert!(y.judged_text().starts_with("K2 +"), "{}", y.judged_text());
        // Judged on k2_max: the larger mounting's k2, with its own U95.
        let mut decision = crate::plan::Limits::default().decision();
        decision.measurand = crate::plan::Measurand::K2Max;
        let by_max = UnitRecord {
            decision: Some(decision),
            ..y.clone()
        };
        let j = by_max.judged().expect("judged");
        assert_eq!(j.value_ug_per_g2, y.k2_max_ug_per_g2);
        assert!(j.u95_ug_per_g2.is_some());
        // A record from before decisions were recorded says so.
        let old = UnitRecord {
            decision: None,
            ..y
        };
        assert_eq!(old.judged(), None);
        assert!(
            old.judged_text().contains("limit not recorded"),
            "{}",
            old.judged_text()
        );
    }

    #[test]
    fn an_inconclusive_instrument_is_told_what_decides_it_and_the_retest_measures_until_certain() {
        // On the limit (20 µg/g²) with a dip: inconclusive; far under it: a pass.
        let records = vec![graded("X", 0, 20.3, -6_000.0), graded("Y", 1, 5.0, 0.0)];
        assert_eq!(
            records[0].outcome,
            Outcome::Inconclusive,
            "{:?}",
            records[0].reasons
        );
        assert_eq!(
            records[1].outcome,
            Outcome::Pass,
            "{:?}",
            records[1].reasons
        );
        let plan = TestPlan::from_toml(
            "levels = \"auto\"\ntarget_k2_u95_ug_per_g2 = 8\n[serials]\n1 = \"X\"\n2 = \"Y\"\n",
        )
        .expect("plan");
        let (again, serials) =
            retest_plan("run-1-ab", &plan, &records, RetestChoice::default()).expect("retest");
        assert_eq!(serials, ["X"]);
        // Measured until certain, designed under what would decide X.
        assert_eq!(
            again.sequential.map(|q| q.max_levels_per_pass),
            Some(RETEST_SEQUENTIAL_LEVELS)
        );
        let advice = retest_advice(&records, Some(0.5), true);
        assert_eq!(advice.len(), 1, "only the inconclusive: {advice:?}");
        let a = &advice[0];
        assert_eq!((a.serial.as_str(), a.slot), ("X", 1));
        let deciding = (a.value_ug_per_g2.abs() - 20.0).abs();
        assert!((a.deciding_u95_ug_per_g2 - deciding).abs() < 1e-12);
        assert!(a.u95_ug_per_g2 > deciding, "{a:?}");
        let target = again.target_k2_u95_ug_per_g2.expect("a target");
        assert!(
            (target - (RETEST_TARGET_FRACTION * deciding).max(MIN_RETEST_TARGET_UG_PER_G2)).abs()
                < 1e-12,
            "target {target} for a distance {deciding}"
        );
        assert!(
            a.off_curve
                .iter()
                .any(|l| l.mount == Mount::P && l.g == 40.0),
            "{a:?}"
        );
        assert_eq!(a.can_decide, Some(0.5 < deciding));
        assert!(a.text().contains("P 40 g"), "{}", a.text());
        // A prediction wider than the distance: no retest decides it, said so.
        let hopeless = retest_advice(&records, Some(deciding + 1.0), true);
        assert_eq!(hopeless[0].can_decide, Some(false));
        assert!(
            hopeless[0].text().contains("judge it by review"),
            "{}",
            hopeless[0].text()
        );
        let again_and_again = RetestAdvice {
            inconclusive_runs: 3,
            ..hopeless[0].clone()
        };
        assert!(
            again_and_again
                .text()
                .starts_with("X (inconclusive in 3 runs): "),
            "{}",
            again_and_again.text()
        );
        // On the plan's own levels, an instrument with no level off its
        // curve would get its interval again.
        let mut clean = records[0].clone();
        if let Some(a) = clean.analysis.as_mut() {
            a.rule_exclusions.clear();
            for f in a.fits.values_mut() {
                if let Some(d) = f.diagnostics.as_mut() {
                    d.outlier_levels.clear();
                }
            }
        }
        let same = retest_advice(std::slice::from_ref(&clean), Some(0.01), false);
        assert_eq!(same[0].predicted_u95_ug_per_g2, Some(a.u95_ug_per_g2));
        assert_eq!(same[0].can_decide, Some(false));
        // A plan at several temperatures is not made sequential.
        let hot = TestPlan {
            temperatures_c: vec![25.0, 60.0],
            ..plan.clone()
        };
        let (again, _) =
            retest_plan("run-1-ab", &hot, &records, RetestChoice::default()).expect("retest");
        assert_eq!(again.sequential, None);
    }

    #[test]
    fn a_retest_of_that_is_not_a_run_id_is_refused_naming_the_key() {
        let e = TestPlan::from_toml("retest_of = \"a b\"\n[serials]\n1 = \"A\"\n")
            .expect_err("not an id");
        assert_eq!(e.key, "retest_of");
    }
}
