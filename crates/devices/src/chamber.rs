//! The `Chamber` trait (a temperature chamber: setpoint, air temperature,
//! run/stop, alarms, the dry-air purge) and its two drivers: Modbus RTU or
//! TCP with a register map ([`ModbusChamber`]) and a templated line dialect
//! ([`LineChamber`]); the `[chamber]` section of the station config.

use crate::config::{ConfigError, ConnectError, TransportConfig};
use crate::error::{DeviceError, DeviceErrorKind};
use crate::line::{IoPolicy, LineChannel};
use crate::transport::Transport;
use serde::Deserialize;
use spinbench_wire::chamber::{
    ChamberCodecError, ChamberOp, ChamberReply, LineChamberDialect, LineExpect, ModbusChamberCodec,
    ModbusFraming, RegisterMap,
};
use std::io;
use std::time::Instant;

/// A temperature chamber, in °C.
pub trait Chamber: Send {
    /// Set the setpoint [°C].
    fn set_setpoint_c(&mut self, celsius: f64) -> Result<(), DeviceError>;
    /// The setpoint the controller holds [°C].
    fn setpoint_c(&mut self) -> Result<f64, DeviceError>;
    /// The air temperature (process value) [°C].
    fn temperature_c(&mut self) -> Result<f64, DeviceError>;
    /// Run (true) or stop the controller.
    fn set_running(&mut self, on: bool) -> Result<(), DeviceError>;
    /// The alarm word (0: no alarm; 0 too for a controller without one).
    fn alarms(&mut self) -> Result<u16, DeviceError>;
    /// Switch the dry-air purge on or off.
    fn set_purge(&mut self, on: bool) -> Result<(), DeviceError>;
    /// How long a controller that is away or busy is waited for from now
    /// on (a driver that cannot ride outages ignores it): the safe state
    /// shortens it and leaves the rest to its keeper.
    fn set_outage_budget(&mut self, _budget: std::time::Duration) {}
    /// Busy replies (Modbus exceptions 05, 06) ridden since the driver was
    /// made (0 for a driver that has none).
    fn busy_replies(&self) -> u64 {
        0
    }
}

/// Largest or smallest setpoint any chamber driver sends [°C].
pub const SETPOINT_RANGE_C: (f64, f64) = (-100.0, 200.0);

fn check_setpoint(device: &str, celsius: f64) -> Result<(), DeviceError> {
    let (lo, hi) = SETPOINT_RANGE_C;
    if celsius.is_finite() && (lo..=hi).contains(&celsius) {
        Ok(())
    } else {
        Err(DeviceError {
            device: device.to_string(),
            command: format!("set setpoint {celsius} °C"),
            kind: DeviceErrorKind::Rejected(format!(
                "a setpoint must be from {lo} to {hi} °C (SETPOINT_RANGE_C)"
            )),
        })
    }
}

/// A chamber controller on Modbus RTU (serial) or TCP. Each operation is one
/// request and its reply; a timeout or a garbled reply is retried as the
/// I/O policy says, a Modbus exception is the controller's refusal (final).
pub struct ModbusChamber<T: Transport> {
    transport: T,
    codec: ModbusChamberCodec,
    device: String,
    policy: IoPolicy,
    /// How long a controller that is away (connection refused or reset) or
    /// busy (exception 05 or 06) is waited for, trying again with back-off.
    outage_budget: std::time::Duration,
    /// Busy replies ridden so far.
    busy_replies: u64,
}

/// How one exchange failed.
enum Failed {
    /// Busy: a Modbus exception 05 or 06 (the code).
    Busy(u8),
    /// Away: the connection failed (refused, reset, closed).
    Away,
    /// Silent: no reply to any of the I/O policy's tries (a link that
    /// drops bytes, a controller busy restarting its Modbus task): ridden
    /// as an outage is.
    Silent,
    /// Anything else: final.
    Final,
}

enum Attempt {
    Timeout,
    Garbled(String, String),
    Io(io::Error),
}

impl<T: Transport> ModbusChamber<T> {
    /// A driver for the chamber named `name`.
    pub fn new(
        transport: T,
        map: RegisterMap,
        framing: ModbusFraming,
        name: &str,
        policy: IoPolicy,
    ) -> Self {
        let device = format!(
            "chamber '{name}' (Modbus {framing:?} at {})",
            transport.describe()
        );
        ModbusChamber {
            transport,
            codec: ModbusChamberCodec::new(map, framing),
            device,
            policy,
            outage_budget: std::time::Duration::from_secs_f64(crate::outage::DEFAULT_OUTAGE_S),
            busy_replies: 0,
        }
    }

    /// The same driver riding outages of at most `budget` (0: none).
    pub fn with_outage_budget(mut self, budget: std::time::Duration) -> Self {
        self.outage_budget = budget;
        self
    }

    /// One operation, riding a controller that is busy, briefly away
    /// (rebooting) or silent (no reply to any of the I/O policy's tries)
    /// within the outage budget, with back-off ([`crate::outage::Outage`]);
    /// a refusal or a garbled reply is final at once.
    fn exchange(&mut self, op: ChamberOp) -> Result<ChamberReply, DeviceError> {
        let mut outage: Option<crate::outage::Outage> = None;
        loop {
            let (error, how) = match self.exchange_once(op) {
                Ok(reply) => return Ok(reply),
                Err(failed) => failed,
            };
            if matches!(how, Failed::Final) {
                return Err(error);
            }
            if matches!(how, Failed::Busy(_)) {
                self.busy_replies += 1;
            }
            let budget = self.outage_budget;
            let o = outage.get_or_insert_with(|| crate::outage::Outage::new(budget));
            if !o.wait() {
                let what = match how {
                    Failed::Busy(code) => format!(
                        "busy for {:.1} s (Modbus exception {code}: {})",
                        o.lasted().as_secs_f64(),
                        spinbench_wire::chamber::modbus_exception_meaning(code)
                    ),
                    Failed::Silent => format!("silent for {:.1} s", o.lasted().as_secs_f64()),
                    _ => format!("away for {:.1} s", o.lasted().as_secs_f64()),
                };
                return Err(self.error(
                    op,
                    DeviceErrorKind::Io(format!(
                        "{what}, {} tries with back-off, beyond its outage budget of {:.0} s \
                         (chamber.outage_s); the last: {}",
                        o.tries() + 1,
                        budget.as_secs_f64(),
                        match &error.kind {
                            DeviceErrorKind::Io(why) | DeviceErrorKind::Refused(why) => why.clone(),
                            other => format!("{other:?}"),
                        }
                    )),
                ));
            }
            // Away: the next exchange reopens the transport first.
        }
    }

    fn error(&self, op: ChamberOp, kind: DeviceErrorKind) -> DeviceError {
        DeviceError {
            device: self.device.clone(),
            command: op.name().to_string(),
            kind,
        }
    }

    /// One operation with the I/O policy's retries of a lost or garbled
    /// reply; how it failed says whether the controller was away or busy.
    fn exchange_once(&mut self, op: ChamberOp) -> Result<ChamberReply, (DeviceError, Failed)> {
        let attempts = self.policy.retries + 1;
        let mut last = Attempt::Timeout;
        for attempt in 1..=attempts {
            if attempt > 1 {
                if let Attempt::Io(_) = last {
                    if let Err(e) = self.transport.reopen() {
                        last = Attempt::Io(e);
                        continue;
                    }
                } else {
                    // A late reply to the failed attempt must not answer this one.
                    let _ = self.transport.discard_input();
                }
            }
            let (frame, pending) = self.codec.request(op).map_err(|e| {
                (
                    self.error(op, DeviceErrorKind::Rejected(e.to_string())),
                    Failed::Final,
                )
            })?;
            let deadline = Instant::now() + self.policy.timeout();
            if let Err(e) = self.transport.write_all(&frame, deadline) {
                last = if e.kind() == io::ErrorKind::TimedOut {
                    Attempt::Timeout
                } else {
                    Attempt::Io(e)
                };
                continue;
            }
            let mut reply: Vec<u8> = Vec::new();
            let mut buf = [0u8; 260];
            let mut failure = None;
            let complete = loop {
                if let Some(n) = self.codec.reply_len(&reply)
                    && reply.len() >= n
                {
                    break true;
                }
                // No Modbus frame is this long: stop reading a babbling line.
                if reply.len() > 512 {
                    break true;
                }
                match self.transport.read(&mut buf, deadline) {
                    Ok(n) => reply.extend_from_slice(&buf[..n]),
                    Err(e) if e.kind() == io::ErrorKind::TimedOut => break false,
                    Err(e) => {
                        failure = Some(e);
                        break false;
                    }
                }
            };
            if !complete {
                last = match failure {
                    Some(e) => Attempt::Io(e),
                    None if reply.is_empty() => Attempt::Timeout,
                    None => Attempt::Garbled(hex(&reply), "a complete Modbus reply".into()),
                };
                continue;
            }
            match self.codec.parse(&pending, &reply) {
                Ok(r) => return Ok(r),
                Err(ChamberCodecError::Exception(code)) => {
                    let how = if spinbench_wire::chamber::modbus_exception_is_transient(code) {
                        Failed::Busy(code)
                    } else {
                        Failed::Final
                    };
                    return Err((
                        self.error(
                            op,
                            DeviceErrorKind::Refused(format!(
                                "Modbus exception {code} ({})",
                                spinbench_wire::chamber::modbus_exception_meaning(code)
                            )),
                        ),
                        how,
                    ));
                }
                Err(e) => last = Attempt::Garbled(hex(&reply), e.to_string()),
            }
        }
        let how = match last {
            Attempt::Io(_) => Failed::Away,
            Attempt::Timeout => Failed::Silent,
            Attempt::Garbled(..) => Failed::Final,
        };
        Err((
            self.error(
                op,
                match last {
                    Attempt::Timeout => DeviceErrorKind::Timeout {
                        waited: self.policy.timeout(),
                        attempts,
                    },
                    Attempt::Garbled(reply, expected) => DeviceErrorKind::Garbled {
                        reply,
                        expected,
                        attempts,
                    },
                    Attempt::Io(e) => DeviceErrorKind::Io(e.to_string()),
                },
            ),
            how,
        ))
    }

    fn celsius(&mut self, op: ChamberOp) -> Result<f64, DeviceError> {
        let reply = self.exchange(op)?;
        celsius_of(&self.device, op, reply)
    }
}

/// The temperature a reply to `op` must be.
fn celsius_of(device: &str, op: ChamberOp, reply: ChamberReply) -> Result<f64, DeviceError> {
    match reply {
        ChamberReply::Celsius(c) => Ok(c),
        other => Err(DeviceError {
            device: device.to_string(),
            command: op.name().to_string(),
            kind: DeviceErrorKind::Garbled {
                reply: format!("{other:?}"),
                expected: "a temperature".into(),
                attempts: 1,
            },
        }),
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes
        .iter()
        .take(64)
        .map(|b| format!("{b:02X}"))
        .collect::<Vec<_>>()
        .join(" ")
}

impl<T: Transport> Chamber for ModbusChamber<T> {
    fn set_outage_budget(&mut self, budget: std::time::Duration) {
        self.outage_budget = budget;
    }
    fn busy_replies(&self) -> u64 {
        self.busy_replies
    }
    fn set_setpoint_c(&mut self, celsius: f64) -> Result<(), DeviceError> {
        check_setpoint(&self.device, celsius)?;
        self.exchange(ChamberOp::SetSetpoint(celsius)).map(|_| ())
    }

    fn setpoint_c(&mut self) -> Result<f64, DeviceError> {
        self.celsius(ChamberOp::ReadSetpoint)
    }

    fn temperature_c(&mut self) -> Result<f64, DeviceError> {
        self.celsius(ChamberOp::ReadTemperature)
    }

    fn set_running(&mut self, on: bool) -> Result<(), DeviceError> {
        self.exchange(ChamberOp::Run(on)).map(|_| ())
    }

    fn alarms(&mut self) -> Result<u16, DeviceError> {
        match self.exchange(ChamberOp::ReadAlarms) {
            Ok(ChamberReply::Alarms(a)) => Ok(a),
            Ok(_) => Ok(0),
            Err(DeviceError {
                kind: DeviceErrorKind::Rejected(_),
                ..
            }) => Ok(0),
            Err(e) => Err(e),
        }
    }

    fn set_purge(&mut self, on: bool) -> Result<(), DeviceError> {
        self.exchange(ChamberOp::Purge(on)).map(|_| ())
    }
}

/// A chamber controller that speaks lines ([`LineChamberDialect`]).
pub struct LineChamber<T: Transport> {
    channel: LineChannel<T>,
    dialect: LineChamberDialect,
}

impl<T: Transport> LineChamber<T> {
    /// A driver for the chamber named `name`.
    pub fn new(transport: T, dialect: LineChamberDialect, name: &str, policy: IoPolicy) -> Self {
        let ending = dialect.line_ending.clone();
        LineChamber {
            channel: LineChannel::new(transport, format!("chamber '{name}'"), &ending, policy),
            dialect,
        }
    }

    fn run_op(&mut self, op: ChamberOp) -> Result<ChamberReply, DeviceError> {
        let (line, expect) = self.dialect.line(op).map_err(|e| DeviceError {
            device: self.channel.device().to_string(),
            command: op.name().to_string(),
            kind: DeviceErrorKind::Rejected(e.to_string()),
        })?;
        let dialect = &self.dialect;
        match expect {
            LineExpect::Nothing => self.channel.send(&line).map(|_| ChamberReply::Done),
            LineExpect::Ack | LineExpect::Number => {
                self.channel.query(&line, |reply| dialect.parse(op, reply))
            }
        }
    }

    fn celsius(&mut self, op: ChamberOp) -> Result<f64, DeviceError> {
        let reply = self.run_op(op)?;
        celsius_of(self.channel.device(), op, reply)
    }
}

impl<T: Transport> Chamber for LineChamber<T> {
    fn set_setpoint_c(&mut self, celsius: f64) -> Result<(), DeviceError> {
        check_setpoint(self.channel.device(), celsius)?;
        self.run_op(ChamberOp::SetSetpoint(celsius)).map(|_| ())
    }

    fn setpoint_c(&mut self) -> Result<f64, DeviceError> {
        self.celsius(ChamberOp::ReadSetpoint)
    }

    fn temperature_c(&mut self) -> Result<f64, DeviceError> {
        self.celsius(ChamberOp::ReadTemperature)
    }

    fn set_running(&mut self, on: bool) -> Result<(), DeviceError> {
        self.run_op(ChamberOp::Run(on)).map(|_| ())
    }

    fn alarms(&mut self) -> Result<u16, DeviceError> {
        if self.dialect.read_alarms.is_none() {
            return Ok(0);
        }
        match self.run_op(ChamberOp::ReadAlarms)? {
            ChamberReply::Alarms(a) => Ok(a),
            _ => Ok(0),
        }
    }

    fn set_purge(&mut self, on: bool) -> Result<(), DeviceError> {
        self.run_op(ChamberOp::Purge(on)).map(|_| ())
    }
}

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
