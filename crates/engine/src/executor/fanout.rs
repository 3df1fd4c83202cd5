//! Fan-out: every event to every subscriber (journal, store, screens), and
//! the hold-and-retry when one cannot take it: nothing is dropped.

use super::state::{StateMachine, Trigger};
use super::{EngineError, Executor};
use crate::event::{Event, EventSink, Wording};
use std::time::{Duration, Instant};

/// The executor's fan-out part: the subscribers, and the run-state table
/// whose changes they are told of.
#[derive(Default)]
pub(super) struct Fanout<'a> {
    /// Every subscriber, in the order they subscribed.
    pub(super) sinks: Vec<Box<dyn EventSink + 'a>>,
    /// The run's state, changed only through the table.
    pub(super) machine: StateMachine,
    /// What a subscriber would not take while another one's write was
    /// held (a second subscriber failing too): said in the run's reason at
    /// the end, never discarded (the first [`MISSED_KEPT`], then a count).
    pub(super) missed: Vec<String>,
    /// How many more were missed than [`Self::missed`] lists.
    pub(super) missed_more: usize,
}

/// How many missed events the run's reason names one by one.
pub(super) const MISSED_KEPT: usize = 20;

impl Fanout<'_> {
    /// Offer `event` to every subscriber but `failed` (whose write is
    /// held); one that refuses it is noted in [`Self::missed`].
    fn tell_others(&mut self, failed: usize, event: &Event) {
        for (j, sink) in self.sinks.iter_mut().enumerate() {
            if j != failed
                && let Err(e) = sink.emit(event)
            {
                if self.missed.len() >= MISSED_KEPT {
                    self.missed_more += 1;
                    continue;
                }
                self.missed.push(format!(
                    "subscriber {} missed {}: {}",
                    j + 1,
                    event.name(),
                    e.problem
                ));
            }
        }
    }
}

impl Executor<'_> {
    /// Offer `event` to every subscriber in turn; one that refuses it holds
    /// the run until it takes it ([`Self::hold_for_sink`]).
    pub(super) fn emit(&mut self, event: Event) -> Result<(), EngineError> {
        for i in 0..self.fanout.sinks.len() {
            if let Err(problem) = self.fanout.sinks[i].emit(&event) {
                self.hold_for_sink(i, &event, problem.problem)?;
            }
        }
        Ok(())
    }

    /// A subscriber (the store, the journal) could not take an event: nothing
    /// is dropped. The run is held (state Paused; the ports are still read,
    /// the table keeps its commanded rate) and the same event is offered again
    /// every second, until it is taken (the run goes on), the operator aborts,
    /// or [`RunOptions::sink_hold_limit`] passes (a fault: safe state).
    pub(super) fn hold_for_sink(
        &mut self,
        failed: usize,
        event: &Event,
        problem: String,
    ) -> Result<(), EngineError> {
        self.fanout.tell_others(
            failed,
            &Event::Notice {
                message: format!(
                    "{problem}; the run is held (paused) and the write is tried again every second \
                     — fix the database or abort"
                ),
                wording: Some(Wording::new("notice.write_held").with("detail", &problem)),
            },
        );
        // Held through the state table; a run already ended (its last
        // events) has no state to hold, but its write is retried all the same.
        let holding = self.fanout.machine.fire(Trigger::WriteFailed).ok();
        if let Some(state) = holding {
            self.fanout
                .tell_others(failed, &Event::StateChanged { state });
        }
        let held = Instant::now();
        let mut last = problem;
        loop {
            let gave_up = if self.options.abort.is_set() {
                // Whoever set the abort (a user, a signal), named as the
                // flag has it (a SIGTERM is not "the operator").
                Some(EngineError::Aborted(format!(
                    "{} while a write was failing ({last})",
                    self.options.abort.by()
                )))
            } else if held.elapsed() > self.options.sink_hold_limit {
                Some(EngineError::Sink(format!(
                    "{last} (held {:.0} s, sink_hold_limit)",
                    held.elapsed().as_secs_f64()
                )))
            } else {
                None
            };
            if let Some(e) = gave_up {
                if holding.is_some() {
                    self.fanout.machine.fire(Trigger::WriteAbandoned)?;
                }
                return Err(e);
            }
            self.drain_ports(Duration::from_secs(1));
            match self.fanout.sinks[failed].emit(event) {
                Ok(()) => break,
                Err(e) => last = e.problem,
            }
        }
        self.fanout.tell_others(
            failed,
            &Event::Notice {
                message: "the write succeeded; nothing was lost and the run goes on".into(),
                wording: Some(Wording::new("notice.write_resumed")),
            },
        );
        if holding.is_some() {
            let state = self.fanout.machine.fire(Trigger::WriteSucceeded)?;
            self.fanout
                .tell_others(failed, &Event::StateChanged { state });
            // The failed subscriber missed the notice; it gets the state,
            // held again like any event if it cannot take it.
            let changed = Event::StateChanged { state };
            if let Err(e) = self.fanout.sinks[failed].emit(&changed) {
                return self.hold_for_sink(failed, &changed, e.problem);
            }
        }
        Ok(())
    }
}
