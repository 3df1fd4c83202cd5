//! The FMU protocol (method.md §3.1):
//! `55 AA | LEN | CMD | DATA[LEN] | CRC16/MODBUS (low byte first) | FF`.

mod frame;
mod line;
mod message;
mod window;

pub use frame::{
    DecoderStats, Frame, FrameDecoder, FrameEncoder, FrameRef, HEADER, MAX_DATA_LEN, MAX_FRAME_LEN,
    TAIL, crc16_modbus, encode_frame,
};
pub use line::{
    LineBudget, LineRateError, STANDARD_BAUDS, SerialFraming, check_line_rate, frame_len,
};
pub use message::{Command, Message, PayloadError, ReciprocalCount, StatusReply, StreamMode};
pub use window::{InstrumentValue, WindowAccumulator, WindowConfig, WindowValue};

/// Ticks per second: the FMU samples every 2.5 ms (method.md §3.3).
pub const TICKS_PER_SECOND: u32 = 400;

/// Instruments per counter module (method.md §3).
pub const INSTRUMENTS_PER_MODULE: usize = 6;

/// Inputs per module: two resonators per instrument.
pub const INPUTS_PER_MODULE: usize = 2 * INSTRUMENTS_PER_MODULE;

/// Default reference clock of reciprocal counting [Hz].
pub const DEFAULT_REFERENCE_HZ: f64 = 100e6;

/// The property the fuzz target checks, shared with the corpus replay test:
/// decode `input` (its first byte sets the chunk size), parse every frame's
/// payload, and panic if any byte is unaccounted for or a decoded frame does
/// not re-encode to the bytes it came from.
#[doc(hidden)]
pub fn fuzz_check_decoder(input: &[u8]) {
    let Some((&first, bytes)) = input.split_first() else {
        return;
    };
    let chunk = usize::from(first % 64) + 1;
    let mut decoder = FrameDecoder::new();
    let mut frames = 0u64;
    let mut check = |f: FrameRef<'_>| {
        frames += 1;
        let _ = Message::decode(f);
        let mut again = Vec::new();
        assert!(
            encode_frame(f.cmd, f.data, &mut again).is_ok(),
            "a decoded frame re-encodes"
        );
        assert_eq!(again.len(), f.data.len() + 7);
    };
    for part in bytes.chunks(chunk) {
        decoder.decode(part, &mut check);
    }
    decoder.finish();
    while let Some(f) = decoder.next_frame() {
        check(f);
    }
    let s = decoder.stats();
    assert_eq!(s.frames, frames);
    assert_eq!(s.bytes_in, bytes.len() as u64);
    assert_eq!(decoder.pending(), 0);
    assert_eq!(
        s.bytes_in,
        s.frame_bytes + s.bytes_skipped,
        "every byte accounted for"
    );
}
