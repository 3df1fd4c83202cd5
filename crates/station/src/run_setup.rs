//! One run set-up, shared by `spinbench demo`, `spinbench run` and the web
//! runner: a run directory ([`RunDir`]), and [`prepare`], which checks and
//! compiles the plan once against the station, writes the run's
//! `station.toml` and `plan.toml` and settles which store the run writes to.
//! What comes out ([`Prepared`]) is all [`crate::station_run::execute`] needs.

use anyhow::{Context, Result, bail};
use spinbench_engine::event::Event;
use spinbench_engine::journal::{JOURNAL_FILE, read_journal};
use spinbench_engine::{CompiledPlan, RunState, StationConfig, TestPlan};
use spinbench_store::StoreTarget;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

pub use crate::paths::{
    DB_FILE, DEFAULT_DATA_DIR, PLAN_FILE, RAW_DIR, RUNS_DIR, STATION_FILE, default_store,
};

/// The device sections of a station config (`[centrifuge]`, `[[fmu]]`,
/// `[[power_supply]]`, `[power]`, which names the supplies, and
/// `[chamber]`).
pub const DEVICE_SECTIONS: [&str; 5] = ["centrifuge", "fmu", "power_supply", "power", "chamber"];

/// Whether a station config is the virtual bench's: marked `simulated`,
/// or (a run of a release before the mark) its centrifuge named as the
/// virtual bench names its own (`sim-table`).
fn simulated(config: &toml::Table) -> bool {
    if let Some(flag) = config.get("simulated").and_then(toml::Value::as_bool) {
        return flag;
    }
    config
        .get("centrifuge")
        .and_then(|c| c.get("name"))
        .and_then(toml::Value::as_str)
        == Some("sim-table")
}

/// A new run identifier: the clock and 48 random bits, so that stations
/// sharing one database never pick the same one.
pub fn new_run_id() -> String {
    let t = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap_or_default();
    let random: u64 = rand::random::<u64>() & 0xffff_ffff_ffff;
    format!("run-{}-{random:012x}", t.as_secs())
}

/// A run's directory: `DATA/runs/<id>`, holding its station config, plan,
/// journal, raw captures, results and reports.
#[derive(Debug)]
pub struct RunDir {
    path: PathBuf,
    id: String,
    /// Made by this process for a new run (removed again if the run never starts).
    new: bool,
    /// An exclusive OS lock on the directory, held while this process runs
    /// it: a second `--resume` of the same run (another process, or the web
    /// runner) is refused instead of writing a second record into it.
    _lock: std::fs::File,
}

/// Take the exclusive lock of run directory `path` (flock on the directory
/// itself: nothing is added to the run's files).
fn lock_run_dir(path: &Path) -> Result<std::fs::File> {
    let dir = std::fs::File::open(path)
        .with_context(|| format!("{}: cannot open the run directory", path.display()))?;
    match dir.try_lock() {
        Ok(()) => Ok(dir),
        Err(std::fs::TryLockError::WouldBlock) => bail!(
            "this run is being run by another process now (its directory is locked); wait for it to end, or stop that process first"
        ),
        Err(std::fs::TryLockError::Error(e)) => {
            Err(e).with_context(|| format!("{}: cannot lock the run directory", path.display()))
        }
    }
}

impl RunDir {
    /// A new run directory under `data/runs`, created.
    pub fn create(data: &Path) -> Result<RunDir> {
        let id = new_run_id();
        let path = data.join(RUNS_DIR).join(&id);
        std::fs::create_dir_all(&path)
            .with_context(|| format!("{}: cannot create the run directory", path.display()))?;
        let lock = lock_run_dir(&path).with_context(|| path.display().to_string())?;
        Ok(RunDir {
            path,
            id,
            new: true,
            _lock: lock,
        })
    }

    /// The directory of an existing run, to resume with `plan`: it must
    /// hold a journal that started a run and the plan the run was started
    /// with, and `plan` must be that very plan (two tests are never merged
    /// into one record); the difference is named otherwise.
    pub fn resume(path: &Path, plan: &TestPlan) -> Result<RunDir> {
        // Said as "run ID" (no server path, no command): the web's resume
        // shows these words as they are; the CLI names its argument around.
        let run = format!(
            "run {}",
            path.file_name().unwrap_or_default().to_string_lossy()
        );
        if !path.is_dir() {
            bail!("{run}: no such run directory");
        }
        let lock = lock_run_dir(path).map_err(|e| anyhow::anyhow!("{run}: {e:#}"))?;
        let plan_path = path.join(PLAN_FILE);
        if !path.join(JOURNAL_FILE).is_file() || !plan_path.is_file() {
            bail!(
                "{run}: not a run directory (it has no {JOURNAL_FILE} and {PLAN_FILE}); give the directory of the run to continue, under DATA/{RUNS_DIR}"
            );
        }
        let (events, _) = read_journal(path).map_err(anyhow::Error::msg)?;
        if !events.iter().any(|e| matches!(e, Event::RunStarted { .. })) {
            bail!("{run}: its journal never started a run; start a new run instead");
        }
        let text = std::fs::read_to_string(&plan_path)
            .with_context(|| format!("{run}: cannot read the run's plan ({PLAN_FILE})"))?;
        let own =
            TestPlan::from_toml(&text).with_context(|| format!("{run}: its plan ({PLAN_FILE})"))?;
        let differences = plan_differences(&own, plan);
        if !differences.is_empty() {
            bail!(
                "{run}: the plan given is not the run's own plan ({}); resume with the {PLAN_FILE} in its directory, or start a new run",
                differences.join("; ")
            );
        }
        // A completed run is not run again: refused before anything is
        // connected or a raw file started in it. An aborted or faulted run
        // may be continued.
        if events.iter().any(|e| {
            matches!(
                e,
                Event::RunFinished {
                    state: RunState::Completed,
                    ..
                }
            )
        }) {
            bail!(
                "{run}: this run already completed; nothing to resume (retest its instruments instead, or start a new run)"
            );
        }
        let id = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .with_context(|| format!("{run}: the directory has no name"))?;
        Ok(RunDir {
            path: path.to_path_buf(),
            id,
            new: false,
            _lock: lock,
        })
    }

    /// The directory.
    /// Refuse to continue this run on another station than its own:
    /// `station_toml` (the config it would go on with)
    /// must have the run's station name, be the virtual bench exactly when
    /// the run was recorded on it, and (on hardware) have the same device
    /// sections as the config the run recorded.
    pub fn check_same_station(&self, station_toml: &str) -> Result<()> {
        let recorded_path = self.path.join(STATION_FILE);
        let Ok(recorded_text) = std::fs::read_to_string(&recorded_path) else {
            // A run directory of a release that kept no station config:
            // nothing to compare with.
            return Ok(());
        };
        let parse = |text: &str, what: &str| -> Result<toml::Table> {
            text.parse::<toml::Table>()
                .with_context(|| format!("{what}: not a station config"))
        };
        let recorded = parse(&recorded_text, &recorded_path.display().to_string())?;
        let now = parse(station_toml, "the station config")?;
        let name = |t: &toml::Table| {
            t.get("station")
                .and_then(toml::Value::as_str)
                .unwrap_or("spinbench")
                .to_string()
        };
        let path = format!("run {}", self.id);
        if name(&recorded) != name(&now) {
            bail!(
                "{path}: the run was recorded on station '{}', this is station '{}': continue it on its own station",
                name(&recorded),
                name(&now)
            );
        }
        let (was_sim, is_sim) = (simulated(&recorded), simulated(&now));
        if was_sim != is_sim {
            bail!(
                "{path}: the run was recorded on {}; it cannot be continued on {} (its points would mix two benches): start a new run",
                if was_sim {
                    "the virtual bench"
                } else {
                    "station hardware"
                },
                if is_sim {
                    "the virtual bench"
                } else {
                    "station hardware"
                },
            );
        }
        // What sets the speed or the g of a level: a resume with another
        // arm would label points measured at 32 g as 20 g in the same run.
        let speed_of = |t: &toml::Table| -> Vec<(&'static str, Option<toml::Value>)> {
            let centrifuge = t.get("centrifuge").and_then(toml::Value::as_table);
            vec![
                ("arm", t.get("arm").cloned()),
                ("g_local_m_s2", t.get("g_local_m_s2").cloned()),
                (
                    "centrifuge.max_rate_deg_s",
                    centrifuge.and_then(|c| c.get("max_rate_deg_s").cloned()),
                ),
                (
                    "centrifuge.max_rate_rpm",
                    centrifuge.and_then(|c| c.get("max_rate_rpm").cloned()),
                ),
            ]
        };
        let speed_differ: Vec<&str> = speed_of(&recorded)
            .into_iter()
            .zip(speed_of(&now))
            .filter(|((_, was), (_, is))| was != is)
            .map(|((key, _), _)| key)
            .collect();
        if !speed_differ.is_empty() {
            bail!(
                "{path}: [{}] is not what the run was recorded with (see the {STATION_FILE} in its directory): the speed of every level \
                 and the g its points are labelled with would change within one run; continue it with the \
                 station config it used, or start a new run",
                speed_differ.join("], [")
            );
        }
        if !is_sim {
            let differ: Vec<&str> = DEVICE_SECTIONS
                .into_iter()
                .filter(|key| recorded.get(*key) != now.get(*key))
                .collect();
            if !differ.is_empty() {
                bail!(
                    "{path}: the station's devices are not those the run was recorded with ([{}] differ from the {STATION_FILE} in its directory): continue it with the station config it used, or start a new run",
                    differ.join("], [")
                );
            }
        }
        Ok(())
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The run's identifier (the directory's name).
    pub fn id(&self) -> &str {
        &self.id
    }

    /// The raw captures' directory.
    pub fn raw_dir(&self) -> PathBuf {
        self.path.join(RAW_DIR)
    }

    /// The store this run writes to unless one is given: the data
    /// directory's, `DATA/spinbench.db` for a run in `DATA/runs/<id>`.
    pub fn default_store(&self) -> StoreTarget {
        let data = self
            .path
            .parent()
            .filter(|p| p.file_name().is_some_and(|n| n == RUNS_DIR))
            .and_then(Path::parent)
            .unwrap_or(Path::new("."));
        default_store(data)
    }

    /// Remove a directory made for a run that never started (nothing of
    /// it is worth keeping); an existing run's directory is never touched.
    pub fn discard(self) {
        if self.new {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}

/// What a run starts from.
pub struct Setup {
    /// The station, and its config's text (kept with the run).
    pub station: StationConfig,
    /// The station config's text.
    pub station_toml: String,
    /// The plan.
    pub plan: TestPlan,
    /// The plan's text as the user wrote it (written as `plan.toml`; the
    /// plan serialised when `None`).
    pub plan_text: Option<String>,
    /// The run's directory (new, or the run to resume).
    pub dir: RunDir,
    /// The store, when given (`--db`); the data directory's otherwise.
    pub store: Option<StoreTarget>,
}

/// A run ready to execute.
pub struct Prepared {
    /// The run's directory.
    pub dir: RunDir,
    /// The station.
    pub station: StationConfig,
    /// The station config's text, stored with the run.
    pub station_toml: String,
    /// The plan as written.
    pub plan: TestPlan,
    /// The plan compiled against the station (once, here).
    pub compiled: CompiledPlan,
    /// The store the run writes to.
    pub store: StoreTarget,
    /// True when the run continues from its journal.
    pub resume: bool,
}

/// Why [`prepare`] refused.
#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    /// The plan cannot run on this station (nothing was written).
    #[error(transparent)]
    Plan(#[from] spinbench_engine::plan::PlanError),
    /// The run's files could not be written.
    #[error("{0:#}")]
    Files(anyhow::Error),
}

/// Check the plan against the station and compile it (once), write the
/// run's `station.toml` (and, for a new run, `plan.toml`; a resumed run
/// keeps its own), and settle the store. A plan refused leaves no new run
/// directory behind.
pub fn prepare(setup: Setup) -> Result<Prepared, PrepareError> {
    let Setup {
        station,
        station_toml,
        plan,
        plan_text,
        dir,
        store,
    } = setup;
    let store = store.unwrap_or_else(|| dir.default_store());
    spinbench_store::name_connections(&station.station);
    // A new run's plan carries its prediction from the station's model of
    // its own runs; `levels = "auto"` is designed here, before anything moves.
    let designing = plan.is_auto();
    let plan = if dir.new {
        let learned = crate::station_model::learn(
            &store,
            &station.station,
            crate::station_model::DEFAULT_MODEL_RUNS,
        );
        match plan.designed(&learned.model) {
            Ok(p) => p,
            Err(e) => {
                dir.discard();
                return Err(e.into());
            }
        }
    } else {
        plan
    };
    let mut compiled = match plan.compile(&station) {
        Ok(c) => c,
        Err(e) => {
            dir.discard();
            return Err(e.into());
        }
    };
    // The centrifuge's signature its past runs measured, pooled with the
    // run's own when its points are corrected.
    compiled.table_prior = crate::station_model::table_prior(
        &store,
        &station,
        crate::station_model::DEFAULT_MODEL_RUNS,
    );
    let resume = !dir.new;
    let write = |name: &str, text: &str| -> Result<(), PrepareError> {
        let path = dir.path().join(name);
        std::fs::write(&path, text)
            .with_context(|| format!("{}: cannot write", path.display()))
            .map_err(PrepareError::Files)
    };
    write(STATION_FILE, &station_toml)?;
    if !resume {
        // A designed plan is written as designed (its levels, dwell and prediction).
        let text = match plan_text {
            Some(t) if !designing => t,
            _ => toml::to_string(&plan)
                .context("cannot write the plan as TOML")
                .map_err(PrepareError::Files)?,
        };
        write(PLAN_FILE, &text)?;
    }
    Ok(Prepared {
        dir,
        station,
        station_toml,
        plan,
        compiled,
        store,
        resume,
    })
}

/// The keys in which two plans differ, with both values ("range_g: 70 in the run, 10 given").
pub fn plan_differences(run: &TestPlan, given: &TestPlan) -> Vec<String> {
    fn walk(prefix: &str, a: &toml::Value, b: &toml::Value, out: &mut Vec<String>) {
        let shown = |v: &toml::Value| spinbench_engine::bounds::shown(&v.to_string());
        match (a, b) {
            (toml::Value::Table(x), toml::Value::Table(y)) => {
                let keys: std::collections::BTreeSet<&String> = x.keys().chain(y.keys()).collect();
                for k in keys {
                    let key = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    match (x.get(k), y.get(k)) {
                        (Some(va), Some(vb)) => walk(&key, va, vb, out),
                        (Some(va), None) => {
                            out.push(format!("{key}: {} in the run, none given", shown(va)))
                        }
                        (None, Some(vb)) => {
                            out.push(format!("{key}: none in the run, {} given", shown(vb)))
                        }
                        (None, None) => {}
                    }
                }
            }
            _ if a != b => out.push(format!(
                "{prefix}: {} in the run, {} given",
                shown(a),
                shown(b)
            )),
            _ => {}
        }
    }
    // The prediction is the station's, written when the run started; a
    // plan given as `levels = "auto"` is the run's when the rest agrees
    // (the run's plan holds what was designed).
    let (mut run, mut given) = (run.clone(), given.clone());
    run.prediction = None;
    given.prediction = None;
    if given.is_auto() {
        for plan in [&mut run, &mut given] {
            plan.levels = None;
            plan.down_levels = None;
            plan.up_down = true;
            plan.dwell = Default::default();
        }
    }
    let (run, given) = (&run, &given);
    let mut out = Vec::new();
    match (toml::Value::try_from(run), toml::Value::try_from(given)) {
        (Ok(a), Ok(b)) => walk("", &a, &b, &mut out),
        _ if run != given => out.push("the plans differ".into()),
        _ => {}
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_in_a_data_directory_writes_to_that_directorys_store() {
        let data = std::env::temp_dir().join(format!("spinbench-setup-{}", std::process::id()));
        let dir = RunDir::create(&data).expect("run dir");
        assert!(dir.path().starts_with(data.join(RUNS_DIR)));
        assert_eq!(dir.default_store(), StoreTarget::File(data.join(DB_FILE)));
        let path = dir.path().to_path_buf();
        dir.discard();
        assert!(
            !path.exists(),
            "a new run that never started leaves nothing"
        );
        let _ = std::fs::remove_dir_all(data);
    }
}
