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
//!
//! | module | job |
//! |---|---|
//! | `db` | the thin layer over both databases: SQL written once, typed values |
//! | `schema` | the migrations and the schema's version and soundness |
//! | `queries` | runs, typed results, points, values, radii read back |
//! | `record` | [`RunRecord`]: a whole run, typed, in one call; the stored enumerations ([`StoredState`]) |
//! | `retention` | an ended run's one-second values and events read out for an archive, then deleted in one transaction ([`Store::prunable_runs`], [`Store::delete_values_and_events`]) |
//! | `sink` | [`StoreSink`]: the engine's events written as they happen |
//! | [`outbox`] | the run's events queued and written on a thread of their own (the run never waits on the database), caught up after an outage or at the next start |
//! | `csv` | points as CSV, text cells guarded against formula injection |
//! | `users` | the web UI's users and the audit log |
//! | `label` | runs' readable labels (`2026-11-24 · station 1 · #7`), typed labels resolved |
//! | [`testing`] | fresh PostgreSQL databases for tests |

mod backup;
pub use backup::{pg_dump, pg_restore, pg_tool};
mod csv;
pub mod db;
pub mod equipment;
pub mod fleet;
mod label;
pub mod leftover;
pub mod outbox;
mod queries;
mod record;
mod retention;
mod schema;
mod sink;
pub mod testing;
pub mod tls;
mod tokens;
mod users;

pub use csv::{FORMULA_STARTS, csv_text_field, csv_text_unguarded};
pub use label::{LABEL_SEPARATOR, TypedLabel, label_file_part, parse_label, run_label};
pub use queries::{MAX_RUNS_PAGE, PointRow, ResultRow, RunRow, UnitRow, ValueRow};
pub use record::{
    DeviceEntry, NoticeKind, OperatorAction, RECORD_VERSION, ResultFigures, RunEnd, RunNotice,
    RunRecord, RunStart, StoredPlan, StoredState,
};
pub use retention::{EventRow, PrunableRun};
pub use schema::{MIGRATIONS, Migration, MigrationApplied, is_role_name};
pub use sink::StoreSink;
pub use tokens::ApiTokenRow;
pub use users::{AuditRow, Replaced, UserRow};

use db::{Db, DbError, Dialect, Row, Value};
use spinbench_engine::event::{Event, EventSink};
use spinbench_engine::{Outcome, UnitRecord};
use std::cell::RefCell;
use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

/// A store operation failed; says which database and what was being done.
#[derive(Debug, thiserror::Error)]
// The database's reason is in the message and is not also the error's
// source: a chain printer (anyhow's `{:#}`) would say it twice.
#[error("store {target}: {what}: {}", whole_reason(reason))]
pub struct StoreError {
    /// The database (a file path, or the server with the password hidden).
    pub target: String,
    /// What was being done.
    pub what: String,
    /// The database's reason.
    pub reason: DbError,
}

/// The database's reason with every cause under it (a PostgreSQL error
/// says only "db error" itself; its message is its source's).
fn whole_reason(reason: &DbError) -> String {
    let mut text = reason.to_string();
    let mut cause = reason.source();
    while let Some(c) = cause {
        let more = c.to_string();
        if !text.ends_with(&more) {
            text.push_str(": ");
            text.push_str(&more);
        }
        cause = c.source();
    }
    text
}

/// Whether the database error `reason` is the database's own refusal of
/// what was asked (PostgreSQL answered with a SQLSTATE outside the outage
/// classes: a permission, a constraint, a missing table; SQLite failed
/// other than busy or locked). Anything else (a lost connection, an error
/// of the store's own) is not known to be one.
pub(crate) fn is_refusal(reason: &DbError) -> bool {
    let known = reason
        .downcast_ref::<postgres::Error>()
        .is_some_and(|e| e.code().is_some())
        || matches!(
            reason.downcast_ref::<rusqlite::Error>(),
            Some(rusqlite::Error::SqliteFailure(..))
        );
    known && !is_unavailable(reason)
}

/// Whether the database error `reason` is an outage or a busy store
/// ([`StoreError::is_unavailable`]), not a refusal.
pub(crate) fn is_unavailable(reason: &DbError) -> bool {
    if let Some(e) = reason.downcast_ref::<postgres::Error>() {
        return match e.code() {
            None => true,
            Some(code) => {
                let c = code.code();
                c.starts_with("08") || c.starts_with("53") || c.starts_with("57P")
            }
        };
    }
    if let Some(rusqlite::Error::SqliteFailure(e, _)) = reason.downcast_ref::<rusqlite::Error>() {
        return matches!(
            e.code,
            rusqlite::ErrorCode::DatabaseBusy | rusqlite::ErrorCode::DatabaseLocked
        );
    }
    false
}

impl StoreError {
    /// Whether the store could not be reached or is busy, rather than
    /// refusing what was asked: a closed or failed PostgreSQL connection, a
    /// server shutting down, starting or out of connections (SQLSTATE
    /// classes 08, 53, 57P), an SQLite file locked by another writer. Such
    /// an error passes when the store is back: try again (the web answers
    /// 503 with Retry-After).
    pub fn is_unavailable(&self) -> bool {
        is_unavailable(&self.reason)
    }

    /// An error of the store's own (not the database's): `problem` says what to do.
    pub fn message(target: &StoreTarget, what: &str, problem: String) -> StoreError {
        StoreError {
            target: target.to_string(),
            what: what.to_string(),
            reason: problem.into(),
        }
    }
}

/// The time now [Unix s].
pub fn now_s() -> i64 {
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

impl StoreTarget {
    /// The store as its owner would name it in a command: a PostgreSQL URL
    /// with its role put as `OWNER` (and no password), so that a station
    /// working as a data-only role is never told to run the owner's work
    /// as itself; a file as it is.
    pub fn for_owner(&self) -> String {
        match self {
            StoreTarget::File(p) => p.display().to_string(),
            StoreTarget::Postgres(url) => match url.split_once("://") {
                Some((scheme, rest)) => match rest.split_once('@') {
                    Some((_, host)) => format!("{scheme}://OWNER@{host}"),
                    None => format!("{scheme}://OWNER@{rest}"),
                },
                None => url.clone(),
            },
        }
    }

    /// The PostgreSQL role the URL names, when it names one.
    pub fn role(&self) -> Option<&str> {
        let StoreTarget::Postgres(url) = self else {
            return None;
        };
        let (auth, _) = url.split_once("://")?.1.split_once('@')?;
        auth.split(':').next().filter(|u| !u.is_empty())
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
    /// When a closed PostgreSQL connection was last made again (at most
    /// one attempt per [`RECONNECT_EVERY`]).
    reconnected: std::cell::Cell<Option<std::time::Instant>>,
}

/// How often a store whose server closed its connection tries to make it
/// again (each call of the store tries, at most this often).
pub const RECONNECT_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

/// An error of `target` while doing `what`, for `map_err`.
fn failed(target: &StoreTarget, what: &str) -> impl Fn(DbError) -> StoreError + use<> {
    let (target, what) = (target.to_string(), what.to_string());
    move |reason| StoreError {
        target: target.clone(),
        what: what.clone(),
        reason,
    }
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
        let err = |what: &str| failed(target, what);
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
                // A store in WAL mode needs its -shm beside it, which SQLite
                // cannot make on read-only media or in a directory this user
                // may not write: such a file, which no one
                // can be writing, is read as immutable.
                let first_read = conn.query_row("SELECT count(*) FROM sqlite_master", [], |r| {
                    r.get::<_, i64>(0)
                });
                if let Err(rusqlite::Error::SqliteFailure(e, _)) = &first_read
                    && matches!(
                        e.code,
                        rusqlite::ErrorCode::ReadOnly | rusqlite::ErrorCode::CannotOpen
                    )
                {
                    Db::Sqlite(
                        open_immutable(path)
                            .map_err(|e| err("cannot open the database file to read")(e.into()))?,
                    )
                } else {
                    Db::Sqlite(conn)
                }
            }
            StoreTarget::Postgres(_) => return Store::connect(target),
        };
        let store = Store {
            db: RefCell::new(db),
            target: target.clone(),
            reconnected: std::cell::Cell::new(None),
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

    /// Open a store for the station's work (`run`, `serve`, the users and
    /// the register). An SQLite file is created if needed and its schema
    /// brought up to date (the file is the station's own). A PostgreSQL
    /// store is never changed here: its schema must be this release's, made
    /// by `spinbench migrate` as the database's owner, so the station can
    /// work with a role that has data rights only; one that is not is
    /// refused, saying the command to run.
    pub fn connect(target: &StoreTarget) -> Result<Store, StoreError> {
        let store = Store::open_connection(target)?;
        match target {
            StoreTarget::File(_) => {
                store.migrate()?;
            }
            StoreTarget::Postgres(_) => store.require_current_schema()?,
        }
        Ok(store)
    }

    /// Open a store and bring its schema up to date on either back end
    /// (`spinbench migrate`, a restore, tests): the versions it was at and
    /// is at now.
    pub fn migrate_target(target: &StoreTarget) -> Result<(Store, i64, i64), StoreError> {
        let store = Store::open_connection(target)?;
        let before = store.migrate()?;
        let after = store.schema_version()?;
        Ok((store, before, after))
    }

    /// The connection to `target`, its schema not looked at.
    fn open_connection(target: &StoreTarget) -> Result<Store, StoreError> {
        let err = |what: &str| failed(target, what);
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
            StoreTarget::Postgres(url) => Db::Postgres(
                Box::new(connect_postgres(url).map_err(|e| err(e.0)(e.1))?),
                Default::default(),
            ),
        };
        Ok(Store {
            db: RefCell::new(db),
            target: target.clone(),
            reconnected: std::cell::Cell::new(None),
        })
    }

    /// The connection. A PostgreSQL server that closed it (restarted, or
    /// the network reset it) is connected to again first, at most once per
    /// [`RECONNECT_EVERY`]; until it answers, the call fails with an error
    /// [`StoreError::is_unavailable`] recognises, and the next tries again.
    fn db(&self) -> std::cell::RefMut<'_, Db> {
        let mut db = self.db.borrow_mut();
        if let (Db::Postgres(client, statements), StoreTarget::Postgres(url)) =
            (&mut *db, &self.target)
            && client.is_closed()
            && self
                .reconnected
                .get()
                .is_none_or(|t| t.elapsed() >= RECONNECT_EVERY)
        {
            self.reconnected.set(Some(std::time::Instant::now()));
            if let Ok(fresh) = connect_postgres(url) {
                **client = fresh;
                statements.clear();
            }
        }
        db
    }

    /// Whether the store can be reached now: a PostgreSQL connection that
    /// is open (made again if it was closed); an SQLite file always.
    pub fn is_connected(&self) -> bool {
        match &*self.db() {
            Db::Postgres(client, _) => !client.is_closed(),
            Db::Sqlite(_) => true,
        }
    }

    fn err(&self, what: &str) -> impl Fn(DbError) -> StoreError + '_ {
        let what = what.to_string();
        move |reason| StoreError {
            target: self.target.to_string(),
            what: what.clone(),
            reason,
        }
    }

    /// Where this store lives.
    pub fn target(&self) -> &StoreTarget {
        &self.target
    }

    /// A read. One that failed because the server closed the connection
    /// under it (a restart: the client learns of it only then) is made once
    /// more on a connection made again.
    fn query(&self, what: &str, sql: &str, params: &[Value]) -> Result<Vec<Row>, StoreError> {
        let first = self.db().query(sql, params);
        match first {
            Err(e) if self.connection_closed() => {
                self.reconnected.set(None);
                self.db().query(sql, params).map_err(|_| e)
            }
            done => done,
        }
        .map_err(self.err(what))
    }

    /// Whether this store's PostgreSQL connection is closed now.
    fn connection_closed(&self) -> bool {
        matches!(&*self.db.borrow(), Db::Postgres(client, _) if client.is_closed())
    }
}

/// How long making a PostgreSQL connection may take.
pub const CONNECT_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);

/// How long sent data may stay unacknowledged by a PostgreSQL server's
/// host before the connection is closed (a network gone without a reset);
/// keepalives find a silent peer the same way when nothing is sent.
pub const TCP_USER_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(15);

/// A PostgreSQL connection to `url` (the password from `PGPASSWORD` when
/// the URL has none), with the deadlines a plant network needs: a connect
/// time-out, TCP keepalives and a TCP user time-out (each unless the URL
/// sets its own). On failure, what was being done and why.
/// The name this process's PostgreSQL connections give the server
/// (`application_name`, what `pg_stat_activity` and the server's log
/// show), unless the URL names one.
static APPLICATION_NAME: std::sync::RwLock<Option<String>> = std::sync::RwLock::new(None);

/// PostgreSQL keeps this many bytes of an `application_name`.
const MAX_APPLICATION_NAME: usize = 63;

/// Name this process's PostgreSQL connections from now on `spinbench
/// STATION` (cut at PostgreSQL's 63 bytes), so that a DBA tells the
/// stations apart in `pg_stat_activity`; a URL's own `application_name`
/// wins.
pub fn name_connections(station: &str) {
    let mut name = format!("spinbench {station}");
    while name.len() > MAX_APPLICATION_NAME {
        name.pop();
    }
    *APPLICATION_NAME.write().unwrap_or_else(|e| e.into_inner()) = Some(name);
}

pub(crate) fn connect_postgres(url: &str) -> Result<postgres::Client, (&'static str, DbError)> {
    let mut config = pg_config(url, std::env::var("PGPASSWORD").ok())
        .map_err(|e| ("not a PostgreSQL URL", e.into()))?;
    if config.get_application_name().is_none() {
        let name = APPLICATION_NAME
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
            .unwrap_or_else(|| "spinbench".to_string());
        config.application_name(&name);
    }
    if config.get_connect_timeout().is_none() {
        config.connect_timeout(CONNECT_TIMEOUT);
    }
    if config.get_tcp_user_timeout().is_none() {
        config.tcp_user_timeout(TCP_USER_TIMEOUT);
    }
    config
        .keepalives(true)
        .keepalives_idle(std::time::Duration::from_secs(10));
    if config.get_keepalives_interval().is_none() {
        config.keepalives_interval(std::time::Duration::from_secs(5));
    }
    if config.get_keepalives_retries().is_none() {
        config.keepalives_retries(3);
    }
    let tls = tls::split(url).map_err(|e| ("not a PostgreSQL URL", e.into()))?;
    let cannot = |e: postgres::Error| -> (&'static str, DbError) {
        (
            "cannot connect (is the server running, and the URL's user, host, port, database and sslmode right?)",
            e.into(),
        )
    };
    match tls::connector(&tls).map_err(|e| ("cannot set up TLS", e.into()))? {
        None => config.connect(postgres::NoTls).map_err(cannot),
        Some(connector) => config.connect(connector).map_err(cannot),
    }
}

/// Switch an SQLite file to WAL. SQLite answers "busy" at once (without
/// its busy handler) while another connection creates or converts the same
/// file, so the switch is retried for up to ten seconds.
/// `path` opened read-only as immutable (no locks, no -shm, the WAL not
/// read): for a file SQLite cannot open otherwise, on read-only media or in a
/// directory this user cannot write, which therefore no one writes either.
fn open_immutable(path: &Path) -> Result<rusqlite::Connection, rusqlite::Error> {
    use rusqlite::OpenFlags;
    // An SQLite URI (https://sqlite.org/uri.html): the path with the three
    // characters that would end or escape it percent-encoded.
    let mut uri = String::from("file:");
    for c in path.to_string_lossy().chars() {
        match c {
            '%' => uri.push_str("%25"),
            '?' => uri.push_str("%3f"),
            '#' => uri.push_str("%23"),
            c => uri.push(c),
        }
    }
    uri.push_str("?immutable=1");
    rusqlite::Connection::open_with_flags(
        uri,
        OpenFlags::SQLITE_OPEN_READ_ONLY
            | OpenFlags::SQLITE_OPEN_URI
            | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
}

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

/// A PostgreSQL URL's connection settings. A URL without a password takes
/// `env_password` (the process's `PGPASSWORD`, as libpq and pg_dump do), so
/// the password need not be on a command line, where every user of the
/// machine reads it in `ps` (the packaged unit reads it
/// from `/etc/spinbench/db.env`, mode 0640).
pub fn pg_config(
    url: &str,
    env_password: Option<String>,
) -> Result<postgres::Config, postgres::Error> {
    // The TLS parameters libpq reads and the client does not (sslmode
    // verify-ca, verify-full; sslrootcert) are the TLS module's.
    let plain = tls::split(url).map_or_else(|_| url.to_string(), |t| t.url);
    let mut config: postgres::Config = plain.parse()?;
    if config.get_password().is_none()
        && let Some(p) = env_password.filter(|p| !p.is_empty())
    {
        config.password(p);
    }
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_url_without_a_password_takes_pgpassword() {
        // The password from the environment (the unit's
        // 0640 file), not the command line; one in the URL wins.
        let from_env =
            pg_config("postgres://spinbench@db/spinbench", Some("s3cret".into())).expect("url");
        assert_eq!(from_env.get_password(), Some(&b"s3cret"[..]));
        let in_url = pg_config(
            "postgres://spinbench:own@db/spinbench",
            Some("s3cret".into()),
        )
        .expect("url");
        assert_eq!(in_url.get_password(), Some(&b"own"[..]));
        let none =
            pg_config("postgres://spinbench@db/spinbench", Some(String::new())).expect("url");
        assert_eq!(none.get_password(), None);
        assert!(pg_config("postgres://[bad", None).is_err());
    }

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
