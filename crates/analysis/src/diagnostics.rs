//! Does the model fit? Diagnostics of one mounting's fit of method.md (2):
//!
//! * **lack of fit** — the classic F test: the residual sum of squares split
//!   into pure error (the scatter of replicated readings of a level, up and
//!   down and repeated visits, about their own mean) and lack of fit (the
//!   rest); F = (SS_lof/ν_lof)/(SS_pe/ν_pe). Replicates are compared through
//!   their residuals, so two readings of a level at slightly different
//!   applied accelerations are still replicates (method.md §5: "a level off
//!   in both directions is a systematic effect at that speed, not noise").
//! * **outlier levels** — each level's readings left out together, the model
//!   refitted, and the mean of their prediction errors judged by its
//!   externally studentized t (variance σ²₍₋L₎/m + x̄ᵀ·Cov₍₋L₎·x̄), with a
//!   Bonferroni correction over the levels; the worst level below
//!   [`OUTLIER_ALPHA`] is listed and left out of the later reference fits,
//!   and the search repeats (a far-off level must not swamp its neighbour).
//! * **influence** — k2 refitted without each level.
//!
//! Nothing here excludes anything: the diagnostics say what a metrologist
//! should look at.

use crate::lsq;
use crate::points::Point;
use crate::{AnalysisError, UG_PER_G};
use serde::{Deserialize, Serialize};
use statrs::distribution::{ContinuousCDF, FisherSnedecor, StudentsT};

/// Family-wise false-alarm rate of the outlier-level test (Bonferroni over levels).
pub const OUTLIER_ALPHA: f64 = 0.05;

/// The lack-of-fit F test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LackOfFit {
    /// F = (SS_lof/ν_lof)/(SS_pe/ν_pe).
    pub f: f64,
    /// Degrees of freedom [lack of fit, pure error].
    pub dof: [usize; 2],
    /// P(F ≥ f) under the model.
    pub p_value: f64,
}

/// A level whose readings sit off the curve.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutlierLevel {
    /// The level [g].
    pub g: f64,
    /// Mean prediction error of its readings by the fit without them [µg].
    pub residual_ug: f64,
    /// Externally studentized t.
    pub t: f64,
    /// Two-sided p, Bonferroni-corrected over the levels.
    pub p: f64,
}

/// k2 without one level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Influence {
    /// The level left out [g].
    pub g: f64,
    /// k2 of the fit without it [µg/g²].
    pub k2_without_ug_per_g2: f64,
}

/// The diagnostics of one mounting's fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Diagnostics {
    /// The lack-of-fit test; `None` without replicated levels or spare levels.
    pub lack_of_fit: Option<LackOfFit>,
    /// RMS of the pure error (replicates about their level's mean) [µg].
    pub pure_error_rms_ug: Option<f64>,
    /// Levels off the curve (corrected p below [`OUTLIER_ALPHA`]), worst first.
    pub outlier_levels: Vec<OutlierLevel>,
    /// k2 without each level (order 2 and up).
    pub influence: Vec<Influence>,
}

/// The points of each level (by |g_nominal|), in level order.
fn levels(points: &[Point]) -> Vec<(f64, Vec<usize>)> {
    let mut out: Vec<(f64, Vec<usize>)> = Vec::new();
    for (i, p) in points.iter().enumerate() {
        let g = p.g_nominal.abs();
        match out.iter_mut().find(|(level, _)| *level == g) {
            Some((_, members)) => members.push(i),
            None => out.push((g, vec![i])),
        }
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// Diagnose the per-mounting fit of `points` (magnitude convention) with a
/// polynomial of `degree` whose residuals are `residuals`; `k1_abs` turns
/// output into acceleration.
pub fn diagnose(
    points: &[Point],
    residuals: &[f64],
    degree: usize,
    k1_abs: f64,
    what: &str,
) -> Result<Diagnostics, AnalysisError> {
    let n = points.len();
    let p = degree + 1;
    let to_ug = |v: f64| v / k1_abs * UG_PER_G;
    let levels = levels(points);

    // Pure error from the residuals of replicated levels.
    let (mut ss_pe, mut dof_pe) = (0.0, 0usize);
    for (_, members) in &levels {
        if members.len() >= 2 {
            let mean = members.iter().map(|&i| residuals[i]).sum::<f64>() / members.len() as f64;
            ss_pe += members
                .iter()
                .map(|&i| (residuals[i] - mean).powi(2))
                .sum::<f64>();
            dof_pe += members.len() - 1;
        }
    }
    let rss: f64 = residuals.iter().map(|r| r * r).sum();
    let dof_lof = levels.len().saturating_sub(p);
    let pure_error_rms_ug = (dof_pe > 0).then(|| to_ug((ss_pe / dof_pe as f64).sqrt()));
    let lack_of_fit = if dof_pe > 0 && dof_lof > 0 && ss_pe > 0.0 {
        let ss_lof = (rss - ss_pe).max(0.0);
        let f = (ss_lof / dof_lof as f64) / (ss_pe / dof_pe as f64);
        let dist = FisherSnedecor::new(dof_lof as f64, dof_pe as f64).map_err(|e| {
            AnalysisError::InvalidInput(format!("{what}: lack-of-fit distribution: {e}"))
        })?;
        Some(LackOfFit {
            f,
            dof: [dof_lof, dof_pe],
            p_value: dist.sf(f),
        })
    } else {
        None
    };

    // Each level left out: its readings predicted by the others. Flagged
    // levels are left out of every later reference fit too (one level far
    // off would otherwise drag the curve and swamp its neighbour).
    let x: Vec<f64> = points.iter().map(Point::g_magnitude).collect();
    let y: Vec<f64> = points.iter().map(|p| p.output).collect();
    let judge = |members: &[usize], flagged: &[usize]| -> Option<(f64, f64, f64)> {
        let keep: Vec<usize> = (0..n)
            .filter(|i| !members.contains(i) && !flagged.contains(i))
            .collect();
        let xs: Vec<f64> = keep.iter().map(|&i| x[i]).collect();
        let ys: Vec<f64> = keep.iter().map(|&i| y[i]).collect();
        let fit = lsq::solve(&lsq::polynomial_design(&xs, degree), &ys, what).ok()?;
        let c = &fit.coefficients;
        let (cov, sigma) = (fit.covariance.as_ref()?, fit.stats.sigma?);
        let m = members.len() as f64;
        let predict = |a: f64| c.iter().rev().fold(0.0, |acc, ci| acc * a + ci);
        let mean_error = members.iter().map(|&i| y[i] - predict(x[i])).sum::<f64>() / m;
        // The mean design row of the level's readings.
        let row: Vec<f64> = (0..p)
            .map(|j| members.iter().map(|&i| x[i].powi(j as i32)).sum::<f64>() / m)
            .collect();
        let mut prediction_var = 0.0;
        for (j, rj) in row.iter().enumerate() {
            for (k, rk) in row.iter().enumerate() {
                prediction_var += rj * cov[(j, k)] * rk;
            }
        }
        let se = (sigma * sigma / m + prediction_var).sqrt();
        if !(se > 0.0 && se.is_finite()) {
            return None;
        }
        let t = mean_error / se;
        let student = StudentsT::new(0.0, 1.0, fit.stats.dof as f64).ok()?;
        let corrected = (2.0 * student.sf(t.abs()) * levels.len() as f64).min(1.0);
        Some((mean_error, t, corrected))
    };
    let enough = |left_out_levels: usize, left_out_points: usize| {
        levels.len() - left_out_levels > p && n - left_out_points > p
    };
    let mut outliers: Vec<OutlierLevel> = Vec::new();
    let mut flagged_points: Vec<usize> = Vec::new();
    loop {
        let mut worst: Option<(usize, f64, f64, f64)> = None;
        for (index, (g, members)) in levels.iter().enumerate() {
            if outliers.iter().any(|o| o.g == *g)
                || !enough(outliers.len() + 1, flagged_points.len() + members.len())
            {
                continue;
            }
            if let Some((e, t, corrected)) = judge(members, &flagged_points)
                && corrected < OUTLIER_ALPHA
                && worst.is_none_or(|w| t.abs() > w.2.abs())
            {
                worst = Some((index, e, t, corrected));
            }
        }
        let Some((index, e, t, corrected)) = worst else {
            break;
        };
        let (g, members) = &levels[index];
        flagged_points.extend(members);
        outliers.push(OutlierLevel {
            g: *g,
            residual_ug: to_ug(e),
            t,
            p: corrected,
        });
    }
    // Influence: k2 without each level (all other readings kept).
    let mut influence = Vec::new();
    for (g, members) in levels.iter().filter(|_| degree >= 2) {
        if !enough(1, members.len()) {
            continue;
        }
        let keep: Vec<usize> = (0..n).filter(|i| !members.contains(i)).collect();
        let xs: Vec<f64> = keep.iter().map(|&i| x[i]).collect();
        let ys: Vec<f64> = keep.iter().map(|&i| y[i]).collect();
        if let Ok(fit) = lsq::solve(&lsq::polynomial_design(&xs, degree), &ys, what)
            && fit.coefficients[1] != 0.0
        {
            influence.push(Influence {
                g: *g,
                k2_without_ug_per_g2: fit.coefficients[2] / fit.coefficients[1] * UG_PER_G,
            });
        }
    }
    outliers.sort_by(|a, b| b.t.abs().total_cmp(&a.t.abs()));
    Ok(Diagnostics {
        lack_of_fit,
        pure_error_rms_ug,
        outlier_levels: outliers,
        influence,
    })
}

impl std::fmt::Display for Diagnostics {
    /// One line: lack of fit, pure error, outlier levels, and the range of
    /// k2 with one level left out (the one wording `analyze` and the reports use).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.lack_of_fit {
            Some(l) => write!(
                f,
                "lack of fit F = {:.2} ({}, {}), p = {:.2e}{}",
                l.f,
                l.dof[0],
                l.dof[1],
                l.p_value,
                if l.p_value < 0.001 {
                    ": the model does not fit"
                } else {
                    ""
                }
            )?,
            None => f.write_str("lack of fit: no replicated levels")?,
        }
        if let Some(pe) = self.pure_error_rms_ug {
            write!(f, "; pure error {pe:.1} µg RMS")?;
        }
        if self.outlier_levels.is_empty() {
            f.write_str("; no outlier level")?;
        } else {
            f.write_str("; outlier level(s): ")?;
            for (i, o) in self.outlier_levels.iter().enumerate() {
                let sep = if i == 0 { "" } else { ", " };
                write!(
                    f,
                    "{sep}{} g ({:+.0} µg, t = {:.1}, p = {:.1e})",
                    o.g, o.residual_ug, o.t, o.p
                )?;
            }
        }
        let by_k2 = |a: &&Influence, b: &&Influence| {
            a.k2_without_ug_per_g2.total_cmp(&b.k2_without_ug_per_g2)
        };
        if let (Some(lo), Some(hi)) = (
            self.influence.iter().min_by(by_k2),
            self.influence.iter().max_by(by_k2),
        ) {
            write!(
                f,
                "; k2 without one level {:.3} ({} g) to {:.3} ({} g) µg/g²",
                lo.k2_without_ug_per_g2, lo.g, hi.k2_without_ug_per_g2, hi.g
            )?;
        }
        Ok(())
    }
}
