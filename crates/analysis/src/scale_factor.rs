//! The scale-factor nonlinearity model, method.md (10)–(11).
//!
//! For every non-zero level i over −m..+m (P gives +a, N gives −a):
//! `K1(i) = (dF(i) − dF(0)) / (a_i − 0)` (10), where dF(0) is the mounting's
//! own 0 g output (a remount may shift the bias, so each side is referred to
//! its own zero), then `K1(a) = KA + KB·a + KC·a²` by least squares (11). The
//! residuals of (11) are the scale-factor nonlinearity.
//!
//! Under method.md (2), K1(a) = k1·(1 + k2·a + k3·a²), so KB/KA estimates k2
//! and KC/KA estimates k3; both ratios are reported as a cross-check.

use crate::lsq;
use crate::points::{Mount, Point, levels_of};
use crate::{AnalysisError, PPM, UG_PER_G};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// One level's scale factor, method.md (10).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScaleFactorPoint {
    /// Mounting of the level.
    pub mount: Mount,
    /// Nominal level [g] (magnitude).
    pub g_nominal: f64,
    /// Signed applied acceleration a_i [g].
    pub g_input: f64,
    /// K1(i) [output units / g].
    pub k1: f64,
    /// K1(i) minus the fitted K1(a_i) [output units / g].
    pub residual: f64,
    /// The residual in ppm of the mean scale factor.
    pub residual_ppm: f64,
}

/// The fitted scale-factor model (11) and its residual figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScaleFactorModel {
    /// KA [output units / g].
    pub ka: f64,
    /// KB [output units / g²].
    pub kb: f64,
    /// KC [output units / g³].
    pub kc: f64,
    /// KB/KA, an estimate of k2 [µg/g²].
    pub kb_over_ka_ug_per_g2: f64,
    /// KC/KA, an estimate of k3 [µg/g³].
    pub kc_over_ka_ug_per_g3: f64,
    /// Mean of the K1(i) [output units / g].
    pub mean_scale_factor: f64,
    /// Largest |residual| of (11) [output units / g].
    pub residual_max: f64,
    /// RMS of the residuals of (11) [output units / g].
    pub residual_rms: f64,
    /// Largest |residual| in ppm of the mean scale factor.
    pub residual_max_ppm: f64,
    /// RMS residual in ppm of the mean scale factor.
    pub residual_rms_ppm: f64,
    /// Mountings that contributed levels.
    pub mounts: Vec<Mount>,
    /// Every level's K1(i), signed input ascending.
    pub points: Vec<ScaleFactorPoint>,
}

/// Build (10) for every non-zero level and fit (11).
///
/// A mounting without a 0 g level cannot form (10) and is left out (its name
/// is returned in the error if no mounting is left). At least three distinct
/// non-zero levels are needed.
pub fn scale_factor_model(points: &[Point], what: &str) -> Result<ScaleFactorModel, AnalysisError> {
    let mut sf_points = Vec::new();
    let mut mounts = Vec::new();
    let mut missing_zero = Vec::new();
    for mount in [Mount::P, Mount::N] {
        let levels = levels_of(points.iter().filter(|p| p.mount == mount));
        if levels.is_empty() {
            continue;
        }
        let Some(zero) = levels.iter().find(|l| l.g_nominal == 0.0) else {
            missing_zero.push(mount.to_string());
            continue;
        };
        mounts.push(mount);
        for level in levels
            .iter()
            .filter(|l| l.g_nominal != 0.0 && l.g_applied != 0.0)
        {
            let a = mount.input_sign() * level.g_applied;
            sf_points.push(ScaleFactorPoint {
                mount,
                g_nominal: level.g_nominal,
                g_input: a,
                k1: (level.output - zero.output) / a,
                residual: 0.0,
                residual_ppm: 0.0,
            });
        }
    }
    if mounts.is_empty() {
        return Err(AnalysisError::InvalidInput(format!(
            "{what}: scale-factor model (10) needs a 0 g level; none in mounting {}",
            missing_zero.join(" or ")
        )));
    }
    let mut keys: Vec<f64> = sf_points.iter().map(|p| p.g_input).collect();
    keys.sort_by(f64::total_cmp);
    keys.dedup();
    if keys.len() < 3 {
        return Err(AnalysisError::TooFewLevels {
            what: format!("{what} scale-factor model (11)"),
            levels: keys.len(),
            needed: 3,
            order: 2,
        });
    }
    sf_points.sort_by(|a, b| a.g_input.total_cmp(&b.g_input));

    let x: Vec<f64> = sf_points.iter().map(|p| p.g_input).collect();
    let y: Vec<f64> = sf_points.iter().map(|p| p.k1).collect();
    let design = DMatrix::from_fn(x.len(), 3, |i, j| x[i].powi(j as i32));
    let fit = lsq::solve(&design, &y, &format!("{what} scale-factor model (11)"))?;
    let (ka, kb, kc) = (
        fit.coefficients[0],
        fit.coefficients[1],
        fit.coefficients[2],
    );
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let to_ppm = |v: f64| v / mean.abs() * PPM;
    for (p, r) in sf_points.iter_mut().zip(&fit.residuals) {
        p.residual = *r;
        p.residual_ppm = to_ppm(*r);
    }
    let residual_max = fit.residuals.iter().fold(0.0_f64, |m, r| m.max(r.abs()));
    Ok(ScaleFactorModel {
        ka,
        kb,
        kc,
        kb_over_ka_ug_per_g2: kb / ka * UG_PER_G,
        kc_over_ka_ug_per_g3: kc / ka * UG_PER_G,
        mean_scale_factor: mean,
        residual_max,
        residual_rms: fit.stats.residual_rms,
        residual_max_ppm: to_ppm(residual_max),
        residual_rms_ppm: to_ppm(fit.stats.residual_rms),
        mounts,
        points: sf_points,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points(k: [f64; 4], levels: &[f64], mounts: &[Mount]) -> Vec<Point> {
        let mut out = Vec::new();
        for &mount in mounts {
            for &g in levels {
                let a = mount.input_sign() * g;
                out.push(Point {
                    mount,
                    g_nominal: g,
                    g_applied: g,
                    output: k[1] * (k[0] + a + k[2] * a * a + k[3] * a * a * a),
                    direction: None,
                });
            }
        }
        out
    }

    #[test]
    fn noise_free_model_gives_k1_k2_k3_back() {
        let k = [0.02, 95.0, 12e-6, -0.5e-6];
        let pts = points(
            k,
            &[0.0, 1.0, 5.0, 10.0, 20.0, 40.0, 70.0],
            &[Mount::P, Mount::N],
        );
        let sf = scale_factor_model(&pts, "test").expect("model");
        assert!((sf.ka - 95.0).abs() < 1e-9);
        assert!((sf.kb_over_ka_ug_per_g2 - 12.0).abs() < 1e-6);
        assert!((sf.kc_over_ka_ug_per_g3 + 0.5).abs() < 1e-6);
        assert!(sf.residual_max_ppm < 1e-6);
        assert_eq!(sf.points.len(), 12);
        assert_eq!(sf.mounts, vec![Mount::P, Mount::N]);
    }

    #[test]
    fn a_mounting_without_zero_is_left_out_and_none_left_is_an_error() {
        let k = [0.0, 100.0, 10e-6, 0.0];
        let mut pts = points(k, &[0.0, 1.0, 5.0, 10.0], &[Mount::P]);
        pts.extend(points(k, &[1.0, 5.0, 10.0], &[Mount::N]));
        let sf = scale_factor_model(&pts, "test").expect("P alone");
        assert_eq!(sf.mounts, vec![Mount::P]);
        let only_n = points(k, &[1.0, 5.0, 10.0], &[Mount::N]);
        let err = scale_factor_model(&only_n, "unit X").expect_err("no zero");
        assert!(err.to_string().contains("0 g level"), "{err}");
    }
}
