//! Line-oriented request/reply over a transport, with a deadline on every
//! call, retries of lost or garbled replies, and reconnection of a port
//! that disappeared. The centrifuge and power-supply drivers are built on it.

use crate::error::{DeviceError, DeviceErrorKind};
use crate::transport::Transport;
use std::io;
use std::time::Instant;

pub use crate::config::{IoPolicy, MAX_COMMAND_MS, MAX_RETRIES, MAX_TIMEOUT_MS};

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
