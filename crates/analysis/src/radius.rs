//! Each instrument's effective radius from a 1 g centrifuge reading,
//! method.md (6)–(9), as IEEE Std 836 practice asks (the drawing radius is
//! not trusted: a radius error is linear in `a` and corrupts k1).

use crate::AnalysisError;
use crate::centrifuge::applied_acceleration_g;
use crate::points::Mount;
use crate::tumble::{CrossAxisSensitivity, MeanReading, TumbleCalibration};
use serde::{Deserialize, Serialize};

/// The radius found for one instrument in one mounting.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RadiusCalibration {
    /// Mounting the reading was taken in.
    pub mount: Mount,
    /// The drawing radius R0 of the fixture position [m].
    pub drawing_radius_m: f64,
    /// Acceleration the instrument measured, method.md (6), magnitude [g].
    pub measured_g: f64,
    /// The acceleration the rate applies at R0 [g] (1 for the standard step).
    pub nominal_g: f64,
    /// The instrument's effective radius R± [m], method.md (7)/(8).
    pub radius_m: f64,
}

impl RadiusCalibration {
    /// method.md (6)–(8): spun at the rate that gives 1 g at `drawing_radius_m`,
    /// the instrument read `output`; with its tumble `cal`,
    /// a_meas = (F − k0')/k1' and R = |a_meas|·R0.
    ///
    /// In mounting P the measured acceleration must be positive and in N
    /// negative; the other sign means the mounting or the tumble is wrong.
    pub fn from_one_g(
        output: f64,
        cal: &TumbleCalibration,
        drawing_radius_m: f64,
        mount: Mount,
    ) -> Result<Self, AnalysisError> {
        Self::from_reading(output, cal, None, drawing_radius_m, 1.0, mount)
    }

    /// The general form of [`Self::from_one_g`]: the rate applied `nominal_g` at
    /// R0, so R = R0 · |a_meas| / nominal_g (method.md (7) with a scaled rate).
    ///
    /// With `cross_axis` from a four-position tumble, gravity's part of the
    /// reading is taken out first: on the arm gravity lies along the cross
    /// axis that the tumble's "as on the arm" position put vertical, in both
    /// mountings (the remount turns the instrument about the vertical), so
    ///
    /// ```text
    /// a_meas = (F − k0')/k1' − c        (method.md (6), corrected)
    /// ```
    ///
    /// Without it, c stays in the radius as a relative error of ±c (the
    /// mounting's sign), which the budget's `cross_axis` source bounds.
    pub fn from_reading(
        output: f64,
        cal: &TumbleCalibration,
        cross_axis: Option<CrossAxisSensitivity>,
        drawing_radius_m: f64,
        nominal_g: f64,
        mount: Mount,
    ) -> Result<Self, AnalysisError> {
        if !output.is_finite() {
            return Err(AnalysisError::NonFinite {
                what: "radius reading".into(),
                value: output,
            });
        }
        if !(drawing_radius_m > 0.0 && drawing_radius_m.is_finite()) {
            return Err(AnalysisError::InvalidInput(format!(
                "drawing radius must be a positive length in metres, got {drawing_radius_m}"
            )));
        }
        if !(nominal_g > 0.0 && nominal_g.is_finite()) {
            return Err(AnalysisError::InvalidInput(format!(
                "radius step level must be positive, got {nominal_g} g"
            )));
        }
        let a_meas = cal.acceleration_g(output) - cross_axis.map_or(0.0, |c| c.g_per_g);
        let signed = mount.input_sign() * a_meas;
        if signed.is_nan() || signed <= 0.0 {
            return Err(AnalysisError::InvalidInput(format!(
                "radius step in mounting {mount}: the instrument measured {a_meas:+.6} g, the wrong \
                 sign for this mounting; check that it is mounted {} and that the tumble readings \
                 (IA up, IA down) were not swapped",
                match mount {
                    Mount::P => "with the input axis toward the spin axis",
                    Mount::N => "with the input axis away from the spin axis",
                }
            )));
        }
        Ok(RadiusCalibration {
            mount,
            drawing_radius_m,
            measured_g: signed,
            nominal_g,
            radius_m: signed / nominal_g * drawing_radius_m,
        })
    }

    /// The radius's relative standard uncertainty from the noise of the
    /// readings it was found from [ppm]: the tumble's IA-up and IA-down
    /// readings, the reading at the radius step and, when measured, the
    /// cross-axis sensitivity. By method.md (5)–(7) with k0' = (U + D)/2,
    /// k1' = (U − D)/2 and m = (F − k0')/k1':
    ///
    /// ```text
    /// u(a)² = (u_F/k1')² + ((1 + m)·u_U/(2k1'))² + ((m − 1)·u_D/(2k1'))² + u(c)²
    /// u(R)/R = u(a)/|a|
    /// ```
    ///
    /// (Standard errors of one-second means: a drift within a step is not in them.)
    pub fn reading_u_ppm(
        &self,
        up: MeanReading,
        down: MeanReading,
        at_radius_step: MeanReading,
        cross_axis: Option<CrossAxisSensitivity>,
    ) -> f64 {
        let k1 = (up.output - down.output) / 2.0;
        if k1 == 0.0 || self.measured_g == 0.0 {
            return 0.0;
        }
        let k0 = (up.output + down.output) / 2.0;
        let m = (at_radius_step.output - k0) / k1;
        let u_a = (at_radius_step.standard_error / k1)
            .hypot((1.0 + m) * up.standard_error / (2.0 * k1))
            .hypot((m - 1.0) * down.standard_error / (2.0 * k1))
            .hypot(cross_axis.map_or(0.0, |c| c.u_g_per_g));
        1e6 * u_a.abs() / self.measured_g.abs()
    }

    /// Radius minus drawing radius [mm].
    pub fn offset_mm(&self) -> f64 {
        (self.radius_m - self.drawing_radius_m) * 1e3
    }

    /// method.md (9): the acceleration applied to this instrument at `rate_rad_s` [g].
    pub fn applied_g(&self, rate_rad_s: f64, g_local_m_s2: f64) -> Result<f64, AnalysisError> {
        applied_acceleration_g(rate_rad_s, self.radius_m, g_local_m_s2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::STANDARD_GRAVITY_M_S2 as G;
    use crate::centrifuge::rate_for_acceleration_rad_s;

    #[test]
    fn radius_follows_from_the_one_g_reading() {
        let cal = TumbleCalibration::from_up_down(140.0, -60.0).expect("tumble");
        let (r0, r_true) = (0.8, 0.8004);
        // At the 1 g rate for R0, the instrument at r_true sees r_true/r0 g.
        let w = rate_for_acceleration_rad_s(1.0, r0, G).expect("rate");
        let a_true = applied_acceleration_g(w, r_true, G).expect("a");
        let out_p = 40.0 + 100.0 * a_true;
        let rp = RadiusCalibration::from_one_g(out_p, &cal, r0, Mount::P).expect("P");
        assert!((rp.radius_m - r_true).abs() < 1e-12);
        assert!((rp.offset_mm() - 0.4).abs() < 1e-9);
        let out_n = 40.0 - 100.0 * a_true;
        let rn = RadiusCalibration::from_one_g(out_n, &cal, r0, Mount::N).expect("N");
        assert!((rn.radius_m - r_true).abs() < 1e-12);
        // (9): the applied acceleration at any rate uses the found radius.
        let w50 = rate_for_acceleration_rad_s(50.0, r0, G).expect("rate");
        let a50 = rp.applied_g(w50, G).expect("a");
        assert!((a50 - 50.0 * r_true / r0).abs() < 1e-9);
    }

    #[test]
    fn gravity_across_the_axis_is_taken_out_of_the_radius() {
        // 40 µg/g across: on the arm gravity adds 40 µg in both mountings.
        let (k0, k1, c) = (40.0, 100.0, 40e-6);
        let cal = TumbleCalibration::from_up_down(k0 + k1, k0 - k1).expect("tumble");
        let r = |output| MeanReading {
            output,
            standard_error: 0.0,
        };
        let cross = CrossAxisSensitivity::from_readings(&cal, r(k0 + k1 * c), r(k0 - k1 * c))
            .expect("cross");
        for mount in [Mount::P, Mount::N] {
            let out = k0 + k1 * (mount.input_sign() * 1.0 + c);
            let plain = RadiusCalibration::from_one_g(out, &cal, 0.8, mount).expect("plain");
            let corrected =
                RadiusCalibration::from_reading(out, &cal, Some(cross), 0.8, 1.0, mount)
                    .expect("corrected");
            assert!((corrected.radius_m - 0.8).abs() < 1e-12, "{mount}");
            // Uncorrected, the radius is off by c with the mounting's sign.
            let off = (plain.radius_m / 0.8 - 1.0) / c;
            assert!((off - mount.input_sign()).abs() < 1e-6, "{mount}: {off}");
        }
    }

    #[test]
    fn the_reading_uncertainty_follows_each_readings_noise() {
        let cal = TumbleCalibration::from_up_down(140.0, -60.0).expect("tumble");
        let reading = |output, standard_error| MeanReading {
            output,
            standard_error,
        };
        let r = RadiusCalibration::from_one_g(140.0, &cal, 0.8, Mount::P).expect("P");
        // In P at 1 g: (u_F/k1)² + (2·u_U/(2k1))² + 0·u_D = (1e-3/100)² + (1e-3/100)².
        let u = r.reading_u_ppm(
            reading(140.0, 1e-3),
            reading(-60.0, 5.0),
            reading(140.0, 1e-3),
            None,
        );
        assert!((u - 1e6 * 2f64.sqrt() * 1e-5).abs() < 1e-9, "{u}");
        let noiseless = r.reading_u_ppm(
            reading(140.0, 0.0),
            reading(-60.0, 0.0),
            reading(140.0, 0.0),
            None,
        );
        assert_eq!(noiseless, 0.0);
    }

    #[test]
    fn wrong_sign_for_the_mounting_is_explained() {
        let cal = TumbleCalibration::from_up_down(140.0, -60.0).expect("tumble");
        let err = RadiusCalibration::from_one_g(-60.0, &cal, 0.8, Mount::P).expect_err("sign");
        assert!(err.to_string().contains("wrong sign"), "{err}");
    }
}
