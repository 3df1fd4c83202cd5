//! The walk through the plan's steps: each step the run still has to do
//! (on a resume, with what it does again: [`super::resume`]), held while
//! paused, announced, handed to its handler ([`super::steps`]) and marked
//! done.

use super::state::Trigger;
use super::{EngineError, Executor, label, wording};
use crate::event::{Event, Wording};
use crate::plan::Step;
use std::sync::atomic::Ordering;
use std::time::Duration;

impl Executor<'_> {
    pub(super) fn execute_steps(&mut self) -> Result<(), EngineError> {
        let steps = self.plan.steps.clone();
        for (index, again) in self.progress.to_run(&steps) {
            let step = &steps[index];
            if again
                && let Step::WarmUp { seconds } = step
                && *seconds > 0.0
            {
                self.emit(Event::Notice {
                    message: format!(
                        "resumed: the instruments warm up again for {seconds:.0} s before the first measured step, so that the run is measured in one thermal state"
                    ),
                    wording: Some(
                        Wording::new("notice.resume_warm_up").with("seconds", format!("{seconds:.0}")),
                    ),
                })?;
            }
            if self.options.abort.is_set() {
                return Err(EngineError::Aborted(self.options.abort.by()));
            }
            if self.options.pause.load(Ordering::Relaxed) {
                self.set_state(Trigger::Pause)?;
                while self.options.pause.load(Ordering::Relaxed) {
                    if self.options.abort.is_set() {
                        return Err(EngineError::Aborted(self.options.abort.by()));
                    }
                    if self.acquisition.streaming {
                        // Keep reading (and keep the safety checks running) while held.
                        self.next_window()?;
                    } else {
                        std::thread::sleep(Duration::from_millis(10));
                    }
                }
                self.set_state(Trigger::Resume)?;
            }
            self.emit(Event::StepStarted {
                index,
                of: steps.len(),
                label: label(step),
                wording: Some(wording(step)),
            })?;
            match step {
                Step::PowerOn => self.power_on()?,
                Step::CheckAlive => self.check_alive()?,
                Step::WarmUp { seconds } => self.warm_up(*seconds)?,
                Step::Mount { fixtures } => self.mount(fixtures)?,
                Step::Tumble { up } => self.tumble(*up)?,
                Step::CrossTumble { as_on_arm } => self.cross_tumble(*as_on_arm)?,
                Step::Soak { setpoint_c } => self.soak(*setpoint_c)?,
                Step::Radius { pass } => self.radius(*pass)?,
                Step::Level {
                    pass,
                    g_nominal,
                    direction,
                } => self.level(index, *pass, *g_nominal, *direction)?,
                Step::Decide { pass, round } => self.decide(index, *pass, *round)?,
                Step::Stop => self.command_rate(0.0)?,
            }
            self.emit(Event::StepDone { index })?;
        }
        Ok(())
    }
}
