//! The bench around the instruments: temperatures, mountings, power and
//! relays, each instrument's input acceleration, the table's disturbance and
//! scheduled faults.

use super::{
    FLICKER_TAUS_S, INSTRUMENTS_PER_MODULE, MODULE_CURRENT_A, Mounting, SlotRef, StandardNormal,
    TICK_S, TICKS_PER_SECOND, World,
};
use rand_distr::Distribution;

/// A table turning faster than this is spinning, for faults timed by
/// spin [rad/s] (1 deg/s).
const SPINNING_RAD_S: f64 = std::f64::consts::PI / 180.0;

impl World {
    /// The laboratory's temperature now [°C].
    pub fn ambient_c(&self) -> f64 {
        self.config.ambient_c + self.config.ambient_drift_c_per_h * self.now_s() / 3600.0
    }

    /// What the instruments' surroundings are at now [°C]: the chamber's
    /// air as they feel it (lagged), or the laboratory.
    pub fn surroundings_c(&self) -> f64 {
        self.chamber
            .as_ref()
            .map_or_else(|| self.ambient_c(), |c| c.instrument_air_c)
    }

    /// The temperature chamber, if the bench has one.
    pub fn chamber(&self) -> Option<&crate::chamber::ChamberModel> {
        self.chamber.as_ref()
    }

    /// The temperature chamber, to answer its controller's requests.
    pub fn chamber_mut(&mut self) -> Option<&mut crate::chamber::ChamberModel> {
        self.chamber.as_mut()
    }

    /// Windage heating of the arm and the instruments now [°C].
    pub fn windage_c(&self) -> f64 {
        self.windage_c
    }

    /// Temperature of instrument `i` now [°C]: the laboratory, its
    /// self-heating since power-on, and the windage.
    pub fn instrument_temperature_c(&self, i: usize) -> f64 {
        let pc = &self.config.instruments;
        self.instruments.get(i).map_or(f64::NAN, |v| {
            v.temperature_c(
                self.now_s(),
                self.surroundings_c(),
                pc.self_heating_c,
                pc.warmup_tau_s,
            ) + self.windage_c
        })
    }

    /// Mount instrument `index` (module·6 + slot) as `mounting` (the operator's hands).
    pub fn set_mounting(&mut self, index: usize, mounting: Mounting) {
        if let Some(v) = self.instruments.get_mut(index) {
            v.mounting = mounting;
        }
    }

    /// The centrifuge controller answers again (a silence fault ends, e.g.
    /// its cable is plugged back in).
    pub fn end_centrifuge_silence(&mut self) {
        self.config.faults.centrifuge_silent_at_s = None;
        self.centrifuge_silent = false;
    }

    /// Mount every instrument the same way.
    pub fn set_all_mountings(&mut self, mounting: Mounting) {
        for v in &mut self.instruments {
            v.mounting = mounting;
        }
    }

    pub(super) fn rails_on(&self) -> bool {
        self.rails.outputs.iter().all(|o| o.on)
    }

    pub(super) fn module_alive(&self, m: usize) -> bool {
        self.logic.outputs[0].on && !self.module_silent.get(m).copied().unwrap_or(true)
    }

    /// Whether instrument `i` has gone silent by now (`faults.instrument_silent_at`).
    pub(super) fn fallen_silent(&self, i: usize) -> bool {
        self.config
            .faults
            .instrument_silent_at
            .as_ref()
            .is_some_and(|(s, at_s)| self.is(std::slice::from_ref(s), i) && self.now_s() >= *at_s)
    }

    pub(super) fn is(&self, list: &[SlotRef], i: usize) -> bool {
        list.iter()
            .any(|s| s.module * INSTRUMENTS_PER_MODULE + s.slot == i)
    }

    /// Module `m`'s relay mask (bit i = instrument i powered), if it exists.
    pub fn relay_mask(&self, m: usize) -> Option<u8> {
        self.modules.get(m).map(|module| module.relay_mask)
    }

    /// Whether module `m` is streaming.
    pub fn streaming(&self, m: usize) -> bool {
        self.modules
            .get(m)
            .is_some_and(|module| module.streaming.is_some())
    }

    /// Whether instrument `i` is powered: rails on and its relay closed.
    pub fn powered(&self, i: usize) -> bool {
        let m = i / INSTRUMENTS_PER_MODULE;
        let bit = 1u8 << (i % INSTRUMENTS_PER_MODULE);
        self.rails_on() && self.module_alive(m) && self.modules[m].relay_mask & bit != 0
    }

    /// Load current of each rails channel [A].
    pub fn rail_currents(&self) -> Vec<f64> {
        let n = (0..self.instruments.len())
            .filter(|&i| self.powered(i))
            .count() as f64;
        vec![n * self.config.instruments.current_a; 2]
    }

    pub(super) fn logic_currents(&self) -> Vec<f64> {
        vec![self.modules.len() as f64 * MODULE_CURRENT_A]
    }

    /// Acceleration along the input axis and across it [g] for instrument
    /// `i` now. On the arm (method.md (3), (13)): a = ω_i²·R(ω)/g with ω_i
    /// the rate in inertial space (the table's plus the Earth's vertical
    /// rate), R(ω) = R + k_s·ω² + R0·α·ΔT_arm + L_chamber·α·ΔT_chamber, plus the tilted axis's
    /// once-per-revolution gravity component along the radius; gravity
    /// lies across the input axis.
    pub fn input_g(&self, i: usize) -> (f64, f64) {
        let w = self.table.measured_rate_rad_s();
        let g = self.config.g_local_m_s2;
        let t = &self.config.centrifuge;
        let p = self.positions[i];
        let inertial = w + self.earth_rate_vertical_rad_s();
        let stretch_m = t.arm_stretch_m_per_rad2_s2 * w * w
            + p.drawing_radius_m * t.arm_expansion_ppm_per_c * 1e-6 * self.windage_c
            // The fixture in the chamber follows the chamber's air.
            + self.chamber.as_ref().map_or(0.0, |c| {
                c.config.radius_in_chamber_mm * 1e-3
                    * t.arm_expansion_ppm_per_c
                    * 1e-6
                    * (c.instrument_air_c - self.config.ambient_c)
            });
        // Only while the table turns: at rest the Earth's rate is no centripetal input.
        let radial = |r: f64| {
            if w == 0.0 {
                0.0
            } else {
                inertial * inertial * (r + stretch_m) / g
            }
        };
        let tilt = (t.tilt_urad * 1e-6).sin() * (self.table.angle_rad() + p.azimuth_rad).cos();
        match self.instruments[i].mounting {
            Mounting::TumbleUp => (1.0, 0.0),
            Mounting::TumbleDown => (-1.0, 0.0),
            Mounting::TumbleCrosswise { as_on_arm } => (0.0, if as_on_arm { 1.0 } else { -1.0 }),
            Mounting::ArmP => (radial(p.radius_p_m) + tilt, 1.0),
            Mounting::ArmN => (-(radial(p.radius_n_m) + tilt), 1.0),
        }
    }

    /// The structural disturbances' shift at the table's rate now [g],
    /// before each instrument's gain.
    pub(super) fn disturbance_g(&self) -> f64 {
        let t = &self.config.centrifuge;
        if t.disturbances.is_empty() {
            return 0.0;
        }
        let w = self.table.measured_rate_rad_s();
        let nominal_g = w * w * t.arm_radius_m / self.config.g_local_m_s2;
        t.disturbances
            .iter()
            .map(|d| d.shift_ug(nominal_g))
            .sum::<f64>()
            * 1e-6
    }

    /// Windage heating and the low-frequency noise, one tick on.
    pub(super) fn step_environment(&mut self) {
        let t = &self.config.centrifuge;
        if t.windage_c_at_100g != 0.0 {
            let w100 = (100.0 * self.config.g_local_m_s2 / t.arm_radius_m).sqrt();
            let ratio = self.table.measured_rate_rad_s().abs() / w100;
            let target = t.windage_c_at_100g * ratio * ratio * ratio;
            self.windage_c += (target - self.windage_c) * TICK_S / t.windage_tau_s;
        }
        // The low-frequency noise moves once a second (its shortest time
        // constant is ten seconds).
        if !self.tick.is_multiple_of(u64::from(TICKS_PER_SECOND)) {
            return;
        }
        let room_c = self.ambient_c();
        if let Some(chamber) = self.chamber.as_mut() {
            chamber.step(1.0, room_c);
        }
        for (state, v) in self.flicker_g.iter_mut().zip(&self.instruments) {
            if v.truth.flicker_ug == 0.0 {
                continue;
            }
            // Each process holds an equal share of the variance.
            let sigma = v.truth.flicker_ug * 1e-6 / (FLICKER_TAUS_S.len() as f64).sqrt();
            for (x, tau) in state.iter_mut().zip(FLICKER_TAUS_S) {
                let n: f64 = StandardNormal.sample(&mut self.noise_rng);
                let decay = (-1.0 / tau).exp();
                *x = *x * decay + sigma * (1.0 - decay * decay).sqrt() * n;
            }
        }
    }

    pub(super) fn fire_faults(&mut self) {
        let now = self.now_s();
        let f = self.config.faults.clone();
        if let Some((m, at)) = f.module_silent
            && now >= at
            && let Some(s) = self.module_silent.get_mut(m)
        {
            *s = true;
        }
        if f.centrifuge_silent_at_s.is_some_and(|at| now >= at) {
            self.centrifuge_silent = true;
        }
        if !self.faults_fired[0] && f.interlock_open_at_s.is_some_and(|at| now >= at) {
            self.faults_fired[0] = true;
            self.table.trip_interlocks();
        }
        if self.table.rate_rad_s.abs() > SPINNING_RAD_S {
            self.spun_s += TICK_S;
        }
        if !self.faults_fired[2]
            && f.interlock_open_after_spin_s
                .is_some_and(|after| self.spun_s >= after)
        {
            self.faults_fired[2] = true;
            self.table.trip_interlocks();
        }
        if !self.faults_fired[1] && f.supply_trip_at_s.is_some_and(|at| now >= at) {
            self.faults_fired[1] = true;
            self.rails.trip();
        }
        // A real over-current: the load exceeds a channel's limit.
        let currents = self.rail_currents();
        if self
            .rails
            .outputs
            .iter()
            .zip(&currents)
            .any(|(o, c)| o.on && *c > o.current_limit_a)
        {
            self.rails.trip();
        }
    }
}
