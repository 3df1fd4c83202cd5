//! One-second windows: the PC sums 400 consecutive 2.5 ms ticks into one
//! value per instrument (method.md §3; dF = f1 − f2, method.md (1)).
//!
//! Ticks are placed in windows by their sequence number, so a lost frame
//! leaves a hole in its window rather than shifting later ticks into it. A
//! window built from fewer ticks than it should hold is marked incomplete,
//! never passed as whole. Sequence numbers are 16-bit: a jump of less than
//! half the range forward is a gap (lost ticks); a jump backward is a
//! duplicate or out-of-order tick and is dropped and counted. A window
//! closes on its own last tick, or on the first tick of a later window when
//! its last tick was lost.

use super::message::{Message, StreamMode};
use super::{DEFAULT_REFERENCE_HZ, INPUTS_PER_MODULE, TICKS_PER_SECOND};

/// How a module's ticks are summed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowConfig {
    /// Counting mode of the stream.
    pub mode: StreamMode,
    /// Inputs per tick (two per instrument).
    pub inputs: usize,
    /// Ticks per window (400 = one second).
    pub ticks_per_window: u32,
    /// Reference clock of reciprocal counting [Hz].
    pub reference_hz: f64,
}

impl Default for WindowConfig {
    fn default() -> Self {
        WindowConfig {
            mode: StreamMode::Reciprocal,
            inputs: INPUTS_PER_MODULE,
            ticks_per_window: TICKS_PER_SECOND,
            reference_hz: DEFAULT_REFERENCE_HZ,
        }
    }
}

/// One instrument's value over a window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InstrumentValue {
    /// First resonator's frequency [Hz]; `None` if it produced no signal.
    pub f1_hz: Option<f64>,
    /// Second resonator's frequency [Hz].
    pub f2_hz: Option<f64>,
    /// dF = f1 − f2 [Hz], method.md (1).
    pub df_hz: Option<f64>,
}

/// One window's values.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowValue {
    /// Window number since the first tick (0, 1, …).
    pub index: u64,
    /// Ticks that arrived in this window.
    pub ticks: u32,
    /// Ticks the window should hold.
    pub ticks_expected: u32,
    /// OR of the module status bytes of the window's ticks.
    pub status: u8,
    /// One value per instrument.
    pub instruments: Vec<InstrumentValue>,
}

impl WindowValue {
    /// True when every tick of the window arrived.
    pub fn is_complete(&self) -> bool {
        self.ticks == self.ticks_expected
    }
}

/// Counters of a window accumulator.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WindowStats {
    /// Ticks accepted.
    pub ticks: u64,
    /// Ticks missing from sequence gaps.
    pub lost_ticks: u64,
    /// Sequence gaps (each may lose several ticks).
    pub gaps: u64,
    /// Ticks dropped as duplicate or out of order.
    pub out_of_order: u64,
    /// Ticks dropped for the wrong mode or input count.
    pub wrong_shape: u64,
    /// Windows emitted.
    pub windows: u64,
    /// Windows emitted incomplete.
    pub incomplete_windows: u64,
}

/// Sums ticks into windows; feed count messages, collect window values.
#[derive(Debug, Clone)]
pub struct WindowAccumulator {
    config: WindowConfig,
    /// Absolute tick number of the last accepted tick.
    last_tick: Option<(u64, u16)>,
    window: u64,
    ticks_in_window: u32,
    status: u8,
    /// Gated: Σcounts; reciprocal: Σperiods, per input.
    sum_a: Vec<u64>,
    /// Reciprocal: Σspan per input.
    sum_b: Vec<u64>,
    stats: WindowStats,
    /// Windows closed and not yet taken by [`WindowAccumulator::decode`]
    /// (its capacity is reused: no allocation per message).
    ready: std::collections::VecDeque<WindowValue>,
}

impl WindowAccumulator {
    /// A new accumulator.
    pub fn new(config: WindowConfig) -> Self {
        WindowAccumulator {
            sum_a: vec![0; config.inputs],
            sum_b: vec![0; config.inputs],
            config,
            last_tick: None,
            window: 0,
            ticks_in_window: 0,
            status: 0,
            stats: WindowStats::default(),
            ready: std::collections::VecDeque::new(),
        }
    }

    /// The counters so far.
    pub fn stats(&self) -> WindowStats {
        self.stats
    }

    /// Feed one message and return the windows it closed (usually none or
    /// one; more after a gap longer than a window): [`Self::feed`], then
    /// every [`Self::decode`], collected.
    pub fn push(&mut self, message: &Message) -> Vec<WindowValue> {
        self.feed(message);
        self.ready.drain(..).collect()
    }

    /// The next closed window, if any (the pull side, in the manner of
    /// tokio-util's `Decoder::decode`: feed messages, then take windows
    /// until `None`).
    pub fn decode(&mut self) -> Option<WindowValue> {
        self.ready.pop_front()
    }

    /// Feed one message; count messages of the configured mode are summed,
    /// others ignored. The windows it closes wait for [`Self::decode`].
    pub fn feed(&mut self, message: &Message) {
        let (seq, status) = match (message, self.config.mode) {
            (
                Message::GatedCounts {
                    seq,
                    status,
                    counts,
                },
                StreamMode::Gated,
            ) if counts.len() == self.config.inputs => (*seq, *status),
            (
                Message::ReciprocalCounts {
                    seq,
                    status,
                    inputs,
                },
                StreamMode::Reciprocal,
            ) if inputs.len() == self.config.inputs => (*seq, *status),
            (Message::GatedCounts { .. } | Message::ReciprocalCounts { .. }, _) => {
                self.stats.wrong_shape += 1;
                return;
            }
            _ => return,
        };

        let tick = match self.last_tick {
            None => 0,
            Some((last, last_seq)) => {
                let step = seq.wrapping_sub(last_seq);
                if step == 0 || step >= 0x8000 {
                    self.stats.out_of_order += 1;
                    return;
                }
                if step > 1 {
                    self.stats.gaps += 1;
                    self.stats.lost_ticks += u64::from(step - 1);
                }
                last + u64::from(step)
            }
        };
        self.last_tick = Some((tick, seq));

        let window = tick / u64::from(self.config.ticks_per_window.max(1));
        while self.window < window {
            let closed = self.close_window();
            self.ready.push_back(closed);
        }
        self.ticks_in_window += 1;
        self.status |= status;
        self.stats.ticks += 1;
        match message {
            Message::GatedCounts { counts, .. } => {
                for (sum, c) in self.sum_a.iter_mut().zip(counts) {
                    *sum += u64::from(*c);
                }
            }
            Message::ReciprocalCounts { inputs, .. } => {
                for ((pa, pb), c) in self.sum_a.iter_mut().zip(self.sum_b.iter_mut()).zip(inputs) {
                    *pa += u64::from(c.periods);
                    *pb += u64::from(c.span);
                }
            }
            _ => {}
        }
        // The window's last tick closes it at once (a window waits for no
        // later tick: a station that reads one second at a time gets it
        // whole); after lost ticks the next window's first tick closes it.
        let per_window = u64::from(self.config.ticks_per_window.max(1));
        if (tick + 1).is_multiple_of(per_window) {
            let closed = self.close_window();
            self.ready.push_back(closed);
        }
    }

    /// Emit the current window even though it is not over (end of a stream);
    /// `None` if it holds no tick.
    pub fn flush(&mut self) -> Option<WindowValue> {
        (self.ticks_in_window > 0).then(|| self.close_window())
    }

    fn close_window(&mut self) -> WindowValue {
        let expected = self.config.ticks_per_window;
        let ticks = self.ticks_in_window;
        let seconds_per_tick = 1.0 / f64::from(TICKS_PER_SECOND);
        let frequency = |i: usize| -> Option<f64> {
            match self.config.mode {
                // Gated: counts per received tick, per second of ticks.
                StreamMode::Gated => (ticks > 0)
                    .then(|| self.sum_a[i] as f64 / (f64::from(ticks) * seconds_per_tick)),
                // Reciprocal: f = Σperiods · f_ref / Σspan.
                StreamMode::Reciprocal => (self.sum_a[i] > 0 && self.sum_b[i] > 0).then(|| {
                    self.sum_a[i] as f64 * self.config.reference_hz / self.sum_b[i] as f64
                }),
            }
        };
        let instruments = (0..self.config.inputs / 2)
            .map(|j| {
                let (f1, f2) = (frequency(2 * j), frequency(2 * j + 1));
                InstrumentValue {
                    f1_hz: f1,
                    f2_hz: f2,
                    df_hz: f1.zip(f2).map(|(a, b)| a - b),
                }
            })
            .collect();
        let value = WindowValue {
            index: self.window,
            ticks,
            ticks_expected: expected,
            status: self.status,
            instruments,
        };
        self.stats.windows += 1;
        if !value.is_complete() {
            self.stats.incomplete_windows += 1;
        }
        self.window += 1;
        self.ticks_in_window = 0;
        self.status = 0;
        self.sum_a.iter_mut().for_each(|v| *v = 0);
        self.sum_b.iter_mut().for_each(|v| *v = 0);
        value
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmu::ReciprocalCount;

    fn gated(seq: u16, counts: [u16; 4]) -> Message {
        Message::GatedCounts {
            seq,
            status: 0,
            counts: counts.to_vec(),
        }
    }

    fn config(mode: StreamMode) -> WindowConfig {
        WindowConfig {
            mode,
            inputs: 4,
            ticks_per_window: 400,
            reference_hz: 100e6,
        }
    }

    #[test]
    fn gated_window_sums_400_ticks_into_hz() {
        let mut acc = WindowAccumulator::new(config(StreamMode::Gated));
        let mut out = Vec::new();
        for i in 0..800u16 {
            out.extend(acc.push(&gated(i.wrapping_add(65000), [75, 74, 80, 80])));
        }
        out.extend(acc.flush());
        assert_eq!(out.len(), 2);
        for w in &out {
            assert!(w.is_complete());
            assert_eq!(w.instruments[0].f1_hz, Some(30_000.0));
            assert_eq!(w.instruments[0].df_hz, Some(400.0));
            assert_eq!(w.instruments[1].df_hz, Some(0.0));
        }
        assert_eq!(acc.stats().lost_ticks, 0);
    }

    #[test]
    fn a_window_closes_on_its_last_tick_without_waiting_for_the_next() {
        let mut acc = WindowAccumulator::new(config(StreamMode::Gated));
        for i in 0..399u16 {
            assert!(acc.push(&gated(i, [75, 75, 75, 75])).is_empty());
        }
        let closed = acc.push(&gated(399, [75, 75, 75, 75]));
        assert_eq!(closed.len(), 1);
        assert!(closed[0].is_complete());
        assert_eq!(acc.flush(), None);
        // The next window starts clean.
        let next = acc.push(&gated(400, [75, 75, 75, 75]));
        assert!(next.is_empty());
        assert_eq!(acc.flush().map(|w| (w.index, w.ticks)), Some((1, 1)));
    }

    #[test]
    fn lost_ticks_mark_the_window_and_do_not_shift_the_next() {
        let mut acc = WindowAccumulator::new(config(StreamMode::Gated));
        let mut out = Vec::new();
        for i in (0..800u16).filter(|i| !(100..110).contains(i)) {
            out.extend(acc.push(&gated(i, [75, 75, 75, 75])));
        }
        out.extend(acc.flush());
        assert_eq!(out[0].ticks, 390);
        assert!(!out[0].is_complete());
        // The per-tick rate is kept: 75 counts per 2.5 ms is 30 kHz.
        assert_eq!(out[0].instruments[0].f1_hz, Some(30_000.0));
        assert!(out[1].is_complete());
        let s = acc.stats();
        assert_eq!((s.gaps, s.lost_ticks, s.incomplete_windows), (1, 10, 1));
    }

    #[test]
    fn the_pull_side_gives_the_windows_push_gives_in_order() {
        let tick = |seq: u16| Message::ReciprocalCounts {
            seq,
            status: 0,
            inputs: (0..4)
                .map(|i| ReciprocalCount {
                    periods: 70 + i,
                    span: 250_000 + u32::from(seq % 7),
                })
                .collect(),
        };
        let mut pushed = WindowAccumulator::new(config(StreamMode::Reciprocal));
        let mut pulled = WindowAccumulator::new(config(StreamMode::Reciprocal));
        let (mut a, mut b) = (Vec::new(), Vec::new());
        // A gap of three windows in the middle closes several at once.
        for seq in (0..900u16).chain(2100..2500) {
            a.extend(pushed.push(&tick(seq)));
            pulled.feed(&tick(seq));
            while let Some(w) = pulled.decode() {
                b.push(w);
            }
        }
        assert!(a.len() >= 5, "{} windows", a.len());
        assert_eq!(a, b);
        assert_eq!(pulled.decode(), None);
    }

    #[test]
    fn reciprocal_window_is_periods_times_reference_over_span() {
        let mut acc = WindowAccumulator::new(config(StreamMode::Reciprocal));
        let tick = |seq| Message::ReciprocalCounts {
            seq,
            status: 0,
            inputs: vec![
                ReciprocalCount {
                    periods: 75,
                    span: 250_001,
                },
                ReciprocalCount {
                    periods: 70,
                    span: 249_999,
                },
                ReciprocalCount {
                    periods: 0,
                    span: 0,
                },
                ReciprocalCount {
                    periods: 0,
                    span: 0,
                },
            ],
        };
        for seq in 0..399 {
            assert!(acc.push(&tick(seq)).is_empty());
        }
        let w = acc.push(&tick(399)).pop().expect("window closed");
        let f1 = 400.0 * 75.0 * 100e6 / (400.0 * 250_001.0);
        let f2 = 400.0 * 70.0 * 100e6 / (400.0 * 249_999.0);
        assert!((w.instruments[0].f1_hz.expect("f1") - f1).abs() < 1e-9);
        assert!((w.instruments[0].df_hz.expect("df") - (f1 - f2)).abs() < 1e-9);
        // An unpowered instrument has no value.
        assert_eq!(w.instruments[1].df_hz, None);
    }

    #[test]
    fn duplicates_and_wrong_shapes_are_dropped_and_counted() {
        let mut acc = WindowAccumulator::new(config(StreamMode::Gated));
        acc.push(&gated(5, [1, 1, 1, 1]));
        acc.push(&gated(5, [1, 1, 1, 1]));
        acc.push(&gated(3, [1, 1, 1, 1]));
        acc.push(&Message::GatedCounts {
            seq: 6,
            status: 0,
            counts: vec![1, 2],
        });
        let s = acc.stats();
        assert_eq!((s.ticks, s.out_of_order, s.wrong_shape), (1, 2, 1));
    }
}
