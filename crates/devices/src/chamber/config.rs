//! The `[chamber]` section of the station config (`ChamberConfig`, its
//! protocol and outage budget), the purge valve on a relay module of its
//! own (`[chamber.purge_relay]`, [`PurgeOnRelay`]), and `connect`, which
//! builds the drivers from them.

use super::{Chamber, LineChamber, ModbusChamber};
use crate::config::{ConfigError, ConnectError, TransportConfig};
use crate::error::DeviceError;
use crate::line::IoPolicy;
use serde::Deserialize;
use spinbench_wire::chamber::{LineChamberDialect, ModbusFraming, RegisterMap};

/// The chamber controller's protocol in the station config.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ChamberProtocol {
    /// Modbus RTU over the serial transport.
    ModbusRtu(RegisterMap),
    /// Modbus TCP.
    ModbusTcp(RegisterMap),
    /// A line dialect (ASCII/SCPI).
    Line(Box<LineChamberDialect>),
}

/// The `[chamber]` section.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChamberConfig {
    /// Name in messages.
    pub name: String,
    /// How to reach it.
    pub transport: TransportConfig,
    /// Its protocol and register map or dialect.
    pub protocol: ChamberProtocol,
    /// Deadlines and retries.
    #[serde(default)]
    pub io: IoPolicy,
    /// How long a Modbus controller that is away (its connection refused
    /// or reset: rebooting) or busy (exceptions 05, 06) is waited for,
    /// trying again with back-off, before the command fails [s] (default
    /// 30, at most 300; 0: not at all).
    #[serde(default = "default_outage_s")]
    pub outage_s: f64,
    /// The dry-air purge valve on a relay module of its own
    /// (`[chamber.purge_relay]`) rather than on the controller.
    #[serde(default)]
    pub purge_relay: Option<PurgeRelayConfig>,
}

/// How a purge relay module is spoken to.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum RelayProtocol {
    /// Modbus RTU: the valve on a coil (function 5).
    ModbusRtu {
        /// Modbus unit id (default 1).
        #[serde(default = "unit_one")]
        unit_id: u8,
        /// The coil the valve is on (0-based).
        coil: u16,
    },
    /// Modbus TCP: the valve on a coil.
    ModbusTcp {
        /// Modbus unit id (default 1).
        #[serde(default = "unit_one")]
        unit_id: u8,
        /// The coil the valve is on (0-based).
        coil: u16,
    },
    /// A line command for on and one for off.
    Line {
        /// Switch the valve on, e.g. `RELAY 1 ON`.
        on: String,
        /// Switch it off.
        off: String,
        /// The module's acknowledgement (absent: silent).
        #[serde(default)]
        ack: Option<String>,
        /// Line ending (default "\r\n").
        #[serde(default = "crlf")]
        line_ending: String,
    },
}

fn default_outage_s() -> f64 {
    crate::outage::DEFAULT_OUTAGE_S
}

fn unit_one() -> u8 {
    1
}

fn crlf() -> String {
    "\r\n".into()
}

/// The `[chamber.purge_relay]` section: a relay module that switches the
/// dry-air purge valve.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PurgeRelayConfig {
    /// Name in messages.
    pub name: String,
    /// How to reach it.
    pub transport: TransportConfig,
    /// Its protocol.
    pub protocol: RelayProtocol,
    /// Deadlines and retries.
    #[serde(default)]
    pub io: IoPolicy,
}

impl PurgeRelayConfig {
    /// Open the module and build its driver: a chamber driver of which only
    /// `set_purge` is ever called (the coil or the on/off lines are its
    /// only entries), so the relay shares the chamber drivers' framing,
    /// retries and refusals.
    fn connect(&self) -> Result<Box<dyn Chamber>, ConnectError> {
        self.io.validate("chamber.purge_relay")?;
        let transport = self.transport.open().map_err(|e| ConnectError::Open {
            device: self.name.clone(),
            error: e.to_string(),
        })?;
        let relay_map = |unit_id: u8, coil: u16| RegisterMap {
            unit_id,
            setpoint: 0,
            process_value: 0,
            process_value_is_input: false,
            run: 0,
            run_value: 1,
            stop_value: 0,
            alarms: None,
            purge: None,
            purge_coil: Some(coil),
            counts_per_c: 10.0,
        };
        Ok(match &self.protocol {
            RelayProtocol::ModbusRtu { unit_id, coil } => Box::new(ModbusChamber::new(
                transport,
                relay_map(*unit_id, *coil),
                ModbusFraming::Rtu,
                &self.name,
                self.io,
            )),
            RelayProtocol::ModbusTcp { unit_id, coil } => Box::new(ModbusChamber::new(
                transport,
                relay_map(*unit_id, *coil),
                ModbusFraming::Tcp,
                &self.name,
                self.io,
            )),
            RelayProtocol::Line {
                on,
                off,
                ack,
                line_ending,
            } => Box::new(LineChamber::new(
                transport,
                LineChamberDialect::relay(on, off, ack.clone(), line_ending),
                &self.name,
                self.io,
            )),
        })
    }
}

/// A chamber whose purge valve is on a relay module: every operation goes
/// to the controller except the purge, which goes to the relay.
pub struct PurgeOnRelay {
    chamber: Box<dyn Chamber>,
    relay: Box<dyn Chamber>,
}

impl PurgeOnRelay {
    /// The controller `chamber` with its purge switched by `relay` (a
    /// driver of which only `set_purge` is called).
    pub fn new(chamber: Box<dyn Chamber>, relay: Box<dyn Chamber>) -> Self {
        PurgeOnRelay { chamber, relay }
    }
}

impl Chamber for PurgeOnRelay {
    fn set_outage_budget(&mut self, budget: std::time::Duration) {
        self.chamber.set_outage_budget(budget);
        self.relay.set_outage_budget(budget);
    }
    fn busy_replies(&self) -> u64 {
        self.chamber.busy_replies() + self.relay.busy_replies()
    }
    fn set_setpoint_c(&mut self, celsius: f64) -> Result<(), DeviceError> {
        self.chamber.set_setpoint_c(celsius)
    }
    fn setpoint_c(&mut self) -> Result<f64, DeviceError> {
        self.chamber.setpoint_c()
    }
    fn temperature_c(&mut self) -> Result<f64, DeviceError> {
        self.chamber.temperature_c()
    }
    fn set_running(&mut self, on: bool) -> Result<(), DeviceError> {
        self.chamber.set_running(on)
    }
    fn alarms(&mut self) -> Result<u16, DeviceError> {
        self.chamber.alarms()
    }
    fn set_purge(&mut self, on: bool) -> Result<(), DeviceError> {
        self.relay.set_purge(on)
    }
}

impl ChamberConfig {
    /// Check the section; the error names the key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.io.validate("chamber")?;
        let max = crate::outage::MAX_OUTAGE_S;
        if !(self.outage_s.is_finite() && (0.0..=max).contains(&self.outage_s)) {
            return Err(ConfigError {
                key: "chamber.outage_s".into(),
                problem: format!("{} s is outside 0 to {max} s (MAX_OUTAGE_S)", self.outage_s),
            });
        }
        self.transport.validate("chamber")?;
        if let Some(relay) = &self.purge_relay {
            relay.io.validate("chamber.purge_relay")?;
            relay.transport.validate("chamber.purge_relay")?;
            let on_controller = match &self.protocol {
                ChamberProtocol::ModbusRtu(map) | ChamberProtocol::ModbusTcp(map) => {
                    map.purge.is_some() || map.purge_coil.is_some()
                }
                ChamberProtocol::Line(d) => d.purge_on.is_some() || d.purge_off.is_some(),
            };
            if on_controller {
                return Err(ConfigError {
                    key: "chamber.purge_relay".into(),
                    problem: "the purge is both on the controller (its map or dialect names a purge output) and on a relay: keep the one the valve is wired to".into(),
                });
            }
        }
        if let ChamberProtocol::ModbusRtu(map) | ChamberProtocol::ModbusTcp(map) = &self.protocol {
            map.validate().map_err(|problem| ConfigError {
                key: "chamber.protocol".into(),
                problem: problem.to_string(),
            })?;
        }
        Ok(())
    }

    /// Open the transport (and the purge relay's) and build the driver.
    pub fn connect(&self) -> Result<Box<dyn Chamber>, ConnectError> {
        self.validate()?;
        let relay = self
            .purge_relay
            .as_ref()
            .map(PurgeRelayConfig::connect)
            .transpose()?;
        let transport = self.transport.open().map_err(|e| ConnectError::Open {
            device: self.name.clone(),
            error: e.to_string(),
        })?;
        let outage = std::time::Duration::from_secs_f64(self.outage_s);
        let controller: Box<dyn Chamber> = match &self.protocol {
            ChamberProtocol::ModbusRtu(map) => Box::new(
                ModbusChamber::new(
                    transport,
                    map.clone(),
                    ModbusFraming::Rtu,
                    &self.name,
                    self.io,
                )
                .with_outage_budget(outage),
            ),
            ChamberProtocol::ModbusTcp(map) => Box::new(
                ModbusChamber::new(
                    transport,
                    map.clone(),
                    ModbusFraming::Tcp,
                    &self.name,
                    self.io,
                )
                .with_outage_budget(outage),
            ),
            ChamberProtocol::Line(dialect) => Box::new(LineChamber::new(
                transport,
                (**dialect).clone(),
                &self.name,
                self.io,
            )),
        };
        Ok(match relay {
            Some(relay) => Box::new(PurgeOnRelay::new(controller, relay)),
            None => controller,
        })
    }
}
