//! Runs started from the web UI: one at a time, each on its own thread
//! through the same [`execute`] as `spinbench run`, with [`WebOperator`]
//! answering prompts from the browser (or the MES) and the hub hearing
//! every event.

use super::hub::{Hub, HubSink};
use crate::run_setup::{PrepareError, RunDir, Setup, prepare};
use crate::station_run::{RunControl, connect_bench, execute};
use spinbench_engine::plan::Fixture;
use spinbench_engine::{AbortFlag, Answer, Operator, StationConfig, TestPlan};
use spinbench_store::StoreTarget;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

/// The prompt between the engine's thread (waiting) and the web (answering).
#[derive(Default)]
pub struct PromptSlot {
    state: Mutex<(Option<String>, Option<Answer>)>,
    answered: Condvar,
}

impl PromptSlot {
    fn lock(&self) -> MutexGuard<'_, (Option<String>, Option<Answer>)> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The prompt waiting for an answer.
    pub fn pending(&self) -> Option<String> {
        self.lock().0.clone()
    }

    /// Answer the waiting prompt; false when none waits.
    pub fn answer(&self, answer: Answer) -> bool {
        let mut state = self.lock();
        if state.0.is_none() {
            return false;
        }
        state.0 = None;
        state.1 = Some(answer);
        self.answered.notify_all();
        true
    }
}

/// Whoever moves the instruments once a user answers a prompt: on the
/// station's hardware a person did it before answering (there are no
/// hands to ask); on the virtual bench the simulator remounts its
/// instruments as the prompt asked. The web asks the bench for its hands
/// ([`crate::virtual_bench::VirtualBench`] is one) and never names the
/// simulator.
pub trait Hands: Send + Sync {
    /// Do what the prompt `text` asked, mounting the instruments as `fixtures`.
    fn carry_out(&self, text: &str, fixtures: &[Option<Fixture>]);
}

/// Answers the engine's prompts with what a user sends through the web; on
/// a bench with hands (the virtual bench) they then do what was asked.
pub struct WebOperator {
    slot: Arc<PromptSlot>,
    abort: AbortFlag,
    hands: Option<Arc<dyn Hands>>,
    /// The question posted, for the bench's hands.
    asked: Option<(String, Vec<Option<Fixture>>)>,
}

impl Operator for WebOperator {
    fn ask(&mut self, text: &str, fixtures: &[Option<Fixture>]) -> Answer {
        if let Some(answer) = self.post(text, fixtures) {
            return answer;
        }
        loop {
            if let Some(answer) = self.poll_answer(Duration::from_millis(200)) {
                return answer;
            }
        }
    }

    fn post(&mut self, text: &str, fixtures: &[Option<Fixture>]) -> Option<Answer> {
        let mut state = self.slot.lock();
        state.0 = Some(text.to_string());
        state.1 = None;
        self.asked = Some((text.to_string(), fixtures.to_vec()));
        None
    }

    fn poll_answer(&mut self, wait: Duration) -> Option<Answer> {
        let state = self.slot.lock();
        let (mut state, _) = self
            .slot
            .answered
            .wait_timeout(state, wait)
            .unwrap_or_else(|e| e.into_inner());
        let answer = match state.1.take() {
            Some(answer) => answer,
            None if self.abort.is_set() => {
                state.0 = None;
                // Who asked (the web UI's user, or a signal), as the
                // record names it.
                Answer {
                    proceed: false,
                    by: self.abort.by(),
                }
            }
            None => return None,
        };
        drop(state);
        if answer.proceed
            && let (Some(hands), Some((text, fixtures))) = (&self.hands, self.asked.take())
        {
            hands.carry_out(&text, &fixtures);
        }
        Some(answer)
    }
}

/// The run the web started and still tracks.
pub struct ActiveRun {
    /// Run identifier.
    pub run_id: String,
    /// Who started it.
    pub started_by: String,
    abort: AbortFlag,
    pause: Arc<AtomicBool>,
    prompt: Arc<PromptSlot>,
    finished: Arc<AtomicBool>,
}

/// Why a run could not be started.
#[derive(Debug)]
pub enum StartError {
    /// A run is active.
    Busy(String),
    /// The plan (or its serials) cannot run on this station.
    Invalid(String),
    /// The hardware could not be reached.
    Hardware(String),
    /// The run's directory or files could not be written.
    Files(String),
    /// No such run in this station's data directory.
    NotHere(String),
    /// The run cannot be continued (completed, or run by another process now).
    Refused(String),
    /// Its audit entry could not be written: nothing was started.
    NotAudited(String),
}

/// Why a control of the active run (an answer, a hold, an abort, a new
/// station config) was not taken: each a conflict with the run's state.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ControlError {
    /// No run is active.
    #[error("no run is active")]
    NoActiveRun,
    /// The active run waits on no prompt.
    #[error("no prompt is waiting for an answer")]
    NoPrompt,
    /// A run is active, so the station config cannot change now.
    #[error("run {run_id} is active; change the station after it")]
    RunActive {
        /// The active run.
        run_id: String,
    },
}

/// Writes a run's audit entries once its id is known and before anything
/// is switched on: an error leaves the run unstarted.
pub type Admit<'a> = &'a dyn Fn(&str) -> Result<(), NotAudited>;

/// A run's audit entries could not be written (the store's words).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct NotAudited(pub String);

/// Starts and steers the web's runs.
pub struct Runner {
    /// The station config and its text (an engineer may replace them between runs).
    station: Mutex<(StationConfig, String)>,
    /// The bench's hands (the virtual bench's), when it has them.
    hands: Option<Arc<dyn Hands>>,
    data_dir: PathBuf,
    db: StoreTarget,
    hub: Arc<Hub>,
    active: Mutex<Option<ActiveRun>>,
    /// The store's health as the last run's outbox saw it.
    store_health: crate::station_run::StoreHealthSlot,
}

impl Runner {
    /// A runner for `station` (on a bench with `hands`, the virtual bench's, when given).
    pub fn new(
        station: StationConfig,
        station_toml: String,
        hands: Option<Arc<dyn Hands>>,
        data_dir: PathBuf,
        db: StoreTarget,
        hub: Arc<Hub>,
    ) -> Runner {
        Runner {
            station: Mutex::new((station, station_toml)),
            hands,
            data_dir,
            db,
            hub,
            active: Mutex::new(None),
            store_health: Default::default(),
        }
    }

    /// The store's health as the running (or last) run's outbox sees it:
    /// none before the first run.
    pub fn store_health(&self) -> Option<spinbench_store::outbox::HealthReading> {
        self.store_health
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()
            .map(|h| h.reading())
    }

    /// The station config and its text.
    pub fn station(&self) -> (StationConfig, String) {
        self.station
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Replace the station config (refused while a run is active).
    pub fn set_station(&self, station: StationConfig, text: String) -> Result<(), ControlError> {
        let active = self.lock();
        if let Some(a) = active.as_ref()
            && !a.finished.load(Ordering::Relaxed)
        {
            return Err(ControlError::RunActive {
                run_id: a.run_id.clone(),
            });
        }
        *self.station.lock().unwrap_or_else(|e| e.into_inner()) = (station, text);
        Ok(())
    }

    /// True on the virtual bench (a bench with hands).
    pub fn simulated(&self) -> bool {
        self.hands.is_some()
    }

    fn lock(&self) -> MutexGuard<'_, Option<ActiveRun>> {
        self.active.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The active run's id (a finished run is no longer active).
    pub fn active(&self) -> Option<String> {
        self.lock()
            .as_ref()
            .filter(|a| !a.finished.load(Ordering::Relaxed))
            .map(|a| a.run_id.clone())
    }

    /// Start `plan` (checked against the station first); returns the run id.
    pub fn start(
        &self,
        plan: TestPlan,
        plan_text: &str,
        by: &str,
        admit: Admit<'_>,
    ) -> Result<String, StartError> {
        let mut active = self.lock();
        if let Some(a) = active.as_ref()
            && !a.finished.load(Ordering::Relaxed)
        {
            return Err(StartError::Busy(a.run_id.clone()));
        }
        let dir =
            RunDir::create(&self.data_dir).map_err(|e| StartError::Files(format!("{e:#}")))?;
        if let Err(why) = admit(dir.id()) {
            dir.discard();
            return Err(StartError::NotAudited(why.0));
        }
        self.launch(&mut active, dir, plan, plan_text, by)
    }

    /// Continue run `run_id` of this data directory, left interrupted (its
    /// process ended without finishing it) or ended aborted or faulted,
    /// with its own plan, from its journal (its completed steps kept).
    pub fn resume(&self, run_id: &str, by: &str, admit: Admit<'_>) -> Result<String, StartError> {
        let mut active = self.lock();
        if let Some(a) = active.as_ref()
            && !a.finished.load(Ordering::Relaxed)
        {
            return Err(StartError::Busy(a.run_id.clone()));
        }
        let (dir, plan, plan_text) = self.resumable_dir(run_id)?;
        admit(run_id).map_err(|e| StartError::NotAudited(e.0))?;
        self.launch(&mut active, dir, plan, &plan_text, by)
    }

    /// Whether run `run_id` can be resumed here (its directory, plan,
    /// state and station), asked before the admission gate so that a run
    /// that cannot be resumed is refused for what it is.
    pub fn check_resumable(&self, run_id: &str) -> Result<(), StartError> {
        self.resumable_dir(run_id).map(drop)
    }

    /// The locked directory of a run this station can resume, its plan
    /// and the plan's text.
    fn resumable_dir(&self, run_id: &str) -> Result<(RunDir, TestPlan, String), StartError> {
        let (path, _, plan_text) = self.resumable(run_id)?;
        let plan = TestPlan::from_toml(&plan_text).map_err(|e| {
            StartError::Files(format!(
                "run {run_id}: its plan ({}): {e}",
                crate::run_setup::PLAN_FILE
            ))
        })?;
        let dir =
            RunDir::resume(&path, &plan).map_err(|e| StartError::Refused(format!("{e:#}")))?;
        dir.check_same_station(&self.station().1)
            .map_err(|e| StartError::Refused(format!("{e:#}")))?;
        Ok((dir, plan, plan_text))
    }

    /// The directory, plan file and plan text of a run this station can
    /// resume; refused (not here) for anything else. A run's id names its
    /// directory: nothing else is looked at.
    fn resumable(&self, run_id: &str) -> Result<(PathBuf, PathBuf, String), StartError> {
        if run_id.is_empty()
            || run_id.len() > 64
            || !run_id
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-')
        {
            return Err(StartError::NotHere(format!("'{run_id}' is not a run id")));
        }
        let path = self.data_dir.join(crate::run_setup::RUNS_DIR).join(run_id);
        let plan_path = path.join(crate::run_setup::PLAN_FILE);
        let plan_text = std::fs::read_to_string(&plan_path).map_err(|_| {
            StartError::NotHere(format!(
                "run {run_id} has no directory with its plan on this station: resume it on the station that ran it"
            ))
        })?;
        Ok((path, plan_path, plan_text))
    }

    /// Write the left-over files of this station's ended runs now (before
    /// a new run or a retest, so what they hold, such as a run's end, is in
    /// the store first); what cannot be written waits for the next try.
    pub fn catch_up_left_over(&self) {
        if crate::recovery::left_over_files(&self.data_dir).is_empty() {
            return;
        }
        let Ok(store) = spinbench_store::Store::connect(&self.db) else {
            return;
        };
        let station = self.station().0.station;
        let done = crate::recovery::catch_up_left_over_files(
            &self.data_dir,
            &station,
            &store,
            &mut |_, _| {},
        );
        for line in done.lines() {
            eprintln!("{line}");
        }
    }

    /// Prepare and start the run in `dir` on its own thread.
    fn launch(
        &self,
        active: &mut Option<ActiveRun>,
        dir: RunDir,
        plan: TestPlan,
        plan_text: &str,
        by: &str,
    ) -> Result<String, StartError> {
        self.catch_up_left_over();
        let (station, station_toml) = self.station();
        let prepared = prepare(Setup {
            station,
            station_toml,
            plan,
            plan_text: Some(plan_text.to_string()),
            dir,
            store: Some(self.db.clone()),
        })
        .map_err(|e| match e {
            PrepareError::Plan(e) => StartError::Invalid(e.to_string()),
            PrepareError::Files(e) => StartError::Files(format!("{e:#}")),
        })?;
        let run_id = prepared.dir.id().to_string();
        let bench = match connect_bench(&prepared.station, Some(&prepared.dir.raw_dir())) {
            Ok(bench) => bench,
            Err(e) => {
                // Nothing ran: leave no run directory behind.
                prepared.dir.discard();
                return Err(StartError::Hardware(format!("{e:#}")));
            }
        };
        let abort = AbortFlag::new();
        let pause = Arc::new(AtomicBool::new(false));
        let prompt = Arc::new(PromptSlot::default());
        let finished = Arc::new(AtomicBool::new(false));
        let operator = WebOperator {
            slot: prompt.clone(),
            abort: abort.clone(),
            hands: self.hands.clone(),
            asked: None,
        };
        let control = RunControl {
            abort: abort.clone(),
            pause: pause.clone(),
            sinks: vec![Box::new(HubSink(self.hub.clone()))],
            store_health: self.store_health.clone(),
        };
        let (hub, done) = (self.hub.clone(), finished.clone());
        std::thread::Builder::new()
            .name(format!("run {run_id}"))
            .spawn(move || {
                let result = execute(prepared, bench, Box::new(operator), true, control);
                if let Err(e) = result {
                    hub.publish_notice(&format!("the run could not go on: {e:#}"));
                }
                done.store(true, Ordering::Relaxed);
            })
            .map_err(|e| StartError::Hardware(format!("cannot start the run's thread: {e}")))?;
        *active = Some(ActiveRun {
            run_id: run_id.clone(),
            started_by: by.to_string(),
            abort,
            pause,
            prompt,
            finished,
        });
        Ok(run_id)
    }

    fn with_active<T>(&self, f: impl FnOnce(&ActiveRun) -> T) -> Result<T, ControlError> {
        let active = self.lock();
        match active.as_ref() {
            Some(a) if !a.finished.load(Ordering::Relaxed) => Ok(f(a)),
            _ => Err(ControlError::NoActiveRun),
        }
    }

    /// Answer the active run's prompt.
    pub fn answer(&self, proceed: bool, by: &str) -> Result<String, ControlError> {
        self.with_active(|a| {
            a.prompt
                .answer(Answer {
                    proceed,
                    by: by.to_string(),
                })
                .then(|| a.run_id.clone())
                .ok_or(ControlError::NoPrompt)
        })?
    }

    /// The prompt the active run waits on.
    pub fn prompt(&self) -> Option<String> {
        self.with_active(|a| a.prompt.pending()).ok().flatten()
    }

    /// Hold (true) or resume (false) the active run.
    pub fn pause(&self, on: bool) -> Result<String, ControlError> {
        self.with_active(|a| {
            a.pause.store(on, Ordering::Relaxed);
            a.run_id.clone()
        })
    }

    /// Abort the active run (the engine brings the station to its safe
    /// state); `by` is recorded as who aborted.
    pub fn abort(&self, by: &str) -> Result<String, ControlError> {
        self.with_active(|a| {
            a.abort.request(by);
            a.run_id.clone()
        })
    }

    /// Abort the active run as the web UI's `user` (recorded as "the web
    /// UI (user …)", worded with the user apart).
    pub fn abort_by_user(&self, user: &str) -> Result<String, ControlError> {
        self.with_active(|a| {
            a.abort.request_by_user(user);
            a.run_id.clone()
        })
    }

    /// Abort whatever runs (recording `why`) and wait, at most `limit`, for
    /// it to reach the safe state and be recorded (server shutdown). True
    /// when no run is active any more.
    pub fn shutdown(&self, why: &str, limit: Duration) -> bool {
        let _ = self.abort(why);
        let until = std::time::Instant::now() + limit;
        while std::time::Instant::now() < until {
            if self.active().is_none() {
                return true;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        self.active().is_none()
    }
}
