//! Temperature-chamber protocols: what to send for each chamber
//! operation and how to read the reply. No I/O; the `devices` crate's
//! drivers run the exchanges over a transport.
//!
//! * [`ModbusChamberCodec`] — Modbus RTU or TCP through the `rmodbus` codec
//!   (request frames, CRC, MBAP header, exception replies), with a
//!   [`RegisterMap`] from the station config: which holding (or input)
//!   register holds the setpoint, the process value, run/stop, the alarms
//!   and the purge output, and how many counts make a degree. The common
//!   chamber controllers (and the PLCs behind chambers) are covered by a map.
//! * [`LineChamberDialect`] — a line-oriented ASCII/SCPI controller described
//!   entirely by command templates and a reply pattern, like the centrifuge's
//!   line dialect, so a new controller needs no code.
//!
//! Temperatures are °C in the station.

use rmodbus::ModbusProto;
use rmodbus::client::ModbusRequest;
use serde::Deserialize;

/// An operation on the chamber.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ChamberOp {
    /// Write the setpoint [°C].
    SetSetpoint(f64),
    /// Read the setpoint back.
    ReadSetpoint,
    /// Read the process value (the air temperature) [°C].
    ReadTemperature,
    /// Run (true) or stop the controller.
    Run(bool),
    /// Read the alarm word (0: none).
    ReadAlarms,
    /// Switch the dry-air purge on or off.
    Purge(bool),
}

impl ChamberOp {
    /// A short name for messages.
    pub fn name(&self) -> &'static str {
        match self {
            ChamberOp::SetSetpoint(_) => "set setpoint",
            ChamberOp::ReadSetpoint => "read setpoint",
            ChamberOp::ReadTemperature => "read temperature",
            ChamberOp::Run(true) => "run",
            ChamberOp::Run(false) => "stop",
            ChamberOp::ReadAlarms => "read alarms",
            ChamberOp::Purge(true) => "purge on",
            ChamberOp::Purge(false) => "purge off",
        }
    }
}

/// A chamber's reply, in station units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ChamberReply {
    /// The operation was done (a write acknowledged).
    Done,
    /// A temperature [°C].
    Celsius(f64),
    /// The alarm word (bits as the controller defines them; 0 = none).
    Alarms(u16),
}

/// Why a request could not be made or a reply not understood.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ChamberCodecError {
    /// The value cannot be put in a register (or the map has no register for it).
    #[error("{0}")]
    Rejected(String),
    /// The controller answered with a Modbus exception.
    #[error("the controller refused it: Modbus exception {0} ({meaning})", meaning = modbus_exception_meaning(*.0))]
    Exception(u8),
    /// The reply is not a valid answer to the request.
    #[error("garbled reply: {0}")]
    Garbled(String),
}

fn one() -> u16 {
    1
}

fn ten() -> f64 {
    10.0
}

fn unit_one() -> u8 {
    1
}

/// Where a chamber controller keeps what the station needs: register
/// numbers (0-based protocol addresses) and the scale. Temperatures are
/// signed 16-bit counts of `1/counts_per_c` °C.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegisterMap {
    /// Modbus unit (slave) id (default 1).
    #[serde(default = "unit_one")]
    pub unit_id: u8,
    /// Holding register of the setpoint.
    pub setpoint: u16,
    /// Register of the process value (air temperature).
    pub process_value: u16,
    /// The process value is an input register (function 4), not a holding one.
    #[serde(default)]
    pub process_value_is_input: bool,
    /// Holding register of run/stop.
    pub run: u16,
    /// The value that means run (default 1).
    #[serde(default = "one")]
    pub run_value: u16,
    /// The value that means stop (default 0).
    #[serde(default)]
    pub stop_value: u16,
    /// Holding register of the alarm word (absent: the controller has none).
    #[serde(default)]
    pub alarms: Option<u16>,
    /// Holding register of the purge output, 1 on and 0 off (absent: the
    /// purge valve is not on the chamber controller).
    #[serde(default)]
    pub purge: Option<u16>,
    /// Coil of the purge output (function 5), for a controller or a relay
    /// module that switches its outputs as coils; takes the place of `purge`.
    #[serde(default)]
    pub purge_coil: Option<u16>,
    /// Register counts per °C (default 10: 0.1 °C per count).
    #[serde(default = "ten")]
    pub counts_per_c: f64,
}

/// Why a chamber's register map cannot work.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapError {
    /// The scale is not a positive number up to 1000.
    #[error("counts_per_c = {0} is not a scale from 0 to 1000 counts per °C")]
    Scale(f64),
    /// The purge valve is named on two outputs.
    #[error(
        "both `purge` (a register) and `purge_coil` are set: name the one output the valve is on"
    )]
    TwoPurgeOutputs,
    /// Run and stop are written as the same value.
    #[error("run_value and stop_value are both {0}: the station could not tell run from stop")]
    RunIsStop(u16),
}

impl RegisterMap {
    /// Check the map: a finite, positive scale no larger than 1000 counts/°C.
    pub fn validate(&self) -> Result<(), MapError> {
        if !(self.counts_per_c.is_finite()
            && self.counts_per_c > 0.0
            && self.counts_per_c <= 1000.0)
        {
            return Err(MapError::Scale(self.counts_per_c));
        }
        if self.purge.is_some() && self.purge_coil.is_some() {
            return Err(MapError::TwoPurgeOutputs);
        }
        if self.run_value == self.stop_value {
            return Err(MapError::RunIsStop(self.run_value));
        }
        Ok(())
    }
}

/// Which Modbus framing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModbusFraming {
    /// RTU over a serial line (CRC-16/MODBUS).
    Rtu,
    /// TCP (MBAP header, port 502).
    Tcp,
}

/// A request on its way: the bytes to send and what its reply must be.
pub struct PendingReply {
    request: ModbusRequest,
    op: ChamberOp,
}

impl PendingReply {
    /// The operation asked.
    pub fn op(&self) -> ChamberOp {
        self.op
    }
}

/// Modbus requests and replies for a chamber with a [`RegisterMap`].
pub struct ModbusChamberCodec {
    map: RegisterMap,
    framing: ModbusFraming,
    transaction: u16,
}

impl ModbusChamberCodec {
    /// A codec for `map` over `framing`.
    pub fn new(map: RegisterMap, framing: ModbusFraming) -> Self {
        ModbusChamberCodec {
            map,
            framing,
            transaction: 0,
        }
    }

    fn proto(&self) -> ModbusProto {
        match self.framing {
            ModbusFraming::Rtu => ModbusProto::Rtu,
            ModbusFraming::Tcp => ModbusProto::TcpUdp,
        }
    }

    fn counts(&self, celsius: f64) -> Result<u16, ChamberCodecError> {
        let c = (celsius * self.map.counts_per_c).round();
        if !(c.is_finite() && (f64::from(i16::MIN)..=f64::from(i16::MAX)).contains(&c)) {
            return Err(ChamberCodecError::Rejected(format!(
                "{celsius} °C does not fit a register at {} counts per °C",
                self.map.counts_per_c
            )));
        }
        // Two's complement in the register: the controller reads it as i16.
        Ok(c as i16 as u16)
    }

    /// The frame that asks for `op`, and what its reply must be.
    pub fn request(&mut self, op: ChamberOp) -> Result<(Vec<u8>, PendingReply), ChamberCodecError> {
        self.transaction = self.transaction.wrapping_add(1);
        let mut request = match self.framing {
            ModbusFraming::Rtu => ModbusRequest::new(self.map.unit_id, ModbusProto::Rtu),
            ModbusFraming::Tcp => ModbusRequest::new_tcp_udp(self.map.unit_id, self.transaction),
        };
        let mut frame = Vec::new();
        let missing = |what: &str| {
            ChamberCodecError::Rejected(format!(
                "the chamber's register map has no `{what}` register"
            ))
        };
        let result = match op {
            ChamberOp::SetSetpoint(c) => {
                let v = self.counts(c)?;
                request.generate_set_holding(self.map.setpoint, v, &mut frame)
            }
            ChamberOp::ReadSetpoint => {
                request.generate_get_holdings(self.map.setpoint, 1, &mut frame)
            }
            ChamberOp::ReadTemperature if self.map.process_value_is_input => {
                request.generate_get_inputs(self.map.process_value, 1, &mut frame)
            }
            ChamberOp::ReadTemperature => {
                request.generate_get_holdings(self.map.process_value, 1, &mut frame)
            }
            ChamberOp::Run(on) => request.generate_set_holding(
                self.map.run,
                if on {
                    self.map.run_value
                } else {
                    self.map.stop_value
                },
                &mut frame,
            ),
            ChamberOp::ReadAlarms => {
                let reg = self.map.alarms.ok_or_else(|| missing("alarms"))?;
                request.generate_get_holdings(reg, 1, &mut frame)
            }
            ChamberOp::Purge(on) => match (self.map.purge_coil, self.map.purge) {
                (Some(coil), _) => request.generate_set_coil(coil, on, &mut frame),
                (None, Some(reg)) => request.generate_set_holding(reg, u16::from(on), &mut frame),
                (None, None) => return Err(missing("purge")),
            },
        };
        result.map_err(|e| ChamberCodecError::Rejected(format!("{e:?}")))?;
        Ok((frame, PendingReply { request, op }))
    }

    /// The length of the reply that begins with `partial`, once enough of it
    /// has arrived to tell (`None` before).
    pub fn reply_len(&self, partial: &[u8]) -> Option<usize> {
        let needed = match self.framing {
            ModbusFraming::Rtu => 3,
            ModbusFraming::Tcp => 6,
        };
        if partial.len() < needed {
            return None;
        }
        match rmodbus::guess_response_frame_len(partial, self.proto()) {
            Ok(n) => Some(usize::from(n)),
            // Not a frame: the caller reads it as garbled at this length.
            Err(_) => Some(partial.len()),
        }
    }

    /// Read the reply `frame` to `pending`.
    pub fn parse(
        &self,
        pending: &PendingReply,
        frame: &[u8],
    ) -> Result<ChamberReply, ChamberCodecError> {
        match pending.op {
            ChamberOp::SetSetpoint(_) | ChamberOp::Run(_) | ChamberOp::Purge(_) => {
                self.check(pending, frame)?;
                Ok(ChamberReply::Done)
            }
            ChamberOp::ReadSetpoint | ChamberOp::ReadTemperature | ChamberOp::ReadAlarms => {
                let mut words: Vec<u16> = Vec::new();
                pending
                    .request
                    .parse_u16(frame, &mut words)
                    .map_err(codec_error)?;
                let &[word] = words.as_slice() else {
                    return Err(ChamberCodecError::Garbled(format!(
                        "{} registers where one was asked",
                        words.len()
                    )));
                };
                Ok(match pending.op {
                    ChamberOp::ReadAlarms => ChamberReply::Alarms(word),
                    _ => ChamberReply::Celsius(f64::from(word as i16) / self.map.counts_per_c),
                })
            }
        }
    }

    fn check(&self, pending: &PendingReply, frame: &[u8]) -> Result<(), ChamberCodecError> {
        pending.request.parse_ok(frame).map_err(codec_error)
    }
}

/// What a Modbus exception code means (the Modbus application protocol
/// specification V1.1b3, §7), with what to check for the codes a station's
/// configuration causes.
pub fn modbus_exception_meaning(code: u8) -> &'static str {
    match code {
        1 => {
            "illegal function: the controller does not know this function code (check the map's register kinds)"
        }
        2 => {
            "illegal data address: a wrong register address (check the register map against the controller's manual)"
        }
        3 => {
            "illegal data value: the value is out of the register's range (check the map's scale and sign)"
        }
        4 => "server device failure: the controller failed while doing it",
        5 => "acknowledge: accepted, still working on it (asked again)",
        6 => "server device busy: try again later (asked again)",
        8 => "memory parity error",
        10 => "gateway path unavailable: check the gateway's routing",
        11 => {
            "gateway target device failed to respond: check the unit id and the controller behind the gateway"
        }
        _ => "an exception code the specification does not define",
    }
}

/// Whether a Modbus exception means "not now, ask again" (05 acknowledge,
/// 06 server device busy) rather than a refusal.
pub fn modbus_exception_is_transient(code: u8) -> bool {
    matches!(code, 5 | 6)
}

/// rmodbus's reading of a reply: a Modbus exception (the controller's
/// refusal, with its code) or a garbled frame (CRC, length, wrong answer).
fn codec_error(e: rmodbus::ErrorKind) -> ChamberCodecError {
    match e.to_modbus_error() {
        Ok(code) => ChamberCodecError::Exception(code as u8),
        Err(_) => ChamberCodecError::Garbled(format!("{e:?}")),
    }
}

/// A line-oriented chamber controller: command templates (`{value}` is the
/// setpoint in °C) and how its replies read. Absent commands are not
/// supported by the controller (the purge may be on a relay instead).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LineChamberDialect {
    /// Line ending of commands and replies (default "\r\n").
    #[serde(default = "crlf")]
    pub line_ending: String,
    /// Identity query (default `*IDN?`).
    #[serde(default = "idn")]
    pub identify: String,
    /// Set the setpoint, e.g. `TEMP:SETP {value}`.
    pub set_setpoint: String,
    /// Read the setpoint, e.g. `TEMP:SETP?`.
    pub read_setpoint: String,
    /// Read the air temperature, e.g. `TEMP?`.
    pub read_temperature: String,
    /// Start the controller.
    pub run: String,
    /// Stop the controller.
    pub stop: String,
    /// Read the alarm word (absent: none).
    #[serde(default)]
    pub read_alarms: Option<String>,
    /// Purge on (absent: not on this controller).
    #[serde(default)]
    pub purge_on: Option<String>,
    /// Purge off.
    #[serde(default)]
    pub purge_off: Option<String>,
    /// The reply to a setting (absent: settings are silent, as in SCPI).
    #[serde(default)]
    pub ack: Option<String>,
    /// A reply that starts with this is a refusal (default `ERR`).
    #[serde(default = "err_prefix")]
    pub error_prefix: String,
}

fn crlf() -> String {
    "\r\n".into()
}

fn idn() -> String {
    "*IDN?".into()
}

fn err_prefix() -> String {
    "ERR".into()
}

/// What a line expects back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineExpect {
    /// Nothing (a silent setting).
    Nothing,
    /// The dialect's acknowledgement.
    Ack,
    /// A number.
    Number,
}

impl LineChamberDialect {
    /// A relay module's dialect: only `Purge` has a line (`on`, `off`); every
    /// other operation is refused as a command the module does not have.
    pub fn relay(on: &str, off: &str, ack: Option<String>, line_ending: &str) -> Self {
        LineChamberDialect {
            line_ending: line_ending.to_string(),
            identify: idn(),
            set_setpoint: String::new(),
            read_setpoint: String::new(),
            read_temperature: String::new(),
            run: String::new(),
            stop: String::new(),
            read_alarms: None,
            purge_on: Some(on.to_string()),
            purge_off: Some(off.to_string()),
            ack,
            error_prefix: err_prefix(),
        }
    }

    /// The line for `op` and what comes back; `Err` when the controller has no such command.
    pub fn line(&self, op: ChamberOp) -> Result<(String, LineExpect), ChamberCodecError> {
        let setting = if self.ack.is_some() {
            LineExpect::Ack
        } else {
            LineExpect::Nothing
        };
        let missing = |what: &str| {
            ChamberCodecError::Rejected(format!("the chamber's dialect has no `{what}` command"))
        };
        let (line, expect) = match op {
            ChamberOp::SetSetpoint(c) => {
                if !c.is_finite() {
                    return Err(ChamberCodecError::Rejected(format!("setpoint {c} °C")));
                }
                (
                    self.set_setpoint.replace("{value}", &format!("{c:.2}")),
                    setting,
                )
            }
            ChamberOp::ReadSetpoint => (self.read_setpoint.clone(), LineExpect::Number),
            ChamberOp::ReadTemperature => (self.read_temperature.clone(), LineExpect::Number),
            ChamberOp::Run(true) => (self.run.clone(), setting),
            ChamberOp::Run(false) => (self.stop.clone(), setting),
            ChamberOp::ReadAlarms => (
                self.read_alarms
                    .clone()
                    .ok_or_else(|| missing("read_alarms"))?,
                LineExpect::Number,
            ),
            ChamberOp::Purge(true) => (
                self.purge_on.clone().ok_or_else(|| missing("purge_on"))?,
                setting,
            ),
            ChamberOp::Purge(false) => (
                self.purge_off.clone().ok_or_else(|| missing("purge_off"))?,
                setting,
            ),
        };
        // An empty template is a command the device does not have (a relay
        // module's dialect has only the purge's).
        if line.trim().is_empty() {
            return Err(missing(op.name()));
        }
        Ok((line, expect))
    }

    /// Read a reply line to `op`: `Err((expected, refused))`, as the line
    /// channel's parsers do (a refusal is final, anything else is retried).
    pub fn parse(&self, op: ChamberOp, reply: &str) -> Result<ChamberReply, (String, bool)> {
        let reply = reply.trim();
        if reply.starts_with(&self.error_prefix) {
            return Err((format!("the controller refused it: {reply}"), true));
        }
        match op {
            ChamberOp::ReadSetpoint | ChamberOp::ReadTemperature | ChamberOp::ReadAlarms => {
                let value = first_number(reply).ok_or_else(|| ("a number".to_string(), false))?;
                Ok(match op {
                    ChamberOp::ReadAlarms if (0.0..=f64::from(u16::MAX)).contains(&value) => {
                        ChamberReply::Alarms(value as u16)
                    }
                    ChamberOp::ReadAlarms => {
                        return Err(("an alarm word 0 to 65535".into(), false));
                    }
                    _ => ChamberReply::Celsius(value),
                })
            }
            _ => match &self.ack {
                Some(ack) if reply == ack.trim() => Ok(ChamberReply::Done),
                Some(ack) => Err((format!("'{ack}'"), false)),
                None => Ok(ChamberReply::Done),
            },
        }
    }
}

/// The first finite number on a line whose words may carry a name or a
/// unit (`T=+25.31 C`, `25.3°C`, `SETP: -40.0`).
fn first_number(line: &str) -> Option<f64> {
    line.split(|c: char| c.is_whitespace() || matches!(c, '=' | ':' | ',' | ';'))
        .map(|word| word.trim_end_matches(|c: char| !(c.is_ascii_digit() || c == '.')))
        .find_map(|word| word.parse::<f64>().ok().filter(|v| v.is_finite()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map() -> RegisterMap {
        toml::from_str(
            "setpoint = 100\nprocess_value = 101\nprocess_value_is_input = true\nrun = 102\nalarms = 103\npurge = 104\n",
        )
        .expect("map")
    }

    #[test]
    fn a_setpoint_is_a_signed_register_at_the_maps_scale_in_an_rtu_frame() {
        let mut codec = ModbusChamberCodec::new(map(), ModbusFraming::Rtu);
        let (frame, pending) = codec.request(ChamberOp::SetSetpoint(-40.0)).expect("frame");
        // unit 1, function 6, register 100, value −400 = 0xFE70, CRC low byte first.
        assert_eq!(&frame[..6], &[0x01, 0x06, 0x00, 0x64, 0xFE, 0x70]);
        assert_eq!(frame.len(), 8);
        // The controller echoes a write.
        assert_eq!(codec.reply_len(&frame[..3]), Some(8));
        assert_eq!(codec.parse(&pending, &frame), Ok(ChamberReply::Done));
        assert!(
            codec.request(ChamberOp::SetSetpoint(5000.0)).is_err(),
            "beyond i16 at 0.1 °C"
        );
    }

    #[test]
    fn a_temperature_reply_is_read_from_its_input_register_and_an_exception_is_a_refusal() {
        let mut codec = ModbusChamberCodec::new(map(), ModbusFraming::Rtu);
        let (frame, pending) = codec.request(ChamberOp::ReadTemperature).expect("frame");
        assert_eq!(&frame[..6], &[0x01, 0x04, 0x00, 0x65, 0x00, 0x01]);
        // 25.3 °C = 253 = 0x00FD.
        let mut reply = vec![0x01, 0x04, 0x02, 0x00, 0xFD];
        let crc = crc::Crc::<u16>::new(&crc::CRC_16_MODBUS).checksum(&reply);
        reply.extend_from_slice(&crc.to_le_bytes());
        assert_eq!(codec.reply_len(&reply[..3]), Some(7));
        assert_eq!(
            codec.parse(&pending, &reply),
            Ok(ChamberReply::Celsius(25.3))
        );
        let mut bad = reply.clone();
        bad[4] ^= 1;
        assert!(
            matches!(
                codec.parse(&pending, &bad),
                Err(ChamberCodecError::Garbled(_))
            ),
            "CRC"
        );
        let mut exception = vec![0x01, 0x84, 0x02];
        let crc = crc::Crc::<u16>::new(&crc::CRC_16_MODBUS).checksum(&exception);
        exception.extend_from_slice(&crc.to_le_bytes());
        assert_eq!(codec.reply_len(&exception[..3]), Some(5));
        assert_eq!(
            codec.parse(&pending, &exception),
            Err(ChamberCodecError::Exception(2))
        );
    }

    #[test]
    fn tcp_frames_carry_the_mbap_header_and_a_transaction_id() {
        let mut codec = ModbusChamberCodec::new(map(), ModbusFraming::Tcp);
        let (first, _) = codec.request(ChamberOp::ReadAlarms).expect("frame");
        let (second, _) = codec.request(ChamberOp::ReadAlarms).expect("frame");
        assert_eq!(
            &first[2..7],
            &[0x00, 0x00, 0x00, 0x06, 0x01],
            "protocol 0, length 6, unit 1"
        );
        assert_ne!(first[..2], second[..2], "a new transaction id");
        assert_eq!(&first[7..], &[0x03, 0x00, 0x67, 0x00, 0x01]);
    }

    #[test]
    fn a_map_without_a_purge_register_says_so_and_a_bad_scale_is_refused() {
        let mut m = map();
        m.purge = None;
        let mut codec = ModbusChamberCodec::new(m.clone(), ModbusFraming::Rtu);
        let err = codec
            .request(ChamberOp::Purge(true))
            .err()
            .expect("no purge");
        assert!(err.to_string().contains("purge"), "{err}");
        m.counts_per_c = f64::NAN;
        assert!(m.validate().is_err());
    }

    #[test]
    fn a_line_dialect_fills_its_templates_and_reads_numbers_acks_and_refusals() {
        let d: LineChamberDialect = toml::from_str(
            "set_setpoint = \"TEMP:SETP {value}\"\nread_setpoint = \"TEMP:SETP?\"\nread_temperature = \"TEMP?\"\nrun = \"RUN\"\nstop = \"STOP\"\nack = \"OK\"\n",
        )
        .expect("dialect");
        assert_eq!(
            d.line(ChamberOp::SetSetpoint(-40.0)).expect("line"),
            ("TEMP:SETP -40.00".to_string(), LineExpect::Ack)
        );
        assert_eq!(
            d.parse(ChamberOp::ReadTemperature, "T=+25.31 C"),
            Ok(ChamberReply::Celsius(25.31))
        );
        assert_eq!(d.parse(ChamberOp::Run(true), "OK"), Ok(ChamberReply::Done));
        assert!(matches!(
            d.parse(ChamberOp::Run(true), "ERR 3 door open"),
            Err((_, true))
        ));
        assert!(matches!(
            d.parse(ChamberOp::ReadTemperature, "???"),
            Err((_, false))
        ));
        assert!(d.line(ChamberOp::Purge(true)).is_err(), "no purge command");
    }
}
