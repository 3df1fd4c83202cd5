//! Temperature coefficients of an instrument (issue 15, part 5): its bias
//! k0, scale factor k1 and K2 reduced at each chamber temperature, and a
//! straight line through each against the instrument's own temperature.
//!
//! ```text
//! y(T) = y₀ + c·(T − T̄),  weights wᵢ = 1/u(yᵢ)²,  T̄ = Σ wᵢTᵢ / Σ wᵢ
//! c = Σ wᵢ(Tᵢ − T̄)yᵢ / Σ wᵢ(Tᵢ − T̄)²,   u(c) = 1/√(Σ wᵢ(Tᵢ − T̄)²)
//! ```
//!
//! With three or more temperatures the scatter about the line is compared
//! with the yᵢ's own uncertainties: when it is larger (Birge ratio
//! √(χ²/(n − 2)) above 1, a bend the line does not hold) u(c) grows by that
//! ratio and U95 takes Student's t at n − 2 degrees of freedom; otherwise
//! U95 = 1.96·u(c). The temperature's own spread over a temperature's points
//! (the instruments still settling while they are measured) enters as
//! errors in the variable: after a first fit, u(yᵢ)² gains (c·u(Tᵢ))² and
//! the line is fitted again. A sensor's calibration offset, common to every
//! temperature, leaves the slope and is not propagated.

use crate::AnalysisError;
use crate::model::student_t_975;
use serde::{Deserialize, Serialize};

/// One instrument's figures at one temperature, each with its standard uncertainty.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AtTemperature {
    /// The chamber's setpoint [°C].
    pub setpoint_c: f64,
    /// The instrument's mean temperature over its points there [°C].
    pub temperature_c: f64,
    /// The standard deviation of its points' temperatures there [°C].
    #[serde(default)]
    pub temperature_spread_c: f64,
    /// Bias [g] and its standard uncertainty.
    pub k0_g: [f64; 2],
    /// Scale factor [Hz/g] and its standard uncertainty.
    pub k1_hz_per_g: [f64; 2],
    /// K2, the even second-order term [µg/g²], and its standard uncertainty
    /// (absent with one mounting).
    pub k2_ug_per_g2: Option<[f64; 2]>,
}

/// The temperature coefficients and their expanded uncertainties (95 %).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TemperatureCoefficients {
    /// Bias [µg/°C].
    pub k0_ug_per_c: f64,
    /// Its U95.
    #[serde(rename = "k0_ug_per_c_U95")]
    pub k0_ug_per_c_u95: f64,
    /// Scale factor, relative to its value at the mean temperature [ppm/°C].
    pub k1_ppm_per_c: f64,
    /// Its U95.
    #[serde(rename = "k1_ppm_per_c_U95")]
    pub k1_ppm_per_c_u95: f64,
    /// K2 [µg/g²/°C] (absent with one mounting).
    pub k2_ug_per_g2_per_c: Option<f64>,
    /// Its U95.
    #[serde(rename = "k2_ug_per_g2_per_c_U95")]
    pub k2_ug_per_g2_per_c_u95: Option<f64>,
    /// Temperatures used.
    pub temperatures: usize,
}

/// The weighted line's slope, its value at T̄ and the slope's U95.
fn slope(t: &[f64], y: &[f64], u: &[f64]) -> Option<(f64, f64, f64)> {
    if t.len() < 2 || u.iter().any(|&v| !(v.is_finite() && v > 0.0)) {
        return None;
    }
    let w: Vec<f64> = u.iter().map(|v| 1.0 / (v * v)).collect();
    let sw: f64 = w.iter().sum();
    let t_bar = w.iter().zip(t).map(|(w, t)| w * t).sum::<f64>() / sw;
    let y_bar = w.iter().zip(y).map(|(w, y)| w * y).sum::<f64>() / sw;
    let stt: f64 = w.iter().zip(t).map(|(w, t)| w * (t - t_bar).powi(2)).sum();
    if stt <= 0.0 {
        return None;
    }
    let c = w
        .iter()
        .zip(t)
        .zip(y)
        .map(|((w, t), y)| w * (t - t_bar) * y)
        .sum::<f64>()
        / stt;
    let mut u_c = 1.0 / stt.sqrt();
    let n = t.len();
    let mut k = 1.96;
    if n >= 3 {
        let chi2: f64 = w
            .iter()
            .zip(t)
            .zip(y)
            .map(|((w, t), y)| w * (y - y_bar - c * (t - t_bar)).powi(2))
            .sum();
        let birge = (chi2 / (n - 2) as f64).sqrt();
        if birge > 1.0 {
            u_c *= birge;
            k = student_t_975(n - 2).unwrap_or(12.71);
        }
    }
    Some((c, y_bar, k * u_c))
}

/// Fit the coefficients through the figures at two or more temperatures.
pub fn temperature_coefficients(
    at: &[AtTemperature],
) -> Result<TemperatureCoefficients, AnalysisError> {
    let t: Vec<f64> = at.iter().map(|a| a.temperature_c).collect();
    let need = || {
        AnalysisError::InvalidInput(format!(
            "temperature coefficients need figures at two or more distinct temperatures with their uncertainties; got {}",
            at.len()
        ))
    };
    let column = |f: &dyn Fn(&AtTemperature) -> [f64; 2]| -> (Vec<f64>, Vec<f64>) {
        at.iter().map(|a| (f(a)[0], f(a)[1])).unzip()
    };
    let u_t: Vec<f64> = at.iter().map(|a| a.temperature_spread_c.max(0.0)).collect();
    // Errors in the variable: fit, widen each u(y) by the slope times u(T), fit again.
    let with_spread = |y: &[f64], u: &[f64]| -> Option<(f64, f64, f64)> {
        let (c, _, _) = slope(&t, y, u)?;
        let widened: Vec<f64> = u.iter().zip(&u_t).map(|(u, ut)| u.hypot(c * ut)).collect();
        slope(&t, y, &widened)
    };
    let (k0, u0) = column(&|a| a.k0_g);
    let (k1, u1) = column(&|a| a.k1_hz_per_g);
    let (c0, _, big_u0) = with_spread(&k0, &u0).ok_or_else(need)?;
    let (c1, k1_bar, big_u1) = with_spread(&k1, &u1).ok_or_else(need)?;
    let k2 = if at.iter().all(|a| a.k2_ug_per_g2.is_some()) {
        let (k2, u2): (Vec<f64>, Vec<f64>) = at
            .iter()
            .filter_map(|a| a.k2_ug_per_g2)
            .map(|v| (v[0], v[1]))
            .unzip();
        with_spread(&k2, &u2)
    } else {
        None
    };
    Ok(TemperatureCoefficients {
        k0_ug_per_c: c0 * 1e6,
        k0_ug_per_c_u95: big_u0 * 1e6,
        k1_ppm_per_c: c1 / k1_bar.abs() * 1e6,
        k1_ppm_per_c_u95: big_u1 / k1_bar.abs() * 1e6,
        k2_ug_per_g2_per_c: k2.map(|v| v.0),
        k2_ug_per_g2_per_c_u95: k2.map(|v| v.2),
        temperatures: at.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t: f64, k0_ug: f64, k1: f64, k2: f64) -> AtTemperature {
        AtTemperature {
            setpoint_c: t - 4.0,
            temperature_c: t,
            temperature_spread_c: 0.0,
            k0_g: [k0_ug * 1e-6, 2e-6],
            k1_hz_per_g: [k1, 1e-3],
            k2_ug_per_g2: Some([k2, 0.2]),
        }
    }

    #[test]
    fn straight_lines_give_their_slopes_and_intervals_at_their_weights() {
        // 20 µg/°C, 30 ppm/°C of 100 Hz/g, 0.05 µg/g²/°C about 25 °C.
        let figs: Vec<AtTemperature> = [-20.0, 25.0, 60.0]
            .iter()
            .map(|&t| {
                let d = t - 25.0;
                at(
                    t,
                    500.0 + 20.0 * d,
                    100.0 * (1.0 + 30e-6 * d),
                    10.0 + 0.05 * d,
                )
            })
            .collect();
        let c = temperature_coefficients(&figs).expect("fit");
        assert!((c.k0_ug_per_c - 20.0).abs() < 1e-6, "{}", c.k0_ug_per_c);
        assert!((c.k1_ppm_per_c - 30.0).abs() < 0.01, "{}", c.k1_ppm_per_c);
        assert!((c.k2_ug_per_g2_per_c.unwrap_or(0.0) - 0.05).abs() < 1e-9);
        // U95 = 1.96 / √(Σ w (T − T̄)²) on a perfect line.
        let stt: f64 = [-20.0f64, 25.0, 60.0]
            .iter()
            .map(|t| (t - 65.0 / 3.0).powi(2))
            .sum();
        let want = 1.96 * 0.2 / stt.sqrt();
        assert!((c.k2_ug_per_g2_per_c_u95.unwrap_or(0.0) - want).abs() < 1e-12);
    }

    #[test]
    fn a_bend_the_line_does_not_hold_widens_the_interval_and_one_temperature_is_refused() {
        let mut figs: Vec<AtTemperature> = [-20.0, 25.0, 60.0]
            .iter()
            .map(|&t| at(t, 500.0, 100.0, 10.0))
            .collect();
        let straight = temperature_coefficients(&figs).expect("fit");
        figs[1].k2_ug_per_g2 = Some([12.0, 0.2]);
        let bent = temperature_coefficients(&figs).expect("fit");
        assert!(
            bent.k2_ug_per_g2_per_c_u95.unwrap_or(0.0)
                > 5.0 * straight.k2_ug_per_g2_per_c_u95.unwrap_or(1.0)
        );
        assert!(temperature_coefficients(&figs[..1]).is_err());
    }
}
