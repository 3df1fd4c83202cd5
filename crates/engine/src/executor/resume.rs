//! Resume: what a journal says was done, restored so the run goes on after
//! its last completed step with no point lost or repeated.

use super::Executor;
use crate::event::Event;
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
