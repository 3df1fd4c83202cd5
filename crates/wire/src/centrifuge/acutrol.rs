//! The ACUTROL SCPI-style command tree (method.md §4), long or short forms.

use super::{
    CentrifugeDialect, CentrifugeReply, CentrifugeRequest, DialectReplyError, Exchange, Expect,
};
use crate::scpi::{self, HeaderSpec, ReplyError};

/// The ACUTROL SCPI-style dialect (method.md §4).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AcutrolDialect {
    /// Axis number of the centrifuge's spin axis (usually 1).
    pub axis: u8,
    /// Send the short (abbreviated) forms.
    pub short_form: bool,
}

impl Default for AcutrolDialect {
    fn default() -> Self {
        AcutrolDialect {
            axis: 1,
            short_form: false,
        }
    }
}

/// The ACUTROL headers the station uses, in SCPI notation.
pub mod acutrol_headers {
    /// Identify.
    pub const IDN: &str = "*IDN?";
    /// Status byte.
    pub const STB: &str = "*STB?";
    /// Enter rate mode: ramp to the demanded rate without overshoot.
    pub const MODE_RATE: &str = ":MODe:RATe";
    /// Controlled stop.
    pub const MODE_OFF: &str = ":MODe:OFF";
    /// Demanded rate: `<axis>,<deg/s>`.
    pub const DEMAND_RATE: &str = ":DEMand:RATe";
    /// Measured rate query: `<axis>`.
    pub const READ_RATE: &str = ":READ:RATe?";
    /// Close interlocks.
    pub const INTERLOCK_CLOSE: &str = ":INTerlock:CLOSe";
    /// Open interlocks.
    pub const INTERLOCK_OPEN: &str = ":INTerlock:OPEN";
    /// Reset interlocks.
    pub const INTERLOCK_RESET: &str = ":INTerlock:RESet";
    /// Interlock state query; replies 1 (closed) or 0 (open).
    pub const INTERLOCK_QUERY: &str = ":INTerlock?";
    /// Rate limit: `<axis>,<deg/s>`.
    pub const LIMIT_RATE: &str = ":LIMit:RATe";
    /// Acceleration limit: `<axis>,<deg/s²>`.
    pub const LIMIT_ACCELERATION: &str = ":LIMit:ACCeleration";
    /// Error queue.
    pub const SYSTEM_ERROR: &str = ":SYSTem:ERRor?";
}

impl AcutrolDialect {
    fn header(&self, spec: &str) -> String {
        HeaderSpec::new(spec).render(self.short_form)
    }
}

impl CentrifugeDialect for AcutrolDialect {
    fn name(&self) -> &str {
        "ACUTROL"
    }

    fn line_ending(&self) -> &str {
        "\n"
    }

    fn exchanges(&self, request: &CentrifugeRequest) -> Vec<Exchange> {
        use acutrol_headers as h;
        let axis = self.axis;
        let silent = |line: String| Exchange {
            line,
            expect: Expect::Nothing,
        };
        let query = |line: String| Exchange {
            line,
            expect: Expect::Value,
        };
        match request {
            CentrifugeRequest::Identify => vec![query(self.header(h::IDN))],
            CentrifugeRequest::Arm => vec![silent(format!(
                "{} {axis}",
                self.header(h::INTERLOCK_CLOSE)
            ))],
            CentrifugeRequest::Disarm => {
                vec![silent(format!("{} {axis}", self.header(h::INTERLOCK_OPEN)))]
            }
            CentrifugeRequest::ResetInterlocks => vec![silent(format!(
                "{} {axis}",
                self.header(h::INTERLOCK_RESET)
            ))],
            CentrifugeRequest::SetRate { rate_deg_s } => vec![
                silent(format!(
                    "{} {axis},{}",
                    self.header(h::DEMAND_RATE),
                    scpi::format_number(*rate_deg_s)
                )),
                silent(format!("{} {axis}", self.header(h::MODE_RATE))),
            ],
            CentrifugeRequest::ReadRate => {
                vec![query(format!("{} {axis}", self.header(h::READ_RATE)))]
            }
            CentrifugeRequest::ReadInterlocks => vec![query(self.header(h::INTERLOCK_QUERY))],
            CentrifugeRequest::Stop => vec![silent(format!("{} {axis}", self.header(h::MODE_OFF)))],
        }
    }

    fn parse_reply(
        &self,
        request: &CentrifugeRequest,
        reply: &str,
    ) -> Result<CentrifugeReply, DialectReplyError> {
        let reply = reply.trim();
        Ok(match request {
            CentrifugeRequest::Identify => {
                if reply.is_empty() {
                    return Err(ReplyError {
                        expected: "an identity string",
                        reply: reply.into(),
                    }
                    .into());
                }
                CentrifugeReply::Identity(reply.to_string())
            }
            CentrifugeRequest::ReadRate => CentrifugeReply::RateDegS(scpi::parse_number(reply)?),
            CentrifugeRequest::ReadInterlocks => {
                CentrifugeReply::Interlocks(match reply.to_ascii_uppercase().as_str() {
                    "CLOSED" => true,
                    "OPEN" => false,
                    _ => scpi::parse_bool(reply)?,
                })
            }
            _ => {
                return Err(ReplyError {
                    expected: "no reply",
                    reply: reply.into(),
                }
                .into());
            }
        })
    }

    fn check_ack(&self, _reply: &str) -> Result<(), DialectReplyError> {
        Ok(())
    }
}
