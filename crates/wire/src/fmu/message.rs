//! Typed FMU payloads (all integers little-endian).
//!
//! | CMD | direction | DATA |
//! |---|---|---|
//! | 0x01 gated counts | FMU→PC | `seq u16`, `status u8`, per input `count u16` |
//! | 0x02 temperatures | FMU→PC | `seq u16`, per instrument `i16` in 0.01 °C |
//! | 0x03 reciprocal counts | FMU→PC | `seq u16`, `status u8`, per input `periods u16`, `span u32` |
//! | 0x10 set power | PC→FMU | `mask u8` (bit i powers instrument i) |
//! | 0x11 start streaming | PC→FMU | `mode u8` (1 gated, 3 reciprocal) |
//! | 0x12 stop streaming | PC→FMU | empty |
//! | 0x20 ack | FMU→PC | echoed `cmd u8`, `result u8` (0 ok) |
//! | 0x21 status | both | request: empty; reply: `firmware_id u16`, `relay_mask u8`, `rx_crc_errors u16`, `rx_tail_errors u16`, `overruns u16` |

use super::frame::{FrameRef, FrameTooLong, encode_frame};

/// Frame CMD values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Command {
    /// Gated edge counts per input per tick.
    GatedCounts = 0x01,
    /// Instrument temperatures.
    Temperatures = 0x02,
    /// Reciprocal counts (periods and reference-clock span) per input per tick.
    ReciprocalCounts = 0x03,
    /// Set the relay mask.
    SetPower = 0x10,
    /// Start streaming in a mode.
    StartStreaming = 0x11,
    /// Stop streaming.
    StopStreaming = 0x12,
    /// Acknowledge a command.
    Ack = 0x20,
    /// Status request (empty) or reply.
    Status = 0x21,
}

impl Command {
    /// The command for a CMD byte.
    pub fn from_byte(byte: u8) -> Option<Command> {
        Some(match byte {
            0x01 => Command::GatedCounts,
            0x02 => Command::Temperatures,
            0x03 => Command::ReciprocalCounts,
            0x10 => Command::SetPower,
            0x11 => Command::StartStreaming,
            0x12 => Command::StopStreaming,
            0x20 => Command::Ack,
            0x21 => Command::Status,
            _ => return None,
        })
    }
}

/// Counting mode of a stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StreamMode {
    /// Edge counts in each 2.5 ms gate (the published design).
    Gated,
    /// Whole periods and the reference-clock span covering them.
    Reciprocal,
}

impl StreamMode {
    /// The mode byte of a start-streaming command (1 gated, 3 reciprocal).
    pub fn byte(self) -> u8 {
        match self {
            StreamMode::Gated => 1,
            StreamMode::Reciprocal => 3,
        }
    }

    /// The mode for a mode byte.
    pub fn from_byte(byte: u8) -> Option<StreamMode> {
        match byte {
            1 => Some(StreamMode::Gated),
            3 => Some(StreamMode::Reciprocal),
            _ => None,
        }
    }
}

/// One input's reciprocal count in one tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ReciprocalCount {
    /// Whole signal periods completed in the tick.
    pub periods: u16,
    /// Reference-clock ticks spanning exactly those periods.
    pub span: u32,
}

/// The FMU's status reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct StatusReply {
    /// Firmware identifier.
    pub firmware_id: u16,
    /// Relays currently closed (bit i = instrument i powered).
    pub relay_mask: u8,
    /// Frames the module received with a bad CRC.
    pub rx_crc_errors: u16,
    /// Frames the module received with a bad tail.
    pub rx_tail_errors: u16,
    /// Ticks the module could not send (its transmit buffer overran).
    pub overruns: u16,
}

/// A decoded FMU message.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Message {
    /// 0x01: gated counts of every input in one tick.
    GatedCounts {
        /// Tick sequence number (wraps at 65536).
        seq: u16,
        /// Module status flags (0 = all well).
        status: u8,
        /// Edge count per input.
        counts: Vec<u16>,
    },
    /// 0x02: temperatures.
    Temperatures {
        /// Sequence number.
        seq: u16,
        /// Per instrument, in 0.01 °C.
        centi_celsius: Vec<i16>,
    },
    /// 0x03: reciprocal counts of every input in one tick.
    ReciprocalCounts {
        /// Tick sequence number (wraps at 65536).
        seq: u16,
        /// Module status flags (0 = all well).
        status: u8,
        /// Per input.
        inputs: Vec<ReciprocalCount>,
    },
    /// 0x10: power the instruments whose bits are set.
    SetPower {
        /// Relay mask.
        mask: u8,
    },
    /// 0x11: start streaming.
    StartStreaming {
        /// Counting mode.
        mode: StreamMode,
    },
    /// 0x12: stop streaming.
    StopStreaming,
    /// 0x20: acknowledgement.
    Ack {
        /// The CMD acknowledged.
        cmd: u8,
        /// 0 ok, else an error code.
        result: u8,
    },
    /// 0x21 with empty DATA: status request.
    StatusRequest,
    /// 0x21 with DATA: status reply.
    Status(StatusReply),
}

/// A frame whose DATA does not fit its CMD.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("FMU frame CMD 0x{cmd:02X} ({name}): {problem}")]
pub struct PayloadError {
    /// The frame's CMD byte.
    pub cmd: u8,
    /// The command's name.
    pub name: &'static str,
    /// What is wrong.
    pub problem: String,
}

fn u16_at(d: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([d[i], d[i + 1]])
}

impl Message {
    /// Decode a frame's payload.
    pub fn decode(frame: FrameRef<'_>) -> Result<Message, PayloadError> {
        let d = frame.data;
        let err = |name: &'static str, problem: String| PayloadError {
            cmd: frame.cmd,
            name,
            problem,
        };
        let exact = |name: &'static str, n: usize| {
            if d.len() == n {
                Ok(())
            } else {
                Err(err(
                    name,
                    format!("DATA is {} bytes, expected {n}", d.len()),
                ))
            }
        };
        let Some(command) = Command::from_byte(frame.cmd) else {
            return Err(err("unknown", "not a command of this protocol".into()));
        };
        Ok(match command {
            Command::GatedCounts => {
                let name = "gated counts";
                if d.len() < 3 || !(d.len() - 3).is_multiple_of(2) {
                    return Err(err(
                        name,
                        format!("DATA is {} bytes, expected 3 + 2·inputs", d.len()),
                    ));
                }
                Message::GatedCounts {
                    seq: u16_at(d, 0),
                    status: d[2],
                    counts: d[3..]
                        .chunks_exact(2)
                        .map(|c| u16::from_le_bytes([c[0], c[1]]))
                        .collect(),
                }
            }
            Command::Temperatures => {
                let name = "temperatures";
                if d.len() < 2 || !d.len().is_multiple_of(2) {
                    return Err(err(
                        name,
                        format!("DATA is {} bytes, expected 2 + 2·instruments", d.len()),
                    ));
                }
                Message::Temperatures {
                    seq: u16_at(d, 0),
                    centi_celsius: d[2..]
                        .chunks_exact(2)
                        .map(|c| i16::from_le_bytes([c[0], c[1]]))
                        .collect(),
                }
            }
            Command::ReciprocalCounts => {
                let name = "reciprocal counts";
                if d.len() < 3 || !(d.len() - 3).is_multiple_of(6) {
                    return Err(err(
                        name,
                        format!("DATA is {} bytes, expected 3 + 6·inputs", d.len()),
                    ));
                }
                Message::ReciprocalCounts {
                    seq: u16_at(d, 0),
                    status: d[2],
                    inputs: d[3..]
                        .chunks_exact(6)
                        .map(|c| ReciprocalCount {
                            periods: u16::from_le_bytes([c[0], c[1]]),
                            span: u32::from_le_bytes([c[2], c[3], c[4], c[5]]),
                        })
                        .collect(),
                }
            }
            Command::SetPower => {
                exact("set power", 1)?;
                Message::SetPower { mask: d[0] }
            }
            Command::StartStreaming => {
                let name = "start streaming";
                exact(name, 1)?;
                let mode = StreamMode::from_byte(d[0]).ok_or_else(|| {
                    err(
                        name,
                        format!("mode {} is not 1 (gated) or 3 (reciprocal)", d[0]),
                    )
                })?;
                Message::StartStreaming { mode }
            }
            Command::StopStreaming => {
                exact("stop streaming", 0)?;
                Message::StopStreaming
            }
            Command::Ack => {
                exact("ack", 2)?;
                Message::Ack {
                    cmd: d[0],
                    result: d[1],
                }
            }
            Command::Status => match d.len() {
                0 => Message::StatusRequest,
                9 => Message::Status(StatusReply {
                    firmware_id: u16_at(d, 0),
                    relay_mask: d[2],
                    rx_crc_errors: u16_at(d, 3),
                    rx_tail_errors: u16_at(d, 5),
                    overruns: u16_at(d, 7),
                }),
                n => {
                    return Err(err(
                        "status",
                        format!("DATA is {n} bytes, expected 0 (request) or 9 (reply)"),
                    ));
                }
            },
        })
    }

    /// The CMD byte of this message.
    pub fn command(&self) -> Command {
        match self {
            Message::GatedCounts { .. } => Command::GatedCounts,
            Message::Temperatures { .. } => Command::Temperatures,
            Message::ReciprocalCounts { .. } => Command::ReciprocalCounts,
            Message::SetPower { .. } => Command::SetPower,
            Message::StartStreaming { .. } => Command::StartStreaming,
            Message::StopStreaming => Command::StopStreaming,
            Message::Ack { .. } => Command::Ack,
            Message::StatusRequest | Message::Status(_) => Command::Status,
        }
    }

    /// The DATA bytes of this message.
    pub fn payload(&self) -> Vec<u8> {
        let mut d = Vec::new();
        match self {
            Message::GatedCounts {
                seq,
                status,
                counts,
            } => {
                d.extend(seq.to_le_bytes());
                d.push(*status);
                counts.iter().for_each(|c| d.extend(c.to_le_bytes()));
            }
            Message::Temperatures { seq, centi_celsius } => {
                d.extend(seq.to_le_bytes());
                centi_celsius.iter().for_each(|t| d.extend(t.to_le_bytes()));
            }
            Message::ReciprocalCounts {
                seq,
                status,
                inputs,
            } => {
                d.extend(seq.to_le_bytes());
                d.push(*status);
                for i in inputs {
                    d.extend(i.periods.to_le_bytes());
                    d.extend(i.span.to_le_bytes());
                }
            }
            Message::SetPower { mask } => d.push(*mask),
            Message::StartStreaming { mode } => d.push(mode.byte()),
            Message::StopStreaming | Message::StatusRequest => {}
            Message::Ack { cmd, result } => d.extend([*cmd, *result]),
            Message::Status(s) => {
                d.extend(s.firmware_id.to_le_bytes());
                d.push(s.relay_mask);
                d.extend(s.rx_crc_errors.to_le_bytes());
                d.extend(s.rx_tail_errors.to_le_bytes());
                d.extend(s.overruns.to_le_bytes());
            }
        }
        d
    }

    /// Append this message's frame to `out` (fails only if the payload exceeds 255 bytes,
    /// e.g. more than 84 gated inputs).
    pub fn encode(&self, out: &mut Vec<u8>) -> Result<(), FrameTooLong> {
        encode_frame(self.command() as u8, &self.payload(), out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmu::FrameDecoder;

    #[test]
    fn every_message_round_trips_through_a_frame() {
        let messages = vec![
            Message::GatedCounts {
                seq: 65535,
                status: 0,
                counts: (0..12).map(|i| 70 + i).collect(),
            },
            Message::Temperatures {
                seq: 7,
                centi_celsius: vec![2512, -1050, 0, 3000, 2999, 1],
            },
            Message::ReciprocalCounts {
                seq: 3,
                status: 2,
                inputs: (0..12)
                    .map(|i| ReciprocalCount {
                        periods: 75 + i,
                        span: 250_000 + u32::from(i),
                    })
                    .collect(),
            },
            Message::SetPower { mask: 0b10_1010 },
            Message::StartStreaming {
                mode: StreamMode::Reciprocal,
            },
            Message::StopStreaming,
            Message::Ack {
                cmd: 0x10,
                result: 0,
            },
            Message::StatusRequest,
            Message::Status(StatusReply {
                firmware_id: 0x0102,
                relay_mask: 0x3F,
                rx_crc_errors: 1,
                rx_tail_errors: 2,
                overruns: 3,
            }),
        ];
        let mut bytes = Vec::new();
        for m in &messages {
            m.encode(&mut bytes).expect("fits");
        }
        let mut decoder = FrameDecoder::new();
        let mut back = Vec::new();
        decoder.decode(&bytes, |f| {
            back.push(Message::decode(f).expect("valid payload"))
        });
        assert_eq!(back, messages);
    }

    #[test]
    fn malformed_payloads_are_named() {
        let cases: [(u8, &[u8], &str); 5] = [
            (0x01, &[0, 0, 0, 1], "gated counts"),
            (0x03, &[0, 0, 0, 1, 2, 3], "3 + 6·inputs"),
            (0x11, &[2], "mode 2"),
            (0x21, &[1, 2], "0 (request) or 9 (reply)"),
            (0x7E, &[], "not a command"),
        ];
        for (cmd, data, want) in cases {
            let e = Message::decode(FrameRef { cmd, data }).expect_err("malformed");
            assert!(e.to_string().contains(want), "{e}");
        }
    }
}
