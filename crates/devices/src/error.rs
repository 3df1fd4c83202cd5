use std::fmt;
use std::time::Duration;

/// What went wrong talking to a device.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DeviceErrorKind {
    /// No (complete) reply before the deadline, on every attempt.
    Timeout {
        /// The deadline of each attempt.
        waited: Duration,
        /// Attempts made.
        attempts: u32,
    },
    /// Replies came but never in the expected form.
    Garbled {
        /// The last reply received.
        reply: String,
        /// What was expected.
        expected: String,
        /// Attempts made.
        attempts: u32,
    },
    /// The device answered that it refused the command.
    Refused(String),
    /// The port or connection failed and could not be reopened.
    Io(String),
    /// A value the driver will not send (e.g. a rate above the configured limit).
    Rejected(String),
}

/// A failed device operation, naming the device and the command.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub struct DeviceError {
    /// The device, e.g. "centrifuge (ACUTROL at 10.0.0.5:9878)".
    pub device: String,
    /// The command or operation, e.g. ":READ:RATE? 1".
    pub command: String,
    /// What happened.
    pub kind: DeviceErrorKind,
}

impl fmt::Display for DeviceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: '{}': ", self.device, self.command)?;
        match &self.kind {
            DeviceErrorKind::Timeout { waited, attempts } => write!(
                f,
                "no reply within {} ms ({attempts} attempt(s)); check the cable, the port settings and that the device is on",
                waited.as_millis()
            ),
            DeviceErrorKind::Garbled {
                reply,
                expected,
                attempts,
            } => write!(
                f,
                "garbled reply '{}' ({attempts} attempt(s)): expected {expected}; check the baud rate and the dialect",
                reply.escape_debug()
            ),
            DeviceErrorKind::Refused(why) => write!(f, "refused by the device: {why}"),
            DeviceErrorKind::Io(why) => {
                write!(f, "connection failed and could not be reopened: {why}")
            }
            DeviceErrorKind::Rejected(why) => write!(f, "not sent: {why}"),
        }
    }
}
