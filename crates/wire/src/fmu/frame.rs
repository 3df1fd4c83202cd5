//! Frame codec: an incremental decoder fed byte chunks of any size, and the
//! encoder for the other direction.
//!
//! The decoder keeps the bytes it has not yet decided on in a buffer. At a
//! header candidate (`55 AA`) it waits until the whole frame (by its LEN) is
//! there, then checks the CRC and the tail. A valid frame is emitted and its
//! bytes consumed; an invalid one is counted and only its first byte is
//! dropped, so the scan resumes at the very next byte: a valid frame that
//! starts inside the rejected span (after a false header in data, or after
//! a corrupted LEN) is still found. The wait is bounded by the largest frame
//! (262 bytes), so no input makes the decoder stall or grow without bound.

use crc::{CRC_16_MODBUS, Crc, Table};

/// Frame header bytes.
pub const HEADER: [u8; 2] = [0x55, 0xAA];
/// Frame tail byte.
pub const TAIL: u8 = 0xFF;
/// Largest DATA length (LEN is one byte).
pub const MAX_DATA_LEN: usize = 255;
/// Bytes around DATA: header 2, LEN 1, CMD 1, CRC 2, tail 1.
const OVERHEAD: usize = 7;
/// Largest frame on the wire.
pub const MAX_FRAME_LEN: usize = MAX_DATA_LEN + OVERHEAD;

/// CRC-16/MODBUS, slice-by-16 tables for speed.
const CRC: Crc<u16, Table<16>> = Crc::<u16, Table<16>>::new(&CRC_16_MODBUS);

/// CRC-16/MODBUS of `bytes` (check value of "123456789" is 0x4B37).
pub fn crc16_modbus(bytes: &[u8]) -> u16 {
    CRC.checksum(bytes)
}

/// A decoded frame that borrows its DATA from the decoder's buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameRef<'a> {
    /// What DATA holds.
    pub cmd: u8,
    /// The payload.
    pub data: &'a [u8],
}

impl FrameRef<'_> {
    /// An owned copy.
    pub fn to_frame(&self) -> Frame {
        Frame {
            cmd: self.cmd,
            data: self.data.to_vec(),
        }
    }
}

/// An owned frame.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Frame {
    /// What DATA holds.
    pub cmd: u8,
    /// The payload (at most 255 bytes).
    pub data: Vec<u8>,
}

impl Frame {
    /// A borrowed view.
    pub fn as_ref(&self) -> FrameRef<'_> {
        FrameRef {
            cmd: self.cmd,
            data: &self.data,
        }
    }
}

/// Append the frame for `cmd` and `data` to `out`.
///
/// Returns an error naming the length if `data` is longer than 255 bytes.
pub fn encode_frame(cmd: u8, data: &[u8], out: &mut Vec<u8>) -> Result<(), FrameTooLong> {
    let len = u8::try_from(data.len()).map_err(|_| FrameTooLong(data.len()))?;
    let start = out.len();
    out.extend_from_slice(&HEADER);
    out.push(len);
    out.push(cmd);
    out.extend_from_slice(data);
    let crc = crc16_modbus(&out[start..]);
    out.extend_from_slice(&crc.to_le_bytes());
    out.push(TAIL);
    Ok(())
}

/// A payload longer than a frame can carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("frame DATA of {0} bytes is longer than the 255 a frame can carry")]
pub struct FrameTooLong(pub usize);

/// Encodes frames into a reusable buffer (the PC → FMU direction, and the
/// simulator's FMU → PC direction).
#[derive(Debug, Default, Clone)]
pub struct FrameEncoder {
    buffer: Vec<u8>,
}

impl FrameEncoder {
    /// A new encoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Encode one frame and return its bytes (valid until the next call).
    pub fn encode(&mut self, cmd: u8, data: &[u8]) -> Result<&[u8], FrameTooLong> {
        self.buffer.clear();
        encode_frame(cmd, data, &mut self.buffer)?;
        Ok(&self.buffer)
    }
}

/// What the decoder has seen. Every byte fed is accounted for:
/// `bytes_in = frame_bytes + bytes_skipped + pending`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DecoderStats {
    /// Bytes fed in.
    pub bytes_in: u64,
    /// Valid frames decoded.
    pub frames: u64,
    /// Bytes that were part of valid frames.
    pub frame_bytes: u64,
    /// Header candidates rejected for a bad CRC.
    pub bad_crc: u64,
    /// Header candidates with a good CRC but no 0xFF tail.
    pub bad_tail: u64,
    /// Bytes dropped outside any valid frame (noise, resynchronisation,
    /// first bytes of rejected candidates, an incomplete frame at `finish`).
    pub bytes_skipped: u64,
}

/// The incremental frame decoder (a state machine over a small buffer).
///
/// Feed bytes with [`push`](Self::push), take frames with
/// [`next_frame`](Self::next_frame) until it returns `None`, repeat. At the
/// end of a stream, [`finish`](Self::finish) decides the bytes still held.
#[derive(Debug, Clone, Default)]
pub struct FrameDecoder {
    buffer: Vec<u8>,
    /// Start of the undecided bytes in `buffer`.
    pos: usize,
    /// At end of stream: incomplete candidates are dropped instead of awaited.
    finishing: bool,
    stats: DecoderStats,
}

impl FrameDecoder {
    /// A new decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// The counters so far.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Bytes held while waiting for the rest of a frame.
    pub fn pending(&self) -> usize {
        self.buffer.len() - self.pos
    }

    /// Feed a chunk of received bytes (any size, frames split anywhere).
    pub fn push(&mut self, chunk: &[u8]) {
        // Drop consumed bytes before growing, so the buffer stays near one frame.
        if self.pos > 0 {
            self.buffer.drain(..self.pos);
            self.pos = 0;
        }
        self.buffer.extend_from_slice(chunk);
        self.stats.bytes_in += chunk.len() as u64;
        self.finishing = false;
    }

    /// Mark the end of the stream: frames still complete in the buffer are
    /// returned by [`next_frame`](Self::next_frame), an incomplete tail is
    /// skipped (and counted) instead of awaited.
    pub fn finish(&mut self) {
        self.finishing = true;
    }

    /// The next valid frame in the bytes fed so far, if any.
    pub fn next_frame(&mut self) -> Option<FrameRef<'_>> {
        loop {
            let rest = &self.buffer[self.pos..];
            // Find the next header; everything before it is noise.
            let Some(at) = find_header(rest) else {
                // Keep a trailing 0x55: it may be the first half of a header.
                let keep = usize::from(rest.last() == Some(&HEADER[0]) && !self.finishing);
                let drop = rest.len() - keep;
                self.skip(drop);
                return None;
            };
            self.skip(at);
            let rest = &self.buffer[self.pos..];
            if rest.len() < 4 {
                if self.finishing {
                    self.skip(rest.len());
                }
                return None;
            }
            let len = usize::from(rest[2]);
            let total = len + OVERHEAD;
            if rest.len() < total {
                if self.finishing {
                    // This candidate can never complete; look past its first byte.
                    self.reject_first_byte();
                    continue;
                }
                return None;
            }
            let body = &rest[..4 + len];
            let crc = u16::from_le_bytes([rest[4 + len], rest[5 + len]]);
            if crc16_modbus(body) != crc {
                self.stats.bad_crc += 1;
                self.reject_first_byte();
                continue;
            }
            if rest[6 + len] != TAIL {
                self.stats.bad_tail += 1;
                self.reject_first_byte();
                continue;
            }
            let start = self.pos;
            self.pos += total;
            self.stats.frames += 1;
            self.stats.frame_bytes += total as u64;
            return Some(FrameRef {
                cmd: self.buffer[start + 3],
                data: &self.buffer[start + 4..start + 4 + len],
            });
        }
    }

    /// Decode everything in `chunk`, calling `on_frame` for each valid frame.
    pub fn decode(&mut self, chunk: &[u8], mut on_frame: impl FnMut(FrameRef<'_>)) {
        self.push(chunk);
        while let Some(frame) = self.next_frame() {
            on_frame(frame);
        }
    }

    fn skip(&mut self, n: usize) {
        self.pos += n;
        self.stats.bytes_skipped += n as u64;
    }

    fn reject_first_byte(&mut self) {
        self.skip(1);
    }
}

/// Position of the first `55 AA` in `bytes`.
fn find_header(bytes: &[u8]) -> Option<usize> {
    let mut from = 0;
    while let Some(i) = memchr::memchr(HEADER[0], &bytes[from..]) {
        let at = from + i;
        match bytes.get(at + 1) {
            Some(&b) if b == HEADER[1] => return Some(at),
            Some(_) => from = at + 1,
            // A 0x55 at the very end: may be a header's first half.
            None => return None,
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(cmd: u8, data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        encode_frame(cmd, data, &mut out).expect("fits");
        out
    }

    fn decode_all(decoder: &mut FrameDecoder, bytes: &[u8]) -> Vec<Frame> {
        let mut frames = Vec::new();
        decoder.decode(bytes, |f| frames.push(f.to_frame()));
        frames
    }

    #[test]
    fn crc_matches_the_modbus_check_values() {
        assert_eq!(crc16_modbus(b"123456789"), 0x4B37);
        // 01 03 00 00 00 0A → CRC 0xCDC5, sent C5 CD.
        assert_eq!(
            crc16_modbus(&[0x01, 0x03, 0x00, 0x00, 0x00, 0x0A]).to_le_bytes(),
            [0xC5, 0xCD]
        );
    }

    #[test]
    fn encodes_the_published_layout() {
        let bytes = frame(0x10, &[0b0000_0101]);
        assert_eq!(&bytes[..5], &[0x55, 0xAA, 1, 0x10, 0x05]);
        let crc = crc16_modbus(&bytes[..5]).to_le_bytes();
        assert_eq!(&bytes[5..7], &crc);
        assert_eq!(bytes[7], 0xFF);
        assert_eq!(bytes.len(), 8);
        let err = encode_frame(1, &[0; 256], &mut Vec::new()).expect_err("too long");
        assert_eq!(err, FrameTooLong(256));
    }

    #[test]
    fn decodes_byte_by_byte_and_whole() {
        let mut stream = frame(1, &[1, 2, 3]);
        stream.extend(frame(2, &[]));
        stream.extend(frame(3, &[0x55, 0xAA, 0xFF]));
        let want = vec![
            Frame {
                cmd: 1,
                data: vec![1, 2, 3],
            },
            Frame {
                cmd: 2,
                data: vec![],
            },
            Frame {
                cmd: 3,
                data: vec![0x55, 0xAA, 0xFF],
            },
        ];
        let mut whole = FrameDecoder::new();
        assert_eq!(decode_all(&mut whole, &stream), want);
        let mut single = FrameDecoder::new();
        let mut got = Vec::new();
        for b in &stream {
            got.extend(decode_all(&mut single, std::slice::from_ref(b)));
        }
        assert_eq!(got, want);
        assert_eq!(single.stats().bytes_skipped, 0);
        assert_eq!(single.pending(), 0);
    }

    #[test]
    fn a_false_header_in_noise_does_not_hide_the_next_frame() {
        // Noise holding a header whose LEN claims 200 bytes, then a real frame.
        let mut stream = vec![0x00, 0x55, 0xAA, 200, 0x01, 0x02];
        let real = frame(1, &[9, 9]);
        stream.extend(&real);
        let mut d = FrameDecoder::new();
        let got = decode_all(&mut d, &stream);
        assert!(got.is_empty(), "waits for the 200-byte candidate");
        d.finish();
        let got: Vec<Frame> = std::iter::from_fn(|| d.next_frame().map(|f| f.to_frame())).collect();
        assert_eq!(
            got,
            vec![Frame {
                cmd: 1,
                data: vec![9, 9]
            }]
        );
        let s = d.stats();
        assert_eq!(
            s.bytes_in,
            s.frame_bytes + s.bytes_skipped + d.pending() as u64
        );
    }

    #[test]
    fn bad_crc_and_bad_tail_are_counted_and_the_stream_recovers() {
        let good = frame(1, &[1, 2, 3, 4]);
        let mut bad_crc = good.clone();
        bad_crc[5] ^= 0x01;
        let mut bad_tail = good.clone();
        let last = bad_tail.len() - 1;
        bad_tail[last] = 0x00;
        let stream: Vec<u8> = [bad_crc, good.clone(), bad_tail, good].concat();
        let mut d = FrameDecoder::new();
        let got = decode_all(&mut d, &stream);
        assert_eq!(got.len(), 2);
        let s = d.stats();
        assert_eq!((s.frames, s.bad_crc, s.bad_tail), (2, 1, 1));
        assert_eq!(
            s.bytes_in,
            s.frame_bytes + s.bytes_skipped + d.pending() as u64
        );
    }
}
