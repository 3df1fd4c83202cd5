//! Model families compared by goodness of fit, as the published method
//! allows (method.md §3.4): polynomials of order 1–3 and two non-polynomial
//! families, ranked by the small-sample corrected Akaike criterion (AICc).
//!
//! The non-polynomial families each have one curvature parameter `c` on top
//! of an offset and a slope:
//! * exponential: `y = b0 + b1·(exp(c·a) − 1)/c`
//! * logarithmic: `y = b0 + b1·ln(1 + c·a)/c`
//!
//! Both tend to the straight line as c → 0. They are fitted by variable
//! projection: for a given c the best (b0, b1) is a straight-line regression
//! in closed form (centred, its residuals summed directly: no cancellation),
//! and c is found by a grid search refined by golden-section search. This 1-D search is written here rather than taken from an
//! optimisation crate (argmin et al.) because it is twenty lines and needs
//! none of a general optimiser's machinery.

use crate::lsq::{self, FitStats};
use crate::{AnalysisError, UG_PER_G};
use serde::{Deserialize, Serialize};

/// One candidate model's fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Short name: `poly1`, `poly2`, `poly3`, `exp` or `log`.
    pub model: String,
    /// The model's formula.
    pub formula: String,
    /// Number of fitted parameters.
    pub parameters: usize,
    /// RMS residual [output units].
    pub residual_rms: f64,
    /// RMS residual as acceleration [µg].
    pub residual_rms_ug: f64,
    /// Akaike information criterion.
    pub aic: f64,
    /// Corrected AIC (the ranking criterion); `None` when n ≤ k + 1.
    pub aicc: Option<f64>,
    /// Bayesian information criterion.
    pub bic: f64,
    /// Criterion minus the best model's criterion (0 for the best).
    pub delta: f64,
    /// Akaike weight exp(−Δ/2)/Σ: the relative likelihood of this model.
    pub weight: f64,
    /// The fitted parameters in the order of the formula.
    pub parameters_fitted: Vec<f64>,
}

/// Candidates ranked best first.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelComparison {
    /// The ranking criterion: `"aicc"`, or `"aic"` when some candidate has too few points for AICc.
    pub criterion: String,
    /// The candidates, best first.
    pub candidates: Vec<Candidate>,
    /// Candidates that could not be fitted, with the reason.
    pub skipped: Vec<String>,
}

/// Fit every family to `(x, y)` and rank them. `k1_abs` converts output
/// residuals to acceleration for `residual_rms_ug`.
pub fn compare_models(
    x: &[f64],
    y: &[f64],
    k1_abs: f64,
    what: &str,
) -> Result<ModelComparison, AnalysisError> {
    let mut fitted: Vec<(Candidate, FitStats)> = Vec::new();
    let mut skipped = Vec::new();
    let mut push =
        |model: &str, formula: &str, result: Result<(Vec<f64>, FitStats), AnalysisError>| {
            match result {
                Ok((params, stats)) => fitted.push((
                    Candidate {
                        model: model.to_string(),
                        formula: formula.to_string(),
                        parameters: stats.parameters,
                        residual_rms: stats.residual_rms,
                        residual_rms_ug: stats.residual_rms / k1_abs * UG_PER_G,
                        aic: stats.aic,
                        aicc: stats.aicc,
                        bic: stats.bic,
                        delta: 0.0,
                        weight: 0.0,
                        parameters_fitted: params,
                    },
                    stats,
                )),
                Err(e) => skipped.push(format!("{model}: {e}")),
            }
        };
    for (degree, model, formula) in [
        (1, "poly1", "b0 + b1·a"),
        (2, "poly2", "b0 + b1·a + b2·a²"),
        (3, "poly3", "b0 + b1·a + b2·a² + b3·a³"),
    ] {
        let result = lsq::solve(&lsq::polynomial_design(x, degree), y, what)
            .map(|fit| (fit.coefficients, fit.stats));
        push(model, formula, result);
    }
    push(
        "exp",
        "b0 + b1·(exp(c·a) − 1)/c",
        fit_curved(x, y, Family::Exponential),
    );
    push(
        "log",
        "b0 + b1·ln(1 + c·a)/c",
        fit_curved(x, y, Family::Logarithmic),
    );

    if fitted.is_empty() {
        return Err(AnalysisError::InvalidInput(format!(
            "{what}: no model family could be fitted ({})",
            skipped.join("; ")
        )));
    }
    let use_aicc = fitted.iter().all(|(c, _)| c.aicc.is_some());
    let score = |c: &Candidate| {
        if use_aicc {
            c.aicc.unwrap_or(c.aic)
        } else {
            c.aic
        }
    };
    let best = fitted
        .iter()
        .map(|(c, _)| score(c))
        .fold(f64::INFINITY, f64::min);
    let total: f64 = fitted
        .iter()
        .map(|(c, _)| (-(score(c) - best) / 2.0).exp())
        .sum();
    let mut candidates: Vec<Candidate> = fitted
        .into_iter()
        .map(|(mut c, _)| {
            c.delta = score(&c) - best;
            c.weight = (-c.delta / 2.0).exp() / total;
            c
        })
        .collect();
    candidates.sort_by(|a, b| {
        a.delta
            .total_cmp(&b.delta)
            .then(a.parameters.cmp(&b.parameters))
    });
    Ok(ModelComparison {
        criterion: if use_aicc { "aicc" } else { "aic" }.to_string(),
        candidates,
        skipped,
    })
}

#[derive(Clone, Copy)]
enum Family {
    Exponential,
    Logarithmic,
}

impl Family {
    /// The basis function value at x for curvature c, or `None` outside its domain.
    fn basis(self, c: f64, x: f64) -> Option<f64> {
        if c == 0.0 {
            return Some(x);
        }
        match self {
            Family::Exponential => Some((c * x).exp_m1() / c),
            Family::Logarithmic => (c * x > -1.0).then(|| (c * x).ln_1p() / c),
        }
    }
}

/// Straight-line regression of y on the basis in closed form; returns (rss, b0, b1).
fn line_on_basis(family: Family, c: f64, x: &[f64], y: &[f64]) -> Option<(f64, f64, f64)> {
    let n = x.len() as f64;
    let f: Vec<f64> = x
        .iter()
        .map(|&v| family.basis(c, v))
        .collect::<Option<_>>()?;
    let fbar = f.iter().sum::<f64>() / n;
    let ybar = y.iter().sum::<f64>() / n;
    let (mut sff, mut sfy) = (0.0, 0.0);
    for (fi, yi) in f.iter().zip(y) {
        let (df, dy) = (fi - fbar, yi - ybar);
        sff += df * df;
        sfy += df * dy;
    }
    if sff.is_nan() || sff <= 0.0 {
        return None;
    }
    let b1 = sfy / sff;
    // The residual sum of squares summed from the residuals themselves: the
    // shortcut Syy − b1·Sfy cancels (on a 70 g range with µg scatter the two
    // terms agree to ten digits) and can rank the families wrongly.
    let rss = f
        .iter()
        .zip(y)
        .map(|(fi, yi)| {
            let r = (yi - ybar) - b1 * (fi - fbar);
            r * r
        })
        .sum::<f64>();
    Some((rss, ybar - b1 * fbar, b1))
}

/// Fit a one-curvature family by grid + golden-section search on c.
fn fit_curved(x: &[f64], y: &[f64], family: Family) -> Result<(Vec<f64>, FitStats), AnalysisError> {
    const GRID: i32 = 40;
    let x_max = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    if x.len() < 4 || x_max == 0.0 {
        return Err(AnalysisError::InvalidInput(
            "needs at least 4 points with non-zero input".into(),
        ));
    }
    // |c·x| ≤ 0.95 keeps ln(1 + c·x) defined for every point and covers
    // curvatures far beyond any accelerometer's.
    let c_bound = 0.95 / x_max;
    let rss = |c: f64| line_on_basis(family, c, x, y).map_or(f64::INFINITY, |r| r.0);
    let step = 2.0 * c_bound / f64::from(GRID);
    let (best_i, _) = (0..=GRID)
        .map(|i| (i, rss(-c_bound + step * f64::from(i))))
        .fold(
            (0, f64::INFINITY),
            |(bi, br), (i, r)| if r < br { (i, r) } else { (bi, br) },
        );
    let centre = -c_bound + step * f64::from(best_i);
    let (mut lo, mut hi) = ((centre - step).max(-c_bound), (centre + step).min(c_bound));
    let ratio = (5.0_f64.sqrt() - 1.0) / 2.0;
    let (mut c1, mut c2) = (hi - ratio * (hi - lo), lo + ratio * (hi - lo));
    let (mut r1, mut r2) = (rss(c1), rss(c2));
    for _ in 0..100 {
        if hi - lo <= 1e-14 * c_bound {
            break;
        }
        if r1 < r2 {
            hi = c2;
            (c2, r2) = (c1, r1);
            c1 = hi - ratio * (hi - lo);
            r1 = rss(c1);
        } else {
            lo = c1;
            (c1, r1) = (c2, r2);
            c2 = lo + ratio * (hi - lo);
            r2 = rss(c2);
        }
    }
    let c = (lo + hi) / 2.0;
    let (_, b0, b1) = line_on_basis(family, c, x, y).ok_or_else(|| {
        AnalysisError::InvalidInput("the basis is constant over the points".into())
    })?;
    let residuals: Vec<f64> = x
        .iter()
        .zip(y)
        .map(|(&xi, &yi)| yi - b0 - b1 * family.basis(c, xi).unwrap_or(xi))
        .collect();
    Ok((vec![b0, b1, c], FitStats::new(&residuals, y, 3)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn levels() -> Vec<f64> {
        let mut x: Vec<f64> = vec![0.0, 1.0];
        x.extend((1..=14).map(|i| 5.0 * f64::from(i)));
        let mut both = x.clone();
        both.extend(x.iter().rev());
        both
    }

    #[test]
    fn exponential_data_prefer_the_exponential_family() {
        let x = levels();
        let c = 4e-3;
        let y: Vec<f64> = x
            .iter()
            .map(|a| 3.0 + 100.0 * (c * a).exp_m1() / c)
            .collect();
        let cmp = compare_models(&x, &y, 100.0, "exp").expect("compare");
        assert_eq!(cmp.candidates[0].model, "exp");
        let fitted_c = cmp.candidates[0].parameters_fitted[2];
        assert!((fitted_c - c).abs() < 1e-9 * c.max(1.0), "{fitted_c}");
        let weights: f64 = cmp.candidates.iter().map(|c| c.weight).sum();
        assert!((weights - 1.0).abs() < 1e-12);
    }

    #[test]
    fn curved_families_lose_no_digits_on_a_large_output_with_tiny_scatter() {
        // A 70 g range at 100 Hz/g with µg-level scatter: the sums of squares
        // are 1e10 times the residual's. The curved families include the
        // straight line (c → 0), so neither may fit worse than it.
        let x = levels();
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(i, a)| 3.0 + 100.0 * a + if i % 3 == 0 { 2e-4 } else { -1e-4 })
            .collect();
        let cmp = compare_models(&x, &y, 100.0, "line").expect("compare");
        let rms = |m: &str| {
            cmp.candidates
                .iter()
                .find(|c| c.model == m)
                .map(|c| c.residual_rms)
                .expect("candidate")
        };
        for family in ["exp", "log"] {
            assert!(
                rms(family) <= rms("poly1") * (1.0 + 1e-9),
                "{family}: {} against the line's {}",
                rms(family),
                rms("poly1")
            );
        }
    }

    #[test]
    fn quadratic_data_rank_a_polynomial_first_and_line_last() {
        let x = levels();
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(i, a)| 100.0 * (a + 2e-5 * a * a) + if i % 2 == 0 { 1e-4 } else { -1e-4 })
            .collect();
        let cmp = compare_models(&x, &y, 100.0, "quad").expect("compare");
        assert!(
            cmp.candidates[0].model.starts_with("poly"),
            "{:?}",
            cmp.candidates[0]
        );
        assert_eq!(
            cmp.candidates.last().map(|c| c.model.as_str()),
            Some("poly1")
        );
        assert_eq!(cmp.criterion, "aicc");
    }
}
