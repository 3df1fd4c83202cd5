//! A finished run's records changed by an engineer (the web UI): a level
//! left out of one instrument's reduction, or such an exclusion withdrawn;
//! the record reduced and graded again by the run's own plan and station
//! config, its readings kept.

use super::grade::grade;
use super::{analysis_options, graded_points, point_list, temperature_reasons};
use crate::config::StationConfig;
use crate::plan::CompiledPlan;
use crate::record::{Outcome, UnitRecord};
use spinbench_analysis::Mount;
use spinbench_analysis::exclusion::LevelExclusion;
use spinbench_analysis::unit::UnitPoints;

/// Why a level was not left out of a finished record, or not given back:
/// each says what to do instead. The record is unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExclusionError {
    /// The record was never graded (incomplete, or the instrument failed).
    #[error(
        "{serial} was not graded ({outcome}): there is no reduction to leave a level out of; retest it"
    )]
    NotGraded {
        /// The instrument.
        serial: String,
        /// Its outcome.
        outcome: Outcome,
    },
    /// No reason was given.
    #[error("a reason is required: say why the level is left out")]
    NoReason,
    /// The level is left out already.
    #[error("{g} g in mounting {mount} of {serial} is already left out")]
    AlreadyOut {
        /// The instrument.
        serial: String,
        /// The mounting.
        mount: Mount,
        /// The level [g].
        g: f64,
    },
    /// The instrument has no reading at that level.
    #[error("{serial} has no reading at {g} g in mounting {mount}; give one of its levels")]
    NoReading {
        /// The instrument.
        serial: String,
        /// The mounting.
        mount: Mount,
        /// The level [g].
        g: f64,
    },
    /// Leaving it out would leave a mounting's fit or the joint K2 unmade.
    #[error(
        "leaving out {g} g in mounting {mount} leaves {serial} too few levels to reduce (a mounting's fit or the joint K2 could no longer be made); refused, the record is unchanged. Withdraw another exclusion first, or retest the instrument"
    )]
    TooFewLevels {
        /// The instrument.
        serial: String,
        /// The mounting.
        mount: Mount,
        /// The level [g].
        g: f64,
    },
    /// The level to give back is not left out.
    #[error("{g} g in mounting {mount} of {serial} is not left out (its exclusions: {listed})")]
    NotOut {
        /// The instrument.
        serial: String,
        /// The mounting.
        mount: Mount,
        /// The level [g].
        g: f64,
        /// Its exclusions, as a list ("none" when it has none).
        listed: String,
    },
}

/// A finished instrument's record reduced again with one more level left
/// out, by an engineer after the run (the web UI): the exclusions it
/// already had and `exclusion` applied to its points, which stay in the
/// record; graded again by the plan's limits. Refused, with what to do, for
/// a record that was never graded (incomplete, or the instrument failed), a
/// level already left out, or one with no reading to leave out.
pub fn exclude_after_run(
    record: &UnitRecord,
    plan: &CompiledPlan,
    station: &StationConfig,
    mut exclusion: LevelExclusion,
) -> Result<UnitRecord, ExclusionError> {
    if record.outcome == Outcome::Incomplete || record.analysis.is_none() {
        return Err(ExclusionError::NotGraded {
            serial: record.serial.clone(),
            outcome: record.outcome,
        });
    }
    if exclusion.reason.trim().is_empty() {
        return Err(ExclusionError::NoReason);
    }
    if record
        .exclusions
        .iter()
        .any(|e| e.mount == exclusion.mount && e.g == exclusion.g)
    {
        return Err(ExclusionError::AlreadyOut {
            serial: record.serial.clone(),
            mount: exclusion.mount,
            g: exclusion.g,
        });
    }
    exclusion.unit = Some(record.serial.clone());
    let exclusions: Vec<LevelExclusion> = record
        .exclusions
        .iter()
        .cloned()
        .chain(std::iter::once(exclusion))
        .collect();
    let (mount, g) = (
        exclusions[exclusions.len() - 1].mount,
        exclusions[exclusions.len() - 1].g,
    );
    let after = regrade(record, plan, station, exclusions)?;
    if after
        .exclusions
        .last()
        .is_some_and(|e| e.points_removed == 0)
    {
        return Err(ExclusionError::NoReading {
            serial: record.serial.clone(),
            mount,
            g,
        });
    }
    // An exclusion that leaves a mounting (or the joint K2)
    // without a fit would turn a graded instrument into an ungradable one,
    // which nothing could undo: refused, the record stays as it was.
    let fitted = |r: &UnitRecord| {
        r.analysis
            .as_ref()
            .map_or((0, false), |a| (a.fits.len(), a.joint.is_some()))
    };
    let (before_fits, before_joint) = fitted(record);
    let (after_fits, after_joint) = fitted(&after);
    if after_fits < before_fits || (before_joint && !after_joint) {
        return Err(ExclusionError::TooFewLevels {
            serial: record.serial.clone(),
            mount,
            g,
        });
    }
    Ok(after)
}

/// Withdraw an engineer's exclusion of level `g` in mounting `mount` from a
/// finished run's record: reduced and graded again with
/// the other exclusions, by the run's own plan and station config.
pub fn withdraw_exclusion_after_run(
    record: &UnitRecord,
    plan: &CompiledPlan,
    station: &StationConfig,
    mount: Mount,
    g: f64,
) -> Result<UnitRecord, ExclusionError> {
    let before = record.exclusions.len();
    let exclusions: Vec<LevelExclusion> = record
        .exclusions
        .iter()
        .filter(|e| !(e.mount == mount && e.g == g))
        .cloned()
        .collect();
    if exclusions.len() == before {
        return Err(ExclusionError::NotOut {
            serial: record.serial.clone(),
            mount,
            g,
            listed: if record.exclusions.is_empty() {
                "none".to_string()
            } else {
                record
                    .exclusions
                    .iter()
                    .map(|e| format!("{} {} g", e.mount, e.g))
                    .collect::<Vec<_>>()
                    .join(", ")
            },
        });
    }
    regrade(record, plan, station, exclusions)
}

/// `record` reduced and graded again with `exclusions` (their readings
/// counted afresh), by the run's own plan and station config.
fn regrade(
    record: &UnitRecord,
    plan: &CompiledPlan,
    station: &StationConfig,
    exclusions: Vec<LevelExclusion>,
) -> Result<UnitRecord, ExclusionError> {
    let mut exclusions: Vec<LevelExclusion> = exclusions
        .into_iter()
        .map(|e| LevelExclusion {
            points_removed: 0,
            ..e
        })
        .collect();
    let mut units = [UnitPoints {
        unit: record.serial.clone(),
        run: None,
        points: point_list(&graded_points(plan, station, &record.points)),
    }];
    spinbench_analysis::exclusion::apply(&mut units, &mut exclusions);
    let [unit] = units;
    let options = analysis_options(
        plan,
        station,
        record.slot,
        &record.radius_reading_u_ppm,
        record.cross_axis_ug_per_g.is_some(),
    );
    let graded = grade(
        &record.serial,
        unit.points,
        options,
        &plan.plan.limits,
        record.table_signature.as_ref(),
    );
    let mut reasons = graded.reasons;
    reasons.extend(temperature_reasons(plan, station, &record.points));
    Ok(UnitRecord {
        analysis: graded.analysis,
        k2_max_ug_per_g2: graded.k2_max_ug_per_g2,
        outcome: graded.outcome,
        reasons,
        decision_rule: Some(plan.plan.limits.decision_rule),
        decision: Some(plan.plan.limits.decision()),
        table_signature: record.table_signature.clone(),
        exclusions,
        ..record.clone()
    })
}
