//! The event hub: the web UI's subscription to the engine's event stream.
//! The engine's thread publishes every event here (through [`HubSink`]);
//! the hub numbers them, keeps the current run's log (so a browser that
//! reconnects catches up from its `Last-Event-ID`), keeps a status snapshot
//! for the status panel, and broadcasts to every connected browser.

use serde::Serialize;
use serde_json::Value;
use spinbench_engine::event::{Event, EventSink, ModuleHealth, Wording};
use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};
use tokio::sync::broadcast;

/// One-second value events kept for catching up (the curves' window).
const VALUES_KEPT: usize = 900;
/// Other events kept for catching up (a whole run's prompts, points, notices).
const OTHERS_KEPT: usize = 20_000;

/// One published event.
#[derive(Debug)]
pub struct HubEvent {
    /// Sequence number (the SSE `id`), increasing over the server's life.
    pub seq: u64,
    /// The event's name (`values`, `prompt`, …).
    pub kind: String,
    /// The event as JSON, with `published_ms` (Unix milliseconds when the
    /// hub got it) added, so a client can measure how late it arrives.
    pub json: String,
}

/// The step a run is at.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct StepNow {
    /// Its index among the run's steps (0-based).
    pub index: usize,
    /// How many steps the run has.
    pub of: usize,
    /// Its label ("10 g Up (pass 1)").
    pub label: String,
}

/// Where a settling or an averaging at a level stands.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct ProgressNow {
    /// `settling`, `averaging`, `warm-up`, `soaking`, ….
    pub phase: String,
    /// Done so far.
    pub done: u32,
    /// Of.
    pub of: u32,
}

/// What the status panel shows, kept current from the events.
#[derive(Debug, Clone, Default, Serialize, utoipa::ToSchema)]
pub struct StatusSnapshot {
    /// The run on the station, if any was started since the server began.
    pub run_id: Option<String>,
    /// Its state.
    #[schema(value_type = Option<crate::web::api::schema::LiveRunState>)]
    pub state: Option<spinbench_engine::RunState>,
    /// The current step.
    pub step: Option<StepNow>,
    /// The current step's label as a key and values, for the page's language.
    #[schema(value_type = Option<crate::web::api::schema::Wording>)]
    pub step_wording: Option<Wording>,
    /// Settling or averaging at a level.
    pub progress: Option<ProgressNow>,
    /// Measured rate [deg/s]; null before the first reading and once the
    /// run has ended (nothing is read then), as are the g, the speed's
    /// stability, the supplies and the interlocks.
    pub rate_deg_s: Option<f64>,
    /// Demanded rate [deg/s].
    pub demand_deg_s: Option<f64>,
    /// The run has ended and its safe state was done (the stop commanded
    /// and read back, the rails off; the reason says what was not
    /// confirmed). The run stays `active` while its record is written.
    pub ended: bool,
    /// Applied acceleration at the mean drawing radius [g].
    pub g_at_r0: Option<f64>,
    /// Rate within tolerance.
    pub on_speed: Option<bool>,
    /// Supply outputs: (volts, amperes).
    #[schema(value_type = Vec<Vec<f64>>)]
    pub supply: Vec<(f64, f64)>,
    /// Interlocks closed.
    pub interlocks_closed: Option<bool>,
    /// Counter-module counters.
    #[schema(value_type = Vec<crate::web::api::schema::ModuleCounters>)]
    pub modules: Vec<ModuleHealth>,
    /// The chamber controller's busy replies ridden in this run (null
    /// without a chamber, or before the first health reading).
    pub chamber_busy_replies: Option<u64>,
    /// The prompt waiting for an answer.
    pub prompt: Option<String>,
    /// When the prompt was raised (server time, Unix seconds): the page
    /// shows how long it has waited.
    pub prompt_since_s: Option<f64>,
    /// When the operator's pause began holding the run (server time, Unix
    /// seconds), while it is paused.
    pub paused_since_s: Option<f64>,
    /// The server's time when this status was read (Unix seconds): the
    /// page counts waits against it, not against its own clock.
    pub server_time_s: f64,
    /// The station's time zone (`UTC+08:00`), which its pages show times in.
    pub time_zone: String,
    /// That zone's offset from UTC [min].
    pub utc_offset_min: i32,
    /// The fixture it asks of each slot (for the page's language): null for
    /// a slot it asks nothing of, else the fixture as the engine names it
    /// (`"Up"`, `"Down"`, `{"Arm": "P"}`, `{"Crosswise": {"as_on_arm": true}}`).
    #[schema(value_type = Vec<Option<crate::web::api::schema::FixtureName>>)]
    pub prompt_fixtures: Vec<Option<spinbench_engine::plan::Fixture>>,
    /// The last notices (newest last).
    pub notices: Vec<String>,
    /// Each of `notices` as a key and values (`None` for the server's own).
    #[schema(value_type = Vec<Option<crate::web::api::schema::Wording>>)]
    pub notice_wordings: Vec<Option<Wording>>,
    /// Why the run stopped, when it faulted or was aborted.
    pub reason: Option<String>,
    /// `reason` as a key and values, when the fault that stopped it had one.
    #[schema(value_type = Option<crate::web::api::schema::Wording>)]
    pub reason_wording: Option<Wording>,
    /// Points taken.
    pub points: usize,
    /// Seconds since the run started (wall clock).
    pub elapsed_s: f64,
    /// Estimated seconds to the end: each step by its kind's time so far
    /// in this run, or by the plan before its kind was timed.
    pub eta_s: Option<f64>,
    /// Instruments in the run (slots).
    pub slots: usize,
    /// Serial number per slot.
    pub serials: Vec<Option<String>>,
    /// Every slot's live state (the board).
    #[schema(value_type = Vec<crate::web::api::schema::BoardSlot>)]
    pub board: Vec<spinbench_engine::board::SlotState>,
    /// A fault stopped the run (`reason` says which); its banner stays
    /// until someone acknowledges it.
    pub fault: bool,
    /// Who acknowledged the fault and when, once someone has (audited).
    pub fault_acknowledged: Option<Acknowledgement>,
    /// The run's plan's predicted K2 U95 and centrifuge time.
    #[schema(value_type = Option<crate::web::api::schema::Prediction>)]
    pub prediction: Option<spinbench_engine::plan::PlanPrediction>,
    /// What the run achieved, once it ended: the median K2 U95 and the
    /// centrifuge time of its level steps.
    #[schema(value_type = Option<crate::web::api::schema::AchievedFigures>)]
    pub achieved: Option<spinbench_engine::planning::Achieved>,
}

/// Who acknowledged a fault, and when.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Acknowledgement {
    /// The user.
    pub by: String,
    /// Unix time [s].
    pub at: i64,
}

struct HubState {
    next_seq: u64,
    values: VecDeque<Arc<HubEvent>>,
    others: VecDeque<Arc<HubEvent>>,
    status: StatusSnapshot,
    started: Option<std::time::Instant>,
    board: spinbench_engine::board::SlotBoard,
    clock: super::eta::StepClock,
    /// The run's records so far, for what it achieved.
    records: Vec<spinbench_engine::UnitRecord>,
}

/// The hub; share it in an `Arc`.
pub struct Hub {
    state: Mutex<HubState>,
    tx: broadcast::Sender<Arc<HubEvent>>,
    /// Set when the server shuts down: every event stream ends.
    closing: tokio::sync::watch::Sender<bool>,
    /// Mean drawing radius of the station's fixtures [m], for g at R0.
    r0_m: f64,
    g_local_m_s2: f64,
    /// The station's time zone, which its pages show times in.
    zone: spinbench_engine::time_zone::UtcOffset,
}

/// Why a fault was not acknowledged.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AcknowledgeError {
    /// Someone acknowledged it before.
    #[error("the fault was acknowledged by {by} already")]
    Already {
        /// Who acknowledged it.
        by: String,
    },
    /// No fault waits.
    #[error("no fault waits for acknowledgement")]
    NoFault,
}

impl Hub {
    /// A hub for a station whose fixtures sit at `r0_m` on average.
    pub fn new(r0_m: f64, g_local_m_s2: f64) -> Hub {
        Hub::in_zone(
            r0_m,
            g_local_m_s2,
            spinbench_engine::time_zone::UtcOffset::UTC,
        )
    }

    /// [`Hub::new`] for a station whose pages show times in `zone`.
    pub fn in_zone(
        r0_m: f64,
        g_local_m_s2: f64,
        zone: spinbench_engine::time_zone::UtcOffset,
    ) -> Hub {
        let (tx, _) = broadcast::channel(4096);
        Hub {
            state: Mutex::new(HubState {
                next_seq: 1,
                values: VecDeque::new(),
                others: VecDeque::new(),
                status: StatusSnapshot::default(),
                started: None,
                board: spinbench_engine::board::SlotBoard::new(),
                clock: super::eta::StepClock::default(),
                records: Vec::new(),
            }),
            tx,
            closing: tokio::sync::watch::channel(false).0,
            r0_m,
            g_local_m_s2,
            zone,
        }
    }

    fn lock(&self) -> MutexGuard<'_, HubState> {
        // A panic elsewhere while holding the lock leaves data that is still
        // consistent enough to show; carry on with it.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// End every event stream (the server is shutting down).
    pub fn close(&self) {
        self.closing.send_replace(true);
    }

    /// Becomes true when the event streams are to end.
    pub fn closing(&self) -> tokio::sync::watch::Receiver<bool> {
        self.closing.subscribe()
    }

    /// Subscribe to new events (subscribe before reading the backlog, so
    /// nothing falls between).
    pub fn subscribe(&self) -> broadcast::Receiver<Arc<HubEvent>> {
        self.tx.subscribe()
    }

    /// Events after `seq` still kept, in order.
    pub fn since(&self, seq: u64) -> Vec<Arc<HubEvent>> {
        let state = self.lock();
        let mut out: Vec<Arc<HubEvent>> = state
            .values
            .iter()
            .chain(state.others.iter())
            .filter(|e| e.seq > seq)
            .cloned()
            .collect();
        out.sort_by_key(|e| e.seq);
        out
    }

    /// The status panel's data now.
    pub fn status(&self) -> StatusSnapshot {
        let state = self.lock();
        let mut status = state.status.clone();
        status.server_time_s = unix_now_s();
        status.time_zone = self.zone.to_string();
        status.utc_offset_min = self.zone.minutes();
        status.board = state.board.slots().to_vec();
        if let Some(t) = state.started {
            status.elapsed_s = t.elapsed().as_secs_f64();
            if status.step.is_some() && status.state.is_some_and(|s| !s.is_ended()) {
                status.eta_s = state.clock.eta_s(std::time::Instant::now());
            }
        }
        status
    }

    /// Acknowledge the fault that stopped the station's run, as `by`:
    /// its banner goes; the run id and the fault's reason, for the audit
    /// log. An error when no fault waits for acknowledgement.
    pub fn acknowledge_fault(&self, by: &str) -> Result<(String, String), AcknowledgeError> {
        let mut state = self.lock();
        let s = &mut state.status;
        match (&s.run_id, s.fault, &s.fault_acknowledged) {
            (Some(run_id), true, None) => {
                let found = (run_id.clone(), s.reason.clone().unwrap_or_default());
                s.fault_acknowledged = Some(Acknowledgement {
                    by: by.to_string(),
                    at: spinbench_store::now_s(),
                });
                Ok(found)
            }
            (_, true, Some(a)) => Err(AcknowledgeError::Already { by: a.by.clone() }),
            _ => Err(AcknowledgeError::NoFault),
        }
    }

    /// Publish a message of the server's own (not from the engine), e.g. a
    /// run that could not start.
    pub fn publish_notice(&self, message: &str) {
        self.publish(&Event::Notice {
            message: message.to_string(),
            wording: None,
        });
    }

    /// Publish one engine event.
    pub fn publish(&self, event: &Event) {
        // One serialisation: the event's tag is its kind, and the time it
        // reached the hub goes in beside its fields.
        let mut value = serde_json::to_value(event).unwrap_or_else(|e| {
            serde_json::json!({"event": "notice", "message": format!("an event could not be shown: {e}")})
        });
        let kind = value["event"].as_str().unwrap_or_default().to_string();
        let published_ms = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_millis());
        if let Some(fields) = value.as_object_mut() {
            fields.insert("published_ms".into(), Value::from(published_ms as u64));
        }
        let json = value.to_string();
        let mut state = self.lock();
        let seq = state.next_seq;
        state.next_seq += 1;
        let hub_event = Arc::new(HubEvent { seq, kind, json });
        self.update_status(&mut state, event);
        state.board.apply(event);
        if matches!(event, Event::Values { .. }) {
            state.values.push_back(hub_event.clone());
            while state.values.len() > VALUES_KEPT {
                state.values.pop_front();
            }
        } else {
            state.others.push_back(hub_event.clone());
            while state.others.len() > OTHERS_KEPT {
                state.others.pop_front();
            }
        }
        drop(state);
        // No browser connected is not an error.
        let _ = self.tx.send(hub_event);
    }

    fn update_status(&self, state: &mut HubState, event: &Event) {
        let s = &mut state.status;
        match event {
            Event::RunStarted { run_id, plan, .. } => {
                // A new run: the log starts again (earlier runs are in the store).
                let keep_seq = state.next_seq;
                state.values.clear();
                state.others.clear();
                state.next_seq = keep_seq;
                state.started = Some(std::time::Instant::now());
                state
                    .clock
                    .run_started(&plan.steps, plan.plan.prediction.as_ref());
                state.records.clear();
                *s = StatusSnapshot {
                    run_id: Some(run_id.clone()),
                    prediction: plan.plan.prediction.clone(),
                    state: Some(spinbench_engine::RunState::Running),
                    slots: plan.serials.len(),
                    serials: plan.serials.clone(),
                    ..StatusSnapshot::default()
                };
            }
            Event::StateChanged { state: st } => {
                s.state = Some(*st);
                // Held since when (the Run page shows the held state and for how long).
                s.paused_since_s = match st {
                    spinbench_engine::RunState::Paused => s.paused_since_s.or(Some(unix_now_s())),
                    _ => None,
                };
            }
            Event::StepStarted {
                index,
                of,
                label,
                wording,
            } => {
                state.clock.step_started(*index, std::time::Instant::now());
                s.step = Some(StepNow {
                    index: *index,
                    of: *of,
                    label: label.clone(),
                });
                s.step_wording = wording.clone();
                s.progress = None;
            }
            Event::Progress { phase, done, of } => {
                s.progress = Some(ProgressNow {
                    phase: phase.clone(),
                    done: *done,
                    of: *of,
                })
            }
            Event::Values {
                rate_deg_s,
                demand_deg_s,
                on_speed,
                ..
            } => {
                s.rate_deg_s = Some(*rate_deg_s);
                s.demand_deg_s = Some(*demand_deg_s);
                s.on_speed = Some(*on_speed);
                let w = rate_deg_s.to_radians();
                s.g_at_r0 = Some(w * w * self.r0_m / self.g_local_m_s2);
            }
            Event::Health {
                supply,
                interlocks_closed,
                modules,
                chamber_busy_replies,
            } => {
                s.supply = supply.clone();
                s.interlocks_closed = Some(*interlocks_closed);
                s.modules = modules.clone();
                s.chamber_busy_replies = *chamber_busy_replies;
            }
            Event::Prompt { text, fixtures } => {
                s.prompt = Some(text.clone());
                s.prompt_fixtures = fixtures.clone();
                s.prompt_since_s = Some(unix_now_s());
            }
            Event::PromptAnswered { .. } => {
                s.prompt = None;
                s.prompt_fixtures.clear();
                s.prompt_since_s = None;
            }
            Event::PointDone { .. } => s.points += 1,
            Event::Notice { message, wording } => {
                s.notices.push(message.clone());
                s.notice_wordings.push(wording.clone());
                if s.notices.len() > 5 {
                    s.notices.remove(0);
                    s.notice_wordings.remove(0);
                }
            }
            Event::Fault { reason, wording } => {
                s.reason = Some(reason.clone());
                s.reason_wording = wording.clone();
                // An abort someone asked for ends the run safely: its banner
                // says so (aborted), it is no fault to acknowledge; a stop
                // not confirmed after it still is.
                let asked = wording
                    .as_ref()
                    .is_some_and(|w| w.key == "fault.aborted" || w.key == "fault.aborted_web");
                if !asked {
                    s.fault = true;
                    s.fault_acknowledged = None;
                }
            }
            Event::RunFinished {
                state: st,
                reason,
                wording,
            } => {
                s.state = Some(*st);
                s.reason = reason.clone();
                s.reason_wording = wording.clone();
                s.prompt = None;
                s.prompt_since_s = None;
                s.paused_since_s = None;
                s.eta_s = None;
                s.ended = true;
                s.demand_deg_s = Some(0.0);
                // Nothing is read once the run has ended: the last readings
                // would show a stopped table spinning and dead rails on.
                s.rate_deg_s = None;
                s.g_at_r0 = None;
                s.on_speed = None;
                s.supply.clear();
                s.interlocks_closed = None;
                s.achieved = Some(spinbench_engine::planning::achieved(&state.records));
            }
            Event::UnitResult { record } => state.records.push((**record).clone()),
            _ => {}
        }
    }
}

/// Now, as Unix seconds.
fn unix_now_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// The engine-side subscriber that publishes into a [`Hub`].
pub struct HubSink(pub Arc<Hub>);

impl EventSink for HubSink {
    fn emit(&mut self, event: &Event) -> Result<(), spinbench_engine::event::SinkError> {
        self.0.publish(event);
        Ok(())
    }
}
