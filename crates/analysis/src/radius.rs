//! Each instrument's effective radius from a 1 g centrifuge reading,
//! method.md (6)–(9), as IEEE Std 836 practice asks (the drawing radius is
//! not trusted: a radius error is linear in `a` and corrupts k1).

use crate::AnalysisError;
use crate::centrifuge::applied_acceleration_g;
use crate::points::Mount;
use crate::tumble::TumbleCalibration;
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
        Self::from_reading(output, cal, drawing_radius_m, 1.0, mount)
    }

    /// The general form of [`Self::from_one_g`]: the rate applied `nominal_g` at
    /// R0, so R = R0 · |a_meas| / nominal_g (method.md (7) with a scaled rate).
    pub fn from_reading(
        output: f64,
        cal: &TumbleCalibration,
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
        let a_meas = cal.acceleration_g(output);
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
    fn wrong_sign_for_the_mounting_is_explained() {
        let cal = TumbleCalibration::from_up_down(140.0, -60.0).expect("tumble");
        let err = RadiusCalibration::from_one_g(-60.0, &cal, 0.8, Mount::P).expect_err("sign");
        assert!(err.to_string().contains("wrong sign"), "{err}");
    }
}
