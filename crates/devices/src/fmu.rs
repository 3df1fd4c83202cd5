//! The `CounterModule` trait and the FMU driver (method.md §3.1) over a
//! serial line (RS-422) or any transport.
//!
//! Commands are answered by an ack (or a status reply) on the same line the
//! counts stream on; frames that arrive while the driver waits for an ack
//! are queued for [`CounterModule::receive`], never dropped.

use crate::error::{DeviceError, DeviceErrorKind};
use crate::line::IoPolicy;
use crate::transport::Transport;
use spinbench_wire::fmu::{DecoderStats, FrameDecoder, Message, StatusReply, StreamMode};
use std::collections::VecDeque;
use std::io;
use std::time::Instant;

/// Counters of a module's link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// The frame decoder's counters (frames, bad CRC, bad tail, skipped bytes).
    pub decoder: DecoderStats,
    /// Frames with a valid CRC whose payload did not fit their CMD.
    pub payload_errors: u64,
    /// Times the port was reopened.
    pub reconnects: u64,
}

/// A frequency-measurement module reading up to 6 instruments.
pub trait CounterModule: Send {
    /// The module's status.
    fn status(&mut self) -> Result<StatusReply, DeviceError>;
    /// Power the instruments whose bits are set in `mask` (relays).
    fn set_power(&mut self, mask: u8) -> Result<(), DeviceError>;
    /// Start streaming counts in `mode`.
    fn start(&mut self, mode: StreamMode) -> Result<(), DeviceError>;
    /// Stop streaming.
    fn stop(&mut self) -> Result<(), DeviceError>;
    /// Stream messages received until `deadline` (returns as soon as some
    /// arrived; an empty vector means none before the deadline).
    fn receive(&mut self, deadline: Instant) -> Result<Vec<Message>, DeviceError>;
    /// The link's counters.
    fn link_stats(&self) -> LinkStats;

    /// Put every byte received so far into the raw capture's file, if the
    /// module's bytes are captured: the engine calls it before it publishes
    /// a second's values, so a killed process never leaves a stored value
    /// whose bytes are not in the capture.
    fn flush_capture(&mut self) {}
}

/// The FMU driver.
pub struct FmuDriver<T: Transport> {
    transport: T,
    device: String,
    policy: IoPolicy,
    decoder: FrameDecoder,
    queue: VecDeque<Message>,
    stats: LinkStats,
}

enum Wait {
    Ack(u8),
    Status,
}

impl<T: Transport> FmuDriver<T> {
    /// A driver for the module named `name`.
    pub fn new(transport: T, name: &str, policy: IoPolicy) -> Self {
        let device = format!("counter module '{name}' ({})", transport.describe());
        FmuDriver {
            transport,
            device,
            policy,
            decoder: FrameDecoder::new(),
            queue: VecDeque::new(),
            stats: LinkStats::default(),
        }
    }

    fn error(&self, command: &str, kind: DeviceErrorKind) -> DeviceError {
        DeviceError {
            device: self.device.clone(),
            command: command.to_string(),
            kind,
        }
    }

    /// Read and decode what arrives before `deadline`; returns the number of messages decoded.
    fn pump(&mut self, deadline: Instant) -> io::Result<usize> {
        let mut buf = [0u8; 4096];
        let n = self.transport.read(&mut buf, deadline)?;
        let mut decoded = 0;
        let mut payload_errors = 0;
        let queue = &mut self.queue;
        self.decoder
            .decode(&buf[..n], |frame| match Message::decode(frame) {
                Ok(m) => {
                    queue.push_back(m);
                    decoded += 1;
                }
                Err(_) => payload_errors += 1,
            });
        self.stats.payload_errors += payload_errors;
        self.stats.decoder = self.decoder.stats();
        Ok(decoded)
    }

    /// Send `message` and wait for its answer, retrying lost answers.
    fn command(
        &mut self,
        message: Message,
        wait: Wait,
    ) -> Result<Option<StatusReply>, DeviceError> {
        let name = format!("{:?}", message.command());
        let mut frame = Vec::new();
        message
            .encode(&mut frame)
            .map_err(|e| self.error(&name, DeviceErrorKind::Rejected(e.to_string())))?;
        let attempts = self.policy.retries + 1;
        let mut last_io: Option<io::Error> = None;
        for attempt in 1..=attempts {
            if attempt > 1 && last_io.is_some() {
                if let Err(e) = self.transport.reopen() {
                    last_io = Some(e);
                    continue;
                }
                self.stats.reconnects += 1;
                last_io = None;
            }
            let deadline = Instant::now() + self.policy.timeout();
            if let Err(e) = self.transport.write_all(&frame, deadline) {
                if e.kind() != io::ErrorKind::TimedOut {
                    last_io = Some(e);
                }
                continue;
            }
            loop {
                // Look for the answer among what was decoded so far.
                let found = self.queue.iter().position(|m| match (&wait, m) {
                    (Wait::Ack(cmd), Message::Ack { cmd: c, .. }) => c == cmd,
                    (Wait::Status, Message::Status(_)) => true,
                    _ => false,
                });
                if let Some(i) = found {
                    return match self.queue.remove(i) {
                        Some(Message::Ack { result: 0, .. }) => Ok(None),
                        Some(Message::Ack { result, .. }) => Err(self.error(
                            &name,
                            DeviceErrorKind::Refused(format!(
                                "the module answered error code {result}"
                            )),
                        )),
                        Some(Message::Status(s)) => Ok(Some(s)),
                        _ => Ok(None),
                    };
                }
                match self.pump(deadline) {
                    Ok(_) => {}
                    Err(e) if e.kind() == io::ErrorKind::TimedOut => break,
                    Err(e) => {
                        last_io = Some(e);
                        break;
                    }
                }
            }
        }
        Err(self.error(
            &name,
            match last_io {
                Some(e) => DeviceErrorKind::Io(e.to_string()),
                None => DeviceErrorKind::Timeout {
                    waited: self.policy.timeout(),
                    attempts,
                },
            },
        ))
    }
}

impl<T: Transport> CounterModule for FmuDriver<T> {
    fn flush_capture(&mut self) {
        // A failed capture is recorded by the capture itself and never
        // stops the measurement (the store keeps the one-second values).
        let _ = self.transport.flush_capture();
    }

    fn status(&mut self) -> Result<StatusReply, DeviceError> {
        match self.command(Message::StatusRequest, Wait::Status)? {
            Some(s) => Ok(s),
            None => Err(self.error("Status", DeviceErrorKind::Io("no status reply".into()))),
        }
    }

    fn set_power(&mut self, mask: u8) -> Result<(), DeviceError> {
        self.command(Message::SetPower { mask }, Wait::Ack(0x10))
            .map(|_| ())
    }

    fn start(&mut self, mode: StreamMode) -> Result<(), DeviceError> {
        self.command(Message::StartStreaming { mode }, Wait::Ack(0x11))
            .map(|_| ())
    }

    fn stop(&mut self) -> Result<(), DeviceError> {
        self.command(Message::StopStreaming, Wait::Ack(0x12))
            .map(|_| ())
    }

    fn receive(&mut self, deadline: Instant) -> Result<Vec<Message>, DeviceError> {
        while self.queue.is_empty() {
            match self.pump(deadline) {
                Ok(_) => {}
                Err(e) if e.kind() == io::ErrorKind::TimedOut => break,
                Err(e) => {
                    // The port went away: reopen once; the caller's deadline bounds the wait.
                    self.transport.reopen().map_err(|r| {
                        self.error(
                            "receive",
                            DeviceErrorKind::Io(format!("{e}; reopen failed: {r}")),
                        )
                    })?;
                    self.stats.reconnects += 1;
                }
            }
        }
        Ok(self.queue.drain(..).collect())
    }

    fn link_stats(&self) -> LinkStats {
        self.stats
    }
}
