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
//!   refitted, and the mean of their prediction errors judged against the
//!   scatter the other levels show: their between-level variance τ̂² plus the
//!   level's pure error ([`crate::inadequacy`]), once, with a Bonferroni
//!   correction over the levels (never repeated: a repeated search shrinks
//!   its yardstick with every level it removes and flags the neighbours of
//!   a real anomaly);
//! * **between-level scatter** — τ̂, the model inadequacy the budget carries;
//! * **influence** — k2 refitted without each level.
//!
//! Nothing here excludes anything: the diagnostics say what a metrologist
//! should look at.

use crate::inadequacy::{self, LevelVariance};
use crate::lsq;
use crate::points::Point;
use crate::{AnalysisError, UG_PER_G};
use serde::{Deserialize, Serialize};
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

pub use crate::inadequacy::{OUTLIER_ALPHA, OutlierLevel};

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
    /// The between-level standard deviation τ̂ the lack of fit shows beyond
    /// the pure error [µg] ([`crate::inadequacy`]); 0 when it fits within it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub between_level_ug: Option<f64>,
    /// Levels off the curve (corrected p below [`OUTLIER_ALPHA`]), worst first.
    pub outlier_levels: Vec<OutlierLevel>,
    /// k2 without each level (order 2 and up).
    pub influence: Vec<Influence>,
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
    let levels = inadequacy::levels(points);

    // Pure error from the residuals of replicated levels (the one definition).
    let (ss_pe, dof_pe) = inadequacy::pure_error(&levels, residuals);
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
    let x: Vec<f64> = points.iter().map(Point::g_magnitude).collect();
    let y: Vec<f64> = points.iter().map(|p| p.output).collect();
    let between_level_ug = LevelVariance::estimate(
        &levels,
        residuals,
        &lsq::polynomial_design(&x, degree),
        what,
    )?
    .map(|v| to_ug(v.tau2.sqrt()));
    let outliers = inadequacy::outlier_levels(points, degree, k1_abs, what);
    let enough = |left_out_levels: usize, left_out_points: usize| {
        levels.len() - left_out_levels > p && n - left_out_points > p
    };
    // Influence: k2 without each level (all other readings kept).
    let mut influence = Vec::new();
    for level in levels.iter().filter(|_| degree >= 2) {
        let (g, members) = (&level.g, &level.members);
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
    Ok(Diagnostics {
        lack_of_fit,
        pure_error_rms_ug,
        between_level_ug,
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
        if let Some(tau) = self.between_level_ug.filter(|t| *t >= 0.5) {
            write!(f, "; between levels {tau:.0} µg")?;
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
