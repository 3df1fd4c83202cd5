//! Any line-oriented controller, described entirely in the station config:
//! command templates, line ending, reply patterns and the rate unit.

use super::{
    CentrifugeDialect, CentrifugeReply, CentrifugeRequest, DialectReplyError, Exchange, Expect,
};
use crate::scpi::{self, ReplyError};
use regex::Regex;
use serde::Deserialize;

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
