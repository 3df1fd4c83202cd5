//! Backups of an SQLite store: a consistent copy made
//! while the station may be writing, through SQLite's online backup API
//! (rusqlite's `backup` feature), checked before it is called a backup.
//! A PostgreSQL store is backed up by the server's own tools: `pg_dump` in
//! its custom format, checked by `pg_restore --list`; restored by
//! `pg_restore` into an empty database ([`pg_dump`], [`pg_restore`]). The
//! password goes to them in `PGPASSWORD`, never on a command line or in a
//! message. Without the tools, one message says what to install.

use crate::db::Db;
use crate::{Store, StoreError, StoreTarget};
use std::path::Path;
use std::time::Duration;

impl Store {
    /// Copy the store to the new file `to` (refused if it exists), page by
    /// page, letting the station's writes through between steps; then open
    /// the copy and check it (integrity, schema version).
    pub fn backup_to(&self, to: &Path) -> Result<(), StoreError> {
        let fail = |problem: String| StoreError::message(&self.target, "back up", problem);
        if to.exists() {
            return Err(fail(format!(
                "{} exists already; a backup never replaces a file",
                to.display()
            )));
        }
        {
            let db = self.db.borrow();
            let Db::Sqlite(conn) = &*db else {
                let url = self.target.to_string();
                return Err(fail(format!(
                    "a PostgreSQL store is backed up by the server's tools: run `pg_dump --format=custom --file=spinbench.dump {url}` (and `pg_restore --dbname=URL spinbench.dump` to restore)"
                )));
            };
            let mut copy = rusqlite::Connection::open(to)
                .map_err(|e| fail(format!("{}: {e}", to.display())))?;
            let backup =
                rusqlite::backup::Backup::new(conn, &mut copy).map_err(|e| fail(e.to_string()))?;
            // 256 pages a step, 10 ms between steps: the station keeps writing.
            backup
                .run_to_completion(256, Duration::from_millis(10), None)
                .map_err(|e| fail(e.to_string()))?;
        }
        let copy = Store::connect(&StoreTarget::File(to.to_path_buf()))?;
        let check = copy.integrity_check()?;
        if check != "ok" {
            return Err(fail(format!(
                "the copy failed its integrity check: {check}"
            )));
        }
        if copy.schema_version()? != self.schema_version()? {
            return Err(fail("the copy's schema version differs".into()));
        }
        // Out of WAL mode: a backup is one self-contained
        // file that reads on read-only media (a WAL file needs its -shm).
        if let Db::Sqlite(conn) = &*copy.db.borrow() {
            conn.pragma_update(None, "journal_mode", "DELETE")
                .map_err(|e| fail(format!("the copy stays in WAL mode: {e}")))?;
        }
        Ok(())
    }
}

/// Where the PostgreSQL client tools are: on `PATH`, else Debian's
/// `/usr/lib/postgresql/*/bin` (newest first).
pub fn pg_tool(name: &str) -> Option<std::path::PathBuf> {
    let on_path = std::env::var_os("PATH").into_iter().flat_map(|p| {
        std::env::split_paths(&p)
            .map(|d| d.join(name))
            .collect::<Vec<_>>()
    });
    let mut debian: Vec<std::path::PathBuf> = std::fs::read_dir("/usr/lib/postgresql")
        .into_iter()
        .flatten()
        .filter_map(|e| Some(e.ok()?.path().join("bin").join(name)))
        .collect();
    debian.sort_by_key(|p| {
        p.parent()
            .and_then(|b| b.parent())
            .and_then(|v| v.file_name())
            .and_then(|v| v.to_str())
            .and_then(|v| v.parse::<u32>().ok())
            .unwrap_or(0)
    });
    debian.reverse();
    on_path.chain(debian).find(|p| p.is_file())
}

/// Why a PostgreSQL client tool did not do its job.
#[derive(Debug, thiserror::Error)]
enum PgToolError {
    /// The URL is not one.
    #[error("not a PostgreSQL URL: {0}")]
    NotAUrl(postgres::Error),
    /// The tool is not installed.
    #[error(
        "{0} is not installed: install the PostgreSQL client tools (Debian: apt install postgresql-client) and run this again"
    )]
    NotInstalled(String),
    /// The tool could not be started.
    #[error("{path}: {source}")]
    NotStarted {
        /// The tool's path, as shown.
        path: String,
        /// The system's error.
        source: std::io::Error,
    },
    /// The tool ran and failed (its error output).
    #[error("{tool} failed: {stderr}")]
    Failed {
        /// The tool.
        tool: String,
        /// What it wrote to its error output.
        stderr: String,
    },
}

/// A PostgreSQL URL as libpq keywords without the password, and the password.
fn pg_connection(url: &str) -> Result<(String, Option<String>), PgToolError> {
    let tls = crate::tls::split(url).ok();
    let plain = tls.as_ref().map_or(url, |t| t.url.as_str());
    let config: postgres::Config = plain.parse().map_err(PgToolError::NotAUrl)?;
    let mut words = Vec::new();
    // libpq reads every sslmode itself, and the root certificate.
    if let Some(t) = &tls {
        use crate::tls::SslMode;
        words.push(format!(
            "sslmode={}",
            match t.mode {
                SslMode::Disable => "disable",
                SslMode::Prefer => "prefer",
                SslMode::Require => "require",
                SslMode::VerifyCa => "verify-ca",
                SslMode::VerifyFull => "verify-full",
            }
        ));
        if let Some(root) = &t.root_cert {
            words.push(format!("sslrootcert='{}'", root.display()));
        }
    }
    if let Some(postgres::config::Host::Tcp(h)) = config.get_hosts().first() {
        words.push(format!("host='{h}'"));
    }
    if let Some(port) = config.get_ports().first() {
        words.push(format!("port={port}"));
    }
    if let Some(user) = config.get_user() {
        words.push(format!("user='{user}'"));
    }
    if let Some(db) = config.get_dbname() {
        words.push(format!("dbname='{db}'"));
    }
    let password = config
        .get_password()
        .map(|p| String::from_utf8_lossy(p).into_owned());
    Ok((words.join(" "), password))
}

/// Run a PostgreSQL client tool on `url`'s database; its error output on failure.
fn run_pg_tool(tool: &str, url: &str, args: &[&std::ffi::OsStr]) -> Result<(), PgToolError> {
    let path = pg_tool(tool).ok_or_else(|| PgToolError::NotInstalled(tool.to_string()))?;
    let (conninfo, password) = pg_connection(url)?;
    let mut cmd = std::process::Command::new(&path);
    cmd.args(args).arg(format!("--dbname={conninfo}"));
    if let Some(p) = password {
        cmd.env("PGPASSWORD", p);
    }
    let out = cmd.output().map_err(|source| PgToolError::NotStarted {
        path: path.display().to_string(),
        source,
    })?;
    if !out.status.success() {
        return Err(PgToolError::Failed {
            tool: tool.to_string(),
            stderr: String::from_utf8_lossy(&out.stderr).trim().to_string(),
        });
    }
    Ok(())
}

/// Back a PostgreSQL store up into the new file `to` with `pg_dump`
/// (custom format), then check the file with `pg_restore --list`. The dump
/// is written under a name of its own beside `to` and put at `to` only
/// once both succeeded (a hard link, which never replaces a file): a
/// failed dump leaves no file named like a good one, so a rotation that
/// keeps the newest backups never keeps an empty one.
pub fn pg_dump(target: &StoreTarget, to: &Path) -> Result<(), StoreError> {
    let fail = |problem: String| StoreError::message(target, "back up", problem);
    let StoreTarget::Postgres(url) = target else {
        return Err(fail("not a PostgreSQL store".into()));
    };
    if to.exists() {
        return Err(fail(format!(
            "{} exists already; a backup never replaces a file",
            to.display()
        )));
    }
    let partial = to.with_file_name(format!(
        ".{}.partial-{}",
        to.file_name()
            .map_or_else(|| "backup".into(), |n| n.to_string_lossy()),
        std::process::id()
    ));
    let _ = std::fs::remove_file(&partial);
    let result = dump_and_check(url, &partial).and_then(|()| {
        std::fs::hard_link(&partial, to).map_err(|e| {
            format!(
                "{}: cannot put the checked dump in place: {e}",
                to.display()
            )
        })
    });
    let _ = std::fs::remove_file(&partial);
    result.map_err(|problem| {
        let hint = if problem.contains("permission denied") {
            "; a backup reads every table and sequence: run it as the store's owner (--db postgres://OWNER@…), not the station's data-only role"
        } else {
            ""
        };
        fail(format!("{problem}{hint}; no backup file was left"))
    })
}

/// `pg_dump` of `url` into `file`, then `pg_restore --list` of it.
fn dump_and_check(url: &str, file: &Path) -> Result<(), String> {
    let arg = std::ffi::OsString::from(format!("--file={}", file.display()));
    run_pg_tool(
        "pg_dump",
        url,
        &[
            "--format=custom".as_ref(),
            "--no-owner".as_ref(),
            arg.as_os_str(),
        ],
    )
    .map_err(|e| e.to_string())?;
    let list = pg_tool("pg_restore").ok_or("pg_restore is not installed to check the dump")?;
    let checked = std::process::Command::new(list)
        .arg("--list")
        .arg(file)
        .output()
        .map_err(|e| e.to_string())?;
    if !checked.status.success() {
        return Err(format!(
            "the dump does not read back: {}",
            String::from_utf8_lossy(&checked.stderr).trim()
        ));
    }
    Ok(())
}

/// Restore a `pg_dump` file into the PostgreSQL store `target`, whose
/// database must be empty (no spinbench schema yet).
pub fn pg_restore(target: &StoreTarget, from: &Path) -> Result<(), StoreError> {
    let fail = |problem: String| StoreError::message(target, "restore", problem);
    let StoreTarget::Postgres(url) = target else {
        return Err(fail("not a PostgreSQL store".into()));
    };
    // Into an empty database only: said in words, not
    // with pg_restore's first "already exists".
    let mut client = crate::connect_postgres(url)
        .map_err(|(what, e)| fail(format!("{what}: {}", crate::whole_reason(&e))))?;
    let tables: Vec<String> = client
        .query(
            "SELECT table_name FROM information_schema.tables
             WHERE table_schema = 'public' ORDER BY table_name LIMIT 6",
            &[],
        )
        .map_err(|e| fail(e.to_string()))?
        .iter()
        .map(|r| r.get::<_, String>(0))
        .collect();
    drop(client);
    if !tables.is_empty() {
        return Err(fail(format!(
            "the database must be empty: it holds tables already ({}{}); restore into a new database \
             (createdb NAME, then --db with its URL), or drop this one's tables first",
            tables
                .iter()
                .take(5)
                .cloned()
                .collect::<Vec<_>>()
                .join(", "),
            if tables.len() > 5 { ", …" } else { "" }
        )));
    }
    run_pg_tool(
        "pg_restore",
        url,
        &[
            "--no-owner".as_ref(),
            "--exit-on-error".as_ref(),
            from.as_os_str(),
        ],
    )
    .map_err(|e| fail(e.to_string()))
}
