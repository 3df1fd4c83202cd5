//! A bench config checked against its named bounds before anything is
//! allocated or started; the error names the key.

use super::{
    MAX_DIP_G, MAX_DIP_UG, MAX_DISTURBANCES, MAX_FAULT_TIME_S, MAX_POSITION_SHIFTS, MAX_SPEED,
    SimConfig, SimConfigError,
};

impl SimConfig {
    /// Check values that TOML types cannot.
    pub fn validate(&self) -> Result<(), SimConfigError> {
        let err = |key: &str, problem: String| {
            Err(SimConfigError {
                key: key.into(),
                problem,
            })
        };
        if let Some(c) = &self.chamber
            && let Err((key, problem)) = c.validate()
        {
            return err(&key, problem);
        }
        let positive = [
            ("g_local_m_s2", self.g_local_m_s2),
            ("reference_hz", self.reference_hz),
            ("centrifuge.arm_radius_m", self.centrifuge.arm_radius_m),
            ("centrifuge.max_rate_deg_s", self.centrifuge.max_rate_deg_s),
            (
                "centrifuge.max_accel_deg_s2",
                self.centrifuge.max_accel_deg_s2,
            ),
            (
                "centrifuge.loop_natural_hz",
                self.centrifuge.loop_natural_hz,
            ),
            ("centrifuge.loop_damping", self.centrifuge.loop_damping),
            ("instruments.resonator_hz", self.instruments.resonator_hz),
        ];
        for (key, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return err(key, format!("must be a positive number, got {v}"));
            }
        }
        if !(self.speed.is_finite() && self.speed >= 0.0) {
            return err(
                "speed",
                format!(
                    "must be 0 (as fast as read), 1 (real time) or more, got {}",
                    self.speed
                ),
            );
        }
        if self.modules == 0 || self.modules > 16 {
            return err("modules", format!("must be 1 to 16, got {}", self.modules));
        }
        let [lo, hi] = self.instruments.k1_hz_per_g;
        if !(lo > 0.0 && hi >= lo) {
            return err(
                "instruments.k1_hz_per_g",
                format!("must be a range [low, high] with 0 < low ≤ high, got [{lo}, {hi}]"),
            );
        }
        for (key, p) in [
            ("faults.bit_error_rate", self.faults.bit_error_rate),
            ("faults.byte_drop_rate", self.faults.byte_drop_rate),
            ("faults.frame_drop_rate", self.faults.frame_drop_rate),
        ] {
            if !(0.0..=1.0).contains(&p) {
                return err(key, format!("must be a probability 0 to 1, got {p}"));
            }
        }
        let d = &self.instruments.activity_dips;
        if !(0.0..=1.0).contains(&d.probability) {
            return err(
                "instruments.activity_dips.probability",
                format!("must be a probability 0 to 1, got {}", d.probability),
            );
        }
        for (key, [lo, hi], max) in [
            ("instruments.activity_dips.at_g", d.at_g, MAX_DIP_G),
            ("instruments.activity_dips.size_ug", d.size_ug, MAX_DIP_UG),
            ("instruments.activity_dips.width_g", d.width_g, MAX_DIP_G),
        ] {
            if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi && hi <= max) {
                return err(
                    key,
                    format!(
                        "must be a range [low, high] with 0 < low ≤ high ≤ {max}, got [{lo}, {hi}]"
                    ),
                );
            }
        }
        let slots = self.modules * spinbench_wire::fmu::INSTRUMENTS_PER_MODULE;
        for (i, dip) in self.instruments.dips.iter().enumerate() {
            let key = format!("instruments.dips[{i}]");
            if dip.module * spinbench_wire::fmu::INSTRUMENTS_PER_MODULE + dip.slot >= slots
                || dip.slot >= spinbench_wire::fmu::INSTRUMENTS_PER_MODULE
            {
                return err(
                    &key,
                    format!(
                        "module {} slot {} is not on the bench",
                        dip.module, dip.slot
                    ),
                );
            }
            if !(dip.resonator == 1 || dip.resonator == 2) {
                return err(
                    &key,
                    format!("resonator must be 1 or 2, got {}", dip.resonator),
                );
            }
            let place_ok = match (dip.at_g, dip.at_hz) {
                (Some(g), None) => g.is_finite() && g > 0.0 && g <= MAX_DIP_G,
                (None, Some(hz)) => hz.is_finite() && hz > 0.0 && hz <= 1e7,
                _ => false,
            };
            if !place_ok {
                return err(
                    &key,
                    format!(
                        "give exactly one of at_g (0 to {MAX_DIP_G} g) or at_hz (a positive frequency)"
                    ),
                );
            }
            if !(dip.size_ug.is_finite() && dip.size_ug.abs() <= MAX_DIP_UG) {
                return err(
                    &key,
                    format!("size_ug must be within ±{MAX_DIP_UG}, got {}", dip.size_ug),
                );
            }
            if !(dip.width_g.is_finite() && dip.width_g > 0.0 && dip.width_g <= MAX_DIP_G) {
                return err(
                    &key,
                    format!("width_g must be from 0 to {MAX_DIP_G}, got {}", dip.width_g),
                );
            }
        }
        // Every other number: finite, of the right sign, within a named bound.
        let p = &self.instruments;
        let c = &self.centrifuge;
        let bounded = [
            ("speed", self.speed, 0.0, MAX_SPEED),
            ("ambient_c", self.ambient_c, -100.0, 200.0),
            ("reference_hz", self.reference_hz, 1.0, 1e10),
            ("g_local_m_s2", self.g_local_m_s2, 9.7, 9.9),
            ("centrifuge.arm_radius_m", c.arm_radius_m, 0.0, 10.0),
            (
                "centrifuge.radius_scatter_mm",
                c.radius_scatter_mm,
                0.0,
                100.0,
            ),
            (
                "centrifuge.proof_mass_offset_mm",
                c.proof_mass_offset_mm,
                -100.0,
                100.0,
            ),
            ("centrifuge.max_rate_deg_s", c.max_rate_deg_s, 0.0, 36_000.0),
            (
                "centrifuge.max_accel_deg_s2",
                c.max_accel_deg_s2,
                0.0,
                36_000.0,
            ),
            ("centrifuge.loop_natural_hz", c.loop_natural_hz, 0.0, 50.0),
            ("centrifuge.loop_damping", c.loop_damping, 0.0, 10.0),
            ("centrifuge.ripple_ppm", c.ripple_ppm, 0.0, 1e5),
            ("centrifuge.wander_ppm", c.wander_ppm, 0.0, 1e5),
            ("instruments.resonator_hz", p.resonator_hz, 100.0, 1e7),
            ("instruments.k0_max_g", p.k0_max_g, 0.0, 100.0),
            ("instruments.k3_max_ug_per_g3", p.k3_max_ug_per_g3, 0.0, 1e6),
            (
                "instruments.cross_axis_max_ug_per_g",
                p.cross_axis_max_ug_per_g,
                0.0,
                1e6,
            ),
            ("instruments.noise_ug", p.noise_ug, 0.0, 1e6),
            (
                "instruments.bias_walk_ug_per_sqrt_h",
                p.bias_walk_ug_per_sqrt_h,
                0.0,
                1e6,
            ),
            (
                "instruments.temp_coeff_ug_per_c",
                p.temp_coeff_ug_per_c,
                -1e6,
                1e6,
            ),
            (
                "instruments.self_heating_c",
                p.self_heating_c,
                -100.0,
                100.0,
            ),
            ("instruments.warmup_tau_s", p.warmup_tau_s, 0.0, 1e6),
            ("instruments.warmup_ug", p.warmup_ug, -1e6, 1e6),
            ("instruments.current_a", p.current_a, 0.0, 1.0),
            ("faults.noisy_factor", self.faults.noisy_factor, 0.0, 1e9),
            (
                "ambient_drift_c_per_h",
                self.ambient_drift_c_per_h,
                -100.0,
                100.0,
            ),
            ("latitude_deg", self.latitude_deg, -90.0, 90.0),
            (
                "centrifuge.arm_stretch_m_per_rad2_s2",
                c.arm_stretch_m_per_rad2_s2,
                -1e-3,
                1e-3,
            ),
            (
                "centrifuge.arm_expansion_ppm_per_c",
                c.arm_expansion_ppm_per_c,
                -1e3,
                1e3,
            ),
            ("centrifuge.tilt_urad", c.tilt_urad, 0.0, 1e5),
            (
                "centrifuge.readback_scale_ppm",
                c.readback_scale_ppm,
                -1e5,
                1e5,
            ),
            (
                "centrifuge.readback_resolution_deg_s",
                c.readback_resolution_deg_s,
                0.0,
                100.0,
            ),
            (
                "centrifuge.readback_gate_s",
                c.readback_gate_s,
                0.0025,
                100.0,
            ),
            (
                "centrifuge.windage_c_at_100g",
                c.windage_c_at_100g,
                0.0,
                100.0,
            ),
            ("centrifuge.windage_tau_s", c.windage_tau_s, 1.0, 1e6),
            (
                "instruments.koq_max_ug_per_g2",
                p.koq_max_ug_per_g2,
                0.0,
                1e6,
            ),
            (
                "instruments.asymmetry_max_ppm",
                p.asymmetry_max_ppm,
                0.0,
                1e6,
            ),
            (
                "instruments.k2_temp_coeff_ug_per_g2_per_c",
                p.k2_temp_coeff_ug_per_g2_per_c,
                0.0,
                100.0,
            ),
            (
                "instruments.k1_temp_coeff_ppm_per_c",
                p.k1_temp_coeff_ppm_per_c,
                -1e4,
                1e4,
            ),
            (
                "instruments.resonator_sum_ppm_per_c",
                p.resonator_sum_ppm_per_c,
                -1e4,
                1e4,
            ),
            ("instruments.flicker_ug", p.flicker_ug, 0.0, 1e6),
            (
                "faults.drift_ug_per_s",
                self.faults.drift_ug_per_s,
                0.0,
                1e9,
            ),
        ];
        for (key, v, lo, hi) in bounded {
            if !(v.is_finite() && (lo..=hi).contains(&v)) {
                return err(key, format!("{v} is outside {lo} to {hi}"));
            }
        }
        for (i, v) in p.k1_hz_per_g.iter().chain(&p.k2_abs_ug_per_g2).enumerate() {
            if !(v.is_finite() && (0.0..=1e6).contains(v)) {
                let key = if i < 2 {
                    "instruments.k1_hz_per_g"
                } else {
                    "instruments.k2_abs_ug_per_g2"
                };
                return err(key, format!("{v} is outside 0 to 1000000"));
            }
        }
        let [lo, hi] = p.disturbance_gain;
        if !(lo.is_finite()
            && hi.is_finite()
            && (-100.0..=100.0).contains(&lo)
            && lo <= hi
            && hi <= 100.0)
        {
            return err(
                "instruments.disturbance_gain",
                format!(
                    "must be a range [low, high] within −100 to 100 with low ≤ high, got [{lo}, {hi}]"
                ),
            );
        }
        if c.disturbances.len() > MAX_DISTURBANCES {
            return err(
                "centrifuge.disturbances",
                format!(
                    "at most {MAX_DISTURBANCES} (MAX_DISTURBANCES), got {}",
                    c.disturbances.len()
                ),
            );
        }
        if c.position_shifts_mm.len() > MAX_POSITION_SHIFTS
            || c.position_shifts_mm
                .iter()
                .any(|v| !(v.is_finite() && v.abs() <= 10.0))
        {
            return err(
                "centrifuge.position_shifts_mm",
                format!(
                    "at most {MAX_POSITION_SHIFTS} shifts (MAX_POSITION_SHIFTS), each within ±10 mm"
                ),
            );
        }
        for (i, d) in c.disturbances.iter().enumerate() {
            let ok = d.at_g.is_finite()
                && (0.0..=1e4).contains(&d.at_g)
                && d.width_g.is_finite()
                && d.width_g > 0.0
                && d.width_g <= 1e4
                && d.amplitude_ug.is_finite()
                && d.amplitude_ug.abs() <= 1e7;
            if !ok {
                return err(
                    &format!("centrifuge.disturbances[{i}]"),
                    format!(
                        "at_g 0 to 10000, width_g above 0 up to 10000 and |amplitude_ug| up to 1e7, got {d:?}"
                    ),
                );
            }
        }
        if p.k2_abs_ug_per_g2[0] > p.k2_abs_ug_per_g2[1] {
            return err(
                "instruments.k2_abs_ug_per_g2",
                "must be a range [low, high] with low ≤ high".into(),
            );
        }
        let times = [
            (
                "faults.module_silent",
                self.faults.module_silent.map(|(_, t)| t),
            ),
            (
                "faults.centrifuge_silent_at_s",
                self.faults.centrifuge_silent_at_s,
            ),
            (
                "faults.interlock_open_at_s",
                self.faults.interlock_open_at_s,
            ),
            (
                "faults.interlock_open_after_spin_s",
                self.faults.interlock_open_after_spin_s,
            ),
            ("faults.supply_trip_at_s", self.faults.supply_trip_at_s),
        ];
        for (key, t) in times {
            if let Some(t) = t
                && !(t.is_finite() && (0.0..=MAX_FAULT_TIME_S).contains(&t))
            {
                return err(
                    key,
                    format!(
                        "{t} s is not a time from 0 to {MAX_FAULT_TIME_S} s (MAX_FAULT_TIME_S)"
                    ),
                );
            }
        }
        if let Some((module, _)) = self.faults.module_silent
            && module >= self.modules
        {
            return err(
                "faults.module_silent",
                format!(
                    "module {module} does not exist (modules are numbered 0 to {})",
                    self.modules - 1
                ),
            );
        }
        if let Some((_, at_s)) = &self.faults.instrument_silent_at
            && !(at_s.is_finite() && (0.0..=1e7).contains(at_s))
        {
            return err(
                "faults.instrument_silent_at",
                format!("{at_s} s is outside 0 to 1e7 s"),
            );
        }
        for s in self
            .faults
            .dead_instruments
            .iter()
            .chain(self.faults.instrument_silent_at.as_ref().map(|(s, _)| s))
            .chain(&self.faults.noisy_instruments)
            .chain(&self.faults.drifting_instruments)
        {
            if s.module >= self.modules || s.slot >= 6 {
                return err(
                    "faults",
                    format!("no instrument at module {} slot {}", s.module, s.slot),
                );
            }
        }
        Ok(())
    }
}
