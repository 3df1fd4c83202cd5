//! The run screen's time to go: each remaining step of the compiled plan
//! estimated by how long the steps of its kind took so far in this run
//! (a level by the levels done, a tumble by the tumbles). While a kind that
//! is still to come has not been timed once, there is no estimate (the
//! screen shows none rather than a wrong one); the operator's remounting and
//! the final stop count as nothing. Counting steps alone was far off: the
//! first steps (power, checks, prompts) are quick, the levels slow.

use spinbench_engine::plan::Step;
use std::collections::HashMap;
use std::time::Instant;

/// Times a run's steps as they start, and estimates the rest.
#[derive(Debug, Default)]
pub struct StepClock {
    /// The kind of every step of the plan (its wording's key).
    kinds: Vec<String>,
    /// The step going on and when it began.
    current: Option<(usize, Instant)>,
    /// Seconds taken per kind: (total, count).
    taken: HashMap<String, (f64, u32)>,
}

impl StepClock {
    /// A new run with these steps.
    pub fn run_started(&mut self, steps: &[Step]) {
        *self = StepClock {
            kinds: steps
                .iter()
                .map(|s| spinbench_engine::executor::wording(s).key)
                .collect(),
            ..StepClock::default()
        };
    }

    /// Step `index` began at `now` (the one before it ended then).
    pub fn step_started(&mut self, index: usize, now: Instant) {
        if let Some((previous, began)) = self.current.take()
            && let Some(kind) = self.kinds.get(previous)
        {
            let entry = self.taken.entry(kind.clone()).or_insert((0.0, 0));
            entry.0 += now.saturating_duration_since(began).as_secs_f64();
            entry.1 += 1;
        }
        self.current = Some((index, now));
    }

    /// Seconds to the end of the plan from `now`; `None` while a kind of
    /// step still to come has not been timed.
    pub fn eta_s(&self, now: Instant) -> Option<f64> {
        let (index, began) = self.current?;
        let estimate = |kind: &String| -> Option<f64> {
            match self.taken.get(kind) {
                Some((s, c)) => Some(s / f64::from(*c)),
                // Operator time and the stop: not the station's to tell.
                None if kind == "step.mount" || kind == "step.stop" => Some(0.0),
                None => None,
            }
        };
        let this = estimate(self.kinds.get(index)?)?;
        let left_of_this = (this - now.saturating_duration_since(began).as_secs_f64()).max(0.0);
        let rest = self
            .kinds
            .iter()
            .skip(index + 1)
            .map(estimate)
            .sum::<Option<f64>>()?;
        Some(left_of_this + rest)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use spinbench_analysis::Direction;
    use std::time::Duration;

    #[test]
    fn levels_are_estimated_by_the_levels_done_not_by_the_quick_first_steps() {
        let level = |g: f64| Step::Level {
            pass: 0,
            g_nominal: g,
            direction: Direction::Up,
        };
        let steps = vec![
            Step::PowerOn,
            Step::CheckAlive,
            Step::Tumble { up: true },
            level(1.0),
            level(2.0),
            level(3.0),
            level(4.0),
            Step::Stop,
        ];
        let mut clock = StepClock::default();
        clock.run_started(&steps);
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        // Power 1 s, check 1 s, tumble 4 s: no level timed yet, no estimate.
        for (i, t) in [(0, 0.0), (1, 1.0), (2, 2.0), (3, 6.0)] {
            clock.step_started(i, at(t));
        }
        assert_eq!(clock.eta_s(at(10.0)), None);
        // The first level took 20 s.
        clock.step_started(4, at(26.0));
        // At 26 s, in the second level: it (20 s), two more levels (40 s)
        // and the stop (counted as nothing).
        let eta = clock.eta_s(at(26.0)).expect("an estimate");
        assert!((eta - 60.0).abs() < 1e-9, "{eta}");
        // Counting steps alone would have said 26 s / 4 × 4 = 26 s.
        let later = clock.eta_s(at(36.0)).expect("an estimate");
        assert!((later - 50.0).abs() < 1e-9, "{later}");
        assert!(StepClock::default().eta_s(t0).is_none());
    }
}
