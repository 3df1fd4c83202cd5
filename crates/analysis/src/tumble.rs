//! Tumble calibration in the 1 g field: bias and scale factor of an
//! instrument from readings with its input axis at known angles to gravity.
//!
//! Accelerations here are in units of local gravity, so a tumble's ±1 g is
//! ±1 `g_local`, the same unit the centrifuge's method.md (3) uses.

use crate::lsq;
use crate::{AnalysisError, statistics::student_t_975};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// Bias and scale factor from a tumble, in output units (method.md (5)).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TumbleCalibration {
    /// k0': the output at 0 g [output units].
    pub bias_output: f64,
    /// k1': the scale factor [output units / g].
    pub scale_factor: f64,
}

impl TumbleCalibration {
    /// method.md (5): from the output with the input axis up (+1 g) and down (−1 g).
    pub fn from_up_down(output_up: f64, output_down: f64) -> Result<Self, AnalysisError> {
        for (what, v) in [("IA-up output", output_up), ("IA-down output", output_down)] {
            if !v.is_finite() {
                return Err(AnalysisError::NonFinite {
                    what: what.into(),
                    value: v,
                });
            }
        }
        let scale_factor = (output_up - output_down) / 2.0;
        if scale_factor == 0.0 {
            return Err(AnalysisError::InvalidInput(
                "tumble: the IA-up and IA-down outputs are equal, so the scale factor is zero \
                 (check the instrument is powered and was turned over)"
                    .into(),
            ));
        }
        Ok(TumbleCalibration {
            bias_output: (output_up + output_down) / 2.0,
            scale_factor,
        })
    }

    /// The bias as acceleration, k0'/k1' [g].
    pub fn bias_g(&self) -> f64 {
        self.bias_output / self.scale_factor
    }

    /// method.md (6): the acceleration an output stands for, (F − k0')/k1' [g].
    pub fn acceleration_g(&self, output: f64) -> f64 {
        (output - self.bias_output) / self.scale_factor
    }
}

/// One averaged reading: the mean of a step's one-second outputs and its
/// standard error (their standard deviation over √n).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeanReading {
    /// Mean output [output units].
    pub output: f64,
    /// Standard error of the mean [output units] (0 when unknown).
    pub standard_error: f64,
}

impl MeanReading {
    /// The mean and standard error of one-second values; `None` for none.
    pub fn of(values: &[f64]) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = if values.len() > 1 {
            values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)
        } else {
            0.0
        };
        Some(MeanReading {
            output: mean,
            standard_error: (var / n).sqrt(),
        })
    }
}

/// The largest cross-axis sensitivity accepted [g per g]: 0.1 is an input
/// axis about 6° off its fixture, far beyond any instrument; more means the
/// extra positions were not taken with the input axis horizontal.
pub const MAX_CROSS_AXIS_G_PER_G: f64 = 0.1;

/// The instrument's sensitivity to gravity across its input axis, from the
/// two extra positions of a four-position tumble: the
/// input axis horizontal, gravity along the cross axis that is vertical on
/// the centrifuge, once as on the arm and once inverted.
///
/// ```text
/// c = (F(as on arm) − F(inverted)) / (2·k1')      [g per g]
/// ```
///
/// On the arm gravity adds c to every reading; at the 1 g radius step it
/// reads as a radius error of c (relative), with the sign of the mounting,
/// which the radius then corrects ([`crate::radius::RadiusCalibration::from_reading`]).
/// The difference of the two positions holds no k2 term (the input axis sees
/// 0 g in both), so c is exact to first order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CrossAxisSensitivity {
    /// c: output per g across the input axis, in g per g.
    pub g_per_g: f64,
    /// Its standard uncertainty from the two readings' noise [g per g].
    pub u_g_per_g: f64,
}

impl CrossAxisSensitivity {
    /// From the readings as on the arm and inverted, with the tumble's `cal`.
    pub fn from_readings(
        cal: &TumbleCalibration,
        as_on_arm: MeanReading,
        inverted: MeanReading,
    ) -> Result<Self, AnalysisError> {
        for (what, v) in [
            ("cross-axis reading as on the arm", as_on_arm.output),
            ("cross-axis reading inverted", inverted.output),
        ] {
            if !v.is_finite() {
                return Err(AnalysisError::NonFinite {
                    what: what.into(),
                    value: v,
                });
            }
        }
        let two_k1 = 2.0 * cal.scale_factor;
        let g_per_g = (as_on_arm.output - inverted.output) / two_k1;
        if g_per_g.abs() > MAX_CROSS_AXIS_G_PER_G {
            return Err(AnalysisError::InvalidInput(format!(
                "four-position tumble: the cross-axis readings differ by {:.3} g, more than an \
                 instrument's cross-axis sensitivity; check that the input axis was horizontal \
                 in both extra positions",
                2.0 * g_per_g
            )));
        }
        Ok(CrossAxisSensitivity {
            g_per_g,
            u_g_per_g: as_on_arm.standard_error.hypot(inverted.standard_error) / two_k1.abs(),
        })
    }

    /// c in µg/g.
    pub fn ug_per_g(&self) -> f64 {
        self.g_per_g * 1e6
    }
}

/// One reading of a multi-position tumble.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TumbleReading {
    /// Rotation about the horizontal tumble axis from the IA-up position [deg].
    pub angle_deg: f64,
    /// Instrument output at that angle.
    pub output: f64,
}

/// A multi-position tumble fitted by least squares:
/// `output(θ) = B + K1·cos(θ − δ) = B + K1·cos δ·cos θ + K1·sin δ·sin θ`,
/// where δ is the input axis' misalignment in the plane of rotation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MultiPositionTumble {
    /// Number of positions used.
    pub positions: usize,
    /// Bias B [output units].
    pub bias_output: f64,
    /// Scale factor K1 [output units / g].
    pub scale_factor: f64,
    /// Input-axis misalignment δ [rad].
    pub misalignment_rad: f64,
    /// Standard errors of (B, K1, δ); `None` with exactly 3 positions' worth of dof.
    pub std_error: Option<[f64; 3]>,
    /// 95 % half-widths of (B, K1, δ).
    pub ci95_half_width: Option<[f64; 3]>,
    /// RMS of the residuals [output units].
    pub residual_rms: f64,
}

impl MultiPositionTumble {
    /// Fit readings at `n ≥ 4` equally spaced angles, the first at `start_deg`.
    pub fn fit_equally_spaced(outputs: &[f64], start_deg: f64) -> Result<Self, AnalysisError> {
        let step = 360.0 / outputs.len().max(1) as f64;
        let readings: Vec<TumbleReading> = outputs
            .iter()
            .enumerate()
            .map(|(i, &output)| TumbleReading {
                angle_deg: start_deg + step * i as f64,
                output,
            })
            .collect();
        Self::fit(&readings)
    }

    /// Fit readings at any angles; at least 4 distinct positions are needed.
    /// Equally spaced angles make the three terms orthogonal and are best.
    pub fn fit(readings: &[TumbleReading]) -> Result<Self, AnalysisError> {
        let mut angles: Vec<f64> = readings
            .iter()
            .map(|r| r.angle_deg.rem_euclid(360.0))
            .collect();
        angles.sort_by(f64::total_cmp);
        angles.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        if angles.len() < 4 {
            return Err(AnalysisError::InvalidInput(format!(
                "multi-position tumble: {} distinct position(s); at least 4 are needed",
                angles.len()
            )));
        }
        let design = DMatrix::from_fn(readings.len(), 3, |i, j| {
            let theta = readings[i].angle_deg.to_radians();
            match j {
                0 => 1.0,
                1 => theta.cos(),
                _ => theta.sin(),
            }
        });
        let y: Vec<f64> = readings.iter().map(|r| r.output).collect();
        let fit = lsq::solve(&design, &y, "multi-position tumble")?;
        let [b, c, s] = [
            fit.coefficients[0],
            fit.coefficients[1],
            fit.coefficients[2],
        ];
        // Keep δ in (−90°, 90°): the sign of the scale factor follows cos δ > 0.
        let sign = if c < 0.0 { -1.0 } else { 1.0 };
        let k1 = sign * c.hypot(s);
        if k1 == 0.0 {
            return Err(AnalysisError::InvalidInput(
                "multi-position tumble: the output does not change with angle".into(),
            ));
        }
        let delta = (s / c).atan();
        // Delta method: K1 = sign·sqrt(c²+s²), δ = atan(s/c).
        let std_error = fit.covariance.as_ref().map(|cov| {
            let h = c.hypot(s);
            let dk = [sign * c / h, sign * s / h];
            let dd = [-s / (h * h), c / (h * h)];
            let var = |g: [f64; 2]| {
                g[0] * g[0] * cov[(1, 1)]
                    + 2.0 * g[0] * g[1] * cov[(1, 2)]
                    + g[1] * g[1] * cov[(2, 2)]
            };
            [
                cov[(0, 0)].sqrt(),
                var(dk).max(0.0).sqrt(),
                var(dd).max(0.0).sqrt(),
            ]
        });
        let t = student_t_975(fit.stats.dof);
        Ok(MultiPositionTumble {
            positions: readings.len(),
            bias_output: b,
            scale_factor: k1,
            misalignment_rad: delta,
            ci95_half_width: std_error.zip(t).map(|(se, t)| se.map(|v| v * t)),
            std_error,
            residual_rms: fit.stats.residual_rms,
        })
    }

    /// The bias and scale factor as a two-position calibration would give them.
    pub fn calibration(&self) -> TumbleCalibration {
        TumbleCalibration {
            bias_output: self.bias_output,
            scale_factor: self.scale_factor,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn up_down_gives_bias_and_scale_factor() {
        // k1 = 100 Hz/g, bias 40 Hz: up = 140, down = −60.
        let cal = TumbleCalibration::from_up_down(140.0, -60.0).expect("cal");
        assert_eq!(cal.scale_factor, 100.0);
        assert_eq!(cal.bias_output, 40.0);
        assert_eq!(cal.bias_g(), 0.4);
        assert_eq!(cal.acceleration_g(240.0), 2.0);
    }

    #[test]
    fn equal_readings_are_refused() {
        assert!(TumbleCalibration::from_up_down(5.0, 5.0).is_err());
        assert!(TumbleCalibration::from_up_down(f64::NAN, 5.0).is_err());
    }

    #[test]
    fn multi_position_recovers_bias_scale_factor_and_misalignment() {
        let (b, k1, delta) = (35.0, 110.0, 0.002_f64);
        for n in [4usize, 6, 8, 12, 24] {
            let outputs: Vec<f64> = (0..n)
                .map(|i| {
                    let th = (360.0 * i as f64 / n as f64).to_radians();
                    b + k1 * (th - delta).cos()
                })
                .collect();
            let t = MultiPositionTumble::fit_equally_spaced(&outputs, 0.0).expect("fit");
            assert!((t.bias_output - b).abs() < 1e-9, "n={n}");
            assert!((t.scale_factor - k1).abs() < 1e-9, "n={n}");
            assert!((t.misalignment_rad - delta).abs() < 1e-12, "n={n}");
        }
    }

    #[test]
    fn cross_axis_positions_give_the_sensitivity_and_its_noise() {
        // k1 = 100 Hz/g, bias 40 Hz, 30 µg/g across: as on the arm 40 + 0.003,
        // inverted 40 − 0.003.
        let cal = TumbleCalibration::from_up_down(140.0, -60.0).expect("cal");
        let r = |output, standard_error| MeanReading {
            output,
            standard_error,
        };
        let c =
            CrossAxisSensitivity::from_readings(&cal, r(40.003, 3e-4), r(39.997, 4e-4)).expect("c");
        assert!((c.ug_per_g() - 30.0).abs() < 1e-6, "{}", c.ug_per_g());
        assert!((c.u_g_per_g - 5e-4 / 200.0).abs() < 1e-15);
        let err = CrossAxisSensitivity::from_readings(&cal, r(140.0, 0.0), r(40.0, 0.0))
            .expect_err("an IA-up reading given as a cross position");
        assert!(err.to_string().contains("horizontal"), "{err}");
    }

    #[test]
    fn a_mean_reading_has_the_standard_error_of_its_values() {
        let m = MeanReading::of(&[1.0, 2.0, 3.0, 4.0]).expect("values");
        assert_eq!(m.output, 2.5);
        assert!((m.standard_error - (5.0f64 / 3.0 / 4.0).sqrt()).abs() < 1e-15);
        assert!(MeanReading::of(&[]).is_none());
    }

    #[test]
    fn three_positions_are_not_enough() {
        let err = MultiPositionTumble::fit_equally_spaced(&[1.0, 2.0, 3.0], 0.0);
        assert!(err.is_err());
    }
}
