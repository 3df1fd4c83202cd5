//! Line-oriented request/reply over a transport, with a deadline on every
//! call, retries of lost or garbled replies, and reconnection of a port
//! that disappeared. The centrifuge and power-supply drivers are built on it.

use crate::error::{DeviceError, DeviceErrorKind};
use crate::transport::Transport;
use serde::Deserialize;
use std::io;
use std::time::{Duration, Instant};

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
/// `TimeoutStopSec=90`, issue 27 item 2), so one command may not take
/// longer than this.
pub const MAX_COMMAND_MS: u64 = 10_000;

impl IoPolicy {
    /// Check the deadline and the retries against their bounds; the error
    /// names the key under `section`.
    pub fn validate(&self, section: &str) -> Result<(), crate::config::ConfigError> {
        if !(1..=MAX_TIMEOUT_MS).contains(&self.timeout_ms) {
            return Err(crate::config::ConfigError {
                key: format!("{section}.io.timeout_ms"),
                problem: format!(
                    "{} ms is outside 1 to {MAX_TIMEOUT_MS} ms (MAX_TIMEOUT_MS)",
                    self.timeout_ms
                ),
            });
        }
        if self.retries > MAX_RETRIES {
            return Err(crate::config::ConfigError {
                key: format!("{section}.io.retries"),
                problem: format!("{} is above {MAX_RETRIES} (MAX_RETRIES)", self.retries),
            });
        }
        let command_ms = self.timeout_ms * (u64::from(self.retries) + 1);
        if command_ms > MAX_COMMAND_MS {
            return Err(crate::config::ConfigError {
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

/// Longest reply line accepted; a longer one is garbage.
const MAX_LINE: usize = 4096;

/// Why one attempt failed.
enum AttemptError {
    Timeout,
    Garbled { reply: String, expected: String },
    Refused(String),
    Io(io::Error),
}

/// A line channel to one device.
pub struct LineChannel<T: Transport> {
    transport: T,
    device: String,
    ending: Vec<u8>,
    policy: IoPolicy,
    /// Bytes read past the last line.
    pending: Vec<u8>,
}

impl<T: Transport> LineChannel<T> {
    /// A channel to `device` (named in errors) whose lines end in `ending`.
    pub fn new(transport: T, device: impl Into<String>, ending: &str, policy: IoPolicy) -> Self {
        let device = format!("{} ({})", device.into(), transport.describe());
        LineChannel {
            transport,
            device,
            ending: ending.as_bytes().to_vec(),
            policy,
            pending: Vec::new(),
        }
    }

    /// The device's name in messages.
    pub fn device(&self) -> &str {
        &self.device
    }

    fn error(&self, command: &str, kind: DeviceErrorKind) -> DeviceError {
        DeviceError {
            device: self.device.clone(),
            command: command.to_string(),
            kind,
        }
    }

    /// Send a line that has no reply. I/O failures reopen the port and retry.
    pub fn send(&mut self, line: &str) -> Result<(), DeviceError> {
        self.exchange(line, None::<fn(&str) -> Result<(), (String, bool)>>)
            .map(|_| ())
    }

    /// Send a line and parse its one-line reply with `parse`, which returns
    /// `Err((expected, refused))`: a refusal is final, anything else is
    /// garbled and retried like a timeout.
    pub fn query<R>(
        &mut self,
        line: &str,
        parse: impl Fn(&str) -> Result<R, (String, bool)>,
    ) -> Result<R, DeviceError> {
        match self.exchange(line, Some(parse))? {
            Some(r) => Ok(r),
            // `exchange` with a parser returns a value on success; never reached.
            None => Err(self.error(line, DeviceErrorKind::Io("no reply value".into()))),
        }
    }

    fn exchange<R>(
        &mut self,
        line: &str,
        parse: Option<impl Fn(&str) -> Result<R, (String, bool)>>,
    ) -> Result<Option<R>, DeviceError> {
        let attempts = self.policy.retries + 1;
        let mut last = AttemptError::Timeout;
        for attempt in 1..=attempts {
            if attempt > 1 {
                // A late reply to the failed attempt must not answer this one.
                self.pending.clear();
                if let AttemptError::Io(_) = last {
                    if let Err(e) = self.transport.reopen() {
                        last = AttemptError::Io(e);
                        continue;
                    }
                } else {
                    let _ = self.transport.discard_input();
                }
            }
            match self.attempt(line, parse.as_ref()) {
                Ok(r) => return Ok(r),
                Err(AttemptError::Refused(why)) => {
                    return Err(self.error(line, DeviceErrorKind::Refused(why)));
                }
                Err(e) => last = e,
            }
        }
        Err(self.error(
            line,
            match last {
                AttemptError::Timeout => DeviceErrorKind::Timeout {
                    waited: self.policy.timeout(),
                    attempts,
                },
                AttemptError::Garbled { reply, expected } => DeviceErrorKind::Garbled {
                    reply,
                    expected,
                    attempts,
                },
                AttemptError::Refused(why) => DeviceErrorKind::Refused(why),
                AttemptError::Io(e) => DeviceErrorKind::Io(e.to_string()),
            },
        ))
    }

    fn attempt<R>(
        &mut self,
        line: &str,
        parse: Option<&impl Fn(&str) -> Result<R, (String, bool)>>,
    ) -> Result<Option<R>, AttemptError> {
        let deadline = Instant::now() + self.policy.timeout();
        let mut bytes = line.as_bytes().to_vec();
        bytes.extend_from_slice(&self.ending);
        self.transport
            .write_all(&bytes, deadline)
            .map_err(io_or_timeout)?;
        let Some(parse) = parse else {
            return Ok(None);
        };
        let reply = self.read_line(deadline)?;
        match parse(&reply) {
            Ok(r) => Ok(Some(r)),
            Err((why, true)) => Err(AttemptError::Refused(why)),
            Err((expected, false)) => Err(AttemptError::Garbled { reply, expected }),
        }
    }

    fn read_line(&mut self, deadline: Instant) -> Result<String, AttemptError> {
        let mut buf = [0u8; 256];
        loop {
            if let Some(at) = find(&self.pending, &self.ending) {
                let line: Vec<u8> = self
                    .pending
                    .drain(..at + self.ending.len())
                    .take(at)
                    .collect();
                return Ok(String::from_utf8_lossy(&line).into_owned());
            }
            if self.pending.len() > MAX_LINE {
                let reply = String::from_utf8_lossy(&self.pending[..64]).into_owned();
                self.pending.clear();
                return Err(AttemptError::Garbled {
                    reply,
                    expected: format!("a line of at most {MAX_LINE} bytes"),
                });
            }
            let n = self
                .transport
                .read(&mut buf, deadline)
                .map_err(io_or_timeout)?;
            self.pending.extend_from_slice(&buf[..n]);
        }
    }
}

fn io_or_timeout(e: io::Error) -> AttemptError {
    match e.kind() {
        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock => AttemptError::Timeout,
        _ => AttemptError::Io(e),
    }
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    if needle.is_empty() {
        return None;
    }
    haystack.windows(needle.len()).position(|w| w == needle)
}
