//! Persistence of runs in an SQLite file (WAL; committed data survive a killed process): the
//! store subscribes to the engine's event stream ([`StoreSink`]) and answers
//! queries (runs, a run's results, every run of one serial number) and
//! exports (a point export is valid input for `spinbench analyze`).
//!
//! The schema is versioned: each migration in [`MIGRATIONS`] runs once, and
//! `PRAGMA user_version` records how far a file has come.

use rusqlite::{Connection, OptionalExtension, params};
use spinbench_engine::event::{Event, EventSink};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

/// Schema migrations, in order; never edit one that has shipped, add a new one.
pub const MIGRATIONS: &[&str] = &[
    // 1: runs, points, per-instrument results, the event log.
    "CREATE TABLE runs (
        id TEXT PRIMARY KEY,
        station TEXT NOT NULL,
        plan_json TEXT NOT NULL,
        software_version TEXT NOT NULL,
        state TEXT NOT NULL,
        reason TEXT,
        started_at INTEGER NOT NULL,
        finished_at INTEGER,
        starts INTEGER NOT NULL DEFAULT 1
    );
    CREATE TABLE points (
        run_id TEXT NOT NULL REFERENCES runs(id),
        step INTEGER NOT NULL,
        slot INTEGER NOT NULL,
        serial TEXT NOT NULL,
        mount TEXT NOT NULL,
        g_nominal REAL NOT NULL,
        direction TEXT NOT NULL,
        g_applied REAL NOT NULL,
        rate_deg_s REAL NOT NULL,
        output_hz REAL NOT NULL,
        std_hz REAL NOT NULL,
        n INTEGER NOT NULL,
        t0_s REAL NOT NULL,
        t1_s REAL NOT NULL,
        PRIMARY KEY (run_id, step, slot)
    );
    CREATE TABLE results (
        run_id TEXT NOT NULL REFERENCES runs(id),
        slot INTEGER NOT NULL,
        serial TEXT NOT NULL,
        outcome TEXT NOT NULL,
        k2_max_ug_per_g2 REAL,
        record_json TEXT NOT NULL,
        PRIMARY KEY (run_id, slot)
    );
    CREATE INDEX results_serial ON results(serial);
    CREATE TABLE events (
        seq INTEGER PRIMARY KEY AUTOINCREMENT,
        run_id TEXT NOT NULL,
        at INTEGER NOT NULL,
        kind TEXT NOT NULL,
        json TEXT NOT NULL
    );",
    // 2: the one-second values of every instrument (and the rate), as the engine saw them.
    "CREATE TABLE values_1s (
        run_id TEXT NOT NULL,
        t_s REAL NOT NULL,
        slot INTEGER NOT NULL,
        output_hz REAL,
        rate_deg_s REAL NOT NULL,
        on_speed INTEGER NOT NULL,
        PRIMARY KEY (run_id, t_s, slot)
    ) WITHOUT ROWID;",
];

/// A store operation failed; says which file and what to do.
#[derive(Debug, thiserror::Error)]
#[error("store {path}: {what}: {source}")]
pub struct StoreError {
    /// The database file.
    pub path: String,
    /// What was being done.
    pub what: String,
    /// The database's reason.
    #[source]
    pub source: rusqlite::Error,
}

fn now_s() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64)
}

/// An open store.
pub struct Store {
    conn: Connection,
    path: PathBuf,
}

/// One run in a listing.
#[derive(Debug, Clone, PartialEq)]
pub struct RunRow {
    /// Run identifier.
    pub id: String,
    /// Station name.
    pub station: String,
    /// Final (or current) state.
    pub state: String,
    /// Why it ended, if not completed.
    pub reason: Option<String>,
    /// Unix time it started.
    pub started_at: i64,
    /// Instruments with results.
    pub units: i64,
    /// Points stored.
    pub points: i64,
}

/// One instrument's result in one run.
#[derive(Debug, Clone, PartialEq)]
pub struct ResultRow {
    /// Run identifier.
    pub run_id: String,
    /// Slot (0-based).
    pub slot: i64,
    /// Serial number.
    pub serial: String,
    /// pass, marginal or fail.
    pub outcome: String,
    /// k2_max [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// The whole record (JSON).
    pub record_json: String,
}

impl Store {
    /// Open (creating if needed) the store at `path` and bring its schema up to date.
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        let err = |what: &str| {
            let p = path.display().to_string();
            let what = what.to_string();
            move |source| StoreError {
                path: p.clone(),
                what: what.clone(),
                source,
            }
        };
        if let Some(dir) = path.parent()
            && !dir.as_os_str().is_empty()
        {
            let _ = std::fs::create_dir_all(dir);
        }
        let conn = Connection::open(path).map_err(err("cannot open the database"))?;
        // WAL and full sync: a committed point survives the process being killed.
        conn.pragma_update(None, "journal_mode", "WAL")
            .map_err(err("cannot enable WAL"))?;
        conn.pragma_update(None, "synchronous", "FULL")
            .map_err(err("cannot set synchronous"))?;
        conn.busy_timeout(std::time::Duration::from_secs(10))
            .map_err(err("cannot set the busy timeout"))?;
        let version: i64 = conn
            .pragma_query_value(None, "user_version", |r| r.get(0))
            .map_err(err("cannot read the schema version"))?;
        for (i, migration) in MIGRATIONS.iter().enumerate().skip(version.max(0) as usize) {
            let tx = conn
                .unchecked_transaction()
                .map_err(err("cannot begin a migration"))?;
            tx.execute_batch(migration)
                .map_err(err(&format!("migration {}", i + 1)))?;
            tx.pragma_update(None, "user_version", (i + 1) as i64)
                .map_err(err("cannot record the schema version"))?;
            tx.commit().map_err(err("cannot commit a migration"))?;
        }
        Ok(Store {
            conn,
            path: path.to_path_buf(),
        })
    }

    fn err(&self, what: &str) -> impl Fn(rusqlite::Error) -> StoreError + '_ {
        let what = what.to_string();
        move |source| StoreError {
            path: self.path.display().to_string(),
            what: what.clone(),
            source,
        }
    }

    /// The schema version of the file.
    pub fn schema_version(&self) -> Result<i64, StoreError> {
        self.conn
            .pragma_query_value(None, "user_version", |r| r.get(0))
            .map_err(self.err("cannot read the schema version"))
    }

    /// The result of `PRAGMA integrity_check` ("ok" when sound).
    pub fn integrity_check(&self) -> Result<String, StoreError> {
        self.conn
            .query_row("PRAGMA integrity_check", [], |r| r.get(0))
            .map_err(self.err("integrity check"))
    }

    /// Every run, newest first.
    pub fn runs(&self) -> Result<Vec<RunRow>, StoreError> {
        let mut stmt = self
            .conn
            .prepare(
                "SELECT r.id, r.station, r.state, r.reason, r.started_at,
                        (SELECT COUNT(*) FROM results s WHERE s.run_id = r.id),
                        (SELECT COUNT(*) FROM points p WHERE p.run_id = r.id)
                 FROM runs r ORDER BY r.started_at DESC, r.id DESC",
            )
            .map_err(self.err("list runs"))?;
        let rows = stmt
            .query_map([], |r| {
                Ok(RunRow {
                    id: r.get(0)?,
                    station: r.get(1)?,
                    state: r.get(2)?,
                    reason: r.get(3)?,
                    started_at: r.get(4)?,
                    units: r.get(5)?,
                    points: r.get(6)?,
                })
            })
            .map_err(self.err("list runs"))?;
        rows.collect::<Result<_, _>>()
            .map_err(self.err("list runs"))
    }

    /// One run, if it exists.
    pub fn run(&self, id: &str) -> Result<Option<RunRow>, StoreError> {
        Ok(self.runs()?.into_iter().find(|r| r.id == id))
    }

    fn results_where(&self, clause: &str, arg: &str) -> Result<Vec<ResultRow>, StoreError> {
        let sql = format!(
            "SELECT s.run_id, s.slot, s.serial, s.outcome, s.k2_max_ug_per_g2, s.record_json
             FROM results s JOIN runs r ON r.id = s.run_id WHERE {clause} ORDER BY r.started_at, s.run_id, s.slot"
        );
        let mut stmt = self.conn.prepare(&sql).map_err(self.err("query results"))?;
        let rows = stmt
            .query_map([arg], |r| {
                Ok(ResultRow {
                    run_id: r.get(0)?,
                    slot: r.get(1)?,
                    serial: r.get(2)?,
                    outcome: r.get(3)?,
                    k2_max_ug_per_g2: r.get(4)?,
                    record_json: r.get(5)?,
                })
            })
            .map_err(self.err("query results"))?;
        rows.collect::<Result<_, _>>()
            .map_err(self.err("query results"))
    }

    /// The per-instrument results of one run.
    pub fn results(&self, run_id: &str) -> Result<Vec<ResultRow>, StoreError> {
        self.results_where("s.run_id = ?1", run_id)
    }

    /// Every result of one serial number, oldest run first.
    pub fn unit_history(&self, serial: &str) -> Result<Vec<ResultRow>, StoreError> {
        self.results_where("s.serial = ?1", serial)
    }

    /// The points of a run as CSV in the `spinbench analyze` format
    /// (`unit,mount,g_nominal,g_applied,output,direction,run`), in the order taken.
    pub fn points_csv(&self, run_id: &str) -> Result<String, StoreError> {
        let mut stmt = self
            .conn
            .prepare(
                "SELECT serial, mount, g_nominal, g_applied, output_hz, direction
                 FROM points WHERE run_id = ?1 ORDER BY step, slot",
            )
            .map_err(self.err("export points"))?;
        let mut out = String::from("unit,mount,g_nominal,g_applied,output,direction,run\n");
        let rows = stmt
            .query_map([run_id], |r| {
                Ok((
                    r.get::<_, String>(0)?,
                    r.get::<_, String>(1)?,
                    r.get::<_, f64>(2)?,
                    r.get::<_, f64>(3)?,
                    r.get::<_, f64>(4)?,
                    r.get::<_, String>(5)?,
                ))
            })
            .map_err(self.err("export points"))?;
        for row in rows {
            let (serial, mount, g, ga, out_hz, dir) = row.map_err(self.err("export points"))?;
            // `{:?}` on f64 prints the shortest text that reads back to the same number.
            out.push_str(&format!(
                "{},{mount},{g:?},{ga:?},{out_hz:?},{dir},{run_id}\n",
                csv_field(&serial)
            ));
        }
        Ok(out)
    }

    /// Number of one-second values stored for a run.
    pub fn value_count(&self, run_id: &str) -> Result<i64, StoreError> {
        self.conn
            .query_row(
                "SELECT COUNT(*) FROM values_1s WHERE run_id = ?1",
                [run_id],
                |r| r.get(0),
            )
            .map_err(self.err("count one-second values"))
    }

    /// The (step, slot) keys of a run's stored points.
    pub fn point_keys(&self, run_id: &str) -> Result<Vec<(i64, i64)>, StoreError> {
        let mut stmt = self
            .conn
            .prepare("SELECT step, slot FROM points WHERE run_id = ?1 ORDER BY step, slot")
            .map_err(self.err("point keys"))?;
        let rows = stmt
            .query_map([run_id], |r| Ok((r.get(0)?, r.get(1)?)))
            .map_err(self.err("point keys"))?;
        rows.collect::<Result<_, _>>()
            .map_err(self.err("point keys"))
    }

    /// A sink that writes the events of the run to this store's file.
    pub fn sink(&self) -> Result<StoreSink, StoreError> {
        Ok(StoreSink {
            store: Store::open(&self.path)?,
            serials: Vec::new(),
            run_id: String::new(),
        })
    }
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Writes a run's events as they happen. A failed write is an error the
/// engine turns into a fault (the run stops safely; nothing passes with an
/// empty database).
pub struct StoreSink {
    store: Store,
    serials: Vec<Option<String>>,
    run_id: String,
}

impl StoreSink {
    fn write(&mut self, event: &Event) -> Result<(), StoreError> {
        let conn = &self.store.conn;
        let err = |what: &str| {
            let p = self.store.path.display().to_string();
            let what = what.to_string();
            move |source| StoreError {
                path: p.clone(),
                what: what.clone(),
                source,
            }
        };
        match event {
            Event::Progress { .. } => return Ok(()),
            Event::Values {
                time_s,
                rate_deg_s,
                on_speed,
                outputs_hz,
                ..
            } => {
                let tx = conn
                    .unchecked_transaction()
                    .map_err(err("begin one-second values"))?;
                {
                    let mut stmt = tx
                        .prepare_cached(
                            "INSERT OR REPLACE INTO values_1s (run_id, t_s, slot, output_hz, rate_deg_s, on_speed)
                             VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                        )
                        .map_err(err("prepare one-second values"))?;
                    for (slot, v) in outputs_hz.iter().enumerate() {
                        if self.serials.get(slot).is_some_and(Option::is_some) {
                            stmt.execute(params![
                                self.run_id,
                                time_s,
                                slot as i64,
                                v,
                                rate_deg_s,
                                i64::from(*on_speed)
                            ])
                            .map_err(err("store one-second values"))?;
                        }
                    }
                }
                tx.commit().map_err(err("commit one-second values"))?;
                return Ok(());
            }
            Event::RunStarted {
                run_id,
                station,
                plan,
                resumed,
            } => {
                self.run_id = run_id.clone();
                self.serials = plan.serials.clone();
                let plan_json = serde_json::to_string(&plan.plan).unwrap_or_default();
                let existing: Option<String> = conn
                    .query_row("SELECT id FROM runs WHERE id = ?1", [run_id], |r| r.get(0))
                    .optional()
                    .map_err(err("look up the run"))?;
                if existing.is_some() {
                    conn.execute(
                        "UPDATE runs SET starts = starts + 1, state = 'running' WHERE id = ?1",
                        [run_id],
                    )
                    .map_err(err("record a resumed run"))?;
                } else {
                    conn.execute(
                        "INSERT INTO runs (id, station, plan_json, software_version, state, started_at, starts)
                         VALUES (?1, ?2, ?3, ?4, 'running', ?5, ?6)",
                        params![run_id, station, plan_json, env!("CARGO_PKG_VERSION"), now_s(), 1 + i64::from(*resumed)],
                    )
                    .map_err(err("record the run"))?;
                }
            }
            Event::PointDone { step, points } => {
                let tx = conn.unchecked_transaction().map_err(err("begin a point"))?;
                for p in points {
                    let serial = self
                        .serials
                        .get(p.slot)
                        .cloned()
                        .flatten()
                        .unwrap_or_default();
                    // A step redone after a resume replaces its row: nothing doubled.
                    tx.execute(
                        "INSERT OR REPLACE INTO points (run_id, step, slot, serial, mount, g_nominal, direction,
                           g_applied, rate_deg_s, output_hz, std_hz, n, t0_s, t1_s)
                         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14)",
                        params![
                            self.run_id,
                            *step as i64,
                            p.slot as i64,
                            serial,
                            p.mount.to_string(),
                            p.g_nominal,
                            format!("{:?}", p.direction).to_lowercase(),
                            p.g_applied,
                            p.rate_deg_s,
                            p.output_hz,
                            p.std_hz,
                            i64::from(p.n),
                            p.time_s[0],
                            p.time_s[1]
                        ],
                    )
                    .map_err(err("store a point"))?;
                }
                tx.commit().map_err(err("commit a point"))?;
            }
            Event::UnitResult { record } => {
                let json = serde_json::to_string(record).unwrap_or_default();
                conn.execute(
                    "INSERT OR REPLACE INTO results (run_id, slot, serial, outcome, k2_max_ug_per_g2, record_json)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                    params![
                        self.run_id,
                        record.slot as i64,
                        record.serial,
                        format!("{:?}", record.outcome).to_lowercase(),
                        record.k2_max_ug_per_g2,
                        json
                    ],
                )
                .map_err(err("store a result"))?;
            }
            Event::RunFinished { state, reason } => {
                conn.execute(
                    "UPDATE runs SET state = ?2, reason = ?3, finished_at = ?4 WHERE id = ?1",
                    params![
                        self.run_id,
                        format!("{state:?}").to_lowercase(),
                        reason,
                        now_s()
                    ],
                )
                .map_err(err("record the end of the run"))?;
            }
            _ => {}
        }
        let kind = serde_json::to_value(event)
            .ok()
            .and_then(|v| v["event"].as_str().map(str::to_string))
            .unwrap_or_default();
        let json = serde_json::to_string(event).unwrap_or_default();
        self.store
            .conn
            .execute(
                "INSERT INTO events (run_id, at, kind, json) VALUES (?1, ?2, ?3, ?4)",
                params![self.run_id, now_s(), kind, json],
            )
            .map_err(err("log an event"))?;
        Ok(())
    }
}

impl EventSink for StoreSink {
    fn emit(&mut self, event: &Event) -> Result<(), String> {
        self.write(event).map_err(|e| e.to_string())
    }
}
