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
//! of widths 2–17 % of the range, smoothed steps (edges 1 % and 4 % of
//! the range) and hinges (nothing below a level, then a slope), centred
//! every 0.5 % of the range — each with its size fitted (least squares)
//! and its effect on the coefficient at that size. The members the data
//! cannot tell from the best one (within χ²₁ at 5 % of the pure error) are
//! the readings the data allow; each one's effect counts in proportion to
//! the share of the misfit beyond what the pure error leaves by chance it
//! explains, over 70 % (whole from 70 % on: a broad shape beside a
//! feature it does not explain is not dropped whole); the largest such
//! effect among their broad ones is the misfit's estimated bias, entered as a standard uncertainty like the jackknife's (the
//! larger of the two counts, never both). A step and a dip at the level
//! beside it fit alike, and which it is cannot be known: the uncertainty
//! carries the larger effect. When only bumps within about one level
//! remain, the misfit is the jackknife's, which sees such a feature whole.
//! Levels flagged off the curve (a dip: the
//! jackknife's) are set aside first and the rest read through the fit
//! without them: a dip's pull on the fit leaves the other levels a residual
//! in that fit's span, which this removes whole, so that an instrument
//! with a dip in one mounting and a broad bump in the other is still read.
//!
//! The misfit may also be read through a polynomial of lower degree than
//! the fit's ([`Readings::read_degree`]) when the caller has put back the
//! fit's top coefficient's part that is known to be wrong (K2's reading:
//! the two mountings' k3 are the instrument's one K3, [`crate::unit`]);
//! the effect is then still taken through the fit's own degree, which is
//! what the coefficient suffered.
//!
//! It counts only when the shape read explains more of the residuals than
//! the pure error would by chance ([`SmoothMisfit::significant`]): its
//! explained sum of squares over σ² against F(1, ν_pe) at 5 % divided by
//! the L − p directions the residuals have (a shape is a direction in that
//! space; Bonferroni over them). A shape that passes counts even when the
//! omnibus lack-of-fit test does not: that test lacks the power for a
//! feature the cubic mostly absorbs.
//!
//! It is not read with fewer than six residual directions (L − p): then
//! some broad member explains most of any misfit, a drift's or the
//! scatter's, and the data do not tell the shape (a ±10 g function check
//! of 7 levels has 3).
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
/// The share of the misfit's sum of squares, beyond the pure error's, a
/// shape must explain to be read.
const MOSTLY: f64 = 0.7;
/// The fewest residual directions (L − p) a shape is read in: with fewer,
/// some broad member explains most of any misfit (a drift, the scatter),
/// and the shape, hence its absorbed part, is not told by the data (a
/// ±10 g plan of 7 levels has 3).
const MIN_DIRECTIONS: usize = 6;
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

/// The readings a smooth misfit is read from, one entry per point.
#[derive(Debug, Clone, Copy)]
pub struct Readings<'a> {
    /// Each point's |g| [g].
    pub x: &'a [f64],
    /// Each point's level-mean residual (the data's units).
    pub misfit: &'a [f64],
    /// Whether the point's level is set aside (flagged off the curve).
    pub set_aside: &'a [bool],
    /// The degree of the polynomial the misfit is read through (shapes
    /// and misfit alike projected off it): the fit's degree, or less when
    /// the fit's top coefficient is known from elsewhere and `misfit`
    /// carries what the fit gave that coefficient (the two mountings'
    /// shared cubic, [`crate::unit`]). The effect is always the fit's.
    pub read_degree: usize,
}

/// The family member that best explains the points' `misfit` (each
/// point's level-mean residual, in the units of the data; `sigma2` one
/// reading's pure-error variance in those units², over `levels` levels),
/// read through the polynomial of `degree` fitted to points at |g| `x`,
/// and its effect
/// on coefficient `coefficient` (module docs). `None` when nothing can be
/// read (too few points, no misfit), or when no broad member explains
/// most of the misfit as well as the best member does (the jackknife's,
/// module docs).
pub fn smooth_misfit(
    readings: &Readings,
    sigma2: f64,
    levels: usize,
    degree: usize,
    coefficient: usize,
    what: &str,
) -> Option<SmoothMisfit> {
    let Readings {
        x,
        misfit,
        set_aside,
        read_degree,
    } = *readings;
    if x.len() != misfit.len()
        || set_aside.len() != x.len()
        || coefficient > degree
        || read_degree > degree
        || levels.saturating_sub(read_degree + 1) < MIN_DIRECTIONS
    {
        return None;
    }
    // The points of the levels set aside (flagged off the curve: the
    // jackknife's) are left out, and what the rest show is read again
    // through the fit without them: a dip's pull on the fit leaves the
    // other levels a residual in the span of that fit, which this removes
    // whole, so that the dip is not read as part of a broad shape.
    let kept: Vec<usize> = (0..x.len()).filter(|&i| !set_aside[i]).collect();
    if kept.len() <= degree + 2 {
        return None;
    }
    let x: Vec<f64> = kept.iter().map(|&i| x[i]).collect();
    let design = lsq::polynomial_design(&x, read_degree);
    let op = lsq::solution_operator(&design, what).ok()?;
    // The fit's own operator: what a shape does to its coefficient.
    let fit_op = lsq::solution_operator(&lsq::polynomial_design(&x, degree), what).ok()?;
    let misfit: Vec<f64> = {
        let m = nalgebra::DVector::from_iterator(kept.len(), kept.iter().map(|&i| misfit[i]));
        let r = &m - &design * (&op * &m);
        r.iter().copied().collect()
    };
    let misfit = misfit.as_slice();
    let x = x.as_slice();
    let range = x.iter().copied().fold(0.0_f64, f64::max);
    if !(range > 0.0 && range.is_finite())
        || misfit.iter().any(|m| !m.is_finite())
        || misfit.iter().all(|m| *m == 0.0)
    {
        return None;
    }
    // Every member: (explained, effect, narrow).
    let mut read: Vec<(f64, f64, bool)> = Vec::new();
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
        let effect = (&fit_op * &sv)[coefficient];
        read.push((dot * dot / ss, dot / ss * effect, narrow));
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
        // A hinge: nothing below a level, then a slope (a stiffening or a
        // drift that starts there).
        consider(&|g: f64| (g - c).max(0.0) / range, false);
    }
    let best = read.iter().map(|r| r.0).fold(0.0_f64, f64::max);
    // The misfit beyond what the pure error leaves in the L − p residual
    // directions by chance.
    let total: f64 = misfit.iter().map(|m| m * m).sum::<f64>()
        - sigma2 * levels.saturating_sub(read_degree + 1) as f64;
    // The members the data cannot tell from the best (within χ²₁ at 5 %
    // of the pure error, 3.84 σ²) that explain most of that misfit (a
    // broad shape explaining some of two separate dips would read their
    // sum as a feature the cubic absorbs, which it is not). Among them the
    // broad one of largest effect: when a step and a dip at the level
    // beside it fit alike, which it is cannot be known, and the larger
    // effect is the one the uncertainty must carry. When only features
    // within one level remain, the misfit is the jackknife's.
    // A member that explains less than most of the misfit is not dropped
    // whole: its effect counts in proportion to the share of the misfit
    // it explains over the share that would make it the reading (a broad
    // shape that explains half of a misfit, beside a dip it does not,
    // still moved the coefficient by about half its effect).
    read.into_iter()
        .filter(|r| !r.2 && r.0 >= best - CHI2_1_95 * sigma2)
        .map(|(explained_ss, effect, narrow)| {
            let share = if total > 0.0 {
                (explained_ss / (MOSTLY * total)).min(1.0)
            } else {
                1.0
            };
            (explained_ss, effect * share, narrow)
        })
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .map(|(explained_ss, effect, _)| SmoothMisfit {
            effect,
            explained_ss,
        })
}
