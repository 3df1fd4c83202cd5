//! Linear least squares by SVD on a column-scaled design matrix.
//!
//! Every fit in this crate comes through [`solve`]. The design matrix is
//! equilibrated (each column divided by its 2-norm, a near-optimal diagonal
//! scaling) and solved by singular value decomposition; the normal equations
//! are never formed, because squaring the condition number of a cubic in
//! `a` up to 100 g would cost the digits k3 lives in.

use crate::AnalysisError;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Singular values below this fraction of the largest mean a rank-deficient design.
const RANK_TOLERANCE: f64 = 1e-12;

/// The solution of one linear least-squares problem, in the caller's (unscaled) basis.
#[derive(Debug, Clone)]
pub struct LinearFit {
    /// Fitted coefficients, one per design column.
    pub coefficients: Vec<f64>,
    /// Covariance of the coefficients, σ̂²·(XᵀX)⁻¹ computed from the SVD;
    /// `None` when there are no degrees of freedom left to estimate σ̂.
    pub covariance: Option<DMatrix<f64>>,
    /// Residuals y − Xβ, in the order of the observations.
    pub residuals: Vec<f64>,
    /// Goodness-of-fit statistics.
    pub stats: FitStats,
}

/// Goodness-of-fit statistics of a least-squares fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitStats {
    /// Number of observations.
    pub n: usize,
    /// Number of fitted parameters (including any found by search).
    pub parameters: usize,
    /// Degrees of freedom, n − parameters.
    pub dof: usize,
    /// Residual sum of squares.
    pub rss: f64,
    /// Root mean square of the residuals, sqrt(rss/n).
    pub residual_rms: f64,
    /// Residual standard error σ̂ = sqrt(rss/dof); `None` when dof = 0.
    pub sigma: Option<f64>,
    /// Coefficient of determination 1 − rss/tss; `None` when the data are constant.
    pub r_squared: Option<f64>,
    /// Akaike information criterion for Gaussian errors, n·ln(rss/n) + 2k with
    /// k = parameters + 1 (the variance). The constant n·(1+ln 2π) is left out:
    /// it is the same for every model of the same data.
    pub aic: f64,
    /// AIC with the small-sample correction 2k(k+1)/(n−k−1); `None` when n ≤ k+1.
    pub aicc: Option<f64>,
    /// Bayesian information criterion, n·ln(rss/n) + k·ln n.
    pub bic: f64,
}

impl FitStats {
    /// Statistics of a fit with `parameters` parameters from its residuals and data.
    ///
    /// A perfect fit has rss = 0 and ln 0 = −∞; the rss used in the criteria is
    /// floored at the size of double-precision rounding of the data, so that
    /// exact fits still rank by parameter count.
    pub fn new(residuals: &[f64], y: &[f64], parameters: usize) -> FitStats {
        let n = residuals.len();
        let rss: f64 = residuals.iter().map(|r| r * r).sum();
        let mean = y.iter().sum::<f64>() / n.max(1) as f64;
        let tss: f64 = y.iter().map(|v| (v - mean) * (v - mean)).sum();
        let dof = n.saturating_sub(parameters);
        let scale = y
            .iter()
            .fold(0.0_f64, |m, v| m.max(v.abs()))
            .max(f64::MIN_POSITIVE);
        let rss_floor = n as f64 * (f64::EPSILON * scale).powi(2);
        let nf = n as f64;
        let k = (parameters + 1) as f64;
        let log_lik_term = nf * (rss.max(rss_floor) / nf).ln();
        let aic = log_lik_term + 2.0 * k;
        FitStats {
            n,
            parameters,
            dof,
            rss,
            residual_rms: (rss / nf).sqrt(),
            sigma: (dof > 0).then(|| (rss / dof as f64).sqrt()),
            r_squared: (tss > 0.0).then(|| 1.0 - rss / tss),
            aic,
            aicc: (nf > k + 1.0).then(|| aic + 2.0 * k * (k + 1.0) / (nf - k - 1.0)),
            bic: log_lik_term + k * nf.ln(),
        }
    }
}

/// Solve `min ‖X β − y‖₂` for a design given row by row.
///
/// `what` names the fit in errors. Fails when there are fewer observations
/// than columns, when any input is not finite, or when the scaled design is
/// singular.
pub fn solve(design: &DMatrix<f64>, y: &[f64], what: &str) -> Result<LinearFit, AnalysisError> {
    let (n, p) = design.shape();
    if n != y.len() {
        return Err(AnalysisError::InvalidInput(format!(
            "{what}: {n} design rows but {} observations",
            y.len()
        )));
    }
    check_design(design, y, what)?;

    let Scaled {
        u,
        v_t,
        s_inv,
        norms,
    } = scaled_svd(design, what)?;

    let y_vec = DVector::from_column_slice(y);
    let uty = u.transpose() * &y_vec;
    let beta_scaled = v_t.transpose() * uty.component_mul(&s_inv);
    let coefficients: Vec<f64> = beta_scaled
        .iter()
        .zip(&norms)
        .map(|(b, norm)| b / norm)
        .collect();

    let fitted = design * DVector::from_column_slice(&coefficients);
    let residuals: Vec<f64> = y_vec
        .iter()
        .zip(fitted.iter())
        .map(|(a, b)| a - b)
        .collect();
    let stats = FitStats::new(&residuals, y, p);

    let covariance = stats.sigma.map(|sigma| {
        // Cov(β_scaled) = σ² V S⁻² Vᵀ; then undo the column scaling.
        let v = v_t.transpose();
        let vs = &v * DMatrix::from_diagonal(&s_inv.map(|x| x * x));
        let mut cov = vs * v_t * (sigma * sigma);
        for i in 0..p {
            for j in 0..p {
                cov[(i, j)] /= norms[i] * norms[j];
            }
        }
        cov
    });

    Ok(LinearFit {
        coefficients,
        covariance,
        residuals,
        stats,
    })
}

/// Refuse a design with fewer rows than columns, or any value of it or of
/// `y` that is not finite.
fn check_design(design: &DMatrix<f64>, y: &[f64], what: &str) -> Result<(), AnalysisError> {
    let (n, p) = design.shape();
    if n < p || p == 0 {
        return Err(AnalysisError::InvalidInput(format!(
            "{what}: {n} observation(s) cannot determine {p} coefficient(s)"
        )));
    }
    match design.iter().chain(y).find(|v| !v.is_finite()) {
        Some(v) => Err(AnalysisError::NonFinite {
            what: format!("{what}: an input value"),
            value: *v,
        }),
        None => Ok(()),
    }
}

/// The SVD of a column-equilibrated design: `design·diag(1/norms) = U·S·Vᵀ`.
struct Scaled {
    u: DMatrix<f64>,
    v_t: DMatrix<f64>,
    s_inv: DVector<f64>,
    norms: Vec<f64>,
}

/// Equilibrate `design` (each column divided by its 2-norm) and decompose
/// it; refuses a rank-deficient design.
fn scaled_svd(design: &DMatrix<f64>, what: &str) -> Result<Scaled, AnalysisError> {
    // Equilibrate: divide each column by its norm.
    let norms: Vec<f64> = design
        .column_iter()
        .map(|c| {
            let norm = c.norm();
            if norm > 0.0 { norm } else { 1.0 }
        })
        .collect();
    let mut scaled = design.clone();
    for (j, norm) in norms.iter().enumerate() {
        scaled.column_mut(j).scale_mut(1.0 / norm);
    }

    let svd = scaled.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(AnalysisError::InvalidInput(format!(
            "{what}: the singular value decomposition did not converge"
        )));
    };
    let s = &svd.singular_values;
    let s_max = s.max();
    let s_min = s.min();
    if s_min.is_nan() || s_min <= RANK_TOLERANCE * s_max {
        return Err(AnalysisError::Singular {
            what: what.to_string(),
            condition: if s_min > 0.0 {
                s_max / s_min
            } else {
                f64::INFINITY
            },
        });
    }

    Ok(Scaled {
        u,
        v_t,
        s_inv: s.map(|v| 1.0 / v),
        norms,
    })
}

/// The least-squares solution operator `(XᵀX)⁻¹Xᵀ` of `design` (p × n):
/// coefficient j of the fit of any y is `Σᵢ P[j,i]·yᵢ`, which is what a
/// budget needs to propagate a variance structure other than σ²·I
/// (`crate::inadequacy`). Computed from the same scaled SVD as [`solve`].
pub fn solution_operator(design: &DMatrix<f64>, what: &str) -> Result<DMatrix<f64>, AnalysisError> {
    check_design(design, &[], what)?;
    let Scaled {
        u,
        v_t,
        s_inv,
        norms,
    } = scaled_svd(design, what)?;
    let mut op = v_t.transpose() * DMatrix::from_diagonal(&s_inv) * u.transpose();
    for (j, norm) in norms.iter().enumerate() {
        op.row_mut(j).scale_mut(1.0 / norm);
    }
    Ok(op)
}

/// Design matrix of a polynomial in `x` of the given degree: columns 1, x, …, x^degree.
pub fn polynomial_design(x: &[f64], degree: usize) -> DMatrix<f64> {
    DMatrix::from_fn(x.len(), degree + 1, |i, j| x[i].powi(j as i32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_an_exact_cubic_at_high_acceleration() {
        let x: Vec<f64> = (0..=20).map(|i| f64::from(i) * 5.0).collect();
        let truth = [0.5, 100.0, 1e-3, 2e-6];
        let y: Vec<f64> = x
            .iter()
            .map(|a| truth[0] + truth[1] * a + truth[2] * a * a + truth[3] * a * a * a)
            .collect();
        let fit = solve(&polynomial_design(&x, 3), &y, "test").expect("fit");
        for (got, want) in fit.coefficients.iter().zip(truth) {
            assert!(((got - want) / want).abs() < 1e-10, "{got} vs {want}");
        }
        assert!(fit.stats.rss < 1e-18);
    }

    #[test]
    fn straight_line_standard_errors_match_textbook_formula() {
        let x = [0.0, 1.0, 2.0, 3.0, 4.0];
        let y = [0.1, 0.9, 2.2, 2.8, 4.1];
        let fit = solve(&polynomial_design(&x, 1), &y, "line").expect("fit");
        let n = 5.0;
        let xbar = 2.0;
        let sxx: f64 = x.iter().map(|v| (v - xbar) * (v - xbar)).sum();
        let sigma = fit.stats.sigma.expect("dof > 0");
        let cov = fit.covariance.expect("covariance");
        let se_slope = sigma / sxx.sqrt();
        let se_icpt = sigma * (1.0 / n + xbar * xbar / sxx).sqrt();
        assert!((cov[(1, 1)].sqrt() - se_slope).abs() < 1e-12);
        assert!((cov[(0, 0)].sqrt() - se_icpt).abs() < 1e-12);
    }

    #[test]
    fn singular_design_is_refused() {
        let x = [1.0, 1.0, 1.0, 1.0];
        let err = solve(&polynomial_design(&x, 1), &[1.0, 2.0, 3.0, 4.0], "flat");
        assert!(
            matches!(err, Err(AnalysisError::Singular { .. })),
            "{err:?}"
        );
    }

    #[test]
    fn non_finite_input_is_refused() {
        let x = [0.0, 1.0, 2.0];
        let err = solve(&polynomial_design(&x, 1), &[1.0, f64::NAN, 3.0], "nan");
        assert!(
            matches!(err, Err(AnalysisError::NonFinite { .. })),
            "{err:?}"
        );
    }
}
