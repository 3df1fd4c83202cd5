//! The `Chamber` trait (a temperature chamber: setpoint, air temperature,
//! run/stop, alarms, the dry-air purge) and its two drivers: Modbus RTU or
//! TCP with a register map ([`ModbusChamber`]) and a templated line dialect
//! ([`LineChamber`]); the `[chamber]` section of the station config and
//! the purge relay in [`config`].

mod config;

pub use config::{ChamberConfig, ChamberProtocol, PurgeOnRelay, PurgeRelayConfig, RelayProtocol};

use crate::error::{DeviceError, DeviceErrorKind};
use crate::line::{IoPolicy, LineChannel};
use crate::transport::Transport;
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
                // Silent beyond the budget stays a timeout: the safe state
                // asks a device that timed out nothing more.
                if matches!(how, Failed::Silent) {
                    return Err(self.error(
                        op,
                        DeviceErrorKind::Timeout {
                            waited: self.policy.timeout(),
                            attempts: (o.tries() + 1) * (self.policy.retries + 1),
                        },
                    ));
                }
                let what = match how {
                    Failed::Busy(code) => format!(
                        "busy for {:.1} s (Modbus exception {code}: {})",
                        o.lasted().as_secs_f64(),
                        spinbench_wire::chamber::modbus_exception_meaning(code)
                    ),
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
