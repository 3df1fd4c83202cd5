//! The judgement: an instrument's points, once measured, reduced and graded
//! against the plan's limits. Plain functions over the plan, the station
//! and the record — the executor calls them at the end of a run, and the
//! store's callers after it (an exclusion or its withdrawal regrades a
//! stored record the same way).
//!
//! | module | job |
//! |---|---|
//! | [`grade`] | a unit's fits and figures against the limits: outcome and reasons |
//! | [`exclusions`] | a level excluded or given back after the run, and the record regraded |
//! | this file | the options a reduction takes, the points graded, the plan's exclusions, the reasons beside the grade |

pub mod exclusions;
pub mod grade;

pub use exclusions::{ExclusionError, exclude_after_run, withdraw_exclusion_after_run};
pub use grade::{Graded, grade};

use crate::config::StationConfig;
use crate::plan::CompiledPlan;
use crate::record::{PointRecord, Reason, ReasonCode};
use spinbench_analysis::exclusion::LevelExclusion;
use spinbench_analysis::unit::{AnalysisOptions, UnitPoints};
use spinbench_analysis::{Mount, Point};
use std::collections::BTreeMap;

/// A unit's points with the plan's exclusions for it left out, and the
/// exclusions that removed something (by: the plan's operator).
pub(crate) fn plan_exclusions(
    plan: &CompiledPlan,
    serial: &str,
    records: &[PointRecord],
) -> (Vec<Point>, Vec<LevelExclusion>) {
    let plan = &plan.plan;
    let mut units = [UnitPoints {
        unit: serial.to_string(),
        run: None,
        points: point_list(records),
    }];
    let by = if plan.operator.is_empty() {
        "the plan".to_string()
    } else {
        plan.operator.clone()
    };
    let mut exclusions: Vec<LevelExclusion> = plan
        .exclusions
        .iter()
        .filter(|e| e.serial.as_deref().is_none_or(|s| s == serial))
        .map(|e| LevelExclusion {
            unit: Some(serial.to_string()),
            mount: e.mount,
            g: e.g,
            reason: e.reason.clone(),
            by: by.clone(),
            points_removed: 0,
        })
        .collect();
    spinbench_analysis::exclusion::apply(&mut units, &mut exclusions);
    // One that removed nothing from this instrument is not its record's.
    exclusions.retain(|e| e.points_removed > 0);
    let [unit] = units;
    (unit.points, exclusions)
}

/// How an instrument's points are reduced: the plan's order; the station's
/// Type B inputs with the slot's radius, the dwell's read-backs per point
/// (the fewest an adaptive dwell takes), and what the instrument's own
/// readings measured — its radii's reading noise and, after a four-position
/// tumble, no unmeasured cross-axis bound (its radius was corrected).
pub fn analysis_options(
    plan: &CompiledPlan,
    station: &StationConfig,
    slot: usize,
    radius_reading_u_ppm: &BTreeMap<Mount, f64>,
    cross_axis_measured: bool,
) -> AnalysisOptions {
    let reading = |m: Mount| radius_reading_u_ppm.get(&m).copied().unwrap_or(0.0);
    let station_b = station.type_b(slot);
    let dwell = &plan.plan.dwell;
    AnalysisOptions {
        anomalies: plan.plan.anomalies,
        // A plan read back from the store has no compiled order: its degree says it.
        order: spinbench_analysis::ModelOrder::from_degree(plan.plan.order).unwrap_or(plan.order),
        type_b: spinbench_analysis::uncertainty::TypeBInputs {
            readings_per_point: f64::from(match dwell.sem_target_ug {
                Some(_) => dwell.min_seconds.max(1),
                None => dwell.seconds.max(1),
            }),
            radius_reading_ppm_p: reading(Mount::P),
            radius_reading_ppm_n: reading(Mount::N),
            cross_axis_ug_per_g: if cross_axis_measured {
                0.0
            } else {
                station_b.cross_axis_ug_per_g
            },
            ..station_b
        },
    }
}

/// The centrifuge's signature learned from a run's instruments
/// ([`spinbench_analysis::table_signature`]); `None` with too few of them.
pub fn table_signature(
    units: impl Iterator<Item = UnitPoints>,
    order: spinbench_analysis::ModelOrder,
    prior: Option<&spinbench_analysis::table_signature::Prior>,
) -> Option<spinbench_analysis::table_signature::TableSignature> {
    let units: Vec<UnitPoints> = units.filter(|u| !u.points.is_empty()).collect();
    spinbench_analysis::table_signature::estimate_with(&units, order, prior)
}

/// The points an instrument is graded on: with temperatures, those at the
/// reference temperature (nearest the laboratory's, `soak::reference_c`);
/// every point stays in the record.
pub(crate) fn graded_points(
    plan: &CompiledPlan,
    station: &StationConfig,
    points: &[PointRecord],
) -> Vec<PointRecord> {
    let reference =
        crate::soak::reference_c(&plan.plan.temperatures_c, station.temperature.ambient_c);
    points
        .iter()
        .filter(|p| reference.is_none() || p.setpoint_c == reference)
        .cloned()
        .collect()
}

/// The reasons a record carries beside its grade, from its points'
/// temperatures: the reference temperature it was graded at, and the points
/// taken while the temperature moved more than the plan allows.
pub(crate) fn temperature_reasons(
    plan: &CompiledPlan,
    station: &StationConfig,
    points: &[PointRecord],
) -> Vec<Reason> {
    let mut reasons = Vec::new();
    if let Some(t) =
        crate::soak::reference_c(&plan.plan.temperatures_c, station.temperature.ambient_c)
    {
        reasons.push(
            Reason::new(
                ReasonCode::AnalysisNote,
                format!(
                    "graded at the reference temperature {t} °C (of {:?} °C); the points at every temperature are in the record",
                    plan.plan.temperatures_c
                ),
            )
            .with("variant", "graded_at_reference")
            .with("reference", t)
            .with("temperatures", format!("{:?}", plan.plan.temperatures_c)),
        );
    }
    let unsettled: Vec<String> = points
        .iter()
        .filter(|p| p.temperature_unsettled)
        .map(|p| format!("{}:{} g", p.mount, p.g_nominal))
        .collect();
    if !unsettled.is_empty() {
        let limit = plan.plan.stability.temperature_change_max_c.unwrap_or(0.0);
        reasons.push(
            Reason::new(
                ReasonCode::TemperatureUnsettled,
                format!(
                    "{} point(s) taken while its temperature moved more than stability.temperature_change_max_c = {limit} °C ({}); retest advised",
                    unsettled.len(),
                    unsettled.join(", ")
                ),
            )
            .with("count", unsettled.len())
            .with("limit", limit)
            .with("points", unsettled.join(", ")),
        );
    }
    reasons
}

/// The analysis' points of a unit's records.
pub(crate) fn point_list(records: &[PointRecord]) -> Vec<Point> {
    records.iter().map(PointRecord::point).collect()
}

/// A failure that means the instrument gave nothing to judge against the
/// limits (dead, unpowered, unplugged, silent, or so noisy that no point
/// could be taken — a noisy channel is as likely its cable as the
/// instrument), so its record is [`Outcome::Incomplete`], never
/// [`Outcome::Fail`].
pub(crate) fn unmeasured(code: ReasonCode) -> bool {
    matches!(
        code,
        ReasonCode::Dead | ReasonCode::NoOutput | ReasonCode::RadiusFailed | ReasonCode::Noisy
    )
}
