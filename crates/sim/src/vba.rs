//! Vibrating-beam accelerometer physics: two resonators in push-pull whose
//! difference follows method.md (2) exactly, plus the effects a real
//! instrument adds (cross-axis sensitivity, bias random walk, temperature,
//! warm-up). Noise is added by the world, per tick.

use serde::{Deserialize, Serialize};

/// How an instrument is mounted (method.md §3.2–§3.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Mounting {
    /// On the bench, input axis up: +1 g.
    TumbleUp,
    /// On the bench, input axis down: −1 g.
    TumbleDown,
    /// On the arm, input axis toward the spin axis: +a.
    #[default]
    ArmP,
    /// On the arm, input axis away from the spin axis: −a.
    ArmN,
}

impl Mounting {
    /// Parse `UP`, `DOWN`, `P` or `N` (any case).
    pub fn parse(text: &str) -> Option<Mounting> {
        match text.trim().to_ascii_uppercase().as_str() {
            "UP" => Some(Mounting::TumbleUp),
            "DOWN" => Some(Mounting::TumbleDown),
            "P" => Some(Mounting::ArmP),
            "N" => Some(Mounting::ArmN),
            _ => None,
        }
    }
}

/// The true parameters of one instrument.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct VbaTruth {
    /// Bias [g].
    pub k0_g: f64,
    /// Scale factor [Hz/g].
    pub k1_hz_per_g: f64,
    /// Second-order coefficient [µg/g²].
    pub k2_ug_per_g2: f64,
    /// Third-order coefficient [µg/g³].
    pub k3_ug_per_g3: f64,
    /// Sensitivity to acceleration across the input axis [µg/g].
    pub cross_axis_ug_per_g: f64,
    /// Resonator rest frequency [Hz].
    pub resonator_hz: f64,
    /// White noise of a 1-s dF value [µg].
    pub noise_ug: f64,
    /// Bias random walk [µg/√h].
    pub bias_walk_ug_per_sqrt_h: f64,
    /// Bias temperature coefficient [µg/°C].
    pub temp_coeff_ug_per_c: f64,
}

/// Common-mode second-order term of each resonator (cancels in dF, as push-pull intends) [1/g²].
const COMMON_MODE_PER_G2: f64 = 2e-6;

/// One instrument's changing state.
#[derive(Debug, Clone, PartialEq)]
pub struct Vba {
    /// The truth.
    pub truth: VbaTruth,
    /// Current mounting.
    pub mounting: Mounting,
    /// Simulated time it was powered on [s], if powered.
    pub powered_since_s: Option<f64>,
    /// Accumulated bias random walk [g].
    pub bias_walk_g: f64,
}

impl Vba {
    /// A new, unpowered instrument.
    pub fn new(truth: VbaTruth) -> Vba {
        Vba {
            truth,
            mounting: Mounting::default(),
            powered_since_s: None,
            bias_walk_g: 0.0,
        }
    }

    /// Temperature [°C] at `now_s`: ambient plus self-heating after power-on.
    pub fn temperature_c(
        &self,
        now_s: f64,
        ambient_c: f64,
        self_heating_c: f64,
        tau_s: f64,
    ) -> f64 {
        match self.powered_since_s {
            Some(t0) => ambient_c + self_heating_c * (1.0 - (-(now_s - t0).max(0.0) / tau_s).exp()),
            None => ambient_c,
        }
    }

    /// The resonator frequencies (f1, f2) [Hz] for input `a_g` along the
    /// input axis and `cross_g` across it, at `temp_offset_c` from the
    /// warmed-up temperature, `warmup_g` of remaining warm-up transient.
    /// dF = f1 − f2 = k1·(k0 + a + k2·a² + k3·a³ + …) — method.md (2).
    pub fn resonators(
        &self,
        a_g: f64,
        cross_g: f64,
        temp_offset_c: f64,
        warmup_g: f64,
    ) -> (f64, f64) {
        let t = &self.truth;
        let a = a_g;
        let input = t.k0_g
            + a
            + t.k2_ug_per_g2 * 1e-6 * a * a
            + t.k3_ug_per_g3 * 1e-6 * a * a * a
            + t.cross_axis_ug_per_g * 1e-6 * cross_g
            + self.bias_walk_g
            + t.temp_coeff_ug_per_c * 1e-6 * temp_offset_c
            + warmup_g;
        let half = t.k1_hz_per_g * input / 2.0;
        let common = t.resonator_hz * (1.0 + COMMON_MODE_PER_G2 * a * a);
        (common + half, common - half)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn difference_follows_the_ieee_model_and_common_mode_cancels() {
        let truth = VbaTruth {
            k0_g: 0.01,
            k1_hz_per_g: 100.0,
            k2_ug_per_g2: 15.0,
            k3_ug_per_g3: 0.05,
            cross_axis_ug_per_g: 0.0,
            resonator_hz: 30_000.0,
            noise_ug: 0.0,
            bias_walk_ug_per_sqrt_h: 0.0,
            temp_coeff_ug_per_c: 0.0,
        };
        let v = Vba::new(truth);
        for a in [-70.0, -1.0, 0.0, 1.0, 35.0, 100.0] {
            let (f1, f2) = v.resonators(a, 0.0, 0.0, 0.0);
            let want = spinbench_analysis::model::ieee1293_output([0.01, 100.0, 15e-6, 0.05e-6], a);
            assert!((f1 - f2 - want).abs() < 1e-9, "a = {a}");
            assert!(f1 > 20_000.0 && f2 > 20_000.0);
        }
        assert_eq!(Mounting::parse("down"), Some(Mounting::TumbleDown));
        assert_eq!(Mounting::parse("x"), None);
    }
}
