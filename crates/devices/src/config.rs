//! Device sections of the station config (TOML) and the functions that
//! connect a driver from them. Rates may be given in deg/s or rpm here; the
//! code works in deg/s. Validation errors name the key.
//!
//! ```toml
//! [centrifuge]
//! name = "table"
//! max_rate_rpm = 400
//! transport = { kind = "tcp", address = "10.0.0.5:9878" }
//! dialect = { kind = "acutrol", axis = 1 }
//!
//! [[fmu]]
//! name = "fmu1"
//! mode = "reciprocal"
//! transport = { kind = "serial", path = "/dev/ttyS4", baud = 921600 }
//! ```

use crate::centrifuge::{Centrifuge, DialectCentrifuge};
use crate::fmu::{CounterModule, FmuDriver};
use crate::psu::{PowerSupply, ScpiPowerSupply};
use crate::transport::{SerialSettings, SerialTransport, TcpTransport, Transport};
use serde::Deserialize;
use spinbench_wire::centrifuge::{AcutrolDialect, LineDialect, LineDialectConfig, RateUnit};
use spinbench_wire::fmu::{self, SerialFraming, StreamMode};
use std::io;
use std::time::{Duration, Instant};

/// Highest centrifuge rate limit a config may give [deg/s] (100 rev/s).
pub const MAX_RATE_DEG_S: f64 = 36_000.0;

/// A configuration that cannot work; names the key and says what to do.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{key}: {problem}")]
pub struct ConfigError {
    /// The TOML key, e.g. `fmu[0].transport.baud`.
    pub key: String,
    /// What is wrong.
    pub problem: String,
}

/// How to reach a device.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum TransportConfig {
    /// A serial port.
    Serial(SerialSettings),
    /// A TCP connection.
    Tcp {
        /// `host:port`.
        address: String,
        /// Connect timeout [ms] (default 2000).
        #[serde(default = "default_connect_ms")]
        connect_timeout_ms: u64,
    },
}

fn default_connect_ms() -> u64 {
    2000
}

/// Longest connect timeout of a TCP transport [ms]: a reconnection is part
/// of a command's retries, so it is bounded like one attempt
/// ([`MAX_TIMEOUT_MS`]).
pub const MAX_CONNECT_TIMEOUT_MS: u64 = MAX_TIMEOUT_MS;

impl TransportConfig {
    /// Check the transport's numbers; the error names the key under `section`.
    pub fn validate(&self, section: &str) -> Result<(), ConfigError> {
        match self {
            TransportConfig::Tcp {
                connect_timeout_ms, ..
            } if !(1..=MAX_CONNECT_TIMEOUT_MS).contains(connect_timeout_ms) => Err(ConfigError {
                key: format!("{section}.transport.connect_timeout_ms"),
                problem: format!(
                    "{connect_timeout_ms} ms is outside 1 to {MAX_CONNECT_TIMEOUT_MS} ms (MAX_CONNECT_TIMEOUT_MS)"
                ),
            }),
            _ => Ok(()),
        }
    }

    /// Open the transport.
    pub fn open(&self) -> io::Result<Box<dyn Transport>> {
        Ok(match self {
            TransportConfig::Serial(s) => Box::new(SerialTransport::open(s.clone())?),
            TransportConfig::Tcp {
                address,
                connect_timeout_ms,
            } => Box::new(TcpTransport::connect(
                address.clone(),
                Duration::from_millis(*connect_timeout_ms),
            )?),
        })
    }
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn describe(&self) -> String {
        (**self).describe()
    }
    fn write_all(&mut self, bytes: &[u8], deadline: Instant) -> io::Result<()> {
        (**self).write_all(bytes, deadline)
    }
    fn read(&mut self, buf: &mut [u8], deadline: Instant) -> io::Result<usize> {
        (**self).read(buf, deadline)
    }
    fn discard_input(&mut self) -> io::Result<()> {
        (**self).discard_input()
    }
    fn reopen(&mut self) -> io::Result<()> {
        (**self).reopen()
    }
    fn flush_capture(&mut self) -> io::Result<()> {
        (**self).flush_capture()
    }
}

/// The controller's command language.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum DialectConfig {
    /// The ACUTROL SCPI-style tree.
    Acutrol {
        /// Spin axis number (default 1).
        #[serde(default = "default_axis")]
        axis: u8,
        /// Send abbreviated headers (default false).
        #[serde(default)]
        short_form: bool,
    },
    /// A line dialect described in the config (boxed: it is large).
    Line(Box<LineDialectConfig>),
}

fn default_axis() -> u8 {
    1
}

/// The `[centrifuge]` section.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CentrifugeConfig {
    /// Name in messages.
    pub name: String,
    /// Rate limit in deg/s (give this or `max_rate_rpm`).
    pub max_rate_deg_s: Option<f64>,
    /// Rate limit in rpm.
    pub max_rate_rpm: Option<f64>,
    /// How to reach it.
    pub transport: TransportConfig,
    /// Its command language.
    pub dialect: DialectConfig,
    /// Deadlines and retries.
    #[serde(default)]
    pub io: IoPolicy,
}

impl CentrifugeConfig {
    /// The rate limit [deg/s], from whichever key was given.
    pub fn max_rate_deg_s(&self) -> Result<f64, ConfigError> {
        let err = |problem: String| ConfigError {
            key: "centrifuge.max_rate_deg_s".into(),
            problem,
        };
        let rate = match (self.max_rate_deg_s, self.max_rate_rpm) {
            (Some(d), None) => d,
            (None, Some(rpm)) => rpm * RateUnit::Rpm.deg_s_per_unit(),
            (Some(_), Some(_)) => {
                return Err(err("give max_rate_deg_s or max_rate_rpm, not both".into()));
            }
            (None, None) => {
                return Err(err(
                    "the centrifuge's rate limit is required (max_rate_deg_s or max_rate_rpm)"
                        .into(),
                ));
            }
        };
        if !(rate.is_finite() && rate > 0.0 && rate <= MAX_RATE_DEG_S) {
            return Err(err(format!(
                "must be a positive rate up to {MAX_RATE_DEG_S} deg/s (MAX_RATE_DEG_S), got {rate} deg/s"
            )));
        }
        Ok(rate)
    }

    /// Check everything that can be checked without the hardware.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.max_rate_deg_s()?;
        self.io.validate("centrifuge")?;
        self.transport.validate("centrifuge")?;
        if let DialectConfig::Line(line) = &self.dialect {
            LineDialect::new((**line).clone()).map_err(|e| ConfigError {
                key: format!("centrifuge.dialect.{}", e.key),
                problem: e.problem,
            })?;
        }
        Ok(())
    }

    /// Open the transport and build the driver.
    pub fn connect(&self) -> Result<Box<dyn Centrifuge>, ConnectError> {
        let max = self.max_rate_deg_s()?;
        let transport = self.transport.open().map_err(|e| ConnectError::Open {
            device: self.name.clone(),
            error: e.to_string(),
        })?;
        Ok(match &self.dialect {
            DialectConfig::Acutrol { axis, short_form } => Box::new(DialectCentrifuge::new(
                transport,
                AcutrolDialect {
                    axis: *axis,
                    short_form: *short_form,
                },
                &self.name,
                self.io,
                max,
            )),
            DialectConfig::Line(line) => {
                let dialect = LineDialect::new((**line).clone()).map_err(|e| ConfigError {
                    key: format!("centrifuge.dialect.{}", e.key),
                    problem: e.problem,
                })?;
                Box::new(DialectCentrifuge::new(
                    transport, dialect, &self.name, self.io, max,
                ))
            }
        })
    }
}

/// Counting mode in config.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ModeConfig {
    /// Gated counts (the published design).
    Gated,
    /// Reciprocal counts (the resolution the measurement needs).
    #[default]
    Reciprocal,
}

impl From<ModeConfig> for StreamMode {
    fn from(m: ModeConfig) -> StreamMode {
        match m {
            ModeConfig::Gated => StreamMode::Gated,
            ModeConfig::Reciprocal => StreamMode::Reciprocal,
        }
    }
}

/// One `[[fmu]]` section.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FmuConfig {
    /// Name in messages.
    pub name: String,
    /// Counting mode (default reciprocal).
    #[serde(default)]
    pub mode: ModeConfig,
    /// Instruments on this module, 1–6 (default 6).
    #[serde(default = "default_instruments")]
    pub instruments: usize,
    /// Reference clock of reciprocal counting [Hz] (default 100 MHz).
    #[serde(default = "default_reference")]
    pub reference_hz: f64,
    /// Temperature frames per second the module sends (default 1).
    #[serde(default = "default_temperature_rate")]
    pub temperature_frames_per_s: f64,
    /// How to reach it.
    pub transport: TransportConfig,
    /// Deadlines and retries of commands.
    #[serde(default)]
    pub io: IoPolicy,
}

fn default_instruments() -> usize {
    fmu::INSTRUMENTS_PER_MODULE
}

fn default_reference() -> f64 {
    fmu::DEFAULT_REFERENCE_HZ
}

fn default_temperature_rate() -> f64 {
    1.0
}

impl FmuConfig {
    /// Check the section; `index` is its place in the `[[fmu]]` list. A
    /// serial line must carry the stream (method.md §3.1): the published
    /// 9600 baud is refused with the baud it needs.
    pub fn validate(&self, index: usize) -> Result<(), ConfigError> {
        let key = |k: &str| format!("fmu[{index}].{k}");
        if !(1..=fmu::INSTRUMENTS_PER_MODULE).contains(&self.instruments) {
            return Err(ConfigError {
                key: key("instruments"),
                problem: format!("{} is not 1 to 6", self.instruments),
            });
        }
        if !(self.reference_hz.is_finite() && self.reference_hz > 0.0 && self.reference_hz <= 1e10)
        {
            return Err(ConfigError {
                key: key("reference_hz"),
                problem: "must be a positive frequency up to 10 GHz".into(),
            });
        }
        if !(self.temperature_frames_per_s.is_finite()
            && (0.0..=100.0).contains(&self.temperature_frames_per_s))
        {
            return Err(ConfigError {
                key: key("temperature_frames_per_s"),
                problem: format!(
                    "{} is outside 0 to 100 frames per second",
                    self.temperature_frames_per_s
                ),
            });
        }
        self.io.validate(&format!("fmu[{index}]"))?;
        self.transport.validate(&format!("fmu[{index}]"))?;
        if let TransportConfig::Serial(s) = &self.transport {
            let framing = SerialFraming {
                data_bits: s.data_bits,
                parity: s.parity != crate::transport::Parity::None,
                stop_bits: s.stop_bits,
            };
            fmu::check_line_rate(
                s.baud,
                framing,
                self.mode.into(),
                fmu::INPUTS_PER_MODULE,
                self.temperature_frames_per_s,
            )
            .map_err(|e| ConfigError {
                key: key("transport.baud"),
                problem: e.to_string(),
            })?;
        }
        Ok(())
    }

    /// Open the transport and build the driver.
    pub fn connect(&self, index: usize) -> Result<Box<dyn CounterModule>, ConnectError> {
        self.connect_capturing(index, None)
    }

    /// As [`FmuConfig::connect`], recording every byte received into `capture`.
    pub fn connect_capturing(
        &self,
        index: usize,
        capture: Option<crate::capture::RawCapture>,
    ) -> Result<Box<dyn CounterModule>, ConnectError> {
        self.validate(index)?;
        let transport = self.transport.open().map_err(|e| ConnectError::Open {
            device: self.name.clone(),
            error: e.to_string(),
        })?;
        Ok(match capture {
            Some(c) => Box::new(FmuDriver::new(
                crate::capture::CaptureTransport::new(transport, c),
                &self.name,
                self.io,
            )),
            None => Box::new(FmuDriver::new(transport, &self.name, self.io)),
        })
    }
}

/// A `[[power_supply]]` section.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PowerSupplyConfig {
    /// Name in messages.
    pub name: String,
    /// Number of outputs (default 1).
    #[serde(default = "default_channels")]
    pub channels: u8,
    /// How to reach it (SCPI over TCP uses port 5025).
    pub transport: TransportConfig,
    /// Deadlines and retries.
    #[serde(default)]
    pub io: IoPolicy,
}

fn default_channels() -> u8 {
    1
}

impl PowerSupplyConfig {
    /// Check what can be checked without the supply (section `index`, 0-based).
    pub fn validate(&self, index: usize) -> Result<(), ConfigError> {
        if !(1..=16).contains(&self.channels) {
            return Err(ConfigError {
                key: format!("power_supply[{index}].channels"),
                problem: format!("{} is not 1 to 16", self.channels),
            });
        }
        self.io.validate(&format!("power_supply[{index}]"))?;
        self.transport.validate(&format!("power_supply[{index}]"))
    }

    /// Open the transport and build the driver.
    pub fn connect(&self) -> Result<Box<dyn PowerSupply>, ConnectError> {
        if self.channels == 0 {
            return Err(ConfigError {
                key: "power_supply.channels".into(),
                problem: "must be at least 1".into(),
            }
            .into());
        }
        let transport = self.transport.open().map_err(|e| ConnectError::Open {
            device: self.name.clone(),
            error: e.to_string(),
        })?;
        Ok(Box::new(ScpiPowerSupply::new(
            transport,
            &self.name,
            self.channels,
            self.io,
        )))
    }
}

/// A device could not be connected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConnectError {
    /// The configuration is wrong.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The port or connection could not be opened.
    #[error("cannot open the connection to '{device}': {error}")]
    Open {
        /// Device name.
        device: String,
        /// The operating system's reason.
        error: String,
    },
}

/// Deadlines and retries of one device, as written in the station config.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IoPolicy {
    /// Deadline of each attempt [ms] (default 500).
    #[serde(default = "default_timeout_ms")]
    pub timeout_ms: u64,
    /// Further attempts after the first fails (default 2).
    #[serde(default = "default_retries")]
    pub retries: u32,
}

fn default_timeout_ms() -> u64 {
    500
}

fn default_retries() -> u32 {
    2
}

/// Longest deadline of one attempt [ms] (ten seconds).
pub const MAX_TIMEOUT_MS: u64 = 10_000;
/// Most retries of one command.
pub const MAX_RETRIES: u32 = 20;
/// Longest a device may take to fail one command, all attempts together,
/// `timeout_ms × (retries + 1)` [ms]. A shutdown sends each device a few
/// commands on the way to the safe state; with silent devices the whole
/// stop must end well inside the service's stop time (the packaged unit's
/// `TimeoutStopSec=90`), so one command may not take
/// longer than this.
pub const MAX_COMMAND_MS: u64 = 10_000;

impl IoPolicy {
    /// Check the deadline and the retries against their bounds; the error
    /// names the key under `section`.
    pub fn validate(&self, section: &str) -> Result<(), ConfigError> {
        if !(1..=MAX_TIMEOUT_MS).contains(&self.timeout_ms) {
            return Err(ConfigError {
                key: format!("{section}.io.timeout_ms"),
                problem: format!(
                    "{} ms is outside 1 to {MAX_TIMEOUT_MS} ms (MAX_TIMEOUT_MS)",
                    self.timeout_ms
                ),
            });
        }
        if self.retries > MAX_RETRIES {
            return Err(ConfigError {
                key: format!("{section}.io.retries"),
                problem: format!("{} is above {MAX_RETRIES} (MAX_RETRIES)", self.retries),
            });
        }
        let command_ms = self.timeout_ms * (u64::from(self.retries) + 1);
        if command_ms > MAX_COMMAND_MS {
            return Err(ConfigError {
                key: format!("{section}.io"),
                problem: format!(
                    "timeout_ms × (retries + 1) = {} × {} = {command_ms} ms is over {MAX_COMMAND_MS} ms \
                     (MAX_COMMAND_MS): a device that stops answering would hold the station's \
                     stop past the service's stop time; shorten the timeout or take fewer retries",
                    self.timeout_ms,
                    self.retries + 1
                ),
            });
        }
        Ok(())
    }
}

impl Default for IoPolicy {
    fn default() -> Self {
        IoPolicy {
            timeout_ms: default_timeout_ms(),
            retries: default_retries(),
        }
    }
}

impl IoPolicy {
    /// The deadline of one attempt.
    pub fn timeout(&self) -> Duration {
        Duration::from_millis(self.timeout_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centrifuge_section_with_rpm_and_a_line_dialect() {
        let c: CentrifugeConfig = toml::from_str(
            r#"
            name = "table"
            max_rate_rpm = 400
            transport = { kind = "serial", path = "/dev/ttyS0", baud = 9600 }
            [dialect]
            kind = "line"
            name = "TM"
            commands = { set_rate = "JOG {rate}", read_rate = "RATE?", stop = "STO" }
            replies = { read_rate = '^(?P<rate>\S+)$' }
            "#,
        )
        .expect("parses");
        assert_eq!(c.max_rate_deg_s(), Ok(2400.0));
        c.validate().expect("valid");
        assert_eq!(c.io, IoPolicy::default());
    }

    #[test]
    fn bad_centrifuge_sections_name_the_key() {
        let base = r#"
            name = "table"
            transport = { kind = "tcp", address = "127.0.0.1:9878" }
            dialect = { kind = "acutrol" }
        "#;
        let c: CentrifugeConfig = toml::from_str(base).expect("parses");
        assert!(
            c.validate()
                .expect_err("no limit")
                .to_string()
                .starts_with("centrifuge.max_rate_deg_s: the centrifuge's rate limit is required")
        );
        let both = format!("max_rate_rpm = 1\nmax_rate_deg_s = 6\n{base}");
        let c: CentrifugeConfig = toml::from_str(&both).expect("parses");
        assert!(c.validate().is_err());
        let e = toml::from_str::<CentrifugeConfig>(&base.replace("acutrol", "hal9000"))
            .expect_err("unknown dialect");
        assert!(e.to_string().contains("hal9000"), "{e}");
    }

    #[test]
    fn the_published_9600_baud_fmu_line_is_refused_with_the_needed_baud() {
        let f: FmuConfig = toml::from_str(
            r#"
            name = "fmu1"
            mode = "gated"
            transport = { kind = "serial", path = "/dev/ttyS4", baud = 9600 }
            "#,
        )
        .expect("parses");
        let e = f.validate(0).expect_err("too slow").to_string();
        assert!(
            e.starts_with("fmu[0].transport.baud: the FMU stream needs 136"),
            "{e}"
        );
        assert!(e.contains("230400 baud"), "{e}");
        let ok: FmuConfig = toml::from_str(
            r#"
            name = "fmu1"
            transport = { kind = "serial", path = "/dev/ttyS4", baud = 921600 }
            "#,
        )
        .expect("parses");
        ok.validate(0).expect("reciprocal at 921600 fits");
    }

    #[test]
    fn opening_a_missing_port_says_which_device() {
        let p: PowerSupplyConfig = toml::from_str(
            r#"
            name = "rails"
            channels = 2
            transport = { kind = "serial", path = "/dev/does-not-exist", baud = 115200 }
            "#,
        )
        .expect("parses");
        let e = p.connect().err().expect("no such port").to_string();
        assert!(
            e.starts_with("cannot open the connection to 'rails':"),
            "{e}"
        );
        assert!(e.contains("/dev/does-not-exist"), "{e}");
    }
}
