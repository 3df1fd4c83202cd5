//! The run record: one typed value that says what a run is, read from the
//! store in one call ([`Store::run_record`]) and used by every reader (the
//! reports, the web API, retests, the station's model). It is laid out as a
//! run's documents are (OpenHTF's test record, Bluesky's documents): what
//! was known at the start, the hardware, the units with their points, the
//! operator's actions, the end.
//!
//! No reader parses the store's JSON by path or its states by string: the
//! columns are read back as the enums the engine wrote ([`StoredState`],
//! [`Mount`], [`Direction`], [`DeviceRole`], [`Outcome`]), and a stored plan
//! is read tolerantly ([`StoredPlan`]): an archive outlives today's plan
//! schema, so a plan this release cannot read is kept as it was stored,
//! with the reason, and the few facts a report needs are still read.

use super::{DbError, PointRow, ResultRow, RunRow, Store, StoreError, UnitRow, Value, run_label};
use crate::equipment::CalibrationStatus;
use spinbench_analysis::{Direction, Mount};
use spinbench_engine::event::{DeviceRole, Wording};
use spinbench_engine::{RunState, TestPlan};

/// The layout version of the records this release writes (`runs.record_version`).
/// 1: runs stored before the version was kept (devices as ad-hoc JSON, no
/// result figures as columns); 2: devices as [`DeviceEntry`], result figures
/// as columns of `results`.
pub const RECORD_VERSION: i64 = 2;

/// A run's state as the store keeps it: the engine's ends, `running` while
/// a process runs it, and `interrupted` (its process ended without finishing
/// it: [`Store::mark_interrupted`]). Stored as [`StoredState::as_str`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StoredState {
    /// A process runs it (or died without saying so; the next start marks it).
    Running,
    /// Finished normally.
    Completed,
    /// Ended by a fault, in the safe state.
    Faulted,
    /// Ended by the operator, in the safe state.
    Aborted,
    /// Its process ended without finishing it (a crash, a power cut).
    Interrupted,
}

impl StoredState {
    /// Every stored state.
    pub const ALL: [StoredState; 5] = [
        StoredState::Running,
        StoredState::Completed,
        StoredState::Faulted,
        StoredState::Aborted,
        StoredState::Interrupted,
    ];

    /// Its name in the store, the API and the reports (`completed`).
    pub fn as_str(self) -> &'static str {
        match self {
            StoredState::Running => "running",
            StoredState::Completed => "completed",
            StoredState::Faulted => "faulted",
            StoredState::Aborted => "aborted",
            StoredState::Interrupted => "interrupted",
        }
    }

    /// Whether the run has ended: the one answer every reader asks.
    pub fn is_ended(self) -> bool {
        self != StoredState::Running
    }

    /// The state the store writes for the engine's `state`: its ends as
    /// themselves, any other (a run still going) as `running`.
    pub fn of_engine(state: RunState) -> StoredState {
        match state {
            RunState::Completed => StoredState::Completed,
            RunState::Faulted => StoredState::Faulted,
            RunState::Aborted => StoredState::Aborted,
            _ => StoredState::Running,
        }
    }
}

impl std::fmt::Display for StoredState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for StoredState {
    type Err = spinbench_engine::event::NotARunState;
    /// A stored name; the engine's transient states (an archive written
    /// while a run was paused or prompting) read as `running`.
    fn from_str(text: &str) -> Result<StoredState, Self::Err> {
        if let Some(s) = StoredState::ALL.into_iter().find(|s| s.as_str() == text) {
            return Ok(s);
        }
        text.parse::<RunState>().map(StoredState::of_engine)
    }
}

/// A plan as the store has it: read as this release's [`TestPlan`] when it
/// can be, else kept as stored with the reason (an archive outlives
/// today's plan schema; its report is still made).
#[derive(Debug, Clone, PartialEq)]
pub struct StoredPlan {
    /// The plan, when this release reads it.
    pub plan: Option<TestPlan>,
    /// The plan as stored (JSON).
    pub stored: serde_json::Value,
    /// Why `plan` is `None`.
    pub unread: Option<String>,
}

impl StoredPlan {
    /// Read the stored JSON text.
    pub fn read(text: &str) -> StoredPlan {
        let stored: serde_json::Value = match serde_json::from_str(text) {
            Ok(v) => v,
            Err(e) => {
                return StoredPlan {
                    plan: None,
                    stored: serde_json::Value::Null,
                    unread: Some(format!("the stored plan is not JSON: {e}")),
                };
            }
        };
        match serde_json::from_value::<TestPlan>(stored.clone()) {
            Ok(plan) => StoredPlan {
                plan: Some(plan),
                stored,
                unread: None,
            },
            Err(e) => StoredPlan {
                plan: None,
                stored,
                unread: Some(format!("this release cannot read the stored plan: {e}")),
            },
        }
    }

    /// A text field of the plan: the typed plan's, or the stored one's when
    /// this release cannot read the plan (the one place a stored plan is
    /// read by name, so an archive's report still shows it).
    fn text(&self, typed: impl Fn(&TestPlan) -> &str, name: &str) -> String {
        match &self.plan {
            Some(p) => typed(p).to_string(),
            None => self.stored[name].as_str().unwrap_or_default().to_string(),
        }
    }

    /// The plan's name.
    pub fn name(&self) -> String {
        self.text(|p| &p.name, "name")
    }

    /// Its operator.
    pub fn operator(&self) -> String {
        self.text(|p| &p.operator, "operator")
    }

    /// The decision rule its limits name; `simple` (the value alone) for a
    /// plan stored before the rule was recorded, or one this release cannot read.
    pub fn decision_rule(&self) -> spinbench_engine::plan::DecisionRule {
        match &self.plan {
            Some(p) if !self.stored["limits"]["decision_rule"].is_null() => p.limits.decision_rule,
            _ => spinbench_engine::plan::DecisionRule::Simple,
        }
    }
}

/// One device of a run: what it is, what it said it is, and its
/// calibration as the register had it when the run started.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DeviceEntry {
    /// What it is in the station.
    pub role: DeviceRole,
    /// What it said (or why it could not say).
    pub identity: String,
    /// Its calibration then (`None`: a run made before the register).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<CalibrationStatus>,
    /// Its certificate, when registered.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub certificate: Option<String>,
    /// Calibrated on (YYYY-MM-DD), when registered.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibrated_on: Option<String>,
    /// Due on (YYYY-MM-DD), when registered.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub due_on: Option<String>,
}

/// One thing the operator did during a run.
#[derive(Debug, Clone, PartialEq)]
pub struct OperatorAction {
    /// When [Unix s].
    pub at: i64,
    /// Who.
    pub who: String,
    /// What (English, as an MES reads it).
    pub action: String,
    /// What, as a catalogue key and values (`action.prompt`: `answer` is
    /// `went_on` or `aborted`, `fixtures` the prompt's fixture per slot as
    /// [`spinbench_engine::plan::Fixture::code`]s, comma-separated, empty for
    /// a slot left alone), so a report words it in its language; `None` for
    /// actions recorded before migration 18.
    pub wording: Option<Wording>,
}

/// What a run's notice or fault is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoticeKind {
    /// Something the operator should know; the run went on.
    Notice,
    /// A fault: the run went to the safe state.
    Fault,
}

impl NoticeKind {
    /// As stored (`notice`, `fault`).
    pub fn as_str(self) -> &'static str {
        match self {
            NoticeKind::Notice => "notice",
            NoticeKind::Fault => "fault",
        }
    }
}

/// A notice or fault of the station during a run, kept with its record
/// (migration 18; the event log, which `prune` removes, has them too).
#[derive(Debug, Clone, PartialEq)]
pub struct RunNotice {
    /// When [Unix s].
    pub at: i64,
    /// A notice or a fault.
    pub kind: NoticeKind,
    /// What happened (English).
    pub message: String,
    /// The message as a catalogue key and values, when the engine worded it.
    pub wording: Option<Wording>,
}

/// What was known when the run started.
#[derive(Debug, Clone, PartialEq)]
pub struct RunStart {
    /// Run identifier.
    pub id: String,
    /// Station name.
    pub station: String,
    /// Unix time it started.
    pub started_at: i64,
    /// Its number among its station's runs of its day (the label's `#7`).
    pub seq: Option<i64>,
    /// The plan.
    pub plan: StoredPlan,
    /// The station config (TOML) as the run used it.
    pub station_config: Option<String>,
    /// The software version that started it.
    pub software_version: String,
    /// The run it retests, if it is a retest.
    pub retest_of: Option<String>,
    /// How many times it was started (1, or more after resumes).
    pub starts: i64,
    /// The layout version it was written with ([`RECORD_VERSION`]).
    pub record_version: i64,
    /// The station's offset from UTC when it started [s] (its `time_zone`):
    /// the label's day is the station's.
    pub utc_offset_s: i64,
}

/// How the run ended (or that it has not).
#[derive(Debug, Clone, PartialEq)]
pub struct RunEnd {
    /// Its state.
    pub state: StoredState,
    /// Why, when not completed.
    pub reason: Option<String>,
    /// The reason as a key and values, for another language.
    pub reason_wording: Option<Wording>,
    /// When it ended [Unix s] (`None` while running).
    pub finished_at: Option<i64>,
}

/// A whole run, as the store has it (see the module's documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct RunRecord {
    /// What was known at the start.
    pub start: RunStart,
    /// The hardware (empty before the devices answered).
    pub devices: Vec<DeviceEntry>,
    /// Each instrument's radius per mounting.
    pub radii: Vec<UnitRow>,
    /// The points, in the order taken.
    pub points: Vec<PointRow>,
    /// Each instrument's result (its whole typed record).
    pub results: Vec<ResultRow>,
    /// What the operator did.
    pub operator_actions: Vec<OperatorAction>,
    /// What the station told the operator (notices and faults), in order.
    pub notices: Vec<RunNotice>,
    /// The end (its state is `running` while it goes on).
    pub end: RunEnd,
}

impl RunRecord {
    /// The run as a listing shows it.
    pub fn row(&self) -> RunRow {
        RunRow {
            id: self.start.id.clone(),
            station: self.start.station.clone(),
            state: self.end.state,
            reason: self.end.reason.clone(),
            started_at: self.start.started_at,
            units: self.results.len() as i64,
            points: self.points.len() as i64,
            retest_of: self.start.retest_of.clone(),
            reason_wording: self.end.reason_wording.clone(),
            seq: self.start.seq,
            utc_offset_s: self.start.utc_offset_s,
        }
    }

    /// Its label (`2026-11-24 · station 1 · #7`).
    pub fn label(&self) -> String {
        match self.start.seq {
            Some(seq) => run_label(
                self.start.started_at + self.start.utc_offset_s,
                &self.start.station,
                seq,
            ),
            None => self.start.id.clone(),
        }
    }
}

/// The figures of a result people query, kept as columns of `results`
/// beside the whole record (a dashboard or an MES reads them with SQL).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ResultFigures {
    /// Mounting P's k2 [µg/g²].
    pub k2_p: Option<f64>,
    /// Its U95 [µg/g²].
    pub k2_p_u95: Option<f64>,
    /// Mounting N's k2 [µg/g²].
    pub k2_n: Option<f64>,
    /// Its U95 [µg/g²].
    pub k2_n_u95: Option<f64>,
    /// The instrument's own K2 = (k2_P − k2_N)/2 [µg/g²].
    pub instrument_k2: Option<f64>,
    /// Its U95 [µg/g²].
    pub instrument_k2_u95: Option<f64>,
    /// The quantity the verdict judged (`K2`, `k2_max`).
    pub measurand: Option<&'static str>,
    /// Its limit [µg/g²].
    pub limit: Option<f64>,
}

impl ResultFigures {
    /// The figures of `record`.
    pub fn of(record: &spinbench_engine::UnitRecord) -> ResultFigures {
        let fit = |m: Mount| record.analysis.as_ref().and_then(|a| a.fits.get(&m));
        let k2 = |m: Mount| fit(m).and_then(|f| f.fit.k2_ug_per_g2);
        let u95 = |m: Mount| {
            fit(m)
                .and_then(|f| f.uncertainty.as_ref())
                .and_then(|c| c.k2_ug_per_g2.as_ref())
                .map(|u| u.u95)
        };
        let joint = record.analysis.as_ref().and_then(|a| a.joint.as_ref());
        ResultFigures {
            k2_p: k2(Mount::P),
            k2_p_u95: u95(Mount::P),
            k2_n: k2(Mount::N),
            k2_n_u95: u95(Mount::N),
            instrument_k2: joint.map(|j| j.k2_even_ug_per_g2),
            instrument_k2_u95: joint.and_then(|j| j.k2_even_u95),
            measurand: record.decision.map(|d| d.measurand.name()),
            limit: record.decision.map(|d| d.limit_ug_per_g2),
        }
    }
}

/// A slot as the store keeps it: numbered from 1, as people number them
/// (migration 16); the engine's and the rows' `slot` is an index from 0.
pub(crate) fn stored_slot(index: usize) -> i64 {
    index as i64 + 1
}

/// The index (from 0) of a slot the store keeps numbered from 1.
pub(crate) fn slot_index(stored: i64) -> i64 {
    stored - 1
}

/// The parameters of a `results` row, in the order the sink's insert and
/// `Store::replace_result`'s update both take them: run, slot, serial,
/// outcome, k2_max, the record (JSON), then its [`ResultFigures`].
pub(crate) fn result_row_values(
    run_id: &str,
    record: &spinbench_engine::UnitRecord,
    json: &str,
) -> Vec<Value> {
    let f = ResultFigures::of(record);
    vec![
        run_id.into(),
        stored_slot(record.slot).into(),
        record.serial.as_str().into(),
        record.outcome.as_str().into(),
        record.k2_max_ug_per_g2.into(),
        json.into(),
        f.k2_p.into(),
        f.k2_p_u95.into(),
        f.k2_n.into(),
        f.k2_n_u95.into(),
        f.instrument_k2.into(),
        f.instrument_k2_u95.into(),
        f.measurand.map(str::to_string).into(),
        f.limit.into(),
    ]
}

/// Read a stored enumeration column: `what` names it in the error.
pub(crate) fn parse_column<T: std::str::FromStr>(text: &str, what: &str) -> Result<T, DbError> {
    text.parse::<T>()
        .map_err(|_| format!("'{text}' is not a {what}").into())
}

/// A stored mount (`P`, `N`).
pub(crate) fn stored_mount(text: &str) -> Result<Mount, DbError> {
    Mount::parse(text).ok_or_else(|| format!("'{text}' is not a mounting (P or N)").into())
}

/// A stored direction (`up`, `down`).
pub(crate) fn stored_direction(text: &str) -> Result<Direction, DbError> {
    Direction::parse(text).ok_or_else(|| format!("'{text}' is not a direction (up or down)").into())
}

/// The devices as stored in `runs.devices_json`: a list of
/// [`DeviceEntry`]; an entry whose role this release does not know is
/// left out of the typed list (and said in the error only when none reads).
pub(crate) fn stored_devices(text: &str) -> Result<Vec<DeviceEntry>, DbError> {
    let listed: Vec<serde_json::Value> = serde_json::from_str(text)
        .map_err(|e| -> DbError { format!("the stored device list: {e}").into() })?;
    Ok(listed
        .into_iter()
        .filter_map(|d| serde_json::from_value::<DeviceEntry>(d).ok())
        .collect())
}

impl Store {
    /// What was known when run `id` started (its plan, station config,
    /// software): the start of its record, without its points and results.
    pub fn run_start(&self, id: &str) -> Result<Option<RunStart>, StoreError> {
        Ok(self.run_head(id)?.map(|(start, _, _)| start))
    }

    /// The run's row: its start, its devices and its end.
    fn run_head(
        &self,
        id: &str,
    ) -> Result<Option<(RunStart, Vec<DeviceEntry>, RunEnd)>, StoreError> {
        let Some(row) = self
            .query(
                "read a run",
                "SELECT id, station, started_at, seq, plan_json, station_config, software_version,
                        retest_of, starts, record_version, devices_json, state, reason,
                        reason_wording, finished_at, utc_offset_s
                 FROM runs WHERE id = $1",
                &[id.into()],
            )?
            .into_iter()
            .next()
        else {
            return Ok(None);
        };
        let unreadable = |problem: DbError| StoreError {
            target: self.target.to_string(),
            what: format!("read run {id}"),
            reason: problem,
        };
        let start = RunStart {
            id: row.text(0),
            station: row.text(1),
            started_at: row.int(2),
            seq: row.opt_int(3),
            plan: StoredPlan::read(&row.text(4)),
            station_config: row.opt_text(5),
            software_version: row.text(6),
            retest_of: row.opt_text(7),
            starts: row.int(8),
            record_version: row.opt_int(9).unwrap_or(1),
            utc_offset_s: row.int(15),
        };
        let devices = match row.opt_text(10) {
            Some(text) => stored_devices(&text).map_err(unreadable)?,
            None => Vec::new(),
        };
        let end = RunEnd {
            state: parse_column(&row.text(11), "run state").map_err(unreadable)?,
            reason: row.opt_text(12),
            reason_wording: row
                .opt_text(13)
                .and_then(|json| serde_json::from_str(&json).ok()),
            finished_at: row.opt_int(14),
        };
        Ok(Some((start, devices, end)))
    }

    /// The whole record of run `id` (`None`: no such run), in one call.
    pub fn run_record(&self, id: &str) -> Result<Option<RunRecord>, StoreError> {
        let Some((start, devices, end)) = self.run_head(id)? else {
            return Ok(None);
        };
        let wording =
            |text: Option<String>| text.and_then(|t| serde_json::from_str::<Wording>(&t).ok());
        let operator_actions = self
            .query(
                "read operator actions",
                "SELECT at, who, action, wording_json FROM operator_actions WHERE run_id = $1 ORDER BY seq",
                &[id.into()],
            )?
            .iter()
            .map(|r| OperatorAction {
                at: r.int(0),
                who: r.text(1),
                action: r.text(2),
                wording: wording(r.opt_text(3)),
            })
            .collect();
        let notices = self
            .query(
                "read the run's notices",
                "SELECT at, kind, message, wording_json FROM run_notices WHERE run_id = $1 ORDER BY seq",
                &[id.into()],
            )?
            .iter()
            .map(|r| RunNotice {
                at: r.int(0),
                kind: if r.text(1) == "fault" {
                    NoticeKind::Fault
                } else {
                    NoticeKind::Notice
                },
                message: r.text(2),
                wording: wording(r.opt_text(3)),
            })
            .collect();
        Ok(Some(RunRecord {
            start,
            devices,
            radii: self.unit_radii(id)?,
            points: self.points(id)?,
            results: self.results(id)?,
            operator_actions,
            notices,
            end,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stored_states_read_back_as_written_and_transients_as_running() {
        for s in StoredState::ALL {
            assert_eq!(s.as_str().parse::<StoredState>(), Ok(s));
        }
        assert_eq!("paused".parse::<StoredState>(), Ok(StoredState::Running));
        assert!("created".parse::<StoredState>().is_err());
        assert!(StoredState::Interrupted.is_ended());
        assert!(!StoredState::Running.is_ended());
    }

    #[test]
    fn a_plan_this_release_cannot_read_keeps_its_name_and_reason() {
        let old = StoredPlan::read(r#"{"name":"archive 2019","operator":"Li","steps":"?"}"#);
        assert!(old.plan.is_none());
        assert_eq!(old.name(), "archive 2019");
        assert_eq!(old.operator(), "Li");
        assert!(old.unread.as_deref().unwrap_or("").contains("cannot read"));
        let garbage = StoredPlan::read("not json");
        assert_eq!(garbage.name(), "");
        assert!(garbage.unread.is_some());
    }

    #[test]
    fn device_entries_keep_the_old_layout_and_skip_unknown_roles() {
        let text = r#"[{"role":"centrifuge","identity":"CT-1"},
            {"role":"fmu 2","identity":"firmware 0x0102","calibration":"valid","certificate":"C-7","calibrated_on":"2026-01-01","due_on":"2027-01-01"},
            {"role":"laser","identity":"?"}]"#;
        let devices = stored_devices(text).expect("reads");
        assert_eq!(devices.len(), 2);
        assert_eq!(devices[1].role, DeviceRole::Fmu(2));
        assert_eq!(devices[1].certificate.as_deref(), Some("C-7"));
        assert!(devices[0].calibration.is_none());
    }
}
