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
        // Said, not refused (a script may still do it).
        eprintln!(
            "warning: the --db URL holds a password, which every user of this machine can read in `ps`; \
             give the URL without it and the password in PGPASSWORD (the packaged service reads /etc/spinbench/db.env, mode 0640)"
        );
    }
    Ok(target)
}

/// The station's identity inside the data directory.
pub const STATION_ID_FILE: &str = "station-id";

/// The station's identity: made at its first start and kept in
/// `DATA/station-id`, apart from its display name, so two installs left
/// with one name are still two stations to the fleet. 32 hex digits, and
/// on a second line the place it was made for (`HOST:DATA`): a file copied
/// to another folder or machine would make a second live process of one
/// station, so it is refused there, saying to remove it (a new identity is
/// then made). A file of a release before the place is given its place.
pub fn station_identity(data: &Path) -> anyhow::Result<String> {
    use anyhow::Context;
    let path = data.join(STATION_ID_FILE);
    let here = identity_place(data);
    match std::fs::read_to_string(&path) {
        Ok(text) => {
            let mut lines = text.lines();
            let id = lines.next().unwrap_or_default().trim();
            anyhow::ensure!(
                id.len() == 32 && id.chars().all(|c| c.is_ascii_hexdigit()),
                "{}: not a station identity (32 hex digits); remove the file and a new one is made at the next start",
                path.display()
            );
            match lines.next().map(str::trim).filter(|l| !l.is_empty()) {
                Some(made_for) if made_for != here => anyhow::bail!(
                    "{}: this station identity was made for {made_for}, and this is {here}: the data folder \
                     (or the file) was copied, and two processes of one identity would share one station's \
                     name, runs and register. Remove {} here so this station gets an identity of its own; \
                     if the station itself moved to this folder, write `{here}` as the file's second line",
                    path.display(),
                    path.display()
                ),
                Some(_) => {}
                None => {
                    std::fs::write(&path, format!("{id}\n{here}\n")).with_context(|| {
                        format!("{}: cannot keep the station's identity", path.display())
                    })?;
                }
            }
            Ok(id.to_ascii_lowercase())
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let bytes: [u8; 16] = rand::random();
            let id: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
            std::fs::write(&path, format!("{id}\n{here}\n")).with_context(|| {
                format!("{}: cannot keep the station's identity", path.display())
            })?;
            Ok(id)
        }
        Err(e) => Err(e)
            .with_context(|| format!("{}: cannot read the station's identity", path.display())),
    }
}

/// Where an identity is kept: this machine's name and the data folder's
/// full path.
fn identity_place(data: &Path) -> String {
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .unwrap_or_default();
    let folder = std::fs::canonicalize(data).unwrap_or_else(|_| data.to_path_buf());
    format!("{host}:{}", folder.display())
}
