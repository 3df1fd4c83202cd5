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

use crate::scpi::ReplyError;
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

mod acutrol;
mod line;
#[cfg(test)]
mod tests;

pub use acutrol::{AcutrolDialect, acutrol_headers};
pub use line::{
    CommandTemplates, DialectConfigError, LineDialect, LineDialectConfig, RateUnit, ReplyPatterns,
};
