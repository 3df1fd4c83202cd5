//! The centrifuge: a rate loop with an acceleration limit, second-order
//! response (spin-up, overshoot, settling), once-per-revolution ripple,
//! slow wander and interlocks.

use crate::config::TableConfig;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};

/// Correlation time of the rate wander [s].
const WANDER_TAU_S: f64 = 60.0;

/// The table's state.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    config: TableConfig,
    /// Rate of the table, without ripple [rad/s].
    pub rate_rad_s: f64,
    rate_dot: f64,
    /// Slew-limited set point [rad/s].
    reference_rad_s: f64,
    /// Demanded rate [rad/s].
    pub demand_rad_s: f64,
    /// Rate mode on (the table follows the demand).
    pub rate_mode: bool,
    /// Interlocks closed (the table may move).
    pub interlocks_closed: bool,
    /// A latched interlock fault: closing needs a reset first.
    pub interlock_fault: bool,
    angle_rad: f64,
    wander: f64,
}

impl Table {
    /// A table at rest with open interlocks.
    pub fn new(config: TableConfig) -> Table {
        Table {
            config,
            rate_rad_s: 0.0,
            rate_dot: 0.0,
            reference_rad_s: 0.0,
            demand_rad_s: 0.0,
            rate_mode: false,
            interlocks_closed: false,
            interlock_fault: false,
            angle_rad: 0.0,
            wander: 0.0,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &TableConfig {
        &self.config
    }

    /// Rate limit [rad/s].
    pub fn max_rate_rad_s(&self) -> f64 {
        self.config.max_rate_deg_s.to_radians()
    }

    /// Advance by `dt` seconds.
    pub fn step(&mut self, dt: f64, rng: &mut impl Rng) {
        let target = if self.rate_mode && self.interlocks_closed {
            self.demand_rad_s
        } else {
            0.0
        };
        let max_step = self.config.max_accel_deg_s2.to_radians() * dt;
        self.reference_rad_s += (target - self.reference_rad_s).clamp(-max_step, max_step);
        let wn = std::f64::consts::TAU * self.config.loop_natural_hz;
        let zeta = self.config.loop_damping;
        let accel =
            wn * wn * (self.reference_rad_s - self.rate_rad_s) - 2.0 * zeta * wn * self.rate_dot;
        self.rate_dot += accel * dt;
        self.rate_rad_s += self.rate_dot * dt;
        self.angle_rad = (self.angle_rad + self.rate_rad_s * dt).rem_euclid(std::f64::consts::TAU);
        // Ornstein-Uhlenbeck wander with RMS `wander_ppm`.
        let sigma = self.config.wander_ppm * 1e-6;
        let n: f64 = StandardNormal.sample(rng);
        self.wander +=
            -self.wander / WANDER_TAU_S * dt + sigma * (2.0 * dt / WANDER_TAU_S).sqrt() * n;
    }

    /// The instantaneous rate with ripple and wander [rad/s]: what the
    /// instruments feel and the controller reports.
    pub fn measured_rate_rad_s(&self) -> f64 {
        self.rate_rad_s * (1.0 + self.config.ripple_ppm * 1e-6 * self.angle_rad.sin() + self.wander)
    }

    /// Open the interlocks as a fault (an operator opened the door): the
    /// table makes a controlled stop and needs a reset before it is armed again.
    pub fn trip_interlocks(&mut self) {
        self.interlocks_closed = false;
        self.interlock_fault = true;
    }
}
