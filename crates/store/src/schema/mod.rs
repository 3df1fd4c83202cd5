//! The schema: every migration in both spellings (SQLite, PostgreSQL),
//! applied once under an exclusive transaction (SQLite) or an advisory lock
//! (PostgreSQL), and the schema's version and soundness.

mod grants;
mod migrations;

pub use grants::is_role_name;
pub use migrations::{MIGRATIONS, Migration};

use super::{Db, DbError, Dialect, Store, StoreError};

/// One row of the migration history (`spinbench_migrations`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MigrationApplied {
    /// Its version (1-based).
    pub version: i64,
    /// What it adds.
    pub what: String,
    /// When it was applied (`YYYY-MM-DD HH:MM:SS UTC`); `None` for one
    /// applied before the history was kept.
    pub applied_at: Option<String>,
    /// The release that applied it.
    pub release: Option<String>,
}

/// The first migration whose application is written into
/// `spinbench_migrations` (the table it makes); the ones before it are
/// listed there with no time, as applied before the history was kept.
const HISTORY_FROM: usize = 13;

/// The history row of migration `v` (1-based), applied now by this
/// release, in a migration that started from version `from`. With the
/// history's own migration, the ones before it are listed too: those this
/// call applied with this time and release, those applied before with none.
fn history_row(db: &mut Db, v: usize, from: usize) -> Result<(), DbError> {
    let now = match db.dialect() {
        Dialect::Sqlite => "CAST(strftime('%s', 'now') AS INTEGER)",
        Dialect::Postgres => "now()",
    };
    let first = if v == HISTORY_FROM { 1 } else { v };
    for version in first..=v {
        let what = MIGRATIONS.get(version - 1).map_or("", |m| m.what);
        if version > from {
            db.execute(
                &format!(
                    "INSERT INTO spinbench_migrations (version, what, applied_at, release) VALUES ($1, $2, {now}, $3)"
                ),
                &[
                    (version as i64).into(),
                    what.into(),
                    env!("CARGO_PKG_VERSION").into(),
                ],
            )?;
        } else {
            db.execute(
                "INSERT INTO spinbench_migrations (version, what) VALUES ($1, $2)",
                &[(version as i64).into(), what.into()],
            )?;
        }
    }
    Ok(())
}

/// What a store written by a newer release is told (never written to).
fn newer_release(version: i64) -> String {
    format!(
        "its schema is version {version}, written by a newer release; this release reads up to version {}: upgrade spinbench on this station",
        MIGRATIONS.len()
    )
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

impl Store {
    /// Bring the schema up to this release's; the version it was at when
    /// this process held the migration lock (a second `migrate` waiting
    /// behind a first finds the first's work done and says so).
    pub(crate) fn migrate(&self) -> Result<i64, StoreError> {
        // A current store is not touched (no lock, no DDL): a role with
        // data rights only may ask.
        let found = self.schema_version_if_any()?;
        if found == MIGRATIONS.len() as i64 {
            return Ok(found);
        }
        // A newer release's store is never written to by this one.
        if found > MIGRATIONS.len() as i64 {
            return self.require_current_schema().map(|()| found);
        }
        let mut found_locked = found;
        let mut db = self.db();
        let dialect = db.dialect();
        let result = match dialect {
            // One exclusive transaction over reading the version and every
            // migration: two processes creating the same new file never
            // both run a migration (the second waits, then finds it done).
            Dialect::Sqlite => db.batch("BEGIN EXCLUSIVE").and_then(|()| {
                let migrated = (|| {
                    let version = schema_version(&mut db)?;
                    found_locked = version;
                    if version > MIGRATIONS.len() as i64 {
                        return Err(newer_release(version).into());
                    }
                    for (i, m) in MIGRATIONS.iter().enumerate().skip(version.max(0) as usize) {
                        let v = (i + 1) as i64;
                        db.batch(&format!("{}; PRAGMA user_version = {v};", m.sqlite))
                            .and_then(|()| {
                                if i + 1 >= HISTORY_FROM {
                                    history_row(&mut db, i + 1, version.max(0) as usize)?;
                                }
                                Ok(())
                            })
                            .map_err(|e| -> DbError {
                                format!("migration {v} ({}): {}", m.what, crate::whole_reason(&e))
                                    .into()
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
            // Every pending migration in one transaction that takes a
            // transaction-level advisory lock and reads the version under
            // it: two processes never both run one (the second waits, then
            // finds nothing to do), an upgrade that fails leaves the schema
            // as it was, and nothing outlives the transaction on the server
            // connection (behind a pooler in transaction pooling, a
            // session-level lock could stay on a connection that another
            // client gets next).
            Dialect::Postgres => db.transaction(|db| {
                db.batch(
                    "SELECT pg_advisory_xact_lock(1293);
                     CREATE TABLE IF NOT EXISTS spinbench_schema (version BIGINT NOT NULL);",
                )?;
                let version = schema_version(db)?;
                found_locked = version;
                if version > MIGRATIONS.len() as i64 {
                    return Err(newer_release(version).into());
                }
                for (i, m) in MIGRATIONS.iter().enumerate().skip(version.max(0) as usize) {
                    let v = (i + 1) as i64;
                    db.batch(&format!(
                        "{}; DELETE FROM spinbench_schema; INSERT INTO spinbench_schema VALUES ({v});",
                        m.postgres
                    ))
                    .and_then(|()| {
                        if i + 1 >= HISTORY_FROM {
                            history_row(db, i + 1, version.max(0) as usize)?;
                        }
                        Ok(())
                    })
                    .map_err(|e| -> DbError {
                        format!("migration {v} ({}): {}", m.what, crate::whole_reason(&e)).into()
                    })?;
                }
                Ok(())
            }),
        };
        result
            .map(|()| found_locked.max(0))
            .map_err(self.err("cannot bring the schema up to date"))
    }

    /// The schema version, 0 for a database the station never migrated
    /// (PostgreSQL: no `spinbench_schema` table yet).
    pub(crate) fn schema_version_if_any(&self) -> Result<i64, StoreError> {
        let mut db = self.db();
        if db.dialect() == Dialect::Postgres {
            let exists = db
                .query_one("SELECT to_regclass('spinbench_schema') IS NOT NULL", &[])
                .map_err(self.err("cannot read the schema version"))?
                .is_some_and(|r| r.int(0) != 0);
            if !exists {
                return Ok(0);
            }
        }
        schema_version(&mut db).map_err(self.err("cannot read the schema version"))
    }

    /// Refuse a store whose schema is not this release's, saying what to do.
    pub(crate) fn require_current_schema(&self) -> Result<(), StoreError> {
        let version = self.schema_version_if_any()?;
        let wanted = MIGRATIONS.len() as i64;
        let problem = if version < wanted {
            let not_this_role = self
                .target
                .role()
                .map(|r| format!(" (OWNER: the role that owns the database, not `{r}`, which this station works as)"))
                .unwrap_or_default();
            format!(
                "its schema is version {version} and this release needs version {wanted}: the database's owner runs `spinbench migrate --db {}`{not_this_role} (the Debian package runs it on install and upgrade), then start again",
                self.target.for_owner()
            )
        } else if version > wanted {
            newer_release(version)
        } else {
            return Ok(());
        };
        Err(StoreError::message(&self.target, "cannot use it", problem))
    }

    /// The migration history, oldest first.
    pub fn migration_history(&self) -> Result<Vec<MigrationApplied>, StoreError> {
        let applied_at = match self.db().dialect() {
            Dialect::Sqlite => "datetime(applied_at, 'unixepoch') || ' UTC'",
            Dialect::Postgres => {
                "to_char(applied_at AT TIME ZONE 'UTC', 'YYYY-MM-DD HH24:MI:SS') || ' UTC'"
            }
        };
        Ok(self
            .query(
                "read the migration history",
                &format!("SELECT version, what, {applied_at}, release FROM spinbench_migrations ORDER BY version"),
                &[],
            )?
            .iter()
            .map(|r| MigrationApplied {
                version: r.int(0),
                what: r.text(1),
                applied_at: r.opt_text(2),
                release: r.opt_text(3),
            })
            .collect())
    }

    /// The schema version of the database.
    pub fn schema_version(&self) -> Result<i64, StoreError> {
        schema_version(&mut self.db()).map_err(self.err("cannot read the schema version"))
    }

    /// Whether this connection may write the store (a write that changes
    /// nothing, rolled back): `spinbench doctor`'s check.
    pub fn check_writable(&self) -> Result<(), StoreError> {
        let mut db = self.db();
        db.batch("BEGIN").map_err(self.err("a write check"))?;
        // A write that changes nothing: refused on a read-only file or
        // without the privilege; rolled back either way.
        let wrote = db.execute(
            "UPDATE runs SET station = station WHERE id = $1",
            &["spinbench doctor: a write check".into()],
        );
        let _ = db.batch("ROLLBACK");
        wrote.map(|_| ()).map_err(self.err("a write check"))
    }

    /// "ok" when the database is sound (SQLite's `PRAGMA integrity_check`;
    /// on PostgreSQL, that every table can be read).
    pub fn integrity_check(&self) -> Result<String, StoreError> {
        let mut db = self.db();
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
}
