//! The IEEE Std 1293 static model, method.md (2):
//! `output = k1 · (k0 + a + k2·a² + k3·a³)`.
//!
//! The model is fitted as the polynomial `c0 + c1·a + c2·a² + c3·a³` by
//! [`crate::lsq::solve`] and reparameterised: `k1 = c1`, `k0 = c0/c1`,
//! `k2 = c2/c1`, `k3 = c3/c1`. The reparameterisation is one-to-one, so the
//! least-squares solution is the same; the covariance of the k's follows by
//! the delta method (first-order propagation through the Jacobian), which is
//! exact to well below the statistical error because c1 is known to parts per
//! million or better.
//!
//! Two conventions are offered (method.md §3.4):
//! * [`Convention::PerMounting`] — against the *magnitude* of the applied
//!   acceleration, one fit per mounting, as the published station does; in
//!   mounting N the output falls as `a` rises, so k1 and k0 (and k2) come
//!   out with the opposite sign and `k2_max` compares magnitudes.
//! * [`Convention::SignedInput`] — the IEEE 1293 form over −m..+m with the
//!   signed input (+a in P, −a in N), one set of coefficients for both.

use crate::lsq::{self, FitStats};
use crate::points::{Direction, Mount, Point};
use crate::statistics::student_t_975;
use crate::{AnalysisError, UG_PER_G};
use nalgebra::{DMatrix, Matrix4};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Polynomial order of the fitted model: 1 (k0, k1), 2 (+k2) or 3 (+k3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub enum ModelOrder {
    /// Bias and scale factor only.
    Linear,
    /// Adds the second-order coefficient k2.
    Quadratic,
    /// Adds k3; the published station's model and the default.
    #[default]
    Cubic,
}

impl ModelOrder {
    /// The order from its number, 1 to 3.
    pub fn from_degree(degree: u8) -> Option<ModelOrder> {
        match degree {
            1 => Some(ModelOrder::Linear),
            2 => Some(ModelOrder::Quadratic),
            3 => Some(ModelOrder::Cubic),
            _ => None,
        }
    }

    /// The highest power of `a` in the model.
    pub fn degree(self) -> u8 {
        match self {
            ModelOrder::Linear => 1,
            ModelOrder::Quadratic => 2,
            ModelOrder::Cubic => 3,
        }
    }

    /// Number of coefficients (degree + 1).
    pub fn coefficients(self) -> usize {
        usize::from(self.degree()) + 1
    }
}

impl Serialize for ModelOrder {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u8(self.degree())
    }
}

impl<'de> Deserialize<'de> for ModelOrder {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let degree = u8::deserialize(d)?;
        ModelOrder::from_degree(degree).ok_or_else(|| {
            serde::de::Error::custom(format!("model order {degree} is not 1, 2 or 3"))
        })
    }
}

/// The output of method.md (2) at signed input `a_g` for coefficients
/// `[k0_g, k1, k2, k3]` (k2 in 1/g, k3 in 1/g², not µg): the truth of simulations and tests.
pub fn ieee1293_output(k: [f64; 4], a_g: f64) -> f64 {
    let [k0, k1, k2, k3] = k;
    k1 * (k0 + a_g + k2 * a_g * a_g + k3 * a_g * a_g * a_g)
}

/// Which acceleration the model is fitted against (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convention {
    /// Magnitude of the applied acceleration, one mounting at a time.
    PerMounting,
    /// Signed input, +|a| in P and −|a| in N, both mountings together.
    SignedInput,
}

/// The four model coefficients with one kind of value each (value, error, interval).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Coefficients<T> {
    /// Bias [g].
    pub k0_g: T,
    /// Scale factor [output units / g].
    pub k1: T,
    /// Second-order coefficient [µg/g²].
    pub k2_ug_per_g2: T,
    /// Third-order coefficient [µg/g³].
    pub k3_ug_per_g3: T,
}

/// A closed interval `[low, high]`.
pub type Interval = [f64; 2];

/// One observation's residual from a fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Residual {
    /// Mounting of the point.
    pub mount: Mount,
    /// Nominal level [g].
    pub g_nominal: f64,
    /// Input used by the fit [g] (magnitude or signed, per the convention).
    pub g_input: f64,
    /// Observed output.
    pub output: f64,
    /// Observed minus fitted output [output units].
    pub residual: f64,
    /// The residual expressed as acceleration, residual/|k1| [µg].
    pub residual_ug: f64,
    /// Ascending or descending, when known.
    pub direction: Option<Direction>,
}

/// The result of fitting method.md (2) to a set of points.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ieee1293Fit {
    /// Model order fitted.
    pub order: ModelOrder,
    /// Number of points used.
    pub points: usize,
    /// Number of distinct nominal levels among them.
    pub levels: usize,
    /// Bias k0 [g].
    pub k0_g: f64,
    /// Scale factor k1 [output units / g].
    pub k1: f64,
    /// k2 [µg/g²]; `None` for order 1.
    pub k2_ug_per_g2: Option<f64>,
    /// k3 [µg/g³]; `None` for orders 1 and 2.
    pub k3_ug_per_g3: Option<f64>,
    /// Standard errors; `None` where the coefficient is not fitted or dof = 0.
    pub std_error: Coefficients<Option<f64>>,
    /// 95 % confidence intervals, value ± t(0.975, dof)·standard error.
    pub ci95: Coefficients<Option<Interval>>,
    /// Residual degrees of freedom.
    pub dof: usize,
    /// RMS of the residuals [output units].
    pub residual_rms: f64,
    /// RMS of the residuals as acceleration [µg].
    pub residual_rms_ug: f64,
    /// Coefficient of determination.
    pub r_squared: Option<f64>,
    /// Akaike information criterion (see [`FitStats::aic`]).
    pub aic: f64,
    /// Small-sample corrected AIC.
    pub aicc: Option<f64>,
    /// Bayesian information criterion.
    pub bic: f64,
    /// Residual of every point, in input order.
    pub residuals: Vec<Residual>,
    /// The fitted polynomial c0..c3 in output units (unused powers are 0).
    /// Not serialized: a fit read back derives it from its coefficients.
    #[serde(skip_serializing, default)]
    pub polynomial: [f64; 4],
}

impl Ieee1293Fit {
    /// The model's output at input acceleration `a_g` (in this fit's convention).
    pub fn predict(&self, a_g: f64) -> f64 {
        let c = self.polynomial_coefficients();
        c[0] + a_g * (c[1] + a_g * (c[2] + a_g * c[3]))
    }

    /// c0..c3 in output units: as fitted, or, for a fit read back from JSON
    /// (which does not carry them), from method.md (2)'s coefficients:
    /// c0 = k1·k0, c1 = k1, c2 = k1·k2, c3 = k1·k3 (k2, k3 in 1/g, 1/g²).
    pub fn polynomial_coefficients(&self) -> [f64; 4] {
        if self.polynomial != [0.0; 4] {
            return self.polynomial;
        }
        let per_g = |ug: Option<f64>| ug.unwrap_or(0.0) / UG_PER_G;
        [
            self.k1 * self.k0_g,
            self.k1,
            self.k1 * per_g(self.k2_ug_per_g2),
            self.k1 * per_g(self.k3_ug_per_g3),
        ]
    }
}

/// One mounting's fit, as the published station reports it (method.md §3.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MountingFit {
    /// The mounting fitted.
    pub mount: Mount,
    /// The fit against the applied-acceleration magnitude.
    #[serde(flatten)]
    pub fit: Ieee1293Fit,
    /// Does the model fit: lack of fit, outlier levels, influence.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diagnostics: Option<crate::diagnostics::Diagnostics>,
    /// The GUM uncertainty of each coefficient: Type A (repeatability) and
    /// the Type B inputs given ([`crate::uncertainty`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<Coefficients<Option<crate::uncertainty::Uncertainty>>>,
}

/// Fit method.md (2) to `points` under `convention`.
///
/// `what` names the data in errors (e.g. "unit SN12 mounting P"). Needs at
/// least `order + 1` distinct levels; standard errors need one point more.
pub fn fit_ieee1293(
    points: &[Point],
    order: ModelOrder,
    convention: Convention,
    what: &str,
) -> Result<Ieee1293Fit, AnalysisError> {
    let input = |p: &Point| match convention {
        Convention::PerMounting => p.g_magnitude(),
        Convention::SignedInput => p.g_signed(),
    };
    let mut level_keys: Vec<f64> = points
        .iter()
        .map(|p| match convention {
            Convention::PerMounting => p.g_nominal.abs(),
            Convention::SignedInput => p.mount.input_sign() * p.g_nominal.abs(),
        })
        .collect();
    level_keys.sort_by(f64::total_cmp);
    level_keys.dedup();
    let levels = level_keys.len();
    let p = order.coefficients();
    if levels < p {
        return Err(AnalysisError::TooFewLevels {
            what: what.to_string(),
            levels,
            needed: p,
            order: order.degree(),
        });
    }

    let x: Vec<f64> = points.iter().map(input).collect();
    let y: Vec<f64> = points.iter().map(|p| p.output).collect();
    let degree = usize::from(order.degree());
    let fit = lsq::solve(&lsq::polynomial_design(&x, degree), &y, what)?;

    let mut c = [0.0; 4];
    c[..p].copy_from_slice(&fit.coefficients);
    let c1 = c[1];
    // The scale factor is "zero" when its change over the range is at the
    // rounding level of the data, or when it is not significant (|c1| < 3σ):
    // the output does not follow the acceleration (a dead or unpowered unit).
    let x_max = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let y_max = y.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let c1_se = fit
        .covariance
        .as_ref()
        .map(|cov| cov[(1, 1)].max(0.0).sqrt());
    let negligible = c1.abs() * x_max <= 1e-9 * y_max;
    let insignificant = c1_se.is_some_and(|se| c1.abs() < 3.0 * se);
    if !c1.is_finite() || c1 == 0.0 || negligible || insignificant {
        return Err(AnalysisError::ZeroScaleFactor {
            what: what.to_string(),
        });
    }

    // k = g(c): k0 = c0/c1, k1 = c1, k2 = c2/c1, k3 = c3/c1 (k2, k3 scaled to µg).
    let k = [c[0] / c1, c1, c[2] / c1 * UG_PER_G, c[3] / c1 * UG_PER_G];
    // Jacobian ∂k/∂c (rows k0..k3, columns c0..c3), for the delta method.
    let jacobian = Matrix4::new(
        1.0 / c1,
        -c[0] / (c1 * c1),
        0.0,
        0.0,
        0.0,
        1.0,
        0.0,
        0.0,
        0.0,
        -c[2] / (c1 * c1) * UG_PER_G,
        UG_PER_G / c1,
        0.0,
        0.0,
        -c[3] / (c1 * c1) * UG_PER_G,
        0.0,
        UG_PER_G / c1,
    );
    let std_errors: [Option<f64>; 4] = match &fit.covariance {
        Some(cov_c) => {
            let mut cov4 = DMatrix::<f64>::zeros(4, 4);
            cov4.view_mut((0, 0), (p, p)).copy_from(cov_c);
            let j = DMatrix::from_fn(4, 4, |r, col| jacobian[(r, col)]);
            let cov_k = &j * cov4 * j.transpose();
            std::array::from_fn(|i| (i < p).then(|| cov_k[(i, i)].max(0.0).sqrt()))
        }
        None => [None; 4],
    };
    let t = student_t_975(fit.stats.dof);
    let interval = |i: usize| -> Option<Interval> {
        let se = std_errors[i]?;
        let t = t?;
        Some([k[i] - t * se, k[i] + t * se])
    };
    let present = |i: usize| (i < p).then_some(k[i]);

    let k1_abs = c1.abs();
    let residuals = points
        .iter()
        .zip(&x)
        .zip(&fit.residuals)
        .map(|((pt, &g_input), &r)| Residual {
            mount: pt.mount,
            g_nominal: pt.g_nominal,
            g_input,
            output: pt.output,
            residual: r,
            residual_ug: r / k1_abs * UG_PER_G,
            direction: pt.direction,
        })
        .collect();
    let FitStats {
        dof,
        residual_rms,
        r_squared,
        aic,
        aicc,
        bic,
        ..
    } = fit.stats;

    Ok(Ieee1293Fit {
        order,
        points: points.len(),
        levels,
        k0_g: k[0],
        k1: k[1],
        k2_ug_per_g2: present(2),
        k3_ug_per_g3: present(3),
        std_error: Coefficients {
            k0_g: std_errors[0],
            k1: std_errors[1],
            k2_ug_per_g2: std_errors[2],
            k3_ug_per_g3: std_errors[3],
        },
        ci95: Coefficients {
            k0_g: interval(0),
            k1: interval(1),
            k2_ug_per_g2: interval(2),
            k3_ug_per_g3: interval(3),
        },
        dof,
        residual_rms,
        residual_rms_ug: residual_rms / k1_abs * UG_PER_G,
        r_squared,
        aic,
        aicc,
        bic,
        residuals,
        polynomial: c,
    })
}

/// Fit one mounting's points (magnitude convention); every point must be in `mount`.
pub fn fit_mounting(
    points: &[Point],
    mount: Mount,
    order: ModelOrder,
    what: &str,
) -> Result<MountingFit, AnalysisError> {
    if points.is_empty() {
        return Err(AnalysisError::NoPoints(mount));
    }
    if let Some(other) = points.iter().find(|p| p.mount != mount) {
        return Err(AnalysisError::InvalidInput(format!(
            "{what}: a point in mounting {} was given to the mounting-{mount} fit",
            other.mount
        )));
    }
    let fit = fit_ieee1293(points, order, Convention::PerMounting, what)?;
    let residuals: Vec<f64> = fit.residuals.iter().map(|r| r.residual).collect();
    let diagnostics = crate::diagnostics::diagnose(
        points,
        &residuals,
        usize::from(order.degree()),
        fit.k1.abs(),
        what,
    )
    .ok();
    Ok(MountingFit {
        mount,
        fit,
        diagnostics,
        uncertainty: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Output of method.md (2) at signed input `a`.
    fn model(k: [f64; 4], a: f64) -> f64 {
        k[1] * (k[0] + a + k[2] * a * a + k[3] * a * a * a)
    }

    fn pass(mount: Mount, k: [f64; 4], levels: &[f64]) -> Vec<Point> {
        levels
            .iter()
            .chain(levels.iter().rev())
            .map(|&g| Point {
                mount,
                g_nominal: g,
                g_applied: g,
                output: model(k, mount.input_sign() * g),
                direction: None,
            })
            .collect()
    }

    #[test]
    fn mounting_n_flips_k1_k0_and_k2_but_not_k3() {
        let truth = [0.01, 120.0, 15e-6, 0.4e-6];
        let levels = [0.0, 1.0, 5.0, 10.0, 20.0, 30.0, 50.0, 70.0];
        let p = fit_mounting(
            &pass(Mount::P, truth, &levels),
            Mount::P,
            ModelOrder::Cubic,
            "P",
        )
        .expect("P fit");
        let n = fit_mounting(
            &pass(Mount::N, truth, &levels),
            Mount::N,
            ModelOrder::Cubic,
            "N",
        )
        .expect("N fit");
        let close = |a: f64, b: f64| ((a - b) / b).abs() < 1e-9;
        assert!(close(p.fit.k1, 120.0) && close(n.fit.k1, -120.0));
        assert!(close(p.fit.k0_g, 0.01) && close(n.fit.k0_g, -0.01));
        assert!(close(p.fit.k2_ug_per_g2.expect("k2"), 15.0));
        assert!(close(n.fit.k2_ug_per_g2.expect("k2"), -15.0));
        assert!(close(n.fit.k3_ug_per_g3.expect("k3"), 0.4));
    }

    #[test]
    fn too_few_levels_says_how_many_are_needed() {
        let pts = pass(Mount::P, [0.0, 100.0, 0.0, 0.0], &[0.0, 10.0, 20.0]);
        let err = fit_mounting(&pts, Mount::P, ModelOrder::Cubic, "unit A mounting P")
            .expect_err("3 levels cannot fit 4 coefficients");
        assert_eq!(
            err,
            AnalysisError::TooFewLevels {
                what: "unit A mounting P".into(),
                levels: 3,
                needed: 4,
                order: 3
            }
        );
        assert!(err.to_string().contains("at least 4"));
    }

    #[test]
    fn flat_output_has_no_scale_factor() {
        let mut pts = pass(Mount::P, [0.0, 100.0, 0.0, 0.0], &[0.0, 10.0, 20.0, 30.0]);
        for p in &mut pts {
            p.output = 5.0;
        }
        let err = fit_mounting(&pts, Mount::P, ModelOrder::Linear, "flat").expect_err("flat");
        assert!(
            matches!(err, AnalysisError::ZeroScaleFactor { .. }),
            "{err:?}"
        );
    }
}
