//! A plan's prediction against what its run achieved, and the readings the
//! station's model learns from ([`spinbench_analysis::design`]): the
//! records of past runs turned into the model's [`Reading`]s, and a run's
//! achieved K2 U95 (the median over its instruments) and centrifuge time.

use crate::plan::TestPlan;
use crate::record::UnitRecord;
use serde::{Deserialize, Serialize};
use spinbench_analysis::design::{self, Reading, StationModel};
use spinbench_analysis::{Direction, Mount, UG_PER_G};

/// What a run achieved, to set beside its plan's prediction.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Achieved {
    /// Median K2 U95 over the instruments that have one [µg/g²].
    pub k2_u95_ug_per_g2: Option<f64>,
    /// Centrifuge time of the level steps, every pass [s]: per mounting
    /// from the first reading's start to the last one's end.
    pub centrifuge_time_s: Option<f64>,
}

/// The readings of one instrument's record at the room's temperature
/// (a chamber run's other temperatures are left out), each over its
/// mounting fit's k1. Empty without a fit.
pub fn readings(record: &UnitRecord) -> Vec<Reading> {
    let Some(analysis) = &record.analysis else {
        return Vec::new();
    };
    record
        .points
        .iter()
        .filter(|p| p.setpoint_c.is_none())
        .filter_map(|p| {
            let k1 = analysis.fits.get(&p.mount)?.fit.k1;
            if !(k1.is_finite() && k1 != 0.0) {
                return None;
            }
            Some(Reading {
                mount: p.mount,
                g: p.g_nominal.abs(),
                down: p.direction == Direction::Down,
                output_g: p.output_hz / k1,
                std_ug: p.std_hz / k1.abs() * UG_PER_G,
                n: p.n,
                time_s: p.time_s,
            })
        })
        .collect()
}

/// The station's model from past runs (each its plan and records) and
/// the instruments' one-second values at rest [µg] (one series per
/// instrument-run, [`at_rest_ug`]), with its calibration: the median ratio
/// of each run's achieved K2 U95 to its plan's prediction on the model
/// learned (analysis::design).
pub fn learn(runs: &[(TestPlan, Vec<UnitRecord>)], at_rest: &[Vec<f64>]) -> Option<StationModel> {
    let readings: Vec<Vec<Vec<Reading>>> = runs
        .iter()
        .map(|(_, records)| records.iter().map(readings).collect())
        .collect();
    let mut model = StationModel::learn(&readings, at_rest)?;
    let mut ratios: Vec<f64> = runs
        .iter()
        .filter_map(|(plan, records)| {
            let achieved = achieved(records).k2_u95_ug_per_g2?;
            let predicted = design::predict(&model, &plan.candidate()).ok()?;
            (predicted.k2_u95_ug_per_g2 > 0.0).then(|| achieved / predicted.k2_u95_ug_per_g2)
        })
        .collect();
    model.calibration = design::median(&mut ratios)
        .map_or(1.0, |r| r.clamp(1.0 / MAX_CALIBRATION, MAX_CALIBRATION));
    Some(model)
}

/// The largest calibration factor (and the smallest, its inverse) the
/// model takes from its history.
pub const MAX_CALIBRATION: f64 = 4.0;

/// What a run's records achieved.
pub fn achieved<'a>(records: impl IntoIterator<Item = &'a UnitRecord>) -> Achieved {
    let records: Vec<&UnitRecord> = records.into_iter().collect();
    let mut u95: Vec<f64> = records
        .iter()
        .filter_map(|r| r.analysis.as_ref()?.joint.as_ref()?.k2_even_u95)
        .filter(|u| u.is_finite())
        .collect();
    u95.sort_by(f64::total_cmp);
    let median = (!u95.is_empty()).then(|| {
        let n = u95.len();
        if n % 2 == 1 {
            u95[n / 2]
        } else {
            0.5 * (u95[n / 2 - 1] + u95[n / 2])
        }
    });
    // The table's time is every instrument's: the record with the most points.
    let time = records.iter().max_by_key(|r| r.points.len()).and_then(|r| {
        let mut total = 0.0;
        let mut any = false;
        for mount in [Mount::P, Mount::N] {
            let of = r
                .points
                .iter()
                .filter(|p| p.mount == mount && p.setpoint_c.is_none());
            let (start, end) = of.fold((f64::INFINITY, f64::NEG_INFINITY), |(s, e), p| {
                (s.min(p.time_s[0]), e.max(p.time_s[1]))
            });
            if start.is_finite() && end >= start {
                total += end - start + 1.0;
                any = true;
            }
        }
        any.then_some(total)
    });
    Achieved {
        k2_u95_ug_per_g2: median,
        centrifuge_time_s: time,
    }
}

/// One instrument's one-second values at rest [µg]: of its outputs [Hz]
/// `values` (time [s], rate [deg/s], output), those with the table at rest
/// (|rate| below [`AT_REST_DEG_S`]) in the longest run of consecutive
/// seconds without a step ([`AT_REST_STEP_UG`]), over its mounting P fit's
/// |k1| (else N's). Empty without a fit.
pub fn at_rest_ug(record: &UnitRecord, values: &[(f64, f64, Option<f64>)]) -> Vec<f64> {
    let Some(k1) = record.analysis.as_ref().and_then(|a| {
        a.fits
            .get(&Mount::P)
            .or_else(|| a.fits.get(&Mount::N))
            .map(|f| f.fit.k1.abs())
    }) else {
        return Vec::new();
    };
    if !(k1.is_finite() && k1 > 0.0) {
        return Vec::new();
    }
    let (mut best, mut current): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    let mut last_t = f64::NEG_INFINITY;
    for &(t, rate, output) in values {
        match output {
            Some(hz) if rate.abs() < AT_REST_DEG_S && hz.is_finite() => {
                let ug = hz / k1 * UG_PER_G;
                // A gap in time, or a step (the instrument turned over for
                // the tumble, remounted): a new segment.
                let continues = t - last_t <= 1.5
                    && current
                        .last()
                        .is_some_and(|prev| (ug - prev).abs() <= AT_REST_STEP_UG);
                if !continues {
                    current.clear();
                }
                current.push(ug);
            }
            _ => current.clear(),
        }
        last_t = t;
        if current.len() > best.len() {
            best = current.clone();
        }
    }
    best
}

/// The table counts as at rest below this rate [deg/s] (0.1 deg/s on a
/// 1 m arm is 3 µg).
pub const AT_REST_DEG_S: f64 = 0.1;

/// A change between two seconds at rest larger than this [µg] is a step
/// (a position of the tumble, a remount), not noise: it starts a new segment.
pub const AT_REST_STEP_UG: f64 = 10_000.0;
