//! The part of a smooth misfit that the cubic absorbs (docs/method.md §6,
//! "Smooth misfit").
//!
//! A feature that spans several levels (a broad bump of the instrument's
//! response, a step where a resonator mode hops) splits in two: the part in
//! the span of the polynomial moves the coefficients and leaves no
//! residual; the rest is the residual the fit leaves. Leaving levels out
//! (the jackknife, single or in blocks) measures what the levels' residuals
//! do to a coefficient, so it sees the second part and not the first. Only
//! a shape links the two: for a bump of a given width, the part a cubic
//! absorbs is a fixed multiple of the part it leaves.
//!
//! So the residuals are read against a family of shapes — Gaussian bumps
//! of widths 2–17 % of the range and smoothed steps (edges 1 % and 4 % of
//! the range), centred every 0.5 % of the range — and the shape that
//! explains most of them (least squares, its size fitted) gives the
//! effect on the coefficient of that shape at that size. That effect is
//! the misfit's estimated bias, entered as a standard uncertainty like the
//! jackknife's (the larger of the two counts, never both).
//!
//! It counts when the lack of fit is significant, or when the best shape
//! alone explains more of the residuals than the pure error would by
//! chance: its explained sum of squares over σ² against χ²₁ at 5 %
//! divided by the L − p directions the residuals have (a shape is a
//! direction in that space; Bonferroni over them). A targeted test has the
//! power the omnibus lack-of-fit test lacks for a feature the cubic mostly
//! absorbs.
//!
//! What it cannot see: a feature wider than about a sixth of the range is
//! not told from the instrument's curvature (it is, for every purpose a
//! smooth model has, the curvature), and a misfit of a shape far from the
//! family is read as the nearest member. Nothing is written by hand that a
//! crate does: the fits are [`crate::lsq`]'s.

use crate::lsq;

/// Bump widths (Gaussian σ) as fractions of the range.
const BUMP_WIDTHS: [f64; 6] = [0.02, 0.035, 0.05, 0.08, 0.12, 0.17];
/// Bumps up to this width (σ, fraction of the range: 2.5 g of 70) are
/// within about one level: leaving levels out sees them whole, and a
/// misfit best read as one of them is the jackknife's, not this module's.
const NARROW: f64 = 0.035;
/// Step edge widths (logistic scale) as fractions of the range.
const STEP_WIDTHS: [f64; 2] = [0.01, 0.04];
/// The share of the residuals' sum of squares the best shape must explain.
const MOSTLY: f64 = 0.5;
/// The 95 % point of χ² with one degree of freedom.
const CHI2_1_95: f64 = 3.841;
/// Spacing of the shapes' centres as a fraction of the range.
const CENTRE_STEP: f64 = 0.005;

/// What the family member that best explains a fit's residuals says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothMisfit {
    /// Its effect on the coefficient asked (the units of the data per
    /// g^coefficient): the misfit's estimated bias there.
    pub effect: f64,
    /// The sum of squares of the residuals it explains (the data's units²).
    pub explained_ss: f64,
}

impl SmoothMisfit {
    /// Whether the shape explains more than the pure error of variance
    /// `sigma2` (of one reading, `dof_pe` degrees of freedom) would by
    /// chance, with `directions` = L − p residual directions (module docs).
    pub fn significant(&self, sigma2: f64, dof_pe: usize, directions: usize) -> bool {
        use statrs::distribution::{ContinuousCDF, FisherSnedecor};
        if sigma2.is_nan() || sigma2 <= 0.0 || dof_pe == 0 || directions == 0 {
            return false;
        }
        let f = self.explained_ss / sigma2;
        FisherSnedecor::new(1.0, dof_pe as f64)
            .map(|d| d.sf(f) < 0.05 / directions as f64)
            .unwrap_or(false)
    }
}

/// The family member that best explains the points' `misfit` (each
/// point's level-mean residual, in the units of the data; `sigma2` one
/// reading's pure-error variance in those units²), read through
/// the polynomial of `degree` fitted to points at |g| `x`, and its effect
/// on coefficient `coefficient` (module docs). `None` when nothing can be
/// read (too few points, no misfit) or when the best is a bump within
/// about one level (the jackknife's, module docs).
pub fn smooth_misfit(
    x: &[f64],
    misfit: &[f64],
    sigma2: f64,
    degree: usize,
    coefficient: usize,
    what: &str,
) -> Option<SmoothMisfit> {
    if x.len() != misfit.len() || x.len() <= degree + 2 || coefficient > degree {
        return None;
    }
    let design = lsq::polynomial_design(x, degree);
    let op = lsq::solution_operator(&design, what).ok()?;
    let range = x.iter().copied().fold(0.0_f64, f64::max);
    if !(range > 0.0 && range.is_finite())
        || misfit.iter().any(|m| !m.is_finite())
        || misfit.iter().all(|m| *m == 0.0)
    {
        return None;
    }
    let mut best: Option<(f64, f64, bool)> = None; // (explained, effect, narrow)
    let mut best_narrow = 0.0_f64;
    let mut consider = |shape: &dyn Fn(f64) -> f64, narrow: bool| {
        let s: Vec<f64> = x.iter().map(|g| shape(*g)).collect();
        let sv = nalgebra::DVector::from_column_slice(&s);
        let coef = &op * &sv;
        let r = &sv - &design * &coef;
        let ss = r.norm_squared();
        if ss.is_nan() || ss <= 1e-12 * sv.norm_squared().max(1e-300) {
            return;
        }
        let dot: f64 = r.iter().zip(misfit).map(|(a, b)| a * b).sum();
        let explained = dot * dot / ss;
        let effect = dot / ss * coef[coefficient];
        if narrow {
            best_narrow = best_narrow.max(explained);
        }
        if best.is_none_or(|(e, _, _)| explained > e) {
            best = Some((explained, effect, narrow));
        }
    };
    let centres =
        (0..=((1.0 / CENTRE_STEP).round() as usize)).map(|i| i as f64 * CENTRE_STEP * range);
    for c in centres {
        for w in BUMP_WIDTHS {
            let sigma = w * range;
            consider(
                &|g: f64| (-0.5 * ((g - c) / sigma).powi(2)).exp(),
                w <= NARROW,
            );
        }
        for w in STEP_WIDTHS {
            let scale = w * range;
            consider(&|g: f64| 1.0 / (1.0 + (-(g - c) / scale).exp()), false);
        }
    }
    // The misfit must be mostly this shape: a broad shape that explains a
    // little of two separate dips would read their sum as a feature the
    // cubic absorbs, which it is not.
    let total: f64 = misfit.iter().map(|m| m * m).sum();
    // And it must explain more than a feature within one level does, by
    // more than chance would (χ²₁ at 5 %, 3.84 σ²): at a level spacing of
    // 5 g a dip at one level is read almost as well by a bump a few g
    // wide, and that is the jackknife's.
    best.filter(|b| !b.2 && b.0 >= MOSTLY * total && b.0 - best_narrow > CHI2_1_95 * sigma2)
        .map(|(explained_ss, effect, _)| SmoothMisfit {
            effect,
            explained_ss,
        })
}
