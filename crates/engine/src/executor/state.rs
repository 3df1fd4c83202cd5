//! The run-state table as data, and the one function every change of state
//! goes through: a transition that is not in [`TRANSITIONS`] is refused.
//!
//! | from | trigger | to |
//! |---|---|---|
//! | Idle | start | Running |
//! | Running | operator prompt | Prompting |
//! | Prompting | answered | Running |
//! | Running | pause (between steps) | Paused |
//! | Paused | resume | Running |
//! | Idle, Running, Prompting, Paused, Stopping | a write fails (store, journal) | Paused (held) |
//! | Paused (held) | the write succeeds, or is given up (abort, hold limit) | the state it was held in |
//! | Idle, Running, Prompting, Paused | end (done, fault, abort) | Stopping |
//! | Stopping | safe: completed / faulted / aborted | Completed / Faulted / Aborted |

use crate::event::RunState;

/// What makes the state change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Trigger {
    /// The run begins.
    Start,
    /// The operator is asked to do something.
    Prompt,
    /// The operator answered.
    Answered,
    /// The operator holds the run between steps.
    Pause,
    /// The operator lets it go on.
    Resume,
    /// A subscriber (store, journal) could not take an event: the run is held.
    WriteFailed,
    /// The held write succeeded: back to where the run was.
    WriteSucceeded,
    /// The held write was given up (an abort, the hold limit): back to
    /// where the run was, which then ends.
    WriteAbandoned,
    /// The run ends (its last step, a fault or an abort): to the safe state.
    End,
    /// Safe, and the plan was done.
    Completed,
    /// Safe, after a fault.
    Faulted,
    /// Safe, after an abort.
    Aborted,
}

/// Every trigger, for tests and tables.
pub const TRIGGERS: [Trigger; 12] = [
    Trigger::Start,
    Trigger::Prompt,
    Trigger::Answered,
    Trigger::Pause,
    Trigger::Resume,
    Trigger::WriteFailed,
    Trigger::WriteSucceeded,
    Trigger::WriteAbandoned,
    Trigger::End,
    Trigger::Completed,
    Trigger::Faulted,
    Trigger::Aborted,
];

/// Every state, for tests and tables.
pub const STATES: [RunState; 8] = [
    RunState::Idle,
    RunState::Running,
    RunState::Prompting,
    RunState::Paused,
    RunState::Stopping,
    RunState::Completed,
    RunState::Faulted,
    RunState::Aborted,
];

/// Where a transition leads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// This state.
    To(RunState),
    /// Back to the state the run was held in.
    Back,
}

/// The table: (from, trigger, to). Nothing else is allowed.
pub const TRANSITIONS: &[(RunState, Trigger, Target)] = &[
    (
        RunState::Idle,
        Trigger::Start,
        Target::To(RunState::Running),
    ),
    (
        RunState::Running,
        Trigger::Prompt,
        Target::To(RunState::Prompting),
    ),
    (
        RunState::Prompting,
        Trigger::Answered,
        Target::To(RunState::Running),
    ),
    (
        RunState::Running,
        Trigger::Pause,
        Target::To(RunState::Paused),
    ),
    (
        RunState::Paused,
        Trigger::Resume,
        Target::To(RunState::Running),
    ),
    (
        RunState::Idle,
        Trigger::WriteFailed,
        Target::To(RunState::Paused),
    ),
    (
        RunState::Running,
        Trigger::WriteFailed,
        Target::To(RunState::Paused),
    ),
    (
        RunState::Prompting,
        Trigger::WriteFailed,
        Target::To(RunState::Paused),
    ),
    (
        RunState::Paused,
        Trigger::WriteFailed,
        Target::To(RunState::Paused),
    ),
    (
        RunState::Stopping,
        Trigger::WriteFailed,
        Target::To(RunState::Paused),
    ),
    (RunState::Paused, Trigger::WriteSucceeded, Target::Back),
    (RunState::Paused, Trigger::WriteAbandoned, Target::Back),
    (RunState::Idle, Trigger::End, Target::To(RunState::Stopping)),
    (
        RunState::Running,
        Trigger::End,
        Target::To(RunState::Stopping),
    ),
    (
        RunState::Prompting,
        Trigger::End,
        Target::To(RunState::Stopping),
    ),
    (
        RunState::Paused,
        Trigger::End,
        Target::To(RunState::Stopping),
    ),
    (
        RunState::Stopping,
        Trigger::Completed,
        Target::To(RunState::Completed),
    ),
    (
        RunState::Stopping,
        Trigger::Faulted,
        Target::To(RunState::Faulted),
    ),
    (
        RunState::Stopping,
        Trigger::Aborted,
        Target::To(RunState::Aborted),
    ),
];

/// A transition the table does not have.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("the run cannot go from {from:?} on {trigger:?} (not in the run-state table)")]
pub struct Refused {
    /// The state.
    pub from: RunState,
    /// What was asked.
    pub trigger: Trigger,
}

/// The run's state, changed only through [`StateMachine::fire`].
#[derive(Debug, Clone)]
pub struct StateMachine {
    state: RunState,
    /// The states a held run returns to, innermost last (a write can fail
    /// while an earlier failed write is being retried).
    held_from: Vec<RunState>,
}

impl Default for StateMachine {
    fn default() -> Self {
        StateMachine {
            state: RunState::Idle,
            held_from: Vec::new(),
        }
    }
}

impl StateMachine {
    /// The state now.
    pub fn state(&self) -> RunState {
        self.state
    }

    /// Apply `trigger`: the new state, or the refusal (the state unchanged).
    pub fn fire(&mut self, trigger: Trigger) -> Result<RunState, Refused> {
        let refused = Refused {
            from: self.state,
            trigger,
        };
        let target = TRANSITIONS
            .iter()
            .find(|(from, t, _)| *from == self.state && *t == trigger)
            .map(|(_, _, to)| *to)
            .ok_or(refused)?;
        let next = match target {
            Target::To(state) => state,
            Target::Back => self.held_from.pop().ok_or(refused)?,
        };
        if trigger == Trigger::WriteFailed {
            self.held_from.push(self.state);
        }
        self.state = next;
        Ok(next)
    }
}

#[cfg(test)]
mod tests {
    use super::{Refused, STATES, StateMachine, TRANSITIONS, TRIGGERS, Target, Trigger};
    use crate::event::RunState;
    use RunState::{Aborted, Completed, Faulted, Paused, Prompting, Running, Stopping};
    use Target::{Back, To};
    use Trigger::{Answered, End, Prompt, Start, WriteFailed, WriteSucceeded};

    /// Every (state, trigger) pair: allowed exactly when the table has it.
    #[test]
    fn every_state_and_trigger_pair_follows_the_table() {
        let mut allowed = 0;
        for from in STATES {
            for trigger in TRIGGERS {
                let mut m = StateMachine {
                    state: from,
                    // A held run knows where it came from.
                    held_from: if from == Paused {
                        vec![Running]
                    } else {
                        vec![]
                    },
                };
                let in_table = TRANSITIONS
                    .iter()
                    .find(|(f, t, _)| *f == from && *t == trigger);
                match (m.fire(trigger), in_table) {
                    (Ok(next), Some((_, _, To(to)))) => {
                        assert_eq!(next, *to, "{from:?} on {trigger:?}");
                        allowed += 1;
                    }
                    (Ok(next), Some((_, _, Back))) => {
                        assert_eq!(next, Running, "{from:?} on {trigger:?}");
                        allowed += 1;
                    }
                    (Err(e), None) => {
                        assert_eq!(e, Refused { from, trigger });
                        assert_eq!(m.state(), from, "a refusal changes nothing");
                    }
                    (got, want) => panic!("{from:?} on {trigger:?}: {got:?}, table says {want:?}"),
                }
            }
        }
        assert_eq!(allowed, TRANSITIONS.len());
        // The final states are final.
        for end in [Completed, Faulted, Aborted] {
            for trigger in TRIGGERS {
                assert!(
                    TRANSITIONS
                        .iter()
                        .all(|(f, t, _)| !(*f == end && *t == trigger)),
                    "{end:?} has a way out"
                );
            }
        }
    }

    #[test]
    fn a_held_run_goes_back_to_where_it_was() {
        let mut m = StateMachine::default();
        assert_eq!(m.fire(Start), Ok(Running));
        assert_eq!(m.fire(Prompt), Ok(Prompting));
        assert_eq!(m.fire(WriteFailed), Ok(Paused));
        assert_eq!(m.fire(WriteSucceeded), Ok(Prompting));
        assert_eq!(m.fire(Answered), Ok(Running));
        assert_eq!(m.fire(End), Ok(Stopping));
        assert_eq!(m.fire(WriteFailed), Ok(Paused));
        assert_eq!(m.fire(WriteSucceeded), Ok(Stopping));
        assert_eq!(m.fire(Trigger::Completed), Ok(Completed));
        assert!(m.fire(Start).is_err());
        // A write that succeeds with nothing held is refused.
        let mut idle = StateMachine::default();
        assert!(idle.fire(WriteSucceeded).is_err());
    }
}
