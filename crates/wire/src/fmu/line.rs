//! Can the serial line carry the configured FMU stream? (method.md §3.1)
//!
//! The published design's 16-bit counts every 2.5 ms do not fit its 9600
//! baud line; the station checks the budget at start-up and refuses a
//! configuration that cannot work, saying which baud it needs.

use super::message::StreamMode;
use super::{MAX_DATA_LEN, TICKS_PER_SECOND};

/// Standard UART rates, slowest first.
pub const STANDARD_BAUDS: [u32; 12] = [
    9_600, 19_200, 38_400, 57_600, 115_200, 230_400, 460_800, 500_000, 921_600, 1_000_000,
    1_500_000, 3_000_000,
];

/// How each byte is framed on the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SerialFraming {
    /// Data bits per character (8 for a binary protocol).
    pub data_bits: u8,
    /// Whether a parity bit is sent.
    pub parity: bool,
    /// Stop bits (1 or 2).
    pub stop_bits: u8,
}

impl Default for SerialFraming {
    /// 8N1.
    fn default() -> Self {
        SerialFraming {
            data_bits: 8,
            parity: false,
            stop_bits: 1,
        }
    }
}

impl SerialFraming {
    /// Bits on the line per byte: start + data + parity + stop.
    pub fn bits_per_byte(&self) -> u32 {
        1 + u32::from(self.data_bits) + u32::from(self.parity) + u32::from(self.stop_bits)
    }
}

/// Bytes of one count frame on the wire for `inputs` inputs.
pub fn frame_len(mode: StreamMode, inputs: usize) -> usize {
    7 + data_len(mode, inputs)
}

fn data_len(mode: StreamMode, inputs: usize) -> usize {
    let per_input = match mode {
        StreamMode::Gated => 2,
        StreamMode::Reciprocal => 6,
    };
    3 + per_input * inputs
}

/// The load a stream puts on its line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineBudget {
    /// Bytes per second of count frames (plus temperature frames).
    pub bytes_per_second: f64,
    /// Baud the stream needs.
    pub needed_baud: f64,
    /// needed / configured (≤ 1 to fit).
    pub utilization: f64,
}

/// A stream that does not fit its line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LineRateError {
    /// The frames need more bits per second than the line carries.
    #[error(
        "the FMU stream needs {needed_baud:.0} baud ({mode:?} mode, {inputs} inputs: {frame_bytes}-byte frames × \
         {ticks} per second at {bits} bits per byte) but the line is set to {baud} baud; {advice}"
    )]
    TooSlow {
        /// Configured baud.
        baud: u32,
        /// Needed baud.
        needed_baud: f64,
        /// Counting mode.
        mode: StreamMode,
        /// Inputs per frame.
        inputs: usize,
        /// Bytes per count frame.
        frame_bytes: usize,
        /// Frames per second.
        ticks: u32,
        /// Line bits per byte.
        bits: u32,
        /// What to do.
        advice: String,
    },
    /// The inputs do not fit one frame's 255 DATA bytes.
    #[error(
        "{inputs} inputs in {mode:?} mode need {data} DATA bytes per frame, more than the 255 a frame carries"
    )]
    FrameTooLong {
        /// Counting mode.
        mode: StreamMode,
        /// Inputs per frame.
        inputs: usize,
        /// DATA bytes needed.
        data: usize,
    },
}

/// Check that `inputs` inputs in `mode`, one frame per 2.5 ms tick plus
/// `temperature_frames_per_s` temperature frames for `inputs / 2`
/// instruments, fit a line of `baud` with `framing`.
pub fn check_line_rate(
    baud: u32,
    framing: SerialFraming,
    mode: StreamMode,
    inputs: usize,
    temperature_frames_per_s: f64,
) -> Result<LineBudget, LineRateError> {
    let data = data_len(mode, inputs);
    if data > MAX_DATA_LEN {
        return Err(LineRateError::FrameTooLong { mode, inputs, data });
    }
    let frame_bytes = frame_len(mode, inputs);
    let temperature_bytes = 7 + 2 + 2 * inputs / 2;
    let bytes_per_second = frame_bytes as f64 * f64::from(TICKS_PER_SECOND)
        + temperature_bytes as f64 * temperature_frames_per_s.max(0.0);
    let bits = framing.bits_per_byte();
    let needed_baud = bytes_per_second * f64::from(bits);
    let utilization = needed_baud / f64::from(baud.max(1));
    if needed_baud > f64::from(baud) {
        let advice = match STANDARD_BAUDS
            .iter()
            .find(|&&b| f64::from(b) >= needed_baud)
        {
            Some(b) => format!("set the line (and the module) to {b} baud or faster"),
            None => "no standard rate carries it: put fewer inputs on each line".to_string(),
        };
        return Err(LineRateError::TooSlow {
            baud,
            needed_baud,
            mode,
            inputs,
            frame_bytes,
            ticks: TICKS_PER_SECOND,
            bits,
            advice,
        });
    }
    Ok(LineBudget {
        bytes_per_second,
        needed_baud,
        utilization,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_published_9600_baud_line_is_refused_with_the_needed_rate() {
        let err = check_line_rate(9_600, SerialFraming::default(), StreamMode::Gated, 12, 1.0)
            .expect_err("published design does not fit");
        let text = err.to_string();
        // 34-byte frames × 400/s × 10 bits = 136,000 baud (+ temperatures).
        assert!(text.contains("needs 136"), "{text}");
        assert!(
            text.contains("set the line (and the module) to 230400 baud"),
            "{text}"
        );
    }

    #[test]
    fn reciprocal_twelve_inputs_fit_460800() {
        let b = check_line_rate(
            460_800,
            SerialFraming::default(),
            StreamMode::Reciprocal,
            12,
            1.0,
        )
        .expect("fits");
        // 82-byte frames × 400 = 32,800 B/s, + one 21-byte temperature frame.
        assert_eq!(b.bytes_per_second, 32_821.0);
        assert!(b.utilization < 0.72);
        assert!(
            check_line_rate(
                230_400,
                SerialFraming::default(),
                StreamMode::Reciprocal,
                12,
                1.0
            )
            .is_err()
        );
    }

    #[test]
    fn parity_and_frame_size_are_accounted() {
        let f = SerialFraming {
            data_bits: 8,
            parity: true,
            stop_bits: 2,
        };
        assert_eq!(f.bits_per_byte(), 12);
        let err =
            check_line_rate(3_000_000, f, StreamMode::Reciprocal, 43, 0.0).expect_err("too long");
        assert!(matches!(err, LineRateError::FrameTooLong { data: 261, .. }));
    }
}
