//! Where things live: the data directory and its store, a run's directory
//! and its files, and `--db` as given on a command line. Used by the
//! command line, the run set-up and the web server alike.

use spinbench_store::StoreTarget;
use std::path::Path;

/// Where runs are kept unless `--data` says otherwise.
pub const DEFAULT_DATA_DIR: &str = "spinbench-data";

/// The store's file inside the data directory.
pub const DB_FILE: &str = "spinbench.db";

/// The default `--db` of the commands that read a store.
pub const DEFAULT_DB: &str = "spinbench-data/spinbench.db";

/// The directory of the runs inside the data directory.
pub const RUNS_DIR: &str = "runs";

/// The raw byte captures of a run, inside its directory.
pub const RAW_DIR: &str = "raw";

/// The plan a run was started with, inside its directory.
pub const PLAN_FILE: &str = "plan.toml";

/// The station config a run was started with, inside its directory.
pub const STATION_FILE: &str = "station.toml";

/// The default store of a data directory: `DATA/spinbench.db`.
pub fn default_store(data: &Path) -> StoreTarget {
    StoreTarget::File(data.join(DB_FILE))
}

/// `--db`: a file path, or a PostgreSQL URL.
pub fn parse_store(text: &str) -> Result<StoreTarget, String> {
    if text.trim().is_empty() {
        return Err("empty: give a file path or postgres://user@host:port/database".into());
    }
    let target = StoreTarget::parse(text);
    if let StoreTarget::Postgres(url) = &target
        && spinbench_store::pg_config(url, None).is_ok_and(|c| c.get_password().is_some())
    {
        // Issue 27 item 26: said, not refused (a script may still do it).
        eprintln!(
            "warning: the --db URL holds a password, which every user of this machine can read in `ps`; \
             give the URL without it and the password in PGPASSWORD (the packaged service reads /etc/spinbench/db.env, mode 0640)"
        );
    }
    Ok(target)
}
