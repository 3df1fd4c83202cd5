//! A scripted transport for driver tests (PyMeasure-style transcripts): the
//! expected writes and the replies, silences and disconnects, in order.
//! Time is virtual: a scripted silence is a timeout at once.
//!
//! The transcript is shared: keep a clone to check, after the driver ran,
//! that every step was used and no write differed ([`Transcript::verify`]).

use crate::transport::Transport;
use std::collections::VecDeque;
use std::io;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// One step of a transcript.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Step {
    /// The driver must write exactly these bytes (one or several writes).
    Write(Vec<u8>),
    /// These bytes arrive for the driver to read.
    Reply(Vec<u8>),
    /// The next read times out.
    Silence,
    /// The connection drops: the next call fails until the driver reopens.
    Disconnect,
    /// The driver must reopen the transport here.
    Reopen,
    /// The driver tries to reopen here and is refused (a controller
    /// rebooting: connection refused); the connection stays down.
    RefuseReopen,
}

impl Step {
    /// An expected write of a text line.
    pub fn write(text: &str) -> Step {
        Step::Write(text.as_bytes().to_vec())
    }

    /// A reply of a text line.
    pub fn reply(text: &str) -> Step {
        Step::Reply(text.as_bytes().to_vec())
    }
}

#[derive(Debug, Default)]
struct State {
    steps: VecDeque<Step>,
    disconnected: bool,
    mismatches: Vec<String>,
    discarded: usize,
}

/// A transport that follows a script.
#[derive(Debug, Clone, Default)]
pub struct Transcript {
    state: Arc<Mutex<State>>,
}

impl Transcript {
    /// A transcript of `steps`.
    pub fn new(steps: impl IntoIterator<Item = Step>) -> Transcript {
        Transcript {
            state: Arc::new(Mutex::new(State {
                steps: steps.into_iter().collect(),
                ..State::default()
            })),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        // A test that panicked while holding the lock has already failed.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Ok if every step was used and every write was as expected; else what differed.
    pub fn verify(&self) -> Result<(), NotFollowed> {
        let s = self.lock();
        if !s.mismatches.is_empty() {
            return Err(NotFollowed::Mismatched(s.mismatches.clone()));
        }
        if !s.steps.is_empty() {
            return Err(NotFollowed::Unused(format!("{:?}", s.steps)));
        }
        Ok(())
    }

    /// How many times the driver discarded pending input.
    pub fn discards(&self) -> usize {
        self.lock().discarded
    }
}

/// How a driver did not follow its transcript.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NotFollowed {
    /// Writes that differed from the transcript's, one line each.
    #[error("{}", .0.join("\n"))]
    Mismatched(Vec<String>),
    /// Steps the driver never reached (listed).
    #[error("step(s) not used: {0}")]
    Unused(String),
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).escape_debug().to_string()
}

impl Transport for Transcript {
    fn describe(&self) -> String {
        "transcript".into()
    }

    fn write_all(&mut self, bytes: &[u8], _deadline: Instant) -> io::Result<()> {
        let mut s = self.lock();
        if s.disconnected {
            return Err(io::Error::new(io::ErrorKind::BrokenPipe, "disconnected"));
        }
        if s.steps.front() == Some(&Step::Disconnect) {
            s.steps.pop_front();
            s.disconnected = true;
            return Err(io::Error::new(io::ErrorKind::BrokenPipe, "disconnected"));
        }
        match s.steps.pop_front() {
            Some(Step::Write(expected)) if expected.starts_with(bytes) => {
                // A write may be split; keep the rest expected.
                if expected.len() > bytes.len() {
                    s.steps
                        .push_front(Step::Write(expected[bytes.len()..].to_vec()));
                }
                Ok(())
            }
            Some(Step::Write(expected)) => {
                let m = format!(
                    "expected write '{}', got '{}'",
                    text(&expected),
                    text(bytes)
                );
                s.mismatches.push(m.clone());
                Err(io::Error::other(m))
            }
            other => {
                let m = format!("unexpected write '{}' at step {other:?}", text(bytes));
                s.mismatches.push(m.clone());
                Err(io::Error::other(m))
            }
        }
    }

    fn read(&mut self, buf: &mut [u8], _deadline: Instant) -> io::Result<usize> {
        let mut s = self.lock();
        if s.disconnected {
            return Err(io::Error::new(io::ErrorKind::BrokenPipe, "disconnected"));
        }
        match s.steps.pop_front() {
            Some(Step::Reply(bytes)) => {
                let n = bytes.len().min(buf.len());
                buf[..n].copy_from_slice(&bytes[..n]);
                if n < bytes.len() {
                    s.steps.push_front(Step::Reply(bytes[n..].to_vec()));
                }
                Ok(n)
            }
            Some(Step::Silence) => Err(io::Error::new(io::ErrorKind::TimedOut, "scripted silence")),
            Some(Step::Disconnect) => {
                s.disconnected = true;
                Err(io::Error::new(io::ErrorKind::BrokenPipe, "disconnected"))
            }
            Some(other) => {
                // Nothing to read here: the driver waited while the script expected something else.
                s.steps.push_front(other);
                Err(io::Error::new(
                    io::ErrorKind::TimedOut,
                    "nothing scripted to read",
                ))
            }
            None => Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "transcript finished",
            )),
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.lock().discarded += 1;
        Ok(())
    }

    fn reopen(&mut self) -> io::Result<()> {
        let mut s = self.lock();
        match s.steps.front() {
            Some(Step::Reopen) => {
                s.steps.pop_front();
                s.disconnected = false;
                Ok(())
            }
            Some(Step::RefuseReopen) => {
                s.steps.pop_front();
                s.disconnected = true;
                Err(io::Error::new(
                    io::ErrorKind::ConnectionRefused,
                    "connection refused (scripted)",
                ))
            }
            other => {
                let m = format!("unexpected reopen at step {other:?}");
                s.mismatches.push(m.clone());
                Err(io::Error::other(m))
            }
        }
    }
}
