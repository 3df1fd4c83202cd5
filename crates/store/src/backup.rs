//! Backups of an SQLite store (issue 17, part 5): a consistent copy made
//! while the station may be writing, through SQLite's online backup API
//! (rusqlite's `backup` feature), checked before it is called a backup.
//! A PostgreSQL store is backed up by the server's own tools (`pg_dump`):
//! the error says what to run.

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
        Ok(())
    }
}
