//! Model inadequacy: what a fit's residuals say beyond the repeatability
//! (method.md §5, "When the model does not fit").
//!
//! The readings of one mounting are modelled as
//!
//! ```text
//! y_ij = f(x_ij; β) + b_i + e_ij,   b_i ~ (0, τ²) per level i,   e_ij ~ (0, σ²) per reading
//! ```
//!
//! σ² is the **pure error**: the scatter of a level's replicated readings
//! (up, down, repeated visits) about their own mean — the one definition
//! every part of the reduction uses ([`pure_error`]). No drift is taken
//! out first: a drift linear in time cannot be told from an up/down
//! difference that depends on the level (hysteresis), so removing one
//! would remove part of the other. τ² is the **between-level variance**
//! that a systematic misfit at a level adds (an activity dip, a structural
//! resonance, smooth structure the cubic cannot follow), estimated by the
//! method of moments from the lack of fit:
//!
//! ```text
//! E[SS_lof] = (L − p)·σ² + τ²·T,   T = Σᵢ (nᵢ − 1ᵀ·H_ii·1)   (H the hat matrix)
//! τ̂² = max(0, (SS_lof − (L − p)·MS_pe) / T)
//! ```
//!
//! exactly, for any number of readings per level. τ̂ is the yardstick of
//! the outlier test below and is reported in the diagnostics.
//!
//! **The budget's model-inadequacy source is the jackknife over levels**,
//! not τ̂² spread over every level's leverage. Real anomalies are sparse
//! and large (an activity dip at one level, a table resonance at another;
//! method.md §5): an iid level effect would give a dip at a mid-range
//! level the leverage of the end levels and make the U95 of a typical
//! bench ten times its error, while understating a dip at the top level.
//! Leaving each level out in turn measures what each level actually does
//! to the coefficient (the residual-based covariance in its
//! leave-one-level-out form):
//!
//! ```text
//! u²_JK(k) = Σ_levels (1 − h_ℓ)·(k₍₋ℓ₎ − k)²
//! u²(model inadequacy) = max(0, u²_JK − u²(repeatability) − u²(table)),  ν = L − p
//! ```
//!
//! (u(table) the table-disturbance Type B source, when the station states
//! one: a broad bump of the table moves the levels' readings too, so the
//! jackknife sees it, and counting it there and as its own source would
//! count it twice.)
//!
//! with h_ℓ the leverage of level ℓ's mean. This is the leverage-adjusted
//! (CR2, HC2) form: since k₍₋ℓ₎ − k = Pℓ·rℓ/(1 − hℓ), it is Σ Pℓ²·rℓ²/(1 − hℓ),
//! unbiased for level effects of equal variance, where the plain delete-one
//! jackknife's Σ Pℓ²·rℓ²/(1 − hℓ)² inflates the end levels (h ≈ 0.6 at the
//! top level of a cubic) several times over. It is included when the lack
//! of fit is significant (F test at 5 %; the GUM's "significant effects"),
//! since with a model that fits the jackknife only re-measures the
//! repeatability, less well. The repeatability itself is σ̂²·G·Gᵀ
//! ([`repeatability`], G = ∂k/∂y). The coefficients stay the ordinary
//! least-squares ones (the published method's).
//!
//! The same structure judges each level ([`outlier_levels`]): a level's
//! mean is compared with the curve through the other levels, against the
//! scatter those other levels show (τ̂² of their fit) plus its own pure
//! error, with a Bonferroni correction over the levels; once a level is
//! flagged the others are judged again with it set aside (a large anomaly
//! inflates the yardstick and hides a smaller one), each step at the same
//! corrected level, the yardstick always keeping two spare levels.
//!
//! For K2 = (k2_P − k2_N)/2 ([`crate::joint`]) the misfit that matters is
//! the part that differs between the mountings: a table's resonance shifts
//! both mountings' indicated acceleration alike and cancels, an instrument's
//! activity dip does not. Its jackknife leaves each level out of both
//! mountings together, and its significance is the lack of fit of the
//! two mountings' half-difference (half-sum, for the odd part) level by
//! level ([`paired_lack_of_fit`]).

use crate::lsq;
use crate::points::Point;
use crate::{AnalysisError, UG_PER_G};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use statrs::distribution::{ContinuousCDF, FisherSnedecor, StudentsT};

/// Family-wise false-alarm rate of the outlier-level test (Bonferroni over levels).
pub const OUTLIER_ALPHA: f64 = 0.05;

/// One level of a mounting: |g_nominal| and the indices of its readings.
#[derive(Debug, Clone, PartialEq)]
pub struct Level {
    /// The level, |g_nominal| [g].
    pub g: f64,
    /// Indices of its readings in the points given.
    pub members: Vec<usize>,
}

/// The points of each level (by |g_nominal|), in level order.
pub fn levels(points: &[Point]) -> Vec<Level> {
    let mut out: Vec<Level> = Vec::new();
    for (i, p) in points.iter().enumerate() {
        let g = p.g_nominal.abs();
        match out.iter_mut().find(|l| l.g == g) {
            Some(l) => l.members.push(i),
            None => out.push(Level {
                g,
                members: vec![i],
            }),
        }
    }
    out.sort_by(|a, b| a.g.total_cmp(&b.g));
    out
}

/// Sum of squares and degrees of freedom of the pure error: each replicated
/// level's readings about their own mean (of `values`: outputs or
/// residuals, the same thing within a level of one input), pooled. The one
/// definition of the reduction (module docs: no drift is removed).
pub fn pure_error(levels: &[Level], values: &[f64]) -> (f64, usize) {
    let (mut ss, mut dof) = (0.0, 0usize);
    for l in levels.iter().filter(|l| l.members.len() >= 2) {
        let m = l.members.len() as f64;
        let mean = l.members.iter().map(|&i| values[i]).sum::<f64>() / m;
        ss += l
            .members
            .iter()
            .map(|&i| (values[i] - mean).powi(2))
            .sum::<f64>();
        dof += l.members.len() - 1;
    }
    (ss, dof)
}

/// The residuals of the polynomial of `degree` fitted to (`x`, `y`), in
/// their order: what the pure error is taken of ([`pure_error`]).
pub fn residuals_of(x: &[f64], y: &[f64], degree: usize, what: &str) -> Option<Vec<f64>> {
    let design = lsq::polynomial_design(x, degree);
    lsq::solve(&design, y, what).ok().map(|f| f.residuals)
}

/// The variance components of one fit (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelVariance {
    /// Pure-error variance of one reading, σ̂² [output units²].
    pub sigma2: f64,
    /// Its degrees of freedom.
    pub dof_pe: usize,
    /// Lack-of-fit mean square [output units²].
    pub ms_lof: f64,
    /// Its degrees of freedom, L − p.
    pub dof_lof: usize,
    /// Between-level variance τ̂² ≥ 0 [output units²].
    pub tau2: f64,
}

impl LevelVariance {
    /// Estimate σ² and τ² for the fit of `design` to readings grouped in
    /// `levels`, whose residuals are `residuals`. `None` without a
    /// replicated level or without a level to spare (σ² and τ² cannot be
    /// told apart).
    pub fn estimate(
        levels: &[Level],
        residuals: &[f64],
        design: &DMatrix<f64>,
        what: &str,
    ) -> Result<Option<LevelVariance>, AnalysisError> {
        let p = design.ncols();
        let (ss_pe, dof_pe) = pure_error(levels, residuals);
        let dof_lof = levels.len().saturating_sub(p);
        if dof_pe == 0 || dof_lof == 0 {
            return Ok(None);
        }
        let rss: f64 = residuals.iter().map(|r| r * r).sum();
        let ss_lof = (rss - ss_pe).max(0.0);
        let sigma2 = ss_pe / dof_pe as f64;
        let ms_lof = ss_lof / dof_lof as f64;
        // T = Σᵢ (nᵢ − 1ᵀ·H_ii·1) = Σᵢ nᵢ·(1 − hᵢ), hᵢ the level mean's leverage.
        let t: f64 = level_leverage(levels, design, what)?
            .iter()
            .zip(levels)
            .map(|(h, l)| l.members.len() as f64 * (1.0 - h))
            .sum();
        let excess = ss_lof - dof_lof as f64 * sigma2;
        let tau2 = if excess > 0.0 && t > 0.0 {
            excess / t
        } else {
            0.0
        };
        Ok(Some(LevelVariance {
            sigma2,
            dof_pe,
            ms_lof,
            dof_lof,
            tau2,
        }))
    }
}

/// ∂k/∂y of the per-mounting fit: row j is the sensitivity of coefficient
/// j (k0 [g], k1, k2 [µg/g²], k3 [µg/g³]) to each reading's output, the
/// Jacobian of k = (c0/c1, c1, c2/c1, c3/c1) times the solution operator.
/// Rows past the model's order are zero.
pub fn coefficient_sensitivities(
    x: &[f64],
    polynomial: [f64; 4],
    degree: usize,
    what: &str,
) -> Result<DMatrix<f64>, AnalysisError> {
    let design = lsq::polynomial_design(x, degree);
    let op = lsq::solution_operator(&design, what)?;
    let c = polynomial;
    let c1 = c[1];
    let mut g = DMatrix::<f64>::zeros(4, x.len());
    for i in 0..x.len() {
        let dc = |j: usize| if j <= degree { op[(j, i)] } else { 0.0 };
        g[(0, i)] = dc(0) / c1 - c[0] / (c1 * c1) * dc(1);
        g[(1, i)] = dc(1);
        for j in 2..=3 {
            if j <= degree {
                g[(j, i)] = (dc(j) / c1 - c[j] / (c1 * c1) * dc(1)) * UG_PER_G;
            }
        }
    }
    Ok(g)
}

/// The standard uncertainty of each coefficient from the pure error,
/// √(σ²·Σᵢ G_ji²).
pub fn repeatability(g: &DMatrix<f64>, sigma2: f64) -> [f64; 4] {
    std::array::from_fn(|j| (sigma2 * g.row(j).iter().map(|x| x * x).sum::<f64>()).sqrt())
}

/// The leverage-adjusted jackknife variance over levels of each value:
/// `without[ℓ]` is the value with level ℓ left out, `full` with every
/// level, `leverage[ℓ]` the leverage of level ℓ's mean;
/// Σ (1 − hℓ)·(vℓ − v)² (module docs).
pub fn jackknife_variance<const N: usize>(
    full: [f64; N],
    without: &[[f64; N]],
    leverage: &[f64],
) -> [f64; N] {
    std::array::from_fn(|j| {
        without
            .iter()
            .zip(leverage)
            .map(|(v, h)| (1.0 - h).clamp(0.0, 1.0) * (v[j] - full[j]).powi(2))
            .sum()
    })
}

/// Whether a fit's misfit spreads over neighbouring levels: the lag-1
/// autocorrelation of its level-mean residuals `by_level` (in level order)
/// above its one-sided 5 % bound 1.645/√L under independent level effects.
/// Then a feature several adjacent levels share (a resonance's wings) moves
/// a coefficient more than leaving one level out shows, and the jackknife
/// leaves blocks of [`NEIGHBOUR_BLOCK`] adjacent levels out too
/// ([`block_jackknife`]).
pub fn neighbours_correlated(by_level: &[f64]) -> bool {
    let n = by_level.len();
    if n < 4 {
        return false;
    }
    let mean = by_level.iter().sum::<f64>() / n as f64;
    let d: Vec<f64> = by_level.iter().map(|v| v - mean).collect();
    let var: f64 = d.iter().map(|x| x * x).sum();
    if var <= 0.0 {
        return false;
    }
    let lag: f64 = d.windows(2).map(|w| w[0] * w[1]).sum();
    lag / var > 1.645 / (n as f64).sqrt()
}

/// Adjacent levels left out together by the block jackknife.
pub const NEIGHBOUR_BLOCK: usize = 2;

/// The jackknife over blocks of `block` adjacent levels (sliding), in the
/// leverage-adjusted form of [`jackknife_variance`] with each block's mean
/// leverage: `without[b]` are the coefficients with block b left out.
/// Not divided by the block size: a feature that spans the block moves
/// the coefficient as a whole, and that is what this measures (for
/// independent level effects it overstates by up to the block size, so it
/// is only used when [`neighbours_correlated`] says the misfit spreads).
pub fn block_jackknife<const N: usize>(
    full: [f64; N],
    without: &[[f64; N]],
    leverage: &[f64],
    block: usize,
) -> [f64; N] {
    let block_leverage: Vec<f64> = leverage
        .windows(block.max(1))
        .map(|w| w.iter().sum::<f64>() / w.len() as f64)
        .collect();
    jackknife_variance(full, without, &block_leverage)
}

/// The leverage of each level's mean in the least-squares fit of `design`
/// to readings grouped in `levels`: 1ᵀ·H_ℓℓ·1 / nℓ (H the hat matrix).
pub fn level_leverage(
    levels: &[Level],
    design: &DMatrix<f64>,
    what: &str,
) -> Result<Vec<f64>, AnalysisError> {
    let op = lsq::solution_operator(design, what)?;
    let p = design.ncols();
    Ok(levels
        .iter()
        .map(|l| {
            let mut block = 0.0;
            for &a in &l.members {
                for &b in &l.members {
                    block += (0..p).map(|j| design[(a, j)] * op[(j, b)]).sum::<f64>();
                }
            }
            block / l.members.len() as f64
        })
        .collect())
}

/// The model-inadequacy part of a variance: what the jackknife finds
/// beyond the repeatability, as a standard uncertainty (0 when none).
pub fn inadequacy_beyond(jackknife_var: f64, repeatability_u: f64) -> f64 {
    (jackknife_var - repeatability_u * repeatability_u)
        .max(0.0)
        .sqrt()
}

/// A level whose readings sit off the curve through the others.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutlierLevel {
    /// The level [g].
    pub g: f64,
    /// Mean prediction error of its readings by the fit without them [µg].
    pub residual_ug: f64,
    /// Its externally studentized t (module docs).
    pub t: f64,
    /// Two-sided p, Bonferroni-corrected over the levels.
    pub p: f64,
}

impl OutlierLevel {
    /// The level and how far off it is, as notes and reasons name it:
    /// `40 g (+262 µg)`.
    pub fn shown(&self) -> String {
        format!("{} g ({:+.0} µg)", self.g, self.residual_ug)
    }
}

/// Judge every level once against the curve through the other levels and
/// the scatter they show (module docs); returns each level's judgement,
/// flagged or not, in level order. `k1_abs` turns output into acceleration.
pub fn judge_levels(points: &[Point], degree: usize, k1_abs: f64, what: &str) -> Vec<OutlierLevel> {
    let all = levels(points);
    (0..all.len())
        .filter_map(|index| judge_level(points, &all, index, &[], degree, k1_abs, what))
        .collect()
}

/// Judge level `index` of `all` against the fit of the readings of every
/// other level except those of `set_aside` (level indices).
fn judge_level(
    points: &[Point],
    all: &[Level],
    index: usize,
    set_aside: &[usize],
    degree: usize,
    k1_abs: f64,
    what: &str,
) -> Option<OutlierLevel> {
    let p = degree + 1;
    let level = &all[index];
    let out_levels: Vec<usize> = std::iter::once(index)
        .chain(set_aside.iter().copied())
        .collect();
    let keep: Vec<usize> = (0..points.len())
        .filter(|i| !out_levels.iter().any(|&l| all[l].members.contains(i)))
        .collect();
    let others_count = all.len() - out_levels.len();
    if others_count <= p || keep.len() <= p {
        return None;
    }
    let x: Vec<f64> = points.iter().map(Point::g_magnitude).collect();
    let y: Vec<f64> = points.iter().map(|pt| pt.output).collect();
    // σ² from every replicated level (a level's own scatter is independent
    // of how far its mean sits off the curve), of the residuals of the fit
    // to every reading: the up and down readings of a level have different
    // applied accelerations, and their outputs' scatter would carry that.
    let (ss_pe_all, dof_pe_all) = pure_error(all, &residuals_of(&x, &y, degree, what)?);
    let xs: Vec<f64> = keep.iter().map(|&i| x[i]).collect();
    let ys: Vec<f64> = keep.iter().map(|&i| y[i]).collect();
    let design = lsq::polynomial_design(&xs, degree);
    let fit = lsq::solve(&design, &ys, what).ok()?;
    let op = lsq::solution_operator(&design, what).ok()?;
    let others: Vec<Level> = all
        .iter()
        .enumerate()
        .filter(|(k, _)| !out_levels.contains(k))
        .map(|(_, l)| Level {
            g: l.g,
            members: l
                .members
                .iter()
                .filter_map(|i| keep.iter().position(|k| k == i))
                .collect(),
        })
        .collect();
    let m = level.members.len() as f64;
    // The prediction at the level's mean design row: weights w over the kept readings.
    let row: Vec<f64> = (0..p)
        .map(|j| {
            level
                .members
                .iter()
                .map(|&i| x[i].powi(j as i32))
                .sum::<f64>()
                / m
        })
        .collect();
    let w: Vec<f64> = (0..keep.len())
        .map(|i| (0..p).map(|j| row[j] * op[(j, i)]).sum())
        .collect();
    let predicted: f64 = w.iter().zip(&ys).map(|(a, b)| a * b).sum();
    let mean: f64 = level.members.iter().map(|&i| y[i]).sum::<f64>() / m;
    let error = mean - predicted;
    let sum_w2: f64 = w.iter().map(|v| v * v).sum();
    let sum_level_w2: f64 = others
        .iter()
        .map(|l| l.members.iter().map(|&i| w[i]).sum::<f64>().powi(2))
        .sum();
    // var(e) = τ²·(1 + Σ_levels W²) + σ²·(1/m + Σ w²).
    let a = 1.0 + sum_level_w2;
    let b = 1.0 / m + sum_w2;
    let (variance, dof) = if dof_pe_all > 0 {
        let sigma2 = ss_pe_all / dof_pe_all as f64;
        match LevelVariance::estimate(&others, &fit.residuals, &design, what) {
            Ok(Some(v)) if v.tau2 > 0.0 => {
                // τ̂² = (ν_lof/T)(MS_lof − MS_pe): var̂ = c_lof·MS_lof + c_pe·MS_pe.
                let per_ms = v.tau2 / (v.ms_lof - v.sigma2);
                let (c_lof, c_pe) = (a * per_ms, b - a * per_ms);
                let var = c_lof * v.ms_lof + c_pe * sigma2;
                let den = (c_lof * v.ms_lof).powi(2) / v.dof_lof as f64
                    + (c_pe * sigma2).powi(2) / dof_pe_all as f64;
                (var, if den > 0.0 { var * var / den } else { 1.0 })
            }
            _ => (b * sigma2, dof_pe_all as f64),
        }
    } else {
        // No replicate anywhere: the others' residual scatter is all there is.
        let s = fit.stats.sigma?;
        (b * s * s, fit.stats.dof as f64)
    };
    let se = variance.sqrt();
    if !(se > 0.0 && se.is_finite()) {
        return None;
    }
    let t = error / se;
    let student = StudentsT::new(0.0, 1.0, dof.max(1.0)).ok()?;
    let corrected = (2.0 * student.sf(t.abs()) * all.len() as f64).min(1.0);
    Some(OutlierLevel {
        g: level.g,
        residual_ug: error / k1_abs * UG_PER_G,
        t,
        p: corrected,
    })
}

/// The levels off the curve, worst first: the candidates of one pass of
/// [`judge_levels`] (corrected p below [`OUTLIER_ALPHA`]), each confirmed
/// only if it is still off the curve with the stronger confirmed ones set
/// aside (a displaced 65 g level makes the curve's extrapolation to 70 g
/// miss: the confirmation clears it). Then, once a level is flagged, the
/// others are judged again with every flagged level set aside, and the
/// worst of them flagged if it passes the same corrected test, until none
/// does (one anomaly no longer hides another: a large one inflates the
/// yardstick the others are held to). The neighbours of a flagged level
/// are not judged again: they are its wings. The false alarms stay controlled:
/// every step holds one level to the Bonferroni-corrected level over all
/// the levels, and a step is only taken after a flag (on clean data the
/// first pass flags nothing in 1 − [`OUTLIER_ALPHA`] of fits). At most
/// L − p − 2 levels are flagged, so the yardstick keeps two levels.
pub fn outlier_levels(
    points: &[Point],
    degree: usize,
    k1_abs: f64,
    what: &str,
) -> Vec<OutlierLevel> {
    let all = levels(points);
    let mut candidates: Vec<(usize, OutlierLevel)> = (0..all.len())
        .filter_map(|i| judge_level(points, &all, i, &[], degree, k1_abs, what).map(|o| (i, o)))
        .filter(|(_, o)| o.p < OUTLIER_ALPHA)
        .collect();
    candidates.sort_by(|a, b| b.1.t.abs().total_cmp(&a.1.t.abs()));
    let mut confirmed: Vec<(usize, OutlierLevel)> = Vec::new();
    for (index, first) in candidates {
        let set_aside: Vec<usize> = confirmed.iter().map(|(i, _)| *i).collect();
        if set_aside.is_empty() {
            confirmed.push((index, first));
            continue;
        }
        if let Some(again) = judge_level(points, &all, index, &set_aside, degree, k1_abs, what)
            && again.p < OUTLIER_ALPHA
        {
            confirmed.push((index, first));
        }
    }
    let most = all.len().saturating_sub(degree + 1 + 2);
    while !confirmed.is_empty() && confirmed.len() < most {
        let set_aside: Vec<usize> = confirmed.iter().map(|(i, _)| *i).collect();
        // A neighbour of a flagged level is judged with it, not again: a
        // feature's wings (the published P 30 g feature's skirts at 25 and
        // 35 g) are its extent, carried by the budget's block jackknife.
        let worst = (0..all.len())
            .filter(|i| !set_aside.iter().any(|f| f.abs_diff(*i) <= 1))
            .filter_map(|i| {
                judge_level(points, &all, i, &set_aside, degree, k1_abs, what).map(|o| (i, o))
            })
            .filter(|(_, o)| o.p < OUTLIER_ALPHA)
            .max_by(|a, b| a.1.t.abs().total_cmp(&b.1.t.abs()));
        match worst {
            Some(found) => confirmed.push(found),
            None => break,
        }
    }
    confirmed.truncate(most.max(1));
    confirmed.into_iter().map(|(_, o)| o).collect()
}

/// One mounting's readings for [`paired_lack_of_fit`]: its points, their
/// residuals from the mounting's fit, its k1 and its pure-error variance
/// per reading [output units²] with dof (of the residuals, [`pure_error`]).
pub struct MountingSeries<'a> {
    /// The points.
    pub points: &'a [Point],
    /// Each point's residual from the mounting's fit [output units].
    pub residuals: &'a [f64],
    /// The fit's k1 (signed: negative in N).
    pub k1: f64,
    /// Pure-error variance of one reading [output units²].
    pub sigma2: f64,
    /// Its degrees of freedom.
    pub dof_pe: usize,
}

/// The lack-of-fit test of the series ½(z_P ± z_N) over the levels both
/// mountings have, z = mean output / k1 (the indicated acceleration):
/// `even` the half-difference (K2's: a table's misfit, the same in both
/// mountings, cancels in it), else the half-sum (the odd part's). The
/// residual mean square of its polynomial fit against the pure error the
/// two mountings' replicates predict for it. Returns (F, p); `None` with
/// fewer than degree + 2 shared levels or no pure error.
pub fn paired_lack_of_fit(
    p: &MountingSeries,
    n: &MountingSeries,
    degree: usize,
    even: bool,
    what: &str,
) -> Result<Option<(f64, f64)>, AnalysisError> {
    if p.dof_pe == 0 || n.dof_pe == 0 || p.k1 == 0.0 || n.k1 == 0.0 {
        return Ok(None);
    }
    let (lp, ln) = (levels(p.points), levels(n.points));
    let mean = |pts: &[Point], l: &Level, f: fn(&Point) -> f64| {
        l.members.iter().map(|&i| f(&pts[i])).sum::<f64>() / l.members.len() as f64
    };
    let mean_of = |values: &[f64], l: &Level| {
        l.members.iter().map(|&i| values[i]).sum::<f64>() / l.members.len() as f64
    };
    let sign = if even { -1.0 } else { 1.0 };
    // (x̄, series value [g], its pure-error variance [g²]).
    let mut series: Vec<(f64, f64, f64)> = Vec::new();
    for a in &lp {
        let Some(b) = ln.iter().find(|b| b.g == a.g) else {
            continue;
        };
        let x =
            0.5 * (mean(p.points, a, Point::g_magnitude) + mean(n.points, b, Point::g_magnitude));
        // Each level's misfit from its own mounting's curve, as acceleration:
        // the two mountings' applied accelerations differ (their radii), so
        // their outputs cannot be paired directly.
        let zp = mean_of(p.residuals, a) / p.k1;
        let zn = mean_of(n.residuals, b) / n.k1;
        let v = 0.25
            * (p.sigma2 / (p.k1 * p.k1 * a.members.len() as f64)
                + n.sigma2 / (n.k1 * n.k1 * b.members.len() as f64));
        series.push((x, 0.5 * (zp + sign * zn), v));
    }
    let cols = degree + 1;
    if series.len() < cols + 1 {
        return Ok(None);
    }
    let x: Vec<f64> = series.iter().map(|s| s.0).collect();
    let y: Vec<f64> = series.iter().map(|s| s.1).collect();
    let design = lsq::polynomial_design(&x, degree);
    let fit = lsq::solve(&design, &y, what)?;
    let op = lsq::solution_operator(&design, what)?;
    // E[RSS] = Σ (1 − h_LL)·v_L without a between-level effect.
    let expected: f64 = (0..x.len())
        .map(|i| {
            let h: f64 = (0..cols).map(|j| design[(i, j)] * op[(j, i)]).sum();
            (1.0 - h) * series[i].2
        })
        .sum();
    if expected.is_nan() || expected <= 0.0 {
        return Ok(None);
    }
    let dof = (x.len() - cols) as f64;
    let f = fit.stats.rss / expected;
    let dist = FisherSnedecor::new(dof, (p.dof_pe + n.dof_pe) as f64).map_err(|e| {
        AnalysisError::InvalidInput(format!("{what}: lack-of-fit distribution: {e}"))
    })?;
    Ok(Some((f, dist.sf(f))))
}

mod smooth;
pub use smooth::{Readings, SmoothMisfit, smooth_misfit};

#[cfg(test)]
mod tests;
