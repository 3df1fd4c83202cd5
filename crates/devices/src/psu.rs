//! The `PowerSupply` trait and its SCPI driver (IEEE 488.2) over serial or TCP port 5025.

use crate::error::{DeviceError, DeviceErrorKind};
use crate::line::{IoPolicy, LineChannel};
use crate::transport::Transport;
use spinbench_wire::psu::PsuRequest;
use spinbench_wire::scpi;

/// Voltage and current measured at an output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputReading {
    /// Volts.
    pub volts: f64,
    /// Amperes.
    pub amps: f64,
}

/// A programmable DC supply with numbered outputs (1-based).
pub trait PowerSupply: Send {
    /// The supply's identity (`*IDN?`).
    fn identify(&mut self) -> Result<String, DeviceError>;
    /// Set an output's voltage and current limit (output state unchanged).
    fn configure(
        &mut self,
        channel: u8,
        volts: f64,
        current_limit_a: f64,
    ) -> Result<(), DeviceError>;
    /// Switch an output on or off.
    fn set_output(&mut self, channel: u8, on: bool) -> Result<(), DeviceError>;
    /// Measure an output.
    fn measure(&mut self, channel: u8) -> Result<OutputReading, DeviceError>;
    /// Read what the error queue holds from before (another program, an
    /// earlier session), oldest first, then clear it (`*CLS`): a setting's
    /// refusal after this is the setting's own. At most
    /// [`MAX_STALE_ERRORS`] entries are read.
    fn clear_errors(&mut self) -> Result<Vec<(i32, String)>, DeviceError>;
}

/// Most error-queue entries read before `*CLS` (a queue that never ends
/// is a supply that does not answer as SCPI says).
pub const MAX_STALE_ERRORS: usize = 32;

/// A SCPI supply. After every setting it reads the error queue, so a
/// refused setting surfaces as an error instead of passing silently.
pub struct ScpiPowerSupply<T: Transport> {
    channel: LineChannel<T>,
    channels: u8,
}

fn number(reply: &str) -> Result<f64, (String, bool)> {
    scpi::parse_number(reply).map_err(|e| (e.expected.to_string(), false))
}

impl<T: Transport> ScpiPowerSupply<T> {
    /// A driver for a supply with `channels` outputs, named `name` in messages.
    pub fn new(transport: T, name: &str, channels: u8, policy: IoPolicy) -> Self {
        ScpiPowerSupply {
            channel: LineChannel::new(transport, format!("power supply '{name}'"), "\n", policy),
            channels,
        }
    }

    fn select(&mut self, channel: u8) -> Result<(), DeviceError> {
        if channel == 0 || channel > self.channels {
            return Err(DeviceError {
                device: self.channel.device().to_string(),
                command: format!("channel {channel}"),
                kind: DeviceErrorKind::Rejected(format!(
                    "the supply has outputs 1 to {}",
                    self.channels
                )),
            });
        }
        if self.channels > 1 {
            self.channel
                .send(&PsuRequest::SelectChannel(channel).line())?;
        }
        Ok(())
    }

    /// Send a setting, then read the error queue: a non-zero entry is a refusal.
    fn set(&mut self, request: PsuRequest) -> Result<(), DeviceError> {
        let line = request.line();
        self.channel.send(&line)?;
        let (code, message) = self.channel.query(&PsuRequest::ReadError.line(), |r| {
            scpi::parse_error_entry(r).map_err(|e| (e.expected.to_string(), false))
        })?;
        if code != 0 {
            return Err(DeviceError {
                device: self.channel.device().to_string(),
                command: line,
                kind: DeviceErrorKind::Refused(format!("error {code}, \"{message}\"")),
            });
        }
        Ok(())
    }
}

impl<T: Transport> PowerSupply for ScpiPowerSupply<T> {
    fn identify(&mut self) -> Result<String, DeviceError> {
        self.channel.query(&PsuRequest::Identify.line(), |r| {
            let r = r.trim();
            if r.is_empty() {
                Err(("an identity string".into(), false))
            } else {
                Ok(r.to_string())
            }
        })
    }

    fn configure(
        &mut self,
        channel: u8,
        volts: f64,
        current_limit_a: f64,
    ) -> Result<(), DeviceError> {
        for (what, v) in [("voltage", volts), ("current limit", current_limit_a)] {
            if !v.is_finite() || v < 0.0 {
                return Err(DeviceError {
                    device: self.channel.device().to_string(),
                    command: format!("set {what} {v}"),
                    kind: DeviceErrorKind::Rejected(format!(
                        "the {what} must be a finite value ≥ 0"
                    )),
                });
            }
        }
        self.select(channel)?;
        self.set(PsuRequest::SetVoltage(volts))?;
        self.set(PsuRequest::SetCurrentLimit(current_limit_a))
    }

    fn set_output(&mut self, channel: u8, on: bool) -> Result<(), DeviceError> {
        self.select(channel)?;
        self.set(PsuRequest::Output(on))
    }

    fn clear_errors(&mut self) -> Result<Vec<(i32, String)>, DeviceError> {
        let mut stale = Vec::new();
        for _ in 0..MAX_STALE_ERRORS {
            let (code, message) = self.channel.query(&PsuRequest::ReadError.line(), |r| {
                scpi::parse_error_entry(r).map_err(|e| (e.expected.to_string(), false))
            })?;
            if code == 0 {
                break;
            }
            stale.push((code, message));
        }
        self.channel.send(&PsuRequest::ClearStatus.line())?;
        Ok(stale)
    }

    fn measure(&mut self, channel: u8) -> Result<OutputReading, DeviceError> {
        self.select(channel)?;
        let volts = self
            .channel
            .query(&PsuRequest::MeasureVoltage.line(), number)?;
        let amps = self
            .channel
            .query(&PsuRequest::MeasureCurrent.line(), number)?;
        Ok(OutputReading { volts, amps })
    }
}
