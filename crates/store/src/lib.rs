//! Persistence of runs: an SQLite file by default (WAL; committed data survive
//! a killed process), or a PostgreSQL server shared by many stations
//! (`postgres://…`), with the same schema and behaviour. The store subscribes
//! to the engine's event stream ([`StoreSink`]) and answers queries (runs, a
//! run's results, every run of one serial number) and exports (a point export
//! is valid input for `spinbench analyze`).
//!
//! The schema is versioned: each migration in [`MIGRATIONS`] runs once, in
//! one transaction; SQLite records how far a file has come in
//! `PRAGMA user_version`, PostgreSQL in the table `spinbench_schema` (under
//! an advisory lock, so stations starting together migrate once).

pub mod db;
mod users;

pub use users::{AuditRow, UserRow};

use db::{Db, DbError, Dialect, Row, Value};
use spinbench_engine::event::{Event, EventSink};
use std::cell::RefCell;
use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

/// One schema migration, as SQLite and PostgreSQL spell it.
#[derive(Debug, Clone, Copy)]
pub struct Migration {
    /// What it adds.
    pub what: &'static str,
    /// SQLite's text.
    pub sqlite: &'static str,
    /// PostgreSQL's text.
    pub postgres: &'static str,
}

/// Schema migrations, in order; never edit one that has shipped, add a new one.
pub const MIGRATIONS: &[Migration] = &[
    Migration {
        what: "runs, points, per-instrument results, the event log",
        sqlite: MIGRATION_1_SQLITE,
        postgres: "CREATE TABLE runs (
        id TEXT PRIMARY KEY,
        station TEXT NOT NULL,
        plan_json TEXT NOT NULL,
        software_version TEXT NOT NULL,
        state TEXT NOT NULL,
        reason TEXT,
        started_at BIGINT NOT NULL,
        finished_at BIGINT,
        starts BIGINT NOT NULL DEFAULT 1
    );
    CREATE TABLE points (
        run_id TEXT NOT NULL REFERENCES runs(id),
        step BIGINT NOT NULL,
        slot BIGINT NOT NULL,
        serial TEXT NOT NULL,
        mount TEXT NOT NULL,
        g_nominal DOUBLE PRECISION NOT NULL,
        direction TEXT NOT NULL,
        g_applied DOUBLE PRECISION NOT NULL,
        rate_deg_s DOUBLE PRECISION NOT NULL,
        output_hz DOUBLE PRECISION NOT NULL,
        std_hz DOUBLE PRECISION NOT NULL,
        n BIGINT NOT NULL,
        t0_s DOUBLE PRECISION NOT NULL,
        t1_s DOUBLE PRECISION NOT NULL,
        PRIMARY KEY (run_id, step, slot)
    );
    CREATE TABLE results (
        run_id TEXT NOT NULL REFERENCES runs(id),
        slot BIGINT NOT NULL,
        serial TEXT NOT NULL,
        outcome TEXT NOT NULL,
        k2_max_ug_per_g2 DOUBLE PRECISION,
        record_json TEXT NOT NULL,
        PRIMARY KEY (run_id, slot)
    );
    CREATE INDEX results_serial ON results(serial);
    CREATE TABLE events (
        seq BIGSERIAL PRIMARY KEY,
        run_id TEXT NOT NULL,
        at BIGINT NOT NULL,
        kind TEXT NOT NULL,
        json TEXT NOT NULL
    );",
    },
    Migration {
        what: "the one-second values of every instrument (and the rate), as the engine saw them",
        sqlite: MIGRATION_2_SQLITE,
        postgres: "CREATE TABLE values_1s (
        run_id TEXT NOT NULL,
        t_s DOUBLE PRECISION NOT NULL,
        slot BIGINT NOT NULL,
        output_hz DOUBLE PRECISION,
        rate_deg_s DOUBLE PRECISION NOT NULL,
        on_speed BIGINT NOT NULL,
        PRIMARY KEY (run_id, t_s, slot)
    );",
    },
    Migration {
        what: "stations, the station config and device identities of a run, units (radius per mounting), operator actions",
        sqlite: "CREATE TABLE stations (
        name TEXT PRIMARY KEY,
        first_seen INTEGER NOT NULL,
        last_seen INTEGER NOT NULL
    );
    ALTER TABLE runs ADD COLUMN station_config TEXT;
    ALTER TABLE runs ADD COLUMN devices_json TEXT;
    CREATE TABLE units (
        run_id TEXT NOT NULL REFERENCES runs(id),
        slot INTEGER NOT NULL,
        mount TEXT NOT NULL,
        serial TEXT NOT NULL,
        drawing_radius_m REAL NOT NULL,
        radius_m REAL NOT NULL,
        PRIMARY KEY (run_id, slot, mount)
    );
    CREATE TABLE operator_actions (
        seq INTEGER PRIMARY KEY AUTOINCREMENT,
        run_id TEXT NOT NULL,
        at INTEGER NOT NULL,
        who TEXT NOT NULL,
        action TEXT NOT NULL
    );",
        postgres: "CREATE TABLE stations (
        name TEXT PRIMARY KEY,
        first_seen BIGINT NOT NULL,
        last_seen BIGINT NOT NULL
    );
    ALTER TABLE runs ADD COLUMN station_config TEXT;
    ALTER TABLE runs ADD COLUMN devices_json TEXT;
    CREATE TABLE units (
        run_id TEXT NOT NULL REFERENCES runs(id),
        slot BIGINT NOT NULL,
        mount TEXT NOT NULL,
        serial TEXT NOT NULL,
        drawing_radius_m DOUBLE PRECISION NOT NULL,
        radius_m DOUBLE PRECISION NOT NULL,
        PRIMARY KEY (run_id, slot, mount)
    );
    CREATE TABLE operator_actions (
        seq BIGSERIAL PRIMARY KEY,
        run_id TEXT NOT NULL,
        at BIGINT NOT NULL,
        who TEXT NOT NULL,
        action TEXT NOT NULL
    );",
    },
    Migration {
        what: "users of the web UI (role, password hash) and the audit log of their actions",
        sqlite: "CREATE TABLE users (
        name TEXT PRIMARY KEY,
        role TEXT NOT NULL,
        password_hash TEXT NOT NULL,
        created_at INTEGER NOT NULL
    );
    CREATE TABLE audit (
        seq INTEGER PRIMARY KEY AUTOINCREMENT,
        at INTEGER NOT NULL,
        who TEXT NOT NULL,
        action TEXT NOT NULL,
        detail TEXT NOT NULL
    );",
        postgres: "CREATE TABLE users (
        name TEXT PRIMARY KEY,
        role TEXT NOT NULL,
        password_hash TEXT NOT NULL,
        created_at BIGINT NOT NULL
    );
    CREATE TABLE audit (
        seq BIGSERIAL PRIMARY KEY,
        at BIGINT NOT NULL,
        who TEXT NOT NULL,
        action TEXT NOT NULL,
        detail TEXT NOT NULL
    );",
    },
];

const MIGRATION_1_SQLITE: &str = "CREATE TABLE runs (
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
    );";

const MIGRATION_2_SQLITE: &str = "CREATE TABLE values_1s (
        run_id TEXT NOT NULL,
        t_s REAL NOT NULL,
        slot INTEGER NOT NULL,
        output_hz REAL,
        rate_deg_s REAL NOT NULL,
        on_speed INTEGER NOT NULL,
        PRIMARY KEY (run_id, t_s, slot)
    ) WITHOUT ROWID;";

/// A store operation failed; says which database and what was being done.
#[derive(Debug, thiserror::Error)]
#[error("store {target}: {what}: {source}")]
pub struct StoreError {
    /// The database (a file path, or the server with the password hidden).
    pub target: String,
    /// What was being done.
    pub what: String,
    /// The database's reason.
    #[source]
    pub source: DbError,
}

fn now_s() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64)
}

/// Where a store lives: an SQLite file, or a PostgreSQL server.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StoreTarget {
    /// An SQLite file.
    File(std::path::PathBuf),
    /// A PostgreSQL connection URL (`postgres://user@host:port/db`).
    Postgres(String),
}

impl StoreTarget {
    /// `postgres://…` or `postgresql://…` is a server; anything else is a file path.
    pub fn parse(text: &str) -> StoreTarget {
        if text.starts_with("postgres://") || text.starts_with("postgresql://") {
            StoreTarget::Postgres(text.to_string())
        } else {
            StoreTarget::File(text.into())
        }
    }
}

impl std::fmt::Display for StoreTarget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StoreTarget::File(p) => write!(f, "{}", p.display()),
            StoreTarget::Postgres(url) => f.write_str(&hide_password(url)),
        }
    }
}

/// `postgres://user:secret@host/db` → `postgres://user:***@host/db`.
fn hide_password(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_string();
    };
    match rest.split_once('@') {
        Some((auth, host)) if auth.contains(':') => {
            let user = auth.split(':').next().unwrap_or_default();
            format!("{scheme}://{user}:***@{host}")
        }
        _ => url.to_string(),
    }
}

/// An open store.
pub struct Store {
    db: RefCell<Db>,
    target: StoreTarget,
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

/// One stored point (a row of the `points` table).
#[derive(Debug, Clone, PartialEq)]
pub struct PointRow {
    /// Step of the plan.
    pub step: i64,
    /// Slot (0-based).
    pub slot: i64,
    /// Serial number.
    pub serial: String,
    /// P or N.
    pub mount: String,
    /// Nominal level [g].
    pub g_nominal: f64,
    /// up or down.
    pub direction: String,
    /// Applied acceleration, method.md (9) [g].
    pub g_applied: f64,
    /// Mean measured rate [deg/s].
    pub rate_deg_s: f64,
    /// Mean output dF [Hz].
    pub output_hz: f64,
    /// Standard deviation of the one-second values [Hz].
    pub std_hz: f64,
    /// Number of one-second values.
    pub n: i64,
    /// Times of the first and last one-second value averaged [s of the run].
    pub time_s: [f64; 2],
}

/// One stored one-second value.
#[derive(Debug, Clone, PartialEq)]
pub struct ValueRow {
    /// Window time [s].
    pub t_s: f64,
    /// Slot (0-based).
    pub slot: i64,
    /// Output dF [Hz], none when the window was missing or incomplete.
    pub output_hz: Option<f64>,
    /// Measured rate [deg/s].
    pub rate_deg_s: f64,
}

/// One instrument's radius in one mounting (method.md (6)–(8)).
#[derive(Debug, Clone, PartialEq)]
pub struct UnitRow {
    /// Slot (0-based).
    pub slot: i64,
    /// P or N.
    pub mount: String,
    /// Serial number.
    pub serial: String,
    /// The fixture's drawing radius R0 [m].
    pub drawing_radius_m: f64,
    /// The radius found [m].
    pub radius_m: f64,
}

/// One run's context: what the station was and what it was made of.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunContext {
    /// The station config (TOML) as the run used it.
    pub station_config: Option<String>,
    /// The devices' identities (JSON list of `{role, identity}`).
    pub devices_json: Option<String>,
    /// The plan (JSON).
    pub plan_json: String,
    /// The software version that ran it.
    pub software_version: String,
    /// Operator actions: (unix time, who, what).
    pub operator_actions: Vec<(i64, String, String)>,
}

impl Store {
    /// Open (creating if needed) the SQLite store at `path`.
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        Store::connect(&StoreTarget::File(path.to_path_buf()))
    }

    /// Open an existing store only to read it (`runs`, `export`, `report`,
    /// `replay`): an SQLite file is opened read-only (no WAL switch, no
    /// migration), so a store on a read-only disk or with read-only
    /// permissions can still be read. A store whose schema is older than
    /// this program's is refused with what to do.
    pub fn open_read_only(target: &StoreTarget) -> Result<Store, StoreError> {
        let err = |what: &str| {
            let t = target.to_string();
            let what = what.to_string();
            move |source: DbError| StoreError {
                target: t.clone(),
                what: what.clone(),
                source,
            }
        };
        let db = match target {
            StoreTarget::File(path) => {
                use rusqlite::OpenFlags;
                let conn = rusqlite::Connection::open_with_flags(
                    path,
                    OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
                )
                .map_err(|e| err("cannot open the database file to read")(e.into()))?;
                conn.busy_timeout(std::time::Duration::from_secs(10))
                    .map_err(|e| err("cannot set the busy timeout")(e.into()))?;
                Db::Sqlite(conn)
            }
            StoreTarget::Postgres(_) => return Store::connect(target),
        };
        let store = Store {
            db: RefCell::new(db),
            target: target.clone(),
        };
        let version = store.schema_version()?;
        if version != MIGRATIONS.len() as i64 {
            return Err(err("cannot read it")(
                format!(
                    "its schema is version {version}, this program reads version {}; open it once read-write (e.g. `spinbench user list`) to upgrade it",
                    MIGRATIONS.len()
                )
                .into(),
            ));
        }
        Ok(store)
    }

    /// Open a store (a file is created if needed) and bring its schema up to date.
    pub fn connect(target: &StoreTarget) -> Result<Store, StoreError> {
        let err = |what: &str| {
            let t = target.to_string();
            let what = what.to_string();
            move |source: DbError| StoreError {
                target: t.clone(),
                what: what.clone(),
                source,
            }
        };
        let db = match target {
            StoreTarget::File(path) => {
                if let Some(dir) = path.parent()
                    && !dir.as_os_str().is_empty()
                {
                    let _ = std::fs::create_dir_all(dir);
                }
                let conn = rusqlite::Connection::open(path)
                    .map_err(|e| err("cannot open the database file")(e.into()))?;
                // Another process creating or migrating the same file waits
                // its turn instead of failing.
                conn.busy_timeout(std::time::Duration::from_secs(10))
                    .map_err(|e| err("cannot set the busy timeout")(e.into()))?;
                // WAL and full sync: a committed transaction survives the
                // process being killed and the machine losing power.
                enable_wal(&conn).map_err(|e| {
                    err("cannot enable WAL (is the file or its directory read-only?)")(e.into())
                })?;
                conn.pragma_update(None, "synchronous", "FULL")
                    .map_err(|e| err("cannot set synchronous")(e.into()))?;
                // References are checked, as PostgreSQL checks them.
                conn.pragma_update(None, "foreign_keys", "ON")
                    .map_err(|e| err("cannot enable foreign keys")(e.into()))?;
                Db::Sqlite(conn)
            }
            StoreTarget::Postgres(url) => {
                let client = postgres::Client::connect(url, postgres::NoTls).map_err(|e| {
                    err("cannot connect (is the server running, and the URL's user, host, port and database right?)")(
                        e.into(),
                    )
                })?;
                Db::Postgres(Box::new(client), Default::default())
            }
        };
        let store = Store {
            db: RefCell::new(db),
            target: target.clone(),
        };
        store.migrate()?;
        Ok(store)
    }

    fn err(&self, what: &str) -> impl Fn(DbError) -> StoreError + '_ {
        let what = what.to_string();
        move |source| StoreError {
            target: self.target.to_string(),
            what: what.clone(),
            source,
        }
    }

    /// Where this store lives.
    pub fn target(&self) -> &StoreTarget {
        &self.target
    }

    fn migrate(&self) -> Result<(), StoreError> {
        let mut db = self.db.borrow_mut();
        let dialect = db.dialect();
        if dialect == Dialect::Postgres {
            db.batch(
                "SELECT pg_advisory_lock(1293);
                 CREATE TABLE IF NOT EXISTS spinbench_schema (version BIGINT NOT NULL);",
            )
            .map_err(self.err("cannot prepare the schema table"))?;
        }
        let result = match dialect {
            // One exclusive transaction over reading the version and every
            // migration: two processes creating the same new file never
            // both run a migration (the second waits, then finds it done).
            Dialect::Sqlite => db.batch("BEGIN EXCLUSIVE").and_then(|()| {
                let migrated = (|| {
                    let version = schema_version(&mut db)?;
                    for (i, m) in MIGRATIONS.iter().enumerate().skip(version.max(0) as usize) {
                        let v = (i + 1) as i64;
                        db.batch(&format!("{}; PRAGMA user_version = {v};", m.sqlite))
                            .map_err(|e| -> DbError {
                                format!("migration {v} ({}): {e}", m.what).into()
                            })?;
                    }
                    Ok::<(), DbError>(())
                })();
                match migrated {
                    Ok(()) => db.batch("COMMIT"),
                    Err(e) => {
                        let _ = db.batch("ROLLBACK");
                        Err(e)
                    }
                }
            }),
            Dialect::Postgres => (|| {
                let version = schema_version(&mut db)?;
                for (i, m) in MIGRATIONS.iter().enumerate().skip(version.max(0) as usize) {
                    let v = (i + 1) as i64;
                    db.transaction(|db| {
                        db.batch(&format!(
                            "{}; DELETE FROM spinbench_schema; INSERT INTO spinbench_schema VALUES ({v});",
                            m.postgres
                        ))
                    })
                    .map_err(|e| -> DbError { format!("migration {v} ({}): {e}", m.what).into() })?;
                }
                Ok::<(), DbError>(())
            })(),
        };
        if dialect == Dialect::Postgres {
            let _ = db.batch("SELECT pg_advisory_unlock(1293)");
        }
        result.map_err(self.err("cannot bring the schema up to date"))
    }

    /// The schema version of the database.
    pub fn schema_version(&self) -> Result<i64, StoreError> {
        schema_version(&mut self.db.borrow_mut())
            .map_err(self.err("cannot read the schema version"))
    }

    /// "ok" when the database is sound (SQLite's `PRAGMA integrity_check`;
    /// on PostgreSQL, that every table can be read).
    pub fn integrity_check(&self) -> Result<String, StoreError> {
        let mut db = self.db.borrow_mut();
        match db.dialect() {
            Dialect::Sqlite => db
                .query_one("PRAGMA integrity_check", &[])
                .map(|r| r.map(|r| r.text(0)).unwrap_or_default())
                .map_err(self.err("integrity check")),
            Dialect::Postgres => {
                for table in ["runs", "points", "results", "events", "values_1s", "units"] {
                    db.query(&format!("SELECT COUNT(*) FROM {table}"), &[])
                        .map_err(self.err("integrity check"))?;
                }
                Ok("ok".into())
            }
        }
    }

    fn query(&self, what: &str, sql: &str, params: &[Value]) -> Result<Vec<Row>, StoreError> {
        self.db
            .borrow_mut()
            .query(sql, params)
            .map_err(self.err(what))
    }

    /// Every run, newest first.
    pub fn runs(&self) -> Result<Vec<RunRow>, StoreError> {
        self.runs_where("TRUE", &[])
    }

    fn runs_where(&self, clause: &str, params: &[Value]) -> Result<Vec<RunRow>, StoreError> {
        let rows = self.query(
            "list runs",
            &format!(
                "SELECT r.id, r.station, r.state, r.reason, r.started_at,
                        (SELECT COUNT(*) FROM results s WHERE s.run_id = r.id),
                        (SELECT COUNT(*) FROM points p WHERE p.run_id = r.id)
                 FROM runs r WHERE {clause} ORDER BY r.started_at DESC, r.id DESC"
            ),
            params,
        )?;
        Ok(rows
            .iter()
            .map(|r| RunRow {
                id: r.text(0),
                station: r.text(1),
                state: r.text(2),
                reason: r.opt_text(3),
                started_at: r.int(4),
                units: r.int(5),
                points: r.int(6),
            })
            .collect())
    }

    /// One run, if it exists.
    pub fn run(&self, id: &str) -> Result<Option<RunRow>, StoreError> {
        Ok(self
            .runs_where("r.id = $1", &[id.into()])?
            .into_iter()
            .next())
    }

    /// A run's context (station config, devices, plan, operator actions).
    pub fn run_context(&self, id: &str) -> Result<Option<RunContext>, StoreError> {
        let Some(row) = self
            .query(
                "read a run",
                "SELECT station_config, devices_json, plan_json, software_version FROM runs WHERE id = $1",
                &[id.into()],
            )?
            .into_iter()
            .next()
        else {
            return Ok(None);
        };
        let actions = self.query(
            "read operator actions",
            "SELECT at, who, action FROM operator_actions WHERE run_id = $1 ORDER BY seq",
            &[id.into()],
        )?;
        Ok(Some(RunContext {
            station_config: row.opt_text(0),
            devices_json: row.opt_text(1),
            plan_json: row.text(2),
            software_version: row.text(3),
            operator_actions: actions
                .iter()
                .map(|r| (r.int(0), r.text(1), r.text(2)))
                .collect(),
        }))
    }

    fn results_where(&self, clause: &str, arg: &str) -> Result<Vec<ResultRow>, StoreError> {
        let rows = self.query(
            "query results",
            &format!(
                "SELECT s.run_id, s.slot, s.serial, s.outcome, s.k2_max_ug_per_g2, s.record_json
                 FROM results s JOIN runs r ON r.id = s.run_id WHERE {clause}
                 ORDER BY r.started_at, s.run_id, s.slot"
            ),
            &[arg.into()],
        )?;
        Ok(rows
            .iter()
            .map(|r| ResultRow {
                run_id: r.text(0),
                slot: r.int(1),
                serial: r.text(2),
                outcome: r.text(3),
                k2_max_ug_per_g2: r.opt_real(4),
                record_json: r.text(5),
            })
            .collect())
    }

    /// The per-instrument results of one run.
    pub fn results(&self, run_id: &str) -> Result<Vec<ResultRow>, StoreError> {
        self.results_where("s.run_id = $1", run_id)
    }

    /// Every result of one serial number, oldest run first.
    pub fn unit_history(&self, serial: &str) -> Result<Vec<ResultRow>, StoreError> {
        self.results_where("s.serial = $1", serial)
    }

    /// The points of a run, in the order taken.
    pub fn points(&self, run_id: &str) -> Result<Vec<PointRow>, StoreError> {
        let rows = self.query(
            "read points",
            "SELECT step, slot, serial, mount, g_nominal, direction, g_applied, rate_deg_s,
                    output_hz, std_hz, n, t0_s, t1_s
             FROM points WHERE run_id = $1 ORDER BY step, slot",
            &[run_id.into()],
        )?;
        Ok(rows
            .iter()
            .map(|r| PointRow {
                step: r.int(0),
                slot: r.int(1),
                serial: r.text(2),
                mount: r.text(3),
                g_nominal: r.real(4),
                direction: r.text(5),
                g_applied: r.real(6),
                rate_deg_s: r.real(7),
                output_hz: r.real(8),
                std_hz: r.real(9),
                n: r.int(10),
                time_s: [r.real(11), r.real(12)],
            })
            .collect())
    }

    /// The points of a run as CSV in the `spinbench analyze` format
    /// (`unit,mount,g_nominal,g_applied,output,direction,run`), in the order taken.
    pub fn points_csv(&self, run_id: &str) -> Result<String, StoreError> {
        let mut out = String::from("unit,mount,g_nominal,g_applied,output,direction,run\n");
        for p in self.points(run_id)? {
            // `{:?}` on f64 prints the shortest text that reads back to the same number.
            out.push_str(&format!(
                "{},{},{:?},{:?},{:?},{},{run_id}\n",
                csv_field(&p.serial),
                p.mount,
                p.g_nominal,
                p.g_applied,
                p.output_hz,
                p.direction
            ));
        }
        Ok(out)
    }

    /// The one-second values of a run, by time and slot.
    pub fn values(&self, run_id: &str) -> Result<Vec<ValueRow>, StoreError> {
        let rows = self.query(
            "read one-second values",
            "SELECT t_s, slot, output_hz, rate_deg_s FROM values_1s WHERE run_id = $1 ORDER BY t_s, slot",
            &[run_id.into()],
        )?;
        Ok(rows
            .iter()
            .map(|r| ValueRow {
                t_s: r.real(0),
                slot: r.int(1),
                output_hz: r.opt_real(2),
                rate_deg_s: r.real(3),
            })
            .collect())
    }

    /// Station time of the last one-second value stored for a run [s].
    pub fn last_value_time_s(&self, run_id: &str) -> Result<Option<f64>, StoreError> {
        Ok(self
            .query(
                "read the last one-second value's time",
                "SELECT t_s FROM values_1s WHERE run_id = $1 ORDER BY t_s DESC LIMIT 1",
                &[run_id.into()],
            )?
            .first()
            .map(|r| r.real(0)))
    }

    /// Number of one-second values stored for a run.
    pub fn value_count(&self, run_id: &str) -> Result<i64, StoreError> {
        Ok(self
            .query(
                "count one-second values",
                "SELECT COUNT(*) FROM values_1s WHERE run_id = $1",
                &[run_id.into()],
            )?
            .first()
            .map_or(0, |r| r.int(0)))
    }

    /// The (step, slot) keys of a run's stored points.
    pub fn point_keys(&self, run_id: &str) -> Result<Vec<(i64, i64)>, StoreError> {
        Ok(self
            .points(run_id)?
            .iter()
            .map(|p| (p.step, p.slot))
            .collect())
    }

    /// The radius found for each (slot, mount) of a run.
    pub fn unit_radii(&self, run_id: &str) -> Result<Vec<UnitRow>, StoreError> {
        let rows = self.query(
            "read units",
            "SELECT slot, mount, serial, drawing_radius_m, radius_m FROM units WHERE run_id = $1 ORDER BY slot, mount",
            &[run_id.into()],
        )?;
        Ok(rows
            .iter()
            .map(|r| UnitRow {
                slot: r.int(0),
                mount: r.text(1),
                serial: r.text(2),
                drawing_radius_m: r.real(3),
                radius_m: r.real(4),
            })
            .collect())
    }

    /// A sink that writes the events of a run to this store (its own connection).
    pub fn sink(&self) -> Result<StoreSink, StoreError> {
        Ok(StoreSink {
            store: Store::connect(&self.target)?,
            serials: Vec::new(),
            run_id: String::new(),
            prompt: String::new(),
        })
    }
}

/// Switch an SQLite file to WAL. SQLite answers "busy" at once (without
/// its busy handler) while another connection creates or converts the same
/// file, so the switch is retried for up to ten seconds.
fn enable_wal(conn: &rusqlite::Connection) -> Result<(), rusqlite::Error> {
    let until = std::time::Instant::now() + std::time::Duration::from_secs(10);
    loop {
        match conn.pragma_update(None, "journal_mode", "WAL") {
            Err(rusqlite::Error::SqliteFailure(e, _))
                if matches!(
                    e.code,
                    rusqlite::ErrorCode::DatabaseBusy | rusqlite::ErrorCode::DatabaseLocked
                ) && std::time::Instant::now() < until =>
            {
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            other => return other,
        }
    }
}

fn schema_version(db: &mut Db) -> Result<i64, DbError> {
    match db.dialect() {
        Dialect::Sqlite => Ok(db
            .query_one("PRAGMA user_version", &[])?
            .map_or(0, |r| r.int(0))),
        Dialect::Postgres => Ok(db
            .query_one("SELECT version FROM spinbench_schema", &[])?
            .map_or(0, |r| r.int(0))),
    }
}

/// The characters that make a spreadsheet program read a cell as a formula.
pub const FORMULA_STARTS: [char; 6] = ['=', '+', '-', '@', '\t', '\r'];

/// A text field of a CSV file written for people and spreadsheets: a text
/// that starts like a formula (`=HYPERLINK(…)`, `+cmd|…`, `@SUM…`) gets a
/// leading `'` so spreadsheet programs show it as text (OWASP's advice for
/// CSV injection); then it is quoted where CSV needs it. Only for text
/// (serials, names, reasons), never for numbers, whose `-` is a sign.
/// `spinbench analyze` takes the `'` off again when it reads the file.
pub fn csv_text_field(s: &str) -> String {
    let s = if s.starts_with(FORMULA_STARTS) {
        format!("'{s}")
    } else {
        s.to_string()
    };
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s
    }
}

/// Undo [`csv_text_field`]'s guard: `'=X` read back is `=X`.
pub fn csv_text_unguarded(s: &str) -> &str {
    match s.strip_prefix('\'') {
        Some(rest) if rest.starts_with(FORMULA_STARTS) => rest,
        _ => s,
    }
}

fn csv_field(s: &str) -> String {
    csv_text_field(s)
}

/// Writes a run's events as they happen. A failed write is an error the
/// engine turns into a fault (the run stops safely; nothing passes with an
/// empty database).
pub struct StoreSink {
    store: Store,
    serials: Vec<Option<String>>,
    run_id: String,
    /// The last prompt, recorded with the operator's answer.
    prompt: String,
}

impl StoreSink {
    fn write(&mut self, event: &Event) -> Result<(), DbError> {
        let mut db = self.store.db.borrow_mut();
        let run_id = self.run_id.clone();
        match event {
            Event::Progress { .. } => return Ok(()),
            Event::Values {
                time_s,
                rate_deg_s,
                on_speed,
                outputs_hz,
                ..
            } => {
                let serials = &self.serials;
                return db.transaction(|db| {
                    for (slot, v) in outputs_hz.iter().enumerate() {
                        if serials.get(slot).is_some_and(Option::is_some) {
                            db.execute(
                                "INSERT INTO values_1s (run_id, t_s, slot, output_hz, rate_deg_s, on_speed)
                                 VALUES ($1, $2, $3, $4, $5, $6)
                                 ON CONFLICT (run_id, t_s, slot) DO UPDATE SET output_hz = excluded.output_hz,
                                   rate_deg_s = excluded.rate_deg_s, on_speed = excluded.on_speed",
                                &[
                                    run_id.as_str().into(),
                                    (*time_s).into(),
                                    (slot as i64).into(),
                                    (*v).into(),
                                    (*rate_deg_s).into(),
                                    i64::from(*on_speed).into(),
                                ],
                            )?;
                        }
                    }
                    Ok(())
                });
            }
            Event::RunStarted {
                run_id,
                station,
                plan,
                resumed,
                station_config,
            } => {
                self.run_id = run_id.clone();
                self.serials = plan.serials.clone();
                let plan_json = serde_json::to_string(&plan.plan).unwrap_or_default();
                let now = now_s();
                db.transaction(|db| {
                    db.execute(
                        "INSERT INTO stations (name, first_seen, last_seen) VALUES ($1, $2, $3)
                         ON CONFLICT (name) DO UPDATE SET last_seen = excluded.last_seen",
                        &[station.into(), now.into(), now.into()],
                    )?;
                    let existing = db.query_one("SELECT id FROM runs WHERE id = $1", &[run_id.into()])?;
                    if existing.is_some() {
                        db.execute(
                            "UPDATE runs SET starts = starts + 1, state = 'running' WHERE id = $1",
                            &[run_id.into()],
                        )?;
                    } else {
                        db.execute(
                            "INSERT INTO runs (id, station, plan_json, software_version, state, started_at, starts,
                               station_config)
                             VALUES ($1, $2, $3, $4, 'running', $5, $6, $7)",
                            &[
                                run_id.into(),
                                station.into(),
                                plan_json.into(),
                                env!("CARGO_PKG_VERSION").into(),
                                now.into(),
                                (1 + i64::from(*resumed)).into(),
                                (!station_config.is_empty()).then(|| station_config.clone()).into(),
                            ],
                        )?;
                    }
                    Ok(())
                })?;
            }
            Event::Identified { devices } => {
                db.execute(
                    "UPDATE runs SET devices_json = $2 WHERE id = $1",
                    &[
                        run_id.as_str().into(),
                        serde_json::to_string(devices).unwrap_or_default().into(),
                    ],
                )?;
            }
            Event::RadiusDone {
                slot,
                mount,
                drawing_radius_m,
                radius_m,
            } => {
                let serial = self
                    .serials
                    .get(*slot)
                    .cloned()
                    .flatten()
                    .unwrap_or_default();
                db.execute(
                    "INSERT INTO units (run_id, slot, mount, serial, drawing_radius_m, radius_m)
                     VALUES ($1, $2, $3, $4, $5, $6)
                     ON CONFLICT (run_id, slot, mount) DO UPDATE SET radius_m = excluded.radius_m",
                    &[
                        run_id.as_str().into(),
                        (*slot as i64).into(),
                        mount.to_string().into(),
                        serial.into(),
                        (*drawing_radius_m).into(),
                        (*radius_m).into(),
                    ],
                )?;
            }
            Event::Prompt { text, .. } => self.prompt = text.clone(),
            Event::PromptAnswered { proceed, by } => {
                let action = format!(
                    "{} at the prompt: {}",
                    if *proceed { "went on" } else { "aborted" },
                    self.prompt
                );
                db.execute(
                    "INSERT INTO operator_actions (run_id, at, who, action) VALUES ($1, $2, $3, $4)",
                    &[run_id.as_str().into(), now_s().into(), by.into(), action.into()],
                )?;
            }
            Event::PointDone { step, points } => {
                let serials = &self.serials;
                db.transaction(|db| {
                    for p in points {
                        let serial = serials.get(p.slot).cloned().flatten().unwrap_or_default();
                        // A step redone after a resume replaces its row: nothing doubled.
                        db.execute(
                            "INSERT INTO points (run_id, step, slot, serial, mount, g_nominal, direction,
                               g_applied, rate_deg_s, output_hz, std_hz, n, t0_s, t1_s)
                             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14)
                             ON CONFLICT (run_id, step, slot) DO UPDATE SET serial = excluded.serial,
                               mount = excluded.mount, g_nominal = excluded.g_nominal,
                               direction = excluded.direction, g_applied = excluded.g_applied,
                               rate_deg_s = excluded.rate_deg_s, output_hz = excluded.output_hz,
                               std_hz = excluded.std_hz, n = excluded.n, t0_s = excluded.t0_s,
                               t1_s = excluded.t1_s",
                            &[
                                run_id.as_str().into(),
                                (*step as i64).into(),
                                (p.slot as i64).into(),
                                serial.into(),
                                p.mount.to_string().into(),
                                p.g_nominal.into(),
                                format!("{:?}", p.direction).to_lowercase().into(),
                                p.g_applied.into(),
                                p.rate_deg_s.into(),
                                p.output_hz.into(),
                                p.std_hz.into(),
                                i64::from(p.n).into(),
                                p.time_s[0].into(),
                                p.time_s[1].into(),
                            ],
                        )?;
                    }
                    Ok(())
                })?;
            }
            Event::UnitResult { record } => {
                let json = serde_json::to_string(record).unwrap_or_default();
                db.execute(
                    "INSERT INTO results (run_id, slot, serial, outcome, k2_max_ug_per_g2, record_json)
                     VALUES ($1, $2, $3, $4, $5, $6)
                     ON CONFLICT (run_id, slot) DO UPDATE SET serial = excluded.serial,
                       outcome = excluded.outcome, k2_max_ug_per_g2 = excluded.k2_max_ug_per_g2,
                       record_json = excluded.record_json",
                    &[
                        run_id.as_str().into(),
                        (record.slot as i64).into(),
                        record.serial.as_str().into(),
                        format!("{:?}", record.outcome).to_lowercase().into(),
                        record.k2_max_ug_per_g2.into(),
                        json.into(),
                    ],
                )?;
            }
            Event::RunFinished { state, reason } => {
                db.execute(
                    "UPDATE runs SET state = $2, reason = $3, finished_at = $4 WHERE id = $1",
                    &[
                        run_id.as_str().into(),
                        format!("{state:?}").to_lowercase().into(),
                        reason.clone().into(),
                        now_s().into(),
                    ],
                )?;
            }
            _ => {}
        }
        let kind = serde_json::to_value(event)
            .ok()
            .and_then(|v| v["event"].as_str().map(str::to_string))
            .unwrap_or_default();
        let json = serde_json::to_string(event).unwrap_or_default();
        db.execute(
            "INSERT INTO events (run_id, at, kind, json) VALUES ($1, $2, $3, $4)",
            &[
                self.run_id.as_str().into(),
                now_s().into(),
                kind.into(),
                json.into(),
            ],
        )?;
        Ok(())
    }
}

impl EventSink for StoreSink {
    fn emit(&mut self, event: &Event) -> Result<(), String> {
        self.write(event).map_err(|e| {
            format!(
                "store {}: cannot record the {} event: {e}",
                self.store.target,
                serde_json::to_value(event)
                    .ok()
                    .and_then(|v| v["event"].as_str().map(str::to_string))
                    .unwrap_or_default()
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_are_told_apart_and_passwords_hidden() {
        assert_eq!(
            StoreTarget::parse("postgres://u:pw@h:5432/d").to_string(),
            "postgres://u:***@h:5432/d"
        );
        assert_eq!(
            StoreTarget::parse("data/spinbench.db"),
            StoreTarget::File("data/spinbench.db".into())
        );
    }
}

/// For tests and benchmarks: a fresh, empty database on a PostgreSQL server.
pub mod testing {
    /// The environment variable that names the test server
    /// (`scripts/test` starts one and sets it).
    pub const POSTGRES_ENV: &str = "SPINBENCH_TEST_POSTGRES";

    /// Create a new database (a random name) on the server at `admin_url` and
    /// return the URL that reaches it.
    pub fn fresh_postgres_database(admin_url: &str) -> Result<String, super::DbError> {
        let mut admin = postgres::Client::connect(admin_url, postgres::NoTls)?;
        let name = format!("spinbench_test_{:016x}", rand_u64());
        admin.batch_execute(&format!("CREATE DATABASE {name}"))?;
        let base = admin_url
            .rsplit_once('/')
            .map_or(admin_url, |(base, _)| base);
        Ok(format!("{base}/{name}"))
    }

    /// The test server's URL, or an error that says how to get one.
    pub fn postgres_url() -> Result<String, String> {
        std::env::var(POSTGRES_ENV).map_err(|_| {
            format!(
                "{POSTGRES_ENV} is not set: run the tests with ./scripts/test, which starts a \
                 throwaway PostgreSQL on loopback, or set it to postgres://user@host:port/database"
            )
        })
    }

    fn rand_u64() -> u64 {
        use std::hash::{BuildHasher, Hasher};
        // RandomState is seeded randomly per process; the clock and the pid separate calls.
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        h.write_u128(
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos()),
        );
        h.write_u32(std::process::id());
        h.finish()
    }
}
