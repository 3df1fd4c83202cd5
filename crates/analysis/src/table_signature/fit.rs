//! The signature's arithmetic: each mounting's level residuals and slope,
//! the median and its standard error, the polynomial's residual projector,
//! and the spikes fitted beside the broad part (the module docs of
//! [`super`]).

use super::{
    BROAD_BUMPS, MAX_HEIGHT_UG, MAX_SPIKES, MIN_SPIKE_G, SE_FLOOR_UG, SIGNATURE_ALPHA, Spike,
};
use crate::UG_PER_G;
use crate::lsq;
use crate::points::Point;
use nalgebra::DMatrix;

/// Median and the standard error of the median (1.2533 × 1.4826 × MAD / √n).
pub(super) fn median_se(values: &mut [f64]) -> Option<(f64, f64)> {
    if values.is_empty() {
        return None;
    }
    let median = |v: &mut [f64]| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    let m = median(values);
    let mut dev: Vec<f64> = values.iter().map(|v| (v - m).abs()).collect();
    let mad = median(&mut dev);
    let n = values.len() as f64;
    Some((m, 1.2533 * 1.4826 * mad / n.sqrt()))
}

/// The projection onto the polynomial's residual space at `levels`:
/// I − X(XᵀX)⁻¹Xᵀ, one reading per level.
pub(super) fn residual_projector(levels: &[f64], degree: usize) -> Option<DMatrix<f64>> {
    let x = lsq::polynomial_design(levels, degree);
    let op = lsq::solution_operator(&x, "table signature").ok()?;
    let h = &x * &op;
    Some(DMatrix::identity(levels.len(), levels.len()) - h)
}

/// Fit spikes to the signature `s` (standard errors `se`) at `levels`
/// through the projector `m`, beside the broad part's powers (module
/// docs): forward selection over the levels, each spike added only while
/// significant.
pub(super) fn fit_spikes(
    levels: &[f64],
    s: &[f64],
    se: &[f64],
    m: &DMatrix<f64>,
    degree: usize,
) -> Vec<Spike> {
    let n = levels.len();
    // One level's standard error from a few mountings can come out small
    // by chance: none counts below half the levels' median.
    let floor = {
        let mut v = se.to_vec();
        median_se(&mut v).map_or(SE_FLOOR_UG, |(m, _)| (0.5 * m).max(SE_FLOOR_UG))
    };
    let w: Vec<f64> = se.iter().map(|e| 1.0 / e.max(floor).powi(2)).collect();
    let top = levels.iter().copied().fold(1.0_f64, f64::max);
    // The broad part: wide bumps spread over the range (half-width a
    // quarter of it), projected likewise.
    let broad: Vec<Vec<f64>> = (0..BROAD_BUMPS)
        .map(|k| {
            let centre = top * k as f64 / (BROAD_BUMPS - 1) as f64;
            let hw = 0.25 * top;
            let raw = DMatrix::from_fn(n, 1, |i, _| {
                1.0 / (1.0 + ((levels[i] - centre) / hw).powi(2))
            });
            (m * raw).iter().copied().collect()
        })
        .collect();
    let spike_shape = |l: usize| -> Vec<f64> { (0..n).map(|i| m[(i, l)]).collect() };
    // A spike is added when its F against what is left (the broad part's
    // misfit counts, not only the standard errors) is significant at
    // SIGNATURE_ALPHA over the candidate levels (Bonferroni).
    let candidates = levels.iter().filter(|g| **g >= MIN_SPIKE_G).count().max(1) as f64;
    // `added` spikes at once (k shapes in all): two resonances mask each
    // other, neither significant alone while the other's misfit counts,
    // so a pair is tried when no single spike is (its candidates the
    // pairs of levels).
    let significant = |ss: f64, new_ss: f64, k: usize, added: usize| -> bool {
        use statrs::distribution::{ContinuousCDF, FisherSnedecor};
        let dof = n as f64 - (degree + 1) as f64 - k as f64;
        if dof < 1.0 || new_ss <= 0.0 {
            return ss > new_ss;
        }
        let q = added as f64;
        let f = (ss - new_ss) / q / (new_ss / dof).max(1.0);
        let tried = if added == 1 {
            candidates
        } else {
            candidates * (candidates - 1.0) / 2.0
        };
        FisherSnedecor::new(q, dof).is_ok_and(|d| d.sf(f) * tried < SIGNATURE_ALPHA)
    };
    // Weighted least squares of s on the broad part and the spikes at
    // `chosen`: the spikes' heights and the weighted residual SS.
    let solve = |chosen: &[usize]| -> Option<(Vec<f64>, f64)> {
        let mut shapes: Vec<Vec<f64>> = broad.clone();
        shapes.extend(chosen.iter().map(|&l| spike_shape(l)));
        let k = shapes.len();
        if k + 1 >= n.saturating_sub(degree + 1) {
            return None;
        }
        let x = DMatrix::from_fn(n, k, |i, j| shapes[j][i] * w[i].sqrt());
        let y: Vec<f64> = (0..n).map(|i| s[i] * w[i].sqrt()).collect();
        let fit = lsq::solve(&x, &y, "table signature spikes").ok()?;
        let c = &fit.coefficients;
        let heights: Vec<f64> = c[broad.len()..].to_vec();
        if heights
            .iter()
            .any(|h| !h.is_finite() || h.abs() > MAX_HEIGHT_UG)
        {
            return None;
        }
        Some((heights, fit.stats.rss))
    };
    let Some((_, mut ss)) = solve(&[]) else {
        return Vec::new();
    };
    let mut chosen: Vec<usize> = Vec::new();
    let mut heights: Vec<f64> = Vec::new();
    while chosen.len() < MAX_SPIKES {
        let mut best: Option<(usize, f64, Vec<f64>)> = None;
        for l in (0..n).filter(|&l| !chosen.contains(&l) && levels[l] >= MIN_SPIKE_G) {
            let mut trial = chosen.clone();
            trial.push(l);
            if let Some((h, new_ss)) = solve(&trial)
                && best.as_ref().is_none_or(|b| new_ss < b.1)
            {
                best = Some((l, new_ss, h));
            }
        }
        let Some((l, new_ss, h)) = best else {
            break;
        };
        if significant(ss, new_ss, broad.len() + chosen.len() + 1, 1) {
            chosen.push(l);
            heights = h;
            ss = new_ss;
            continue;
        }
        if chosen.len() + 2 > MAX_SPIKES {
            break;
        }
        let open: Vec<usize> = (0..n)
            .filter(|&l| !chosen.contains(&l) && levels[l] >= MIN_SPIKE_G)
            .collect();
        let mut best_pair: Option<([usize; 2], f64, Vec<f64>)> = None;
        for (i, &a) in open.iter().enumerate() {
            // Two spikes side by side are a broad feature, not two
            // resonances each met at one speed.
            for &b in open[i + 1..].iter().filter(|&&b| b > a + 1) {
                let mut trial = chosen.clone();
                trial.extend([a, b]);
                if let Some((h, new_ss)) = solve(&trial)
                    && best_pair.as_ref().is_none_or(|p| new_ss < p.1)
                {
                    best_pair = Some(([a, b], new_ss, h));
                }
            }
        }
        match best_pair {
            Some((pair, new_ss, h))
                if significant(ss, new_ss, broad.len() + chosen.len() + 2, 2) =>
            {
                chosen.extend(pair);
                heights = h;
                ss = new_ss;
            }
            _ => break,
        }
    }
    chosen
        .iter()
        .zip(&heights)
        .map(|(&l, &h)| Spike {
            g: levels[l],
            height_ug: h,
        })
        .collect()
}

/// The level-mean residuals of `points`' polynomial fit of `degree`
/// (leaving the levels `skip` out of the fit) as acceleration [µg], by level.
pub(super) fn level_residuals(
    points: &[Point],
    degree: usize,
    skip: &[f64],
) -> Option<Vec<(f64, f64)>> {
    let kept: Vec<&Point> = points
        .iter()
        .filter(|p| !skip.contains(&p.g_nominal.abs()))
        .collect();
    let x: Vec<f64> = kept.iter().map(|p| p.g_magnitude()).collect();
    let y: Vec<f64> = kept.iter().map(|p| p.output).collect();
    let fit = lsq::solve(&lsq::polynomial_design(&x, degree), &y, "table signature").ok()?;
    let c = &fit.coefficients;
    let k1 = *c.get(1)?;
    if !(k1.is_finite() && k1 != 0.0) {
        return None;
    }
    let levels = crate::inadequacy::levels(points);
    Some(
        levels
            .iter()
            .map(|l| {
                let r = l
                    .members
                    .iter()
                    .map(|&i| {
                        let a = points[i].g_magnitude();
                        let predicted: f64 = c
                            .iter()
                            .enumerate()
                            .map(|(j, cj)| cj * a.powi(j as i32))
                            .sum();
                        points[i].output - predicted
                    })
                    .sum::<f64>()
                    / l.members.len() as f64;
                (l.g, r / k1 * UG_PER_G)
            })
            .collect(),
    )
}

/// The k1 (linear coefficient) of `points`' polynomial fit of `degree`.
pub(super) fn slope_of(points: &[Point], degree: usize) -> Option<f64> {
    let x: Vec<f64> = points.iter().map(Point::g_magnitude).collect();
    let y: Vec<f64> = points.iter().map(|p| p.output).collect();
    let fit = lsq::solve(&lsq::polynomial_design(&x, degree), &y, "table signature").ok()?;
    fit.coefficients.get(1).copied()
}
