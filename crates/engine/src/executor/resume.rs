//! Resume: what a journal says was done, restored so the run goes on after
//! its last completed step with no point lost or repeated.

use super::Executor;
use crate::event::Event;
use crate::plan::Step;
use crate::record::{PointRecord, Reason};
use spinbench_analysis::tumble::{MeanReading, TumbleCalibration};
use std::collections::{BTreeMap, BTreeSet};

/// The executor's progress part: which of the plan's steps are done.
#[derive(Debug, Clone, Default)]
pub(super) struct Progress {
    /// The indices of the steps done (from the journal on resume).
    pub(super) completed: BTreeSet<usize>,
    /// The run continues one recorded before.
    pub(super) resumed: bool,
}

impl Progress {
    /// The steps of `steps` to run, in order, each with whether it was done
    /// before and is done again. A fresh run does every step. A resume does
    /// the steps not done, and again what the break undid: the power-on and
    /// alive check, the warm-up (the instruments were unpowered: a run is
    /// measured in one thermal state), the last mounting before the first
    /// step to do and the last chamber soak before it.
    pub(super) fn to_run(&self, steps: &[Step]) -> Vec<(usize, bool)> {
        let first_todo = (0..steps.len()).find(|i| !self.completed.contains(i));
        let last_before =
            |is: fn(&Step) -> bool| first_todo.and_then(|t| (0..t).rev().find(|&i| is(&steps[i])));
        let remount = last_before(|s| matches!(s, Step::Mount { .. }));
        let resoak = last_before(|s| matches!(s, Step::Soak { .. }));
        steps
            .iter()
            .enumerate()
            .filter_map(|(index, step)| {
                let setup = matches!(step, Step::PowerOn | Step::CheckAlive | Step::WarmUp { .. });
                if !self.completed.contains(&index) {
                    Some((index, false))
                } else {
                    (self.resumed && (setup || Some(index) == remount || Some(index) == resoak))
                        .then_some((index, true))
                }
            })
            .collect()
    }
}

impl Executor<'_> {
    /// Restore what a journal says was done, so [`run`](Self::run) continues
    /// after the last completed step with no point lost or repeated.
    pub fn restore(&mut self, events: &[Event]) {
        self.progress.resumed = true;
        let mut last_points: BTreeMap<usize, &Vec<PointRecord>> = BTreeMap::new();
        // Station time goes on from where the journal ends, so the resumed
        // run's one-second values never take the times of the first's.
        let mut last_time_s: f64 = 0.0;
        for e in events {
            match e {
                Event::Values { time_s, .. } => {
                    last_time_s = last_time_s.max(*time_s);
                }

                Event::StepDone { index } => {
                    self.progress.completed.insert(*index);
                }
                Event::TumbleDone {
                    slot,
                    up,
                    output_hz,
                    standard_error_hz,
                } => {
                    if let Some(u) = self.units.get_mut(*slot) {
                        let reading = Some(MeanReading {
                            output: *output_hz,
                            standard_error: *standard_error_hz,
                        });
                        if *up {
                            u.up = reading;
                        } else {
                            u.down = reading;
                        }
                        if let (Some(up), Some(down)) = (u.up, u.down) {
                            u.cal = TumbleCalibration::from_up_down(up.output, down.output).ok();
                        }
                    }
                }
                Event::CrossTumbleDone {
                    slot,
                    as_on_arm,
                    output_hz,
                    standard_error_hz,
                } => {
                    if let Some(u) = self.units.get_mut(*slot) {
                        u.crosswise[usize::from(!*as_on_arm)] = Some(MeanReading {
                            output: *output_hz,
                            standard_error: *standard_error_hz,
                        });
                        // A failure was journalled as UnitFailed when it happened.
                        let _ = u.find_cross_axis();
                    }
                }
                Event::RadiusDone {
                    slot,
                    mount,
                    radius_m,
                    reading_u_ppm,
                    ..
                } => {
                    if let Some(u) = self.units.get_mut(*slot) {
                        u.radius.insert(*mount, *radius_m);
                        u.radius_reading_u_ppm.insert(*mount, *reading_u_ppm);
                    }
                }
                Event::PointDone { step, points } => {
                    for p in points.iter() {
                        last_time_s = last_time_s.max(p.time_s[1]);
                    }
                    // A step killed between its PointDone and StepDone is redone
                    // and journals its point again: only the last one counts.
                    last_points.insert(*step, points);
                }
                Event::UnitFailed {
                    slot,
                    reason,
                    code,
                    args,
                } => {
                    if let Some(u) = self.units.get_mut(*slot) {
                        u.failed = Some(Reason {
                            code: *code,
                            text: reason.clone(),
                            args: args.clone(),
                        });
                    }
                }
                _ => {}
            }
        }
        if last_time_s.is_finite() && last_time_s > 0.0 {
            self.acquisition.windows = last_time_s.ceil() as u64;
        }
        // A point is whole only with its StepDone; a torn step is redone.
        for (step, points) in last_points {
            if self.progress.completed.contains(&step) {
                for p in points {
                    if let Some(u) = self.units.get_mut(p.slot) {
                        u.points.push(p.clone());
                    }
                }
            }
        }
    }

    /// Go on counting station time after `time_s` (on resume: the last
    /// one-second value the store holds of the run), so no value of the
    /// resumed run takes the time of one already stored.
    pub fn continue_time_after(&mut self, time_s: f64) {
        if time_s.is_finite() && time_s > 0.0 {
            self.acquisition.windows = self.acquisition.windows.max(time_s.ceil() as u64);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::Fixture;

    #[test]
    fn a_resume_does_again_what_the_break_undid_and_nothing_else() {
        let mount = || Step::Mount {
            fixtures: Vec::<Option<Fixture>>::new(),
        };
        let steps = vec![
            Step::PowerOn,
            Step::CheckAlive,
            Step::WarmUp { seconds: 600.0 },
            mount(),
            Step::Radius { pass: 0 },
            mount(),
            Step::Soak { setpoint_c: 60.0 },
            Step::Radius { pass: 1 },
            Step::Stop,
        ];
        let fresh = Progress::default();
        assert_eq!(
            fresh.to_run(&steps),
            (0..steps.len()).map(|i| (i, false)).collect::<Vec<_>>()
        );
        // Broken off in the second mounting's radius: the set-up, the warm-up,
        // that mounting and its soak again; the first mounting's radius not.
        let resumed = Progress {
            completed: (0..7).collect(),
            resumed: true,
        };
        assert_eq!(
            resumed.to_run(&steps),
            [
                (0, true),
                (1, true),
                (2, true),
                (5, true),
                (6, true),
                (7, false),
                (8, false)
            ]
        );
    }
}
