//! The virtual bench's temperature chamber: air that
//! heats and cools at limited rates toward the setpoint, overshoots and
//! settles, instruments that follow the air with a lag, alarms, the dry-air
//! purge, and two faults (a controller that stops answering; a heater that
//! runs away). It answers Modbus RTU through the `rmodbus` server codec with
//! the register map [`SIM_REGISTERS`] states.

use rmodbus::server::ModbusFrame;
use rmodbus::server::context::ModbusContext;
use rmodbus::server::storage::ModbusStorageSmall;
use rmodbus::{ModbusFrameBuf, ModbusProto};
use serde::{Deserialize, Serialize};

/// The chamber's faults.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ChamberFault {
    /// None.
    #[default]
    None,
    /// The controller stops answering at `fault_at_s`.
    Silent,
    /// The heater sticks on at `fault_at_s`: the air rises at the heating
    /// rate whatever the setpoint, and the over-temperature alarm sets.
    Runaway,
}

/// The `[chamber]` section of a bench config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ChamberSimConfig {
    /// Fastest heating of the air [°C per minute].
    pub heat_rate_c_per_min: f64,
    /// Fastest cooling of the air [°C per minute].
    pub cool_rate_c_per_min: f64,
    /// How far the air overshoots a new setpoint [°C], decaying with `settle_tau_s`.
    pub overshoot_c: f64,
    /// Time constant of the overshoot's decay [s].
    pub settle_tau_s: f64,
    /// Time constant of the instruments following the air [s] (their mass and fixture).
    pub instrument_lag_s: f64,
    /// The alarm sets when the air is this far above the setpoint [°C].
    pub alarm_band_c: f64,
    /// A fault to inject.
    pub fault: ChamberFault,
    /// When the fault starts [s of bench time].
    pub fault_at_s: f64,
    /// The dry-air purge valve is on a relay module of its own (Modbus RTU
    /// on its own pty, the valve on coil [`SIM_RELAY_COIL`]) and not on the
    /// controller, whose purge register then switches nothing.
    pub purge_on_relay: bool,
    /// How much of each instrument's radius sits in the chamber and follows
    /// its air (the fixture) [mm]: it grows with the arm's
    /// `arm_expansion_ppm_per_c` per °C of the chamber, so a radius found
    /// at one temperature is off at the others.
    pub radius_in_chamber_mm: f64,
}

impl Default for ChamberSimConfig {
    fn default() -> Self {
        ChamberSimConfig {
            heat_rate_c_per_min: 3.0,
            cool_rate_c_per_min: 2.0,
            overshoot_c: 0.8,
            settle_tau_s: 120.0,
            instrument_lag_s: 300.0,
            alarm_band_c: 5.0,
            fault: ChamberFault::None,
            fault_at_s: 0.0,
            purge_on_relay: false,
            radius_in_chamber_mm: 30.0,
        }
    }
}

impl ChamberSimConfig {
    /// Check every number against its bound; the error names the key.
    pub fn validate(&self) -> Result<(), (String, String)> {
        for (key, v, lo, hi) in [
            (
                "chamber.heat_rate_c_per_min",
                self.heat_rate_c_per_min,
                0.01,
                100.0,
            ),
            (
                "chamber.cool_rate_c_per_min",
                self.cool_rate_c_per_min,
                0.01,
                100.0,
            ),
            ("chamber.overshoot_c", self.overshoot_c, 0.0, 20.0),
            ("chamber.settle_tau_s", self.settle_tau_s, 1.0, 86_400.0),
            (
                "chamber.instrument_lag_s",
                self.instrument_lag_s,
                1.0,
                86_400.0,
            ),
            ("chamber.alarm_band_c", self.alarm_band_c, 0.1, 100.0),
            ("chamber.fault_at_s", self.fault_at_s, 0.0, 1e7),
            (
                "chamber.radius_in_chamber_mm",
                self.radius_in_chamber_mm,
                0.0,
                1000.0,
            ),
        ] {
            if !(v.is_finite() && (lo..=hi).contains(&v)) {
                return Err((key.into(), format!("{v} is not from {lo} to {hi}")));
            }
        }
        Ok(())
    }
}

/// The simulated controller's register map (holding registers, 0-based),
/// as a station config's `[chamber.protocol]` names them.
pub struct SimRegisters {
    /// Setpoint, 0.1 °C counts, signed.
    pub setpoint: u16,
    /// Air temperature, 0.1 °C counts, signed (an input register too).
    pub process_value: u16,
    /// 1 run, 0 stop.
    pub run: u16,
    /// Bit 0: over-temperature.
    pub alarms: u16,
    /// 1 purge on.
    pub purge: u16,
    /// Counts per °C.
    pub counts_per_c: f64,
    /// Modbus unit id.
    pub unit_id: u8,
}

/// The register map of the simulated chamber controller.
pub const SIM_REGISTERS: SimRegisters = SimRegisters {
    setpoint: 100,
    process_value: 101,
    run: 102,
    alarms: 103,
    purge: 104,
    counts_per_c: 10.0,
    unit_id: 1,
};

/// The purge relay module's coil that switches the valve (unit id 1).
pub const SIM_RELAY_COIL: u16 = 0;

/// The chamber's state.
#[derive(Debug)]
pub struct ChamberModel {
    /// The chamber as configured.
    pub config: ChamberSimConfig,
    /// Air temperature [°C].
    pub air_c: f64,
    /// What the instruments' surroundings are at (the air, lagged) [°C].
    pub instrument_air_c: f64,
    /// Setpoint [°C].
    pub setpoint_c: f64,
    /// Running (else the air drifts back to the room).
    pub running: bool,
    /// The dry-air purge is on.
    pub purge: bool,
    /// Over-temperature alarm (latched until the air is back in band).
    pub alarm: bool,
    /// The air above this is over temperature [°C]: the band above the
    /// setpoint, or above where the air was when it was set (a chamber
    /// cooling down is not over temperature).
    ceiling_c: f64,
    /// Overshoot still to decay [°C] and its sign.
    overshoot_left_c: f64,
    /// The air was moving toward the setpoint (to know when it arrives).
    approaching: bool,
    registers: ModbusStorageSmall,
    relay: ModbusStorageSmall,
    now_s: f64,
}

impl ChamberModel {
    /// A chamber at room temperature `room_c`, stopped.
    pub fn new(config: ChamberSimConfig, room_c: f64) -> Self {
        let ceiling_c = room_c + config.alarm_band_c;
        ChamberModel {
            config,
            air_c: room_c,
            instrument_air_c: room_c,
            setpoint_c: room_c,
            running: false,
            purge: false,
            alarm: false,
            ceiling_c,
            overshoot_left_c: 0.0,
            approaching: false,
            registers: ModbusStorageSmall::default(),
            relay: ModbusStorageSmall::default(),
            now_s: 0.0,
        }
    }

    fn fault_active(&self, fault: ChamberFault) -> bool {
        self.config.fault == fault && self.now_s >= self.config.fault_at_s
    }

    /// Whether the controller answers now.
    pub fn answers(&self) -> bool {
        !self.fault_active(ChamberFault::Silent)
    }

    /// Advance `dt_s` seconds with the room at `room_c`.
    pub fn step(&mut self, dt_s: f64, room_c: f64) {
        self.now_s += dt_s;
        let c = &self.config;
        let heat = c.heat_rate_c_per_min / 60.0 * dt_s;
        let cool = c.cool_rate_c_per_min / 60.0 * dt_s;
        if self.fault_active(ChamberFault::Runaway) {
            self.air_c += heat;
        } else if self.running {
            let error = self.setpoint_c + self.overshoot_left_c - self.air_c;
            if self.approaching && error.abs() <= heat.max(cool) {
                // Arrived: overshoot by the configured amount, then settle.
                self.approaching = false;
                self.overshoot_left_c = c.overshoot_c * self.overshoot_left_c.signum();
            }
            self.air_c += error.clamp(-cool, heat);
            self.overshoot_left_c *= (-dt_s / c.settle_tau_s).exp();
        } else {
            // Stopped: the air drifts back to the room at the cooling rate's pace.
            let error = room_c - self.air_c;
            self.air_c += error * (1.0 - (-dt_s / c.settle_tau_s).exp());
        }
        self.instrument_air_c +=
            (self.air_c - self.instrument_air_c) * (1.0 - (-dt_s / c.instrument_lag_s).exp());
        // Once the air is back near the setpoint, the band is the setpoint's.
        if (self.air_c - self.setpoint_c).abs() < 0.5 * c.alarm_band_c {
            self.ceiling_c = self.setpoint_c + c.alarm_band_c;
        }
        if self.air_c > self.ceiling_c {
            self.alarm = true;
        } else if self.air_c < self.ceiling_c - 0.5 * c.alarm_band_c {
            self.alarm = false;
        }
    }

    fn set_setpoint(&mut self, celsius: f64) {
        if celsius != self.setpoint_c {
            // The overshoot goes beyond the new setpoint, in the direction moved.
            self.overshoot_left_c = if celsius > self.air_c { 1e-9 } else { -1e-9 };
            self.approaching = true;
            self.setpoint_c = celsius;
            self.ceiling_c = celsius.max(self.air_c) + self.config.alarm_band_c;
        }
    }

    fn counts(celsius: f64) -> u16 {
        let c = (celsius * SIM_REGISTERS.counts_per_c)
            .round()
            .clamp(f64::from(i16::MIN), f64::from(i16::MAX));
        c as i16 as u16
    }

    /// Answer one Modbus RTU request frame; `None` when the controller is
    /// silent or the frame is not for it (a wrong CRC is not answered, as
    /// on a real line).
    pub fn answer_rtu(&mut self, request: &[u8]) -> Option<Vec<u8>> {
        if !self.answers() || request.len() > 256 {
            return None;
        }
        let r = &SIM_REGISTERS;
        // The registers show the state; writes land in them and are taken in.
        let pv = Self::counts(self.air_c);
        let _ = self
            .registers
            .set_holding(r.setpoint, Self::counts(self.setpoint_c));
        let _ = self.registers.set_holding(r.process_value, pv);
        let _ = self.registers.set_input(r.process_value, pv);
        let _ = self.registers.set_holding(r.run, u16::from(self.running));
        let _ = self.registers.set_holding(r.alarms, u16::from(self.alarm));
        let _ = self.registers.set_holding(r.purge, u16::from(self.purge));
        let mut buf: ModbusFrameBuf = [0; 256];
        buf[..request.len()].copy_from_slice(request);
        let mut response = Vec::new();
        let mut frame = ModbusFrame::new(r.unit_id, &buf, ModbusProto::Rtu, &mut response);
        frame.parse().ok()?;
        if frame.processing_required {
            let result = if frame.readonly {
                frame.process_read(&self.registers)
            } else {
                frame.process_write(&mut self.registers)
            };
            result.ok()?;
        }
        if !frame.response_required {
            return None;
        }
        frame.finalize_response().ok()?;
        let as_c = |v: u16| f64::from(v as i16) / r.counts_per_c;
        if let Ok(v) = self.registers.get_holding(r.setpoint) {
            self.set_setpoint(as_c(v));
        }
        if let Ok(v) = self.registers.get_holding(r.run) {
            self.running = v != 0;
        }
        if !self.config.purge_on_relay
            && let Ok(v) = self.registers.get_holding(r.purge)
        {
            self.purge = v != 0;
        }
        Some(response)
    }

    /// The purge relay module's answer to one Modbus RTU request frame (a
    /// module of its own: it answers whatever the controller's fault).
    pub fn answer_relay_rtu(&mut self, request: &[u8]) -> Option<Vec<u8>> {
        if !self.config.purge_on_relay || request.len() > 256 {
            return None;
        }
        let _ = self.relay.set_coil(SIM_RELAY_COIL, self.purge);
        let mut buf: ModbusFrameBuf = [0; 256];
        buf[..request.len()].copy_from_slice(request);
        let mut response = Vec::new();
        let mut frame = ModbusFrame::new(1, &buf, ModbusProto::Rtu, &mut response);
        frame.parse().ok()?;
        if frame.processing_required {
            let result = if frame.readonly {
                frame.process_read(&self.relay)
            } else {
                frame.process_write(&mut self.relay)
            };
            result.ok()?;
        }
        if !frame.response_required {
            return None;
        }
        frame.finalize_response().ok()?;
        if let Ok(on) = self.relay.get_coil(SIM_RELAY_COIL) {
            self.purge = on;
        }
        Some(response)
    }

    /// The valve is on a relay module of its own.
    pub fn purge_on_relay(&self) -> bool {
        self.config.purge_on_relay
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_air_heats_at_its_rate_overshoots_and_settles_and_the_instruments_lag() {
        let mut c = ChamberModel::new(ChamberSimConfig::default(), 23.0);
        c.running = true;
        c.set_setpoint(70.0);
        c.step(60.0, 23.0);
        assert!(
            (c.air_c - 26.0).abs() < 1e-9,
            "3 °C in a minute: {}",
            c.air_c
        );
        let mut peak: f64 = 0.0;
        for _ in 0..3600 {
            c.step(1.0, 23.0);
            peak = peak.max(c.air_c);
        }
        assert!(peak > 70.3 && peak < 71.0, "overshoot: {peak}");
        assert!((c.air_c - 70.0).abs() < 0.05, "settled: {}", c.air_c);
        assert!(c.instrument_air_c < c.air_c && c.instrument_air_c > 60.0);
        assert!(!c.alarm);
    }

    #[test]
    fn a_runaway_heater_sets_the_alarm_and_a_silent_controller_answers_nothing() {
        let config = ChamberSimConfig {
            fault: ChamberFault::Runaway,
            fault_at_s: 10.0,
            ..ChamberSimConfig::default()
        };
        let mut c = ChamberModel::new(config, 23.0);
        c.running = true;
        for _ in 0..200 {
            c.step(1.0, 23.0);
        }
        assert!(c.alarm && c.air_c > 28.0, "{}", c.air_c);
        let mut silent = ChamberModel::new(
            ChamberSimConfig {
                fault: ChamberFault::Silent,
                ..ChamberSimConfig::default()
            },
            23.0,
        );
        silent.step(1.0, 23.0);
        assert!(silent.answer_rtu(&[1, 3, 0, 101, 0, 1, 0, 0]).is_none());
    }
}
