//! The Allan deviation of an instrument's one-second values at rest and
//! its fit to white, flicker and random-walk terms: the noise half of the
//! station's model ([`super::StationModel::learn`]).

use crate::lsq;

/// The overlapping Allan deviation of one-second values [µg] at τ = 1, 2,
/// 4, … s up to a quarter of the series: (τ [s], σ_A(τ) [µg]).
pub fn allan_deviation(values_ug: &[f64]) -> Vec<(f64, f64)> {
    let n = values_ug.len();
    if values_ug.iter().any(|v| !v.is_finite()) {
        return Vec::new();
    }
    let mut sum = vec![0.0; n + 1];
    for (i, v) in values_ug.iter().enumerate() {
        sum[i + 1] = sum[i] + v;
    }
    let mut out = Vec::new();
    let mut m = 1usize;
    while 4 * m <= n {
        let mean = |k: usize| (sum[k + m] - sum[k]) / m as f64;
        let count = n - 2 * m + 1;
        let var = (0..count)
            .map(|k| (mean(k + m) - mean(k)).powi(2))
            .sum::<f64>()
            / (2.0 * count as f64);
        out.push((m as f64, var.sqrt()));
        m *= 2;
    }
    out
}

/// The terms of an Allan fit [µg, µg, µg²/s].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AllanFit {
    /// White: σ_A at 1 s of its term.
    pub white_ug: f64,
    /// Flicker floor.
    pub flicker_ug: f64,
    /// Random walk.
    pub random_walk_ug2_per_s: f64,
}

/// Fit `σ_A²(τ) = w²/τ + f² + q·τ/3` to an Allan deviation (relative
/// least squares, every term ≥ 0: the best of the fits of each subset of
/// terms whose coefficients are all non-negative). `None` with fewer than
/// three points.
pub fn fit_allan(adev: &[(f64, f64)]) -> Option<AllanFit> {
    let points: Vec<(f64, f64)> = adev
        .iter()
        .filter(|(t, s)| *t > 0.0 && s.is_finite() && *s > 0.0)
        .map(|(t, s)| (*t, s * s))
        .collect();
    if points.len() < 3 {
        return None;
    }
    let basis = |j: usize, tau: f64| match j {
        0 => 1.0 / tau,
        1 => 1.0,
        _ => tau / 3.0,
    };
    let mut best: Option<([f64; 3], f64)> = None;
    for mask in 1u8..8 {
        let terms: Vec<usize> = (0..3).filter(|j| mask & (1 << j) != 0).collect();
        // Rows scaled by 1/σ² (relative residuals).
        let design = nalgebra::DMatrix::from_fn(points.len(), terms.len(), |i, c| {
            basis(terms[c], points[i].0) / points[i].1
        });
        let y = vec![1.0; points.len()];
        let Ok(fit) = lsq::solve(&design, &y, "Allan fit") else {
            continue;
        };
        if fit
            .coefficients
            .iter()
            .any(|c| !(c.is_finite() && *c >= 0.0))
        {
            continue;
        }
        let mut coef = [0.0; 3];
        for (c, &j) in terms.iter().enumerate() {
            coef[j] = fit.coefficients[c];
        }
        if best.as_ref().is_none_or(|(_, rss)| fit.stats.rss < *rss) {
            best = Some((coef, fit.stats.rss));
        }
    }
    let (c, _) = best?;
    Some(AllanFit {
        white_ug: c[0].sqrt(),
        flicker_ug: c[1].sqrt(),
        random_walk_ug2_per_s: c[2],
    })
}
