//! Vibrating-beam accelerometer physics: two resonators in push-pull whose
//! difference follows method.md (2), with the terms of the fuller model
//! (12) a real instrument adds: an odd-quadratic term Koq·a·|a|, scale-factor
//! asymmetry, cross-axis sensitivity, temperature coefficients of bias and
//! scale factor, a common frequency (f1 + f2) that tracks temperature, bias
//! random walk and warm-up. Noise is added by the world, per tick.

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
    /// On the bench, input axis horizontal, gravity along the cross axis
    /// that is vertical on the arm: +1 g across as on the arm, −1 g inverted.
    TumbleCrosswise {
        /// As on the arm (else inverted).
        as_on_arm: bool,
    },
}

impl Mounting {
    /// Parse `UP`, `DOWN`, `P`, `N`, `CROSS` or `CROSS-INVERTED` (any case).
    pub fn parse(text: &str) -> Option<Mounting> {
        match text.trim().to_ascii_uppercase().as_str() {
            "UP" => Some(Mounting::TumbleUp),
            "DOWN" => Some(Mounting::TumbleDown),
            "P" => Some(Mounting::ArmP),
            "N" => Some(Mounting::ArmN),
            "CROSS" => Some(Mounting::TumbleCrosswise { as_on_arm: true }),
            "CROSS-INVERTED" => Some(Mounting::TumbleCrosswise { as_on_arm: false }),
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
    /// Odd-quadratic coefficient Koq (Koq·a·|a|) [µg/g²].
    pub koq_ug_per_g2: f64,
    /// Scale-factor asymmetry (K1+ − K1−)/K1 [ppm].
    pub asymmetry_ppm: f64,
    /// Scale-factor temperature coefficient [ppm/°C].
    pub k1_temp_coeff_ppm_per_c: f64,
    /// Temperature coefficient of k2 [µg/g²/°C].
    pub k2_temp_coeff_ug_per_g2_per_c: f64,
    /// Temperature coefficient of the common frequency (f1 + f2)/2 [ppm/°C].
    pub resonator_sum_ppm_per_c: f64,
    /// Low-frequency (1/f-like) noise, RMS [µg].
    pub flicker_ug: f64,
    /// Gain on the centrifuge's structural disturbances.
    pub disturbance_gain: f64,
    /// Activity dips (resonator mode crossings), one per resonator at most.
    pub dips: [Option<ActivityDip>; 2],
}

/// A resonator mode crossing (an "activity dip", method.md §5): near one
/// frequency of one resonator the difference frequency is pulled off the
/// model. It belongs to the instrument: reached at the same acceleration on
/// every centrifuge, by resonator 1 in mounting P and resonator 2 in N, and
/// not part of its K2.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ActivityDip {
    /// Resonator 1 or 2.
    pub resonator: u8,
    /// The resonator frequency at its centre [Hz].
    pub frequency_hz: f64,
    /// Its width, the standard deviation of a Gaussian in that frequency [Hz].
    pub width_hz: f64,
    /// The shift of dF at its centre, as acceleration [µg].
    pub size_ug: f64,
    /// The acceleration at which the resonator reaches it at rest temperature [g].
    pub reached_at_g: f64,
}

impl ActivityDip {
    /// A dip that `truth`'s resonator reaches at `at_g`, `width_g` wide.
    pub fn at_acceleration(
        truth: &VbaTruth,
        resonator: u8,
        at_g: f64,
        width_g: f64,
        size_ug: f64,
    ) -> ActivityDip {
        // f1 = common + k1·(k0 + a)/2 rises in P (a > 0); f2 = common +
        // k1·(|a| − k0)/2 rises in N (a < 0).
        let bias = if resonator == 1 {
            truth.k0_g
        } else {
            -truth.k0_g
        };
        let frequency_hz = truth.resonator_hz * (1.0 + COMMON_MODE_PER_G2 * at_g * at_g)
            + 0.5 * truth.k1_hz_per_g * (at_g + bias);
        ActivityDip {
            resonator,
            frequency_hz,
            width_hz: 0.5 * truth.k1_hz_per_g * width_g,
            size_ug,
            reached_at_g: at_g,
        }
    }

    /// A dip at resonator frequency `at_hz`, `width_g` wide, for `truth`.
    pub fn at_frequency(
        truth: &VbaTruth,
        resonator: u8,
        at_hz: f64,
        width_g: f64,
        size_ug: f64,
    ) -> ActivityDip {
        let half = 0.5 * truth.k1_hz_per_g;
        let bias = if resonator == 1 {
            truth.k0_g
        } else {
            -truth.k0_g
        };
        ActivityDip {
            resonator,
            frequency_hz: at_hz,
            width_hz: half * width_g,
            size_ug,
            // f = R·(1 + c·a²) + half·(a + bias), solved for a (c the common mode).
            reached_at_g: {
                let (r, c) = (truth.resonator_hz, COMMON_MODE_PER_G2);
                let constant = r + half * bias - at_hz;
                (-half + (half * half - 4.0 * r * c * constant).max(0.0).sqrt()) / (2.0 * r * c)
            },
        }
    }

    /// The shift of dF [Hz] when its resonator is at `f_hz`.
    fn shift_hz(&self, f_hz: f64, k1_hz_per_g: f64) -> f64 {
        let x = (f_hz - self.frequency_hz) / self.width_hz;
        if x.abs() > 12.0 {
            return 0.0;
        }
        self.size_ug * 1e-6 * k1_hz_per_g * (-0.5 * x * x).exp()
    }
}

/// What an instrument feels at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Inputs {
    /// Acceleration along the input axis [g].
    pub a_g: f64,
    /// Acceleration across it [g].
    pub cross_g: f64,
    /// Temperature above the warmed-up temperature at rest [°C].
    pub temp_offset_c: f64,
    /// Remaining warm-up transient [g].
    pub warmup_g: f64,
    /// Further bias: disturbances and low-frequency noise [g].
    pub extra_g: f64,
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

    /// The resonator frequencies (f1, f2) [Hz] for `inputs`.
    /// dF = f1 − f2 = k1·(k0 + a + k2·a² + k3·a³ + Koq·a·|a| + …) —
    /// method.md (2) and (12), K1 split into K1+ and K1− by the asymmetry.
    pub fn resonators(&self, inputs: &Inputs) -> (f64, f64) {
        let t = &self.truth;
        let a = inputs.a_g;
        let dt = inputs.temp_offset_c;
        // K1+ for a > 0, K1− for a < 0: (K1+ − K1−)/K1 = asymmetry.
        let linear = a * (1.0 + 0.5e-6 * t.asymmetry_ppm * a.signum());
        let input = t.k0_g
            + linear
            + (t.k2_ug_per_g2 + t.k2_temp_coeff_ug_per_g2_per_c * dt) * 1e-6 * a * a
            + t.k3_ug_per_g3 * 1e-6 * a * a * a
            + t.koq_ug_per_g2 * 1e-6 * a * a.abs()
            + t.cross_axis_ug_per_g * 1e-6 * inputs.cross_g
            + self.bias_walk_g
            + t.temp_coeff_ug_per_c * 1e-6 * dt
            + inputs.warmup_g
            + inputs.extra_g;
        let k1 = t.k1_hz_per_g * (1.0 + t.k1_temp_coeff_ppm_per_c * 1e-6 * dt);
        let half = k1 * input / 2.0;
        let common = t.resonator_hz
            * (1.0 + COMMON_MODE_PER_G2 * a * a + t.resonator_sum_ppm_per_c * 1e-6 * dt);
        let (f1, f2) = (common + half, common - half);
        // A mode crossing pulls dF by its shift, split over the two resonators.
        let pull: f64 = t
            .dips
            .iter()
            .flatten()
            .map(|d| d.shift_hz(if d.resonator == 1 { f1 } else { f2 }, t.k1_hz_per_g))
            .sum();
        (f1 + 0.5 * pull, f2 - 0.5 * pull)
    }

    /// The same instrument without its activity dips (its smooth model, the truth of K2).
    pub fn without_dips(&self) -> Vba {
        Vba::new(VbaTruth {
            dips: [None; 2],
            ..self.truth
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A clean instrument: 100 Hz/g, k2 = 15 µg/g², no error source.
    fn clean_truth() -> VbaTruth {
        VbaTruth {
            k0_g: 0.01,
            k1_hz_per_g: 100.0,
            k2_ug_per_g2: 15.0,
            k3_ug_per_g3: 0.05,
            cross_axis_ug_per_g: 0.0,
            resonator_hz: 30_000.0,
            noise_ug: 0.0,
            bias_walk_ug_per_sqrt_h: 0.0,
            temp_coeff_ug_per_c: 0.0,
            koq_ug_per_g2: 0.0,
            asymmetry_ppm: 0.0,
            k1_temp_coeff_ppm_per_c: 0.0,
            k2_temp_coeff_ug_per_g2_per_c: 0.0,
            resonator_sum_ppm_per_c: 0.0,
            flicker_ug: 0.0,
            disturbance_gain: 1.0,
            dips: [None; 2],
        }
    }

    #[test]
    fn difference_follows_the_ieee_model_and_common_mode_cancels() {
        let truth = clean_truth();
        let v = Vba::new(truth);
        for a in [-70.0, -1.0, 0.0, 1.0, 35.0, 100.0] {
            let (f1, f2) = v.resonators(&Inputs {
                a_g: a,
                ..Inputs::default()
            });
            let want = spinbench_analysis::model::ieee1293_output([0.01, 100.0, 15e-6, 0.05e-6], a);
            assert!((f1 - f2 - want).abs() < 1e-9, "a = {a}");
            assert!(f1 > 20_000.0 && f2 > 20_000.0);
        }
        // Koq·a·|a| and the asymmetry: odd and even parts as the model says.
        let v = Vba::new(VbaTruth {
            koq_ug_per_g2: 4.0,
            asymmetry_ppm: 100.0,
            ..truth
        });
        let df = |a: f64| {
            let (f1, f2) = v.resonators(&Inputs {
                a_g: a,
                ..Inputs::default()
            });
            f1 - f2
        };
        let (plus, minus, zero) = (df(50.0), df(-50.0), df(0.0));
        // Odd in a: Koq·a·|a| and the linear term; even: k2·a² and the asymmetry's |a|.
        let odd = (plus - minus) / 2.0 / 100.0;
        let even = ((plus + minus) / 2.0 - zero) / 100.0;
        assert!(
            (odd - (50.0 + 0.05e-6 * 125_000.0 + 4e-6 * 2500.0)).abs() < 1e-9,
            "{odd}"
        );
        assert!(
            (even - (15e-6 * 2500.0 + 50e-6 * 50.0)).abs() < 1e-9,
            "{even}"
        );
        assert_eq!(Mounting::parse("down"), Some(Mounting::TumbleDown));
        assert_eq!(Mounting::parse("x"), None);
        assert_eq!(
            Mounting::parse("cross-inverted"),
            Some(Mounting::TumbleCrosswise { as_on_arm: false })
        );
    }

    #[test]
    fn an_activity_dip_is_met_at_one_acceleration_in_one_mounting_only() {
        let base = VbaTruth {
            k0_g: 0.02,
            k3_ug_per_g3: 0.0,
            ..clean_truth()
        };
        let p_dip = ActivityDip::at_acceleration(&base, 1, 30.0, 1.0, 15_000.0);
        let n_dip = ActivityDip::at_acceleration(&base, 2, 65.0, 1.0, -8_000.0);
        let v = Vba::new(VbaTruth {
            dips: [Some(p_dip), Some(n_dip)],
            ..base
        });
        let smooth = v.without_dips();
        let shift_ug = |a: f64| {
            let df = |v: &Vba| {
                let (f1, f2) = v.resonators(&Inputs {
                    a_g: a,
                    ..Inputs::default()
                });
                f1 - f2
            };
            (df(&v) - df(&smooth)) / 100.0 * 1e6
        };
        // Mounting P (+a) meets resonator 1's dip at 30 g, N (−a) resonator 2's at 65 g.
        assert!(
            (shift_ug(30.0) - 15_000.0).abs() < 100.0,
            "{}",
            shift_ug(30.0)
        );
        assert!(shift_ug(-30.0).abs() < 1.0, "{}", shift_ug(-30.0));
        assert!(
            (shift_ug(-65.0) + 8_000.0).abs() < 100.0,
            "{}",
            shift_ug(-65.0)
        );
        assert!(shift_ug(65.0).abs() < 1.0);
        // Five widths away it is gone; the same dip given by its frequency is the same dip.
        assert!(shift_ug(35.0).abs() < 1.0);
        let again = ActivityDip::at_frequency(&base, 1, p_dip.frequency_hz, 1.0, 15_000.0);
        assert!(
            (again.reached_at_g - 30.0).abs() < 1e-3,
            "{}",
            again.reached_at_g
        );
    }
}
