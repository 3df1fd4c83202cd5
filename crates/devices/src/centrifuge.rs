//! The `Centrifuge` trait and its driver over any dialect and transport.

use crate::error::{DeviceError, DeviceErrorKind};
use crate::line::{IoPolicy, LineChannel};
use crate::transport::Transport;
use spinbench_wire::centrifuge::{
    CentrifugeDialect, CentrifugeReply, CentrifugeRequest, DialectReplyError, Expect,
};

/// A rate table or centrifuge controller. Rates are deg/s.
pub trait Centrifuge: Send {
    /// The controller's identity (`*IDN?` or the dialect's equivalent).
    fn identify(&mut self) -> Result<String, DeviceError>;
    /// Close the interlocks so the table may move.
    fn arm(&mut self) -> Result<(), DeviceError>;
    /// Clear latched interlock faults (a no-op if the controller has none).
    fn reset_interlocks(&mut self) -> Result<(), DeviceError>;
    /// Ramp to `rate_deg_s` without overshoot.
    fn set_rate(&mut self, rate_deg_s: f64) -> Result<(), DeviceError>;
    /// The measured rate [deg/s].
    fn read_rate(&mut self) -> Result<f64, DeviceError>;
    /// True when the interlocks are closed.
    fn read_interlocks(&mut self) -> Result<bool, DeviceError>;
    /// Controlled stop.
    fn stop(&mut self) -> Result<(), DeviceError>;
    /// Open the interlocks.
    fn disarm(&mut self) -> Result<(), DeviceError>;
}

/// A centrifuge driven through a [`CentrifugeDialect`] over a transport.
///
/// It refuses to demand a rate above `max_rate_deg_s` whatever the caller
/// asks: the last line of defence behind the engine's plan check.
pub struct DialectCentrifuge<T: Transport, D: CentrifugeDialect> {
    channel: LineChannel<T>,
    dialect: D,
    max_rate_deg_s: f64,
}

impl<T: Transport, D: CentrifugeDialect> DialectCentrifuge<T, D> {
    /// A driver named `name` with a rate limit.
    pub fn new(
        transport: T,
        dialect: D,
        name: &str,
        policy: IoPolicy,
        max_rate_deg_s: f64,
    ) -> Self {
        let ending = dialect.line_ending().to_string();
        let device = format!("centrifuge '{name}' ({})", dialect.name());
        DialectCentrifuge {
            channel: LineChannel::new(transport, device, &ending, policy),
            dialect,
            max_rate_deg_s,
        }
    }

    /// Run a request's exchanges; returns the value reply, if the request has one.
    fn run(&mut self, request: CentrifugeRequest) -> Result<Option<CentrifugeReply>, DeviceError> {
        let mut value = None;
        for exchange in self.dialect.exchanges(&request) {
            let dialect = &self.dialect;
            let classify = |e: DialectReplyError| match e {
                DialectReplyError::Refused(why) => (why, true),
                DialectReplyError::Garbled(g) => (g.expected.to_string(), false),
            };
            match exchange.expect {
                Expect::Nothing => self.channel.send(&exchange.line)?,
                Expect::Ack => self
                    .channel
                    .query(&exchange.line, |r| dialect.check_ack(r).map_err(classify))?,
                Expect::Value => {
                    value = Some(self.channel.query(&exchange.line, |r| {
                        dialect.parse_reply(&request, r).map_err(classify)
                    })?);
                }
            }
        }
        Ok(value)
    }

    fn unexpected(&self, request: CentrifugeRequest, what: &str) -> DeviceError {
        DeviceError {
            device: self.channel.device().to_string(),
            command: request.name().to_string(),
            kind: DeviceErrorKind::Garbled {
                reply: String::new(),
                expected: what.to_string(),
                attempts: 1,
            },
        }
    }

    fn value(
        &mut self,
        request: CentrifugeRequest,
        what: &str,
    ) -> Result<CentrifugeReply, DeviceError> {
        match self.run(request)? {
            Some(v) => Ok(v),
            None => Err(DeviceError {
                device: self.channel.device().to_string(),
                command: request.name().to_string(),
                kind: DeviceErrorKind::Rejected(format!(
                    "the {} dialect has no command to {what}",
                    self.dialect.name()
                )),
            }),
        }
    }
}

impl<T: Transport, D: CentrifugeDialect> Centrifuge for DialectCentrifuge<T, D> {
    fn identify(&mut self) -> Result<String, DeviceError> {
        match self.value(CentrifugeRequest::Identify, "identify")? {
            CentrifugeReply::Identity(id) => Ok(id),
            _ => Err(self.unexpected(CentrifugeRequest::Identify, "an identity")),
        }
    }

    fn arm(&mut self) -> Result<(), DeviceError> {
        self.run(CentrifugeRequest::Arm).map(|_| ())
    }

    fn reset_interlocks(&mut self) -> Result<(), DeviceError> {
        self.run(CentrifugeRequest::ResetInterlocks).map(|_| ())
    }

    fn set_rate(&mut self, rate_deg_s: f64) -> Result<(), DeviceError> {
        if !rate_deg_s.is_finite() || rate_deg_s.abs() > self.max_rate_deg_s {
            return Err(DeviceError {
                device: self.channel.device().to_string(),
                command: format!("set rate {rate_deg_s} deg/s"),
                kind: DeviceErrorKind::Rejected(format!(
                    "the rate limit is {} deg/s (centrifuge max_rate in the station config)",
                    self.max_rate_deg_s
                )),
            });
        }
        self.run(CentrifugeRequest::SetRate { rate_deg_s })
            .map(|_| ())
    }

    fn read_rate(&mut self) -> Result<f64, DeviceError> {
        match self.value(CentrifugeRequest::ReadRate, "read the rate")? {
            CentrifugeReply::RateDegS(r) => Ok(r),
            _ => Err(self.unexpected(CentrifugeRequest::ReadRate, "a rate")),
        }
    }

    fn read_interlocks(&mut self) -> Result<bool, DeviceError> {
        match self.value(CentrifugeRequest::ReadInterlocks, "read the interlocks")? {
            CentrifugeReply::Interlocks(closed) => Ok(closed),
            _ => Err(self.unexpected(CentrifugeRequest::ReadInterlocks, "the interlock state")),
        }
    }

    fn stop(&mut self) -> Result<(), DeviceError> {
        self.run(CentrifugeRequest::Stop).map(|_| ())
    }

    fn disarm(&mut self) -> Result<(), DeviceError> {
        self.run(CentrifugeRequest::Disarm).map(|_| ())
    }
}
