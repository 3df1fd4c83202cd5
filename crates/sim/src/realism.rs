//! The bench's presets of realism: `ideal` (no error source beyond white
//! noise, a small bias walk and gravity across the axis: the world the
//! station was first built in), `typical` (the error sources of precision
//! centrifuge testing, IEEE Std 836, at sizes that give the station's own
//! points the signature of the published station's data: method.md §5
//! "What real data look like"), and `harsh` (typical, plus drift, a dead
//! and a noisy instrument and intermittent faults on the counter lines).
//!
//! A bench config file is read here too ([`SimConfig::from_toml`]): its
//! preset first, its keys over it. This module depends on [`crate::config`]
//! (the types), never the other way round.

pub use crate::config::Realism;
use crate::config::{Disturbance, FaultConfig, SimConfig, SimConfigError, SlotRef};

/// Arm stretch of the typical bench: 2 µg/g² common to both mountings on
/// the 0.8 m arm, c = k_s·g/R0² (method.md (15)) → k_s = c·R0²/g.
const TYPICAL_STRETCH_UG_PER_G2: f64 = 2.0;

impl Realism {
    /// The complete bench of this preset (every other key at its default).
    pub fn config(self) -> SimConfig {
        let mut c = SimConfig {
            realism: self,
            ..SimConfig::default()
        };
        if self == Realism::Ideal {
            return c;
        }
        // The laboratory: a Chinese production line's latitude, a slow drift.
        c.latitude_deg = 34.3;
        c.ambient_drift_c_per_h = 0.3;
        let t = &mut c.centrifuge;
        t.arm_stretch_m_per_rad2_s2 = TYPICAL_STRETCH_UG_PER_G2 * 1e-6 * t.arm_radius_m.powi(2)
            / spinbench_analysis::STANDARD_GRAVITY_M_S2;
        t.arm_expansion_ppm_per_c = 12.0;
        t.tilt_urad = 50.0;
        t.readback_scale_ppm = 8.0;
        t.readback_resolution_deg_s = 0.001;
        t.ripple_ppm = 20.0;
        // Wander stays at the ideal bench's 2 ppm: the station reads the rate
        // each second, but a faster wander would part up and down readings.

        t.windage_c_at_100g = 1.5;
        t.windage_tau_s = 120.0;
        t.disturbances = vec![
            // A sharp structural resonance at one mid-range level ...
            Disturbance {
                at_g: 40.0,
                width_g: 0.6,
                amplitude_ug: 16_000.0,
            },
            // ... and a broad one: the smooth structure a cubic leaves.
            Disturbance {
                at_g: 52.0,
                width_g: 14.0,
                amplitude_ug: -3_500.0,
            },
        ];
        let p = &mut c.instruments;
        p.noise_ug = 10.0;
        p.bias_walk_ug_per_sqrt_h = 20.0;
        p.koq_max_ug_per_g2 = 3.0;
        p.asymmetry_max_ppm = 80.0;
        p.k1_temp_coeff_ppm_per_c = 15.0;
        p.resonator_sum_ppm_per_c = -30.0;
        p.flicker_ug = 15.0;
        p.disturbance_gain = [0.8, 1.2];
        // The instruments' own anomalies: a resonator mode crossing on
        // most resonators, met at different levels in P and N, the
        // published data's 1,000–20,000 µg (method.md §5).
        p.activity_dips = crate::config::ActivityDipDraw {
            probability: 0.75,
            ..Default::default()
        };
        if self == Realism::Harsh {
            c.ambient_drift_c_per_h = 1.5;
            c.centrifuge.windage_c_at_100g = 4.0;
            let p = &mut c.instruments;
            p.noise_ug = 20.0;
            p.bias_walk_ug_per_sqrt_h = 80.0;
            p.flicker_ug = 40.0;
            c.faults = FaultConfig {
                bit_error_rate: 1e-7,
                frame_drop_rate: 2e-4,
                dead_instruments: vec![SlotRef { module: 1, slot: 5 }],
                noisy_instruments: vec![SlotRef { module: 0, slot: 2 }],
                noisy_factor: 30.0,
                ..FaultConfig::default()
            };
        }
        c
    }
}

impl SimConfig {
    /// Parse TOML text: the preset its `realism` key names (`ideal` when
    /// absent), with the file's other keys over it.
    pub fn from_toml(text: &str) -> Result<SimConfig, SimConfigError> {
        SimConfig::from_toml_with(text, None)
    }

    /// Parse TOML text as [`from_toml`](Self::from_toml); `realism`, when
    /// given (a command line's `--realism`), replaces the file's preset.
    pub fn from_toml_with(
        text: &str,
        realism: Option<Realism>,
    ) -> Result<SimConfig, SimConfigError> {
        let file_error = |problem: String| SimConfigError {
            key: "(file)".into(),
            problem,
        };
        let mut table: toml::Table = toml::from_str(text).map_err(|e| file_error(e.to_string()))?;
        let named = match table.remove("realism") {
            None => Realism::Ideal,
            Some(v) => v.try_into().map_err(|_| SimConfigError {
                key: "realism".into(),
                problem: "must be \"ideal\", \"typical\" or \"harsh\"".into(),
            })?,
        };
        let realism = realism.unwrap_or(named);
        let mut merged = toml::Table::try_from(realism.config())
            .map_err(|e| file_error(format!("the {realism:?} preset: {e}")))?;
        merge(&mut merged, table);
        let config: SimConfig = merged
            .try_into()
            .map_err(|e: toml::de::Error| file_error(e.to_string()))?;
        config.validate()?;
        Ok(config)
    }
}

/// Put `over`'s keys into `base`, table by table (a key of `over` replaces
/// the same key of `base`; tables are merged key by key).
pub fn merge(base: &mut toml::Table, over: toml::Table) {
    for (key, value) in over {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            (_, value) => {
                base.insert(key, value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_starts_from_its_preset_and_overrides_it_key_by_key() {
        let c = SimConfig::from_toml("realism = \"typical\"\n[centrifuge]\ntilt_urad = 7\n")
            .expect("typical");
        assert_eq!(c.realism, Realism::Typical);
        assert_eq!(c.centrifuge.tilt_urad, 7.0);
        assert_eq!(c.centrifuge.disturbances.len(), 2);
        assert_eq!(c.instruments.noise_ug, 10.0);
        // No realism key: ideal; the command line's realism replaces the file's.
        assert_eq!(
            SimConfig::from_toml("").expect("ideal"),
            SimConfig::default()
        );
        let harsh =
            SimConfig::from_toml_with("realism = \"ideal\"", Some(Realism::Harsh)).expect("harsh");
        assert_eq!(harsh.faults.dead_instruments.len(), 1);
        let e = SimConfig::from_toml("realism = \"dirty\"").expect_err("unknown");
        assert_eq!(e.key, "realism");
        for r in [Realism::Ideal, Realism::Typical, Realism::Harsh] {
            assert_eq!(r.config().validate(), Ok(()));
            assert_eq!(r.to_string().parse::<Realism>(), Ok(r));
        }
    }
}
