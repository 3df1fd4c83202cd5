//! Centrifuge kinematics: method.md (3) and (4), and rate unit conversions.
//!
//! Rates are rad/s in these formulas; the station works in deg/s and allows
//! rpm in configuration, so conversions live here too.

/// The Earth's rate [rad/s] (sidereal).
pub const EARTH_RATE_RAD_S: f64 = 7.292_115e-5;

use crate::AnalysisError;

/// Degrees per second to radians per second.
pub fn deg_s_to_rad_s(rate_deg_s: f64) -> f64 {
    rate_deg_s.to_radians()
}

/// Radians per second to degrees per second.
pub fn rad_s_to_deg_s(rate_rad_s: f64) -> f64 {
    rate_rad_s.to_degrees()
}

/// Revolutions per minute to radians per second.
pub fn rpm_to_rad_s(rate_rpm: f64) -> f64 {
    rate_rpm * std::f64::consts::TAU / 60.0
}

/// Radians per second to revolutions per minute.
pub fn rad_s_to_rpm(rate_rad_s: f64) -> f64 {
    rate_rad_s * 60.0 / std::f64::consts::TAU
}

fn check_positive(what: &str, value: f64) -> Result<(), AnalysisError> {
    if !value.is_finite() {
        return Err(AnalysisError::NonFinite {
            what: what.into(),
            value,
        });
    }
    if value <= 0.0 {
        return Err(AnalysisError::InvalidInput(format!(
            "{what} must be positive, got {value}"
        )));
    }
    Ok(())
}

/// method.md (3): centripetal acceleration a = ω²·R / g_local [g].
pub fn applied_acceleration_g(
    rate_rad_s: f64,
    radius_m: f64,
    g_local_m_s2: f64,
) -> Result<f64, AnalysisError> {
    check_positive("radius [m]", radius_m)?;
    check_positive("g_local [m/s²]", g_local_m_s2)?;
    if !rate_rad_s.is_finite() {
        return Err(AnalysisError::NonFinite {
            what: "rate [rad/s]".into(),
            value: rate_rad_s,
        });
    }
    Ok(rate_rad_s * rate_rad_s * radius_m / g_local_m_s2)
}

/// method.md (4): the rate ω = sqrt(a·g_local / R) [rad/s] that applies `a_g` at `radius_m`.
pub fn rate_for_acceleration_rad_s(
    a_g: f64,
    radius_m: f64,
    g_local_m_s2: f64,
) -> Result<f64, AnalysisError> {
    check_positive("radius [m]", radius_m)?;
    check_positive("g_local [m/s²]", g_local_m_s2)?;
    if !a_g.is_finite() || a_g < 0.0 {
        return Err(AnalysisError::InvalidInput(format!(
            "target acceleration must be a finite number ≥ 0 g, got {a_g}"
        )));
    }
    Ok((a_g * g_local_m_s2 / radius_m).sqrt())
}

/// Error propagation of method.md §2: da/a = 2·dω/ω + dR/R (worst case, magnitudes).
pub fn relative_acceleration_error(relative_rate_error: f64, relative_radius_error: f64) -> f64 {
    2.0 * relative_rate_error.abs() + relative_radius_error.abs()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::STANDARD_GRAVITY_M_S2 as G;

    #[test]
    fn rate_and_acceleration_are_inverse() {
        for a in [0.0, 1.0, 5.0, 70.0, 100.0] {
            let w = rate_for_acceleration_rad_s(a, 0.8, G).expect("rate");
            let back = applied_acceleration_g(w, 0.8, G).expect("a");
            assert!((back - a).abs() < 1e-12 * a.max(1.0));
        }
    }

    #[test]
    fn one_g_at_eight_tenths_of_a_metre() {
        // ω = sqrt(9.80665 / 0.8) = 3.5012 rad/s = 33.43 rpm.
        let w = rate_for_acceleration_rad_s(1.0, 0.8, G).expect("rate");
        assert!((w - 3.501_187).abs() < 1e-6);
        assert!((rad_s_to_rpm(w) - 33.434).abs() < 1e-3);
        assert!((rpm_to_rad_s(rad_s_to_rpm(w)) - w).abs() < 1e-12);
        assert!((deg_s_to_rad_s(rad_s_to_deg_s(w)) - w).abs() < 1e-12);
    }

    #[test]
    fn bad_inputs_are_refused() {
        assert!(rate_for_acceleration_rad_s(-1.0, 0.8, G).is_err());
        assert!(rate_for_acceleration_rad_s(1.0, 0.0, G).is_err());
        assert!(applied_acceleration_g(1.0, 0.8, f64::NAN).is_err());
    }

    #[test]
    fn rate_error_counts_twice() {
        assert_eq!(relative_acceleration_error(1e-6, 1e-6), 3e-6);
    }
}
