//! Retest: from a finished run, a plan that tests again
//! only its instruments that failed, were inconclusive, were not fully
//! measured or were flagged, with the same serials, slots and plan, and
//! `retest_of` naming the original (the store keeps the link both ways).

use crate::plan::TestPlan;
use crate::record::{Outcome, ReasonCode, UnitRecord};

/// The reasons that flag an instrument for a retest whatever its outcome.
pub const FLAGS: [ReasonCode; 2] = [ReasonCode::TemperatureUnsettled, ReasonCode::K2Inconclusive];

pub use crate::bounds::is_run_id;

/// Whether an instrument's record calls for a retest: failed,
/// inconclusive, incomplete, or flagged by one of [`FLAGS`].
pub fn needs_retest(record: &UnitRecord) -> bool {
    matches!(
        record.outcome,
        Outcome::Fail | Outcome::Inconclusive | Outcome::Incomplete
    ) || record.reasons.iter().any(|r| FLAGS.contains(&r.code))
}

/// Why no retest plan could be made.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RetestError {
    /// Every instrument passed (or was marginal) with nothing flagged.
    #[error("nothing to retest in run {0}: every instrument passed with nothing flagged")]
    NothingToRetest(String),
    /// The run has no results yet.
    #[error("run {0} has no graded results yet: wait for it to finish, then retest it")]
    NotGraded(String),
    /// The run id is not one.
    #[error("'{0}' is not a run identifier")]
    BadRunId(String),
}

/// The plan that retests `run_id`: `original` with only the slots whose
/// records need a retest, `retest_of` set, and the name marked.
pub fn retest_plan(
    run_id: &str,
    original: &TestPlan,
    records: &[UnitRecord],
) -> Result<(TestPlan, Vec<String>), RetestError> {
    if !is_run_id(run_id) {
        return Err(RetestError::BadRunId(run_id.chars().take(80).collect()));
    }
    if records.is_empty() {
        return Err(RetestError::NotGraded(run_id.to_string()));
    }
    let again: Vec<&UnitRecord> = records.iter().filter(|r| needs_retest(r)).collect();
    if again.is_empty() {
        return Err(RetestError::NothingToRetest(run_id.to_string()));
    }
    let mut plan = original.clone();
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
    fn only_the_failed_inconclusive_incomplete_and_flagged_are_tested_again() {
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
        let (again, serials) = retest_plan("run-1-ab", &plan, &records).expect("retest");
        assert_eq!(serials, ["B", "C", "D", "E"]);
        let kept: Vec<(&str, &str)> = again
            .serials
            .iter()
            .map(|(k, v)| (k.as_str(), v.as_str()))
            .collect();
        // Same slots, same serials with their mountings.
        assert_eq!(kept, [("2", "P:B"), ("3", "N:C"), ("4", "D"), ("5", "E")]);
        assert_eq!(again.retest_of.as_deref(), Some("run-1-ab"));
        assert_eq!(again.name, "retest of batch 7");
        again.validate().expect("a valid plan");
        // Through TOML and back: the link survives.
        let text = toml::to_string(&again).expect("toml");
        assert_eq!(TestPlan::from_toml(&text).expect("parsed"), again);

        let all_pass = vec![record(0, "A", Outcome::Pass, vec![])];
        assert_eq!(
            retest_plan("run-1-ab", &plan, &all_pass),
            Err(RetestError::NothingToRetest("run-1-ab".into()))
        );
        assert!(matches!(
            retest_plan("run-1-ab", &plan, &[]),
            Err(RetestError::NotGraded(_))
        ));
        assert!(matches!(
            retest_plan("../etc", &plan, &records),
            Err(RetestError::BadRunId(_))
        ));
    }

    #[test]
    fn a_retest_of_that_is_not_a_run_id_is_refused_naming_the_key() {
        let e = TestPlan::from_toml("retest_of = \"a b\"\n[serials]\n1 = \"A\"\n")
            .expect_err("not an id");
        assert_eq!(e.key, "retest_of");
    }
}
