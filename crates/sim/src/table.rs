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
    /// The measured rate of each step within the last gate [rad/s].
    gate: std::collections::VecDeque<f64>,
    /// Sum of `gate`.
    gate_sum: f64,
    /// Steps since the start, to sum the gate afresh once per gate.
    gate_steps: u64,
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
            gate: std::collections::VecDeque::new(),
            gate_sum: 0.0,
            gate_steps: 0,
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
        // The controller's gate: a running sum, summed afresh once per gate
        // so rounding cannot accumulate over a long run.
        // Like a real controller counting encoder lines, it reports the mean
        // rate over its last gate, not one instant of the ripple.
        let steps = ((self.config.readback_gate_s / dt).round() as usize).max(1);
        let rate = self.measured_rate_rad_s();
        self.gate.push_back(rate);
        self.gate_sum += rate;
        while self.gate.len() > steps {
            self.gate_sum -= self.gate.pop_front().unwrap_or(0.0);
        }
        self.gate_steps += 1;
        if self.gate_steps.is_multiple_of(steps as u64) {
            self.gate_sum = self.gate.iter().sum();
        }
    }

    /// The rate the controller reports [rad/s]: the mean of the measured
    /// rate over its last gate (`readback_gate_s`), with its scale error
    /// and rounded to its resolution.
    pub fn reported_rate_rad_s(&self) -> f64 {
        let mean = if self.gate.is_empty() {
            self.measured_rate_rad_s()
        } else {
            self.gate_sum / self.gate.len() as f64
        };
        let scaled_deg_s = mean.to_degrees() * (1.0 + self.config.readback_scale_ppm * 1e-6);
        let step = self.config.readback_resolution_deg_s;
        let shown = if step > 0.0 {
            (scaled_deg_s / step).round() * step
        } else {
            scaled_deg_s
        };
        shown.to_radians()
    }

    /// The table's angle [rad], 0 to 2π.
    pub fn angle_rad(&self) -> f64 {
        self.angle_rad
    }

    /// The instantaneous rate with ripple and wander [rad/s]: what the
    /// instruments feel.
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
