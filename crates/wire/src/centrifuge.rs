//! Centrifuge controller dialects (method.md §4): what to send for each
//! operation and how to read the replies. No I/O; the `devices` crate's
//! driver runs the exchanges over a transport.
//!
//! * [`AcutrolDialect`] — the SCPI-style ACUTROL command tree
//!   (`:MODE:RATE 1`, `:DEMAND:RATE 1,<deg/s>`, `:READ:RATE? 1`, …), sent
//!   in long or short form;
//! * [`LineDialect`] — any line-oriented controller, described entirely in
//!   the station config ([`LineDialectConfig`]): command templates, line
//!   ending, reply patterns and the rate unit, so a new controller needs no code.
//!
//! Rates are deg/s in the station; a dialect converts to the controller's unit.

use crate::scpi::{self, HeaderSpec, ReplyError};
use regex::Regex;
use serde::Deserialize;
use std::fmt;

/// An operation on the centrifuge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CentrifugeRequest {
    /// Ask for the controller's identity.
    Identify,
    /// Close the interlocks so the table may move.
    Arm,
    /// Open the interlocks.
    Disarm,
    /// Clear latched interlock faults.
    ResetInterlocks,
    /// Ramp to a rate [deg/s] without overshoot.
    SetRate {
        /// Demanded rate [deg/s].
        rate_deg_s: f64,
    },
    /// Read the measured rate.
    ReadRate,
    /// Read whether the interlocks are closed.
    ReadInterlocks,
    /// Controlled stop.
    Stop,
}

impl CentrifugeRequest {
    /// A short name for messages.
    pub fn name(&self) -> &'static str {
        match self {
            CentrifugeRequest::Identify => "identify",
            CentrifugeRequest::Arm => "arm",
            CentrifugeRequest::Disarm => "disarm",
            CentrifugeRequest::ResetInterlocks => "reset interlocks",
            CentrifugeRequest::SetRate { .. } => "set rate",
            CentrifugeRequest::ReadRate => "read rate",
            CentrifugeRequest::ReadInterlocks => "read interlocks",
            CentrifugeRequest::Stop => "stop",
        }
    }
}

/// A parsed reply.
#[derive(Debug, Clone, PartialEq)]
pub enum CentrifugeReply {
    /// The identity string.
    Identity(String),
    /// Measured rate [deg/s].
    RateDegS(f64),
    /// Interlocks closed (true) or open.
    Interlocks(bool),
}

/// What reply a line expects.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expect {
    /// None (SCPI setting commands are silent).
    Nothing,
    /// An acknowledgement line (checked with [`CentrifugeDialect::check_ack`]).
    Ack,
    /// A value (parsed with [`CentrifugeDialect::parse_reply`]).
    Value,
}

/// One line to send and the reply it expects.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Exchange {
    /// The line, without its terminator.
    pub line: String,
    /// The reply expected.
    pub expect: Expect,
}

/// A reply that says the controller refused or did not understand.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DialectReplyError {
    /// The reply has the wrong form.
    #[error(transparent)]
    Garbled(#[from] ReplyError),
    /// The controller reported an error.
    #[error("the controller reported an error: {0}")]
    Refused(String),
}

/// A controller's command language.
pub trait CentrifugeDialect: fmt::Debug + Send {
    /// Name for messages (e.g. "ACUTROL").
    fn name(&self) -> &str;
    /// Line terminator sent after each command and expected after each reply.
    fn line_ending(&self) -> &str;
    /// The exchanges that carry out `request`; empty if this controller has
    /// no such operation (the driver then skips it, e.g. no interlock reset).
    fn exchanges(&self, request: &CentrifugeRequest) -> Vec<Exchange>;
    /// Parse the value reply of `request`.
    fn parse_reply(
        &self,
        request: &CentrifugeRequest,
        reply: &str,
    ) -> Result<CentrifugeReply, DialectReplyError>;
    /// Check an acknowledgement line.
    fn check_ack(&self, reply: &str) -> Result<(), DialectReplyError>;
}

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

/// The unit a controller speaks its rates in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum RateUnit {
    /// Degrees per second.
    #[default]
    DegS,
    /// Revolutions per minute.
    Rpm,
    /// Radians per second.
    RadS,
}

impl RateUnit {
    /// deg/s per one of this unit.
    pub fn deg_s_per_unit(self) -> f64 {
        match self {
            RateUnit::DegS => 1.0,
            RateUnit::Rpm => 6.0,
            RateUnit::RadS => 180.0 / std::f64::consts::PI,
        }
    }
}

/// Command templates of a configurable dialect; `{rate}` is replaced by the
/// demanded rate in the dialect's unit. A missing command means the
/// controller has no such operation.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct CommandTemplates {
    /// Identify (a query).
    pub identify: Option<String>,
    /// Close interlocks / enable.
    pub arm: Option<String>,
    /// Open interlocks / disable.
    pub disarm: Option<String>,
    /// Reset latched faults.
    pub reset_interlocks: Option<String>,
    /// Set the rate; must contain `{rate}`.
    pub set_rate: String,
    /// Read the rate (a query).
    pub read_rate: String,
    /// Read the interlocks (a query).
    pub read_interlocks: Option<String>,
    /// Controlled stop.
    pub stop: String,
}

/// Reply patterns of a configurable dialect (regular expressions).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ReplyPatterns {
    /// Reply to `identify`; the whole line by default.
    pub identify: Option<String>,
    /// Reply to `read_rate`, with a named group `rate`.
    pub read_rate: String,
    /// Reply to `read_interlocks`, with a named group `closed`.
    pub read_interlocks: Option<String>,
    /// The value of `closed` that means closed (default "1").
    pub interlocks_closed_value: Option<String>,
    /// If set, every non-query command is answered by a line matching this.
    pub ack: Option<String>,
    /// A reply matching this is a refusal; a named group `message` is reported.
    pub error: Option<String>,
}

/// The station-config description of a line-oriented controller.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LineDialectConfig {
    /// Name for messages.
    pub name: String,
    /// Line terminator (default CR LF).
    #[serde(default = "default_line_ending")]
    pub line_ending: String,
    /// Unit of rates in commands and replies.
    #[serde(default)]
    pub rate_unit: RateUnit,
    /// Decimals of the rate in commands.
    #[serde(default = "default_decimals")]
    pub rate_decimals: usize,
    /// Command templates.
    pub commands: CommandTemplates,
    /// Reply patterns.
    pub replies: ReplyPatterns,
}

fn default_line_ending() -> String {
    "\r\n".into()
}

fn default_decimals() -> usize {
    3
}

/// A configuration that cannot describe a working dialect; names the key.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("centrifuge dialect '{dialect}': {key}: {problem}")]
pub struct DialectConfigError {
    /// Dialect name.
    pub dialect: String,
    /// The config key, e.g. `replies.read_rate`.
    pub key: &'static str,
    /// What is wrong.
    pub problem: String,
}

/// A configured line dialect, with its patterns compiled.
#[derive(Debug, Clone)]
pub struct LineDialect {
    config: LineDialectConfig,
    identify: Regex,
    read_rate: Regex,
    read_interlocks: Option<Regex>,
    ack: Option<Regex>,
    error: Option<Regex>,
}

impl LineDialect {
    /// Validate and compile a configuration.
    pub fn new(config: LineDialectConfig) -> Result<LineDialect, DialectConfigError> {
        let err = |key: &'static str, problem: String| DialectConfigError {
            dialect: config.name.clone(),
            key,
            problem,
        };
        let compile = |key: &'static str,
                       pattern: &str,
                       group: Option<&str>|
         -> Result<Regex, DialectConfigError> {
            let re = Regex::new(pattern)
                .map_err(|e| err(key, format!("not a valid regular expression: {e}")))?;
            if let Some(g) = group
                && !re.capture_names().any(|n| n == Some(g))
            {
                return Err(err(
                    key,
                    format!("the pattern needs a named group (?P<{g}>…)"),
                ));
            }
            Ok(re)
        };
        if !config.commands.set_rate.contains("{rate}") {
            return Err(err(
                "commands.set_rate",
                "the template must contain {rate}".into(),
            ));
        }
        if config.line_ending.is_empty() {
            return Err(err("line_ending", "must not be empty".into()));
        }
        if config.rate_decimals > 12 {
            return Err(err(
                "rate_decimals",
                format!("{} is more than 12", config.rate_decimals),
            ));
        }
        let identify = compile(
            "replies.identify",
            config.replies.identify.as_deref().unwrap_or("^(?s).+$"),
            None,
        )?;
        let read_rate = compile("replies.read_rate", &config.replies.read_rate, Some("rate"))?;
        let read_interlocks = match (
            &config.commands.read_interlocks,
            &config.replies.read_interlocks,
        ) {
            (Some(_), Some(p)) => Some(compile("replies.read_interlocks", p, Some("closed"))?),
            (Some(_), None) => {
                return Err(err(
                    "replies.read_interlocks",
                    "commands.read_interlocks is set, so a reply pattern is needed".into(),
                ));
            }
            (None, _) => None,
        };
        let ack = config
            .replies
            .ack
            .as_deref()
            .map(|p| compile("replies.ack", p, None))
            .transpose()?;
        let error = config
            .replies
            .error
            .as_deref()
            .map(|p| compile("replies.error", p, None))
            .transpose()?;
        Ok(LineDialect {
            config,
            identify,
            read_rate,
            read_interlocks,
            ack,
            error,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &LineDialectConfig {
        &self.config
    }

    fn refusal(&self, reply: &str) -> Option<DialectReplyError> {
        let caps = self.error.as_ref()?.captures(reply)?;
        let message = caps.name("message").map_or(reply, |m| m.as_str());
        Some(DialectReplyError::Refused(message.to_string()))
    }
}

impl CentrifugeDialect for LineDialect {
    fn name(&self) -> &str {
        &self.config.name
    }

    fn line_ending(&self) -> &str {
        &self.config.line_ending
    }

    fn exchanges(&self, request: &CentrifugeRequest) -> Vec<Exchange> {
        let c = &self.config.commands;
        let command = |t: &Option<String>| -> Vec<Exchange> {
            t.iter()
                .map(|line| Exchange {
                    line: line.clone(),
                    expect: if self.ack.is_some() {
                        Expect::Ack
                    } else {
                        Expect::Nothing
                    },
                })
                .collect()
        };
        let query = |t: &Option<String>| -> Vec<Exchange> {
            t.iter()
                .map(|line| Exchange {
                    line: line.clone(),
                    expect: Expect::Value,
                })
                .collect()
        };
        match request {
            CentrifugeRequest::Identify => query(&c.identify),
            CentrifugeRequest::Arm => command(&c.arm),
            CentrifugeRequest::Disarm => command(&c.disarm),
            CentrifugeRequest::ResetInterlocks => command(&c.reset_interlocks),
            CentrifugeRequest::SetRate { rate_deg_s } => {
                let value = rate_deg_s / self.config.rate_unit.deg_s_per_unit();
                let text = format!("{value:.prec$}", prec = self.config.rate_decimals);
                command(&Some(c.set_rate.replace("{rate}", &text)))
            }
            CentrifugeRequest::ReadRate => query(&Some(c.read_rate.clone())),
            CentrifugeRequest::ReadInterlocks => query(&c.read_interlocks),
            CentrifugeRequest::Stop => command(&Some(c.stop.clone())),
        }
    }

    fn parse_reply(
        &self,
        request: &CentrifugeRequest,
        reply: &str,
    ) -> Result<CentrifugeReply, DialectReplyError> {
        let reply = reply.trim();
        if let Some(refused) = self.refusal(reply) {
            return Err(refused);
        }
        let garbled = |expected: &'static str| {
            DialectReplyError::Garbled(ReplyError {
                expected,
                reply: reply.to_string(),
            })
        };
        match request {
            CentrifugeRequest::Identify => {
                if self.identify.is_match(reply) {
                    Ok(CentrifugeReply::Identity(reply.to_string()))
                } else {
                    Err(garbled("an identity matching replies.identify"))
                }
            }
            CentrifugeRequest::ReadRate => {
                let caps = self
                    .read_rate
                    .captures(reply)
                    .ok_or_else(|| garbled("a rate matching replies.read_rate"))?;
                let text = caps.name("rate").map_or("", |m| m.as_str());
                let value =
                    scpi::parse_number(text).map_err(|_| garbled("a number in the rate group"))?;
                Ok(CentrifugeReply::RateDegS(
                    value * self.config.rate_unit.deg_s_per_unit(),
                ))
            }
            CentrifugeRequest::ReadInterlocks => {
                let re = self
                    .read_interlocks
                    .as_ref()
                    .ok_or_else(|| garbled("no reply (no interlock query configured)"))?;
                let caps = re
                    .captures(reply)
                    .ok_or_else(|| garbled("interlocks matching replies.read_interlocks"))?;
                let value = caps.name("closed").map_or("", |m| m.as_str());
                let closed_value = self
                    .config
                    .replies
                    .interlocks_closed_value
                    .as_deref()
                    .unwrap_or("1");
                Ok(CentrifugeReply::Interlocks(value == closed_value))
            }
            _ => Err(garbled("no value reply")),
        }
    }

    fn check_ack(&self, reply: &str) -> Result<(), DialectReplyError> {
        let reply = reply.trim();
        if let Some(refused) = self.refusal(reply) {
            return Err(refused);
        }
        match &self.ack {
            Some(re) if !re.is_match(reply) => Err(DialectReplyError::Garbled(ReplyError {
                expected: "an acknowledgement matching replies.ack",
                reply: reply.to_string(),
            })),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(d: &dyn CentrifugeDialect, r: CentrifugeRequest) -> Vec<String> {
        d.exchanges(&r).into_iter().map(|e| e.line).collect()
    }

    #[test]
    fn acutrol_sends_long_or_short_forms() {
        let long = AcutrolDialect::default();
        assert_eq!(
            lines(&long, CentrifugeRequest::SetRate { rate_deg_s: 360.5 }),
            vec![":DEMAND:RATE 1,360.5", ":MODE:RATE 1"]
        );
        assert_eq!(
            lines(&long, CentrifugeRequest::ReadRate),
            vec![":READ:RATE? 1"]
        );
        assert_eq!(lines(&long, CentrifugeRequest::Stop), vec![":MODE:OFF 1"]);
        assert_eq!(
            lines(&long, CentrifugeRequest::Arm),
            vec![":INTERLOCK:CLOSE 1"]
        );
        let short = AcutrolDialect {
            axis: 2,
            short_form: true,
        };
        assert_eq!(
            lines(&short, CentrifugeRequest::SetRate { rate_deg_s: 90.0 }),
            vec![":DEM:RAT 2,90", ":MOD:RAT 2"]
        );
        assert_eq!(
            lines(&short, CentrifugeRequest::ReadInterlocks),
            vec![":INT?"]
        );
        assert_eq!(lines(&short, CentrifugeRequest::Identify), vec!["*IDN?"]);
    }

    #[test]
    fn acutrol_replies_parse() {
        let d = AcutrolDialect::default();
        assert_eq!(
            d.parse_reply(&CentrifugeRequest::ReadRate, "+3.6000E+02\r"),
            Ok(CentrifugeReply::RateDegS(360.0))
        );
        assert_eq!(
            d.parse_reply(&CentrifugeRequest::ReadInterlocks, "CLOSED"),
            Ok(CentrifugeReply::Interlocks(true))
        );
        assert_eq!(
            d.parse_reply(&CentrifugeRequest::ReadInterlocks, "0"),
            Ok(CentrifugeReply::Interlocks(false))
        );
        assert!(matches!(
            d.parse_reply(&CentrifugeRequest::ReadRate, "#!"),
            Err(DialectReplyError::Garbled(_))
        ));
    }

    const MNEMONIC_TOML: &str = r#"
        name = "TurnMaster 3000"
        line_ending = "\r"
        rate_unit = "rpm"
        rate_decimals = 2
        [commands]
        identify = "ID?"
        arm = "ENA"
        disarm = "DIS"
        set_rate = "JOG {rate}"
        read_rate = "RATE?"
        read_interlocks = "ILK?"
        stop = "STO"
        [replies]
        read_rate = '^RATE\s+(?P<rate>[-+0-9.eE]+)$'
        read_interlocks = '^ILK (?P<closed>[01])$'
        ack = '^OK$'
        error = '^ERR (?P<message>.*)$'
    "#;

    #[test]
    fn a_configured_dialect_needs_no_code() {
        let config: LineDialectConfig = toml::from_str(MNEMONIC_TOML).expect("toml");
        let d = LineDialect::new(config).expect("valid");
        assert_eq!(d.line_ending(), "\r");
        // 360 deg/s is 60 rpm.
        let ex = d.exchanges(&CentrifugeRequest::SetRate { rate_deg_s: 360.0 });
        assert_eq!(
            ex,
            vec![Exchange {
                line: "JOG 60.00".into(),
                expect: Expect::Ack
            }]
        );
        assert_eq!(
            d.parse_reply(&CentrifugeRequest::ReadRate, "RATE 30.5"),
            Ok(CentrifugeReply::RateDegS(183.0))
        );
        assert_eq!(
            d.parse_reply(&CentrifugeRequest::ReadInterlocks, "ILK 1"),
            Ok(CentrifugeReply::Interlocks(true))
        );
        assert_eq!(d.check_ack("OK"), Ok(()));
        assert_eq!(
            d.check_ack("ERR overspeed"),
            Err(DialectReplyError::Refused("overspeed".into()))
        );
        assert!(matches!(
            d.check_ack("what?"),
            Err(DialectReplyError::Garbled(_))
        ));
        assert!(d.exchanges(&CentrifugeRequest::ResetInterlocks).is_empty());
    }

    #[test]
    fn bad_dialect_configs_name_the_key() {
        let base: LineDialectConfig = toml::from_str(MNEMONIC_TOML).expect("toml");
        let mut c = base.clone();
        c.commands.set_rate = "JOG".into();
        assert!(
            LineDialect::new(c)
                .expect_err("no {rate}")
                .to_string()
                .contains("commands.set_rate")
        );
        let mut c = base.clone();
        c.replies.read_rate = "^RATE (.*)$".into();
        let e = LineDialect::new(c).expect_err("no group").to_string();
        assert!(
            e.contains("replies.read_rate: the pattern needs a named group (?P<rate>"),
            "{e}"
        );
        let mut c = base;
        c.replies.ack = Some("(".into());
        assert!(
            LineDialect::new(c)
                .expect_err("bad regex")
                .to_string()
                .contains("replies.ack: not a valid regular expression")
        );
        let unknown = MNEMONIC_TOML.replace("stop = \"STO\"", "stop = \"STO\"\nhalt = \"H\"");
        let e = toml::from_str::<LineDialectConfig>(&unknown)
            .expect_err("unknown key")
            .to_string();
        assert!(e.contains("halt"), "{e}");
    }
}
