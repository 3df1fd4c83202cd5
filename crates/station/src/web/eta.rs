//! The run screen's time to go, from the start: each remaining step of the
//! compiled plan estimated by how long the steps of its kind took so far in
//! this run (a level by the levels done, a tumble by the tumbles, the
//! operator's remounting by the remountings, their waits included), and
//! before a kind has been timed, by the plan: a level by the plan's
//! predicted centrifuge time shared over its levels, a warm-up by its
//! seconds, the others by a nominal time of their kind
//! ([`NOMINAL_S`]). Counting steps alone was far off: the first steps
//! (power, checks, prompts) are quick, the levels slow.

use spinbench_engine::plan::{PlanPrediction, Step};
use std::collections::HashMap;
use std::time::Instant;

/// A kind's time before one of its steps has been timed in this run [s]:
/// a bench's typical times (the virtual bench's at its real speed, and the
/// published station's procedure), replaced by the measured as soon as one
/// step of the kind is done.
const NOMINAL_S: [(&str, f64); 10] = [
    ("step.power_on", 5.0),
    ("step.check_alive", 15.0),
    // The operator's remounting of every instrument.
    ("step.mount", 120.0),
    ("step.tumble", 60.0),
    ("step.cross_tumble", 60.0),
    ("step.radius", 120.0),
    ("step.level", 60.0),
    // A round of deciding: most measure nothing (every instrument decided).
    ("step.decide", 5.0),
    ("step.soak", 1800.0),
    ("step.stop", 30.0),
];

/// Times a run's steps as they start, and estimates the rest.
#[derive(Debug, Default)]
pub struct StepClock {
    /// The kind of every step of the plan (its wording's key).
    kinds: Vec<String>,
    /// Each step's time before its kind is timed, from the plan [s].
    planned_s: Vec<f64>,
    /// The step going on and when it began.
    current: Option<(usize, Instant)>,
    /// Seconds taken per kind: (total, count).
    taken: HashMap<String, (f64, u32)>,
}

impl StepClock {
    /// A new run with these steps and the plan's prediction (its centrifuge
    /// time is shared over the level steps).
    pub fn run_started(&mut self, steps: &[Step], prediction: Option<&PlanPrediction>) {
        let levels = steps
            .iter()
            .filter(|s| matches!(s, Step::Level { .. }))
            .count()
            .max(1);
        let nominal = |kind: &str| {
            NOMINAL_S
                .iter()
                .find(|(k, _)| *k == kind)
                .map_or(30.0, |(_, s)| *s)
        };
        let kinds: Vec<String> = steps
            .iter()
            .map(|s| spinbench_engine::executor::wording(s).key)
            .collect();
        let planned_s = steps
            .iter()
            .zip(&kinds)
            .map(|(step, kind)| match step {
                Step::WarmUp { seconds } => *seconds,
                Step::Level { .. } => prediction
                    .map(|p| p.centrifuge_time_s / levels as f64)
                    .filter(|s| s.is_finite() && *s > 0.0)
                    .unwrap_or_else(|| nominal(kind)),
                _ => nominal(kind),
            })
            .collect();
        *self = StepClock {
            kinds,
            planned_s,
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

    /// Seconds to the end of the plan from `now` (`None` before the first
    /// step): each step by its kind's measured mean, or by the plan.
    pub fn eta_s(&self, now: Instant) -> Option<f64> {
        let (index, began) = self.current?;
        let estimate = |k: usize| -> f64 {
            let kind = &self.kinds[k];
            match self.taken.get(kind) {
                Some((s, c)) => s / f64::from(*c),
                None => self.planned_s.get(k).copied().unwrap_or(0.0),
            }
        };
        if index >= self.kinds.len() {
            return None;
        }
        let left_of_this =
            (estimate(index) - now.saturating_duration_since(began).as_secs_f64()).max(0.0);
        let rest: f64 = (index + 1..self.kinds.len()).map(estimate).sum();
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
        let prediction = PlanPrediction {
            k2_u95_ug_per_g2: 4.0,
            centrifuge_time_s: 100.0,
            published_k2_u95_ug_per_g2: None,
            published_centrifuge_time_s: None,
            target_k2_u95_ug_per_g2: None,
            model_runs: 0,
            sequential_centrifuge_time_max_s: None,
            k2_u95_run_range_ug_per_g2: None,
        };
        let mut clock = StepClock::default();
        clock.run_started(&steps, Some(&prediction));
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        // From the start, by the plan: power 5 + check 15 + tumble 60 +
        // four levels of 100/4 s + the stop 30 = 210 s.
        clock.step_started(0, at(0.0));
        let eta = clock.eta_s(at(0.0)).expect("an estimate from the start");
        assert!((eta - 210.0).abs() < 1e-9, "{eta}");
        // Power 1 s, check 1 s, tumble 4 s: measured replace planned.
        for (i, t) in [(1, 1.0), (2, 2.0), (3, 6.0)] {
            clock.step_started(i, at(t));
        }
        // In the first level at 10 s: 25 − 4 s of it, three more (75 s), the stop (30 s).
        let eta = clock.eta_s(at(10.0)).expect("an estimate");
        assert!((eta - 126.0).abs() < 1e-9, "{eta}");
        // The first level took 20 s.
        clock.step_started(4, at(26.0));
        // At 26 s, in the second level: it (20 s), two more levels (40 s)
        // and the stop (30 s, not timed yet).
        let eta = clock.eta_s(at(26.0)).expect("an estimate");
        assert!((eta - 90.0).abs() < 1e-9, "{eta}");
        let later = clock.eta_s(at(36.0)).expect("an estimate");
        assert!((later - 80.0).abs() < 1e-9, "{later}");
        assert!(StepClock::default().eta_s(t0).is_none());
    }
}
