//! A counter module's inputs: each resonator's phase is integrated tick by
//! tick; gated mode counts the edges in each 2.5 ms gate, reciprocal mode
//! reports the whole periods completed in the tick and the reference-clock
//! ticks spanning them edge to edge, the edge times quantised to the
//! reference clock exactly as real hardware does (method.md §3.1).

use spinbench_wire::fmu::ReciprocalCount;

/// One input's counter.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InputCounter {
    /// Fractional phase [cycles] at the start of the next tick.
    frac: f64,
    /// Absolute reference-clock time of the last edge seen.
    last_edge_ref: Option<u64>,
}

/// What one input produced in one tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TickCount {
    /// Edges in the tick (the gated count).
    pub edges: u32,
    /// The reciprocal count.
    pub reciprocal: ReciprocalCount,
}

impl InputCounter {
    /// Advance over the tick starting at reference time `tick_start_ref`
    /// (`tick_ref` reference ticks long) with the signal at `f_hz`
    /// (0 = no signal).
    pub fn advance(
        &mut self,
        f_hz: f64,
        tick_start_ref: u64,
        tick_ref: u64,
        reference_hz: f64,
    ) -> TickCount {
        if f_hz.is_nan() || f_hz <= 0.0 {
            self.last_edge_ref = None;
            return TickCount::default();
        }
        let dt = tick_ref as f64 / reference_hz;
        let total = self.frac + f_hz * dt;
        let edges = total.floor();
        let n = edges as u32;
        self.frac = total - edges;
        if n == 0 {
            return TickCount::default();
        }
        // Edge k (1-based) of this tick is (k − frac0)/f seconds after its start.
        let frac0 = total - f_hz * dt;
        let edge_ref = |k: u32| -> u64 {
            let offset_s = (f64::from(k) - frac0) / f_hz;
            tick_start_ref + ((offset_s * reference_hz).floor() as u64).min(tick_ref - 1)
        };
        let last = edge_ref(n);
        let (periods, span) = match self.last_edge_ref {
            Some(prev) => (n, last.saturating_sub(prev)),
            // First edges after power-on: count from the first edge of this tick.
            None => (n - 1, last.saturating_sub(edge_ref(1))),
        };
        self.last_edge_ref = Some(last);
        TickCount {
            edges: n,
            reciprocal: ReciprocalCount {
                periods: u16::try_from(periods).unwrap_or(u16::MAX),
                span: u32::try_from(span).unwrap_or(u32::MAX),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reciprocal_counts_resolve_the_reference_clock() {
        let f = 30_000.123_456;
        let (tick_ref, fref) = (250_000u64, 100e6);
        let mut c = InputCounter::default();
        let (mut periods, mut span, mut edges) = (0u64, 0u64, 0u64);
        for tick in 0..400u64 {
            let t = c.advance(f, tick * tick_ref, tick_ref, fref);
            periods += u64::from(t.reciprocal.periods);
            span += u64::from(t.reciprocal.span);
            edges += u64::from(t.edges);
        }
        let recip = periods as f64 * fref / span as f64;
        // One reference tick in a second: ~1e-8 relative (method.md §3.1).
        assert!(((recip - f) / f).abs() < 3e-8, "{recip}");
        // Gated: one count per gate, summed over 1 s: ±1 Hz.
        assert!((edges as f64 - f).abs() <= 1.0, "{edges}");
    }

    #[test]
    fn no_signal_counts_nothing() {
        let mut c = InputCounter::default();
        assert_eq!(c.advance(0.0, 0, 250_000, 100e6), TickCount::default());
    }
}
