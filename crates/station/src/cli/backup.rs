//! `spinbench backup DIR` and `spinbench restore FILE`.

use anyhow::{Context, Result};
use spinbench_store::{Store, StoreTarget};
use std::io::Write;
use std::path::Path;

/// `spinbench backup DIR`.
pub(super) fn backup(
    dir: &Path,
    db: &StoreTarget,
    data: Option<&Path>,
    out: &mut dyn Write,
) -> Result<()> {
    refuse_inside(dir, db, data)?;
    create_private_dir(dir)?;
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64);
    let secs = now.rem_euclid(86_400);
    let stamp = format!(
        "{}-{:02}{:02}{:02}",
        spinbench_store::equipment::civil_date(now).replace('-', ""),
        secs / 3600,
        secs % 3600 / 60,
        secs % 60
    );
    if let StoreTarget::Postgres(_) = db {
        // The server's own tools (the password through PGPASSWORD only).
        let file = unused_name(dir, &stamp, "dump");
        spinbench_store::pg_dump(db, &file)?;
        make_private(&file)?;
        let size = std::fs::metadata(&file).map_or(0, |m| m.len());
        writeln!(
            out,
            "backup: {} ({:.1} MB, pg_dump custom format, checked: pg_restore --list reads it); restore with `spinbench restore {} --db URL` into an empty database",
            file.display(),
            size as f64 / 1e6,
            file.display()
        )?;
    } else {
        let store =
            Store::open_read_only(db).with_context(|| format!("cannot open the store {db}"))?;
        let file = unused_name(dir, &stamp, "db");
        store.backup_to(&file)?;
        make_private(&file)?;
        let size = std::fs::metadata(&file).map_or(0, |m| m.len());
        writeln!(
            out,
            "backup: {} ({:.1} MB, checked: integrity ok, schema version {})",
            file.display(),
            size as f64 / 1e6,
            store.schema_version()?
        )?;
    }
    if let Some(data) = data {
        let (from, to) = (
            data.join(crate::paths::RUNS_DIR),
            dir.join(crate::paths::RUNS_DIR),
        );
        let (copied, in_progress) = copy_runs(&from, &to)?;
        writeln!(out, "runs' files: {copied} copied to {}", to.display())?;
        if !in_progress.is_empty() {
            writeln!(
                out,
                "runs in progress, their files not backed up (they are still being written; back up again once they end): {}",
                in_progress.join(", ")
            )?;
        }
    }
    Ok(())
}

/// `DIR/spinbench-STAMP.EXT`, or with `-2`, `-3` … when a backup of the same
/// second is there already (a backup never replaces a file).
fn unused_name(dir: &Path, stamp: &str, ext: &str) -> std::path::PathBuf {
    let mut file = dir.join(format!("spinbench-{stamp}.{ext}"));
    let mut n = 2;
    while file.exists() && n < 1000 {
        file = dir.join(format!("spinbench-{stamp}-{n}.{ext}"));
        n += 1;
    }
    file
}

/// Copy each run's directory under `from` (DATA/runs) to `to`, except runs
/// being run now (a run's journal grows while it runs, so
/// a copy taken then is a torn one): a run's directory is locked by the
/// process running it, and is copied under a shared lock of its own, so no
/// run starts or resumes into it half-copied. Returns how many files were
/// copied and the runs left out.
fn copy_runs(from: &Path, to: &Path) -> Result<(usize, Vec<String>)> {
    let (mut copied, mut in_progress) = (0, Vec::new());
    if !from.is_dir() {
        return Ok((0, in_progress));
    }
    create_private_dir(to)?;
    let mut entries = std::fs::read_dir(from)
        .with_context(|| format!("{}: cannot read", from.display()))?
        .collect::<std::io::Result<Vec<_>>>()
        .with_context(|| format!("{}: cannot read", from.display()))?;
    entries.sort_by_key(|e| e.file_name());
    for entry in entries {
        let (src, dst) = (entry.path(), to.join(entry.file_name()));
        let kind = entry.file_type()?;
        if kind.is_dir() {
            let dir = std::fs::File::open(&src)
                .with_context(|| format!("{}: cannot open", src.display()))?;
            match dir.try_lock_shared() {
                Ok(()) => copied += copy_new_files(&src, &dst)?,
                Err(std::fs::TryLockError::WouldBlock) => {
                    in_progress.push(entry.file_name().to_string_lossy().into_owned());
                }
                Err(std::fs::TryLockError::Error(e)) => {
                    return Err(e).with_context(|| format!("{}: cannot lock", src.display()));
                }
            }
        } else if kind.is_file() && changed(&src, &dst) {
            std::fs::copy(&src, &dst)
                .with_context(|| format!("{} → {}", src.display(), dst.display()))?;
            make_private(&dst)?;
            copied += 1;
        }
    }
    Ok((copied, in_progress))
}

/// Whether `src` is not yet at `dst` as it is now (missing, another size,
/// or changed since it was copied: a resumed run's journal grows).
fn changed(src: &Path, dst: &Path) -> bool {
    let (Ok(s), Ok(d)) = (std::fs::metadata(src), std::fs::metadata(dst)) else {
        return true;
    };
    s.len() != d.len() || matches!((s.modified(), d.modified()), (Ok(sm), Ok(dm)) if sm > dm)
}

/// Copy every file under `from` to the same place under `to` that is not
/// there yet as it is now ([`changed`]); how many.
fn copy_new_files(from: &Path, to: &Path) -> Result<usize> {
    let mut copied = 0;
    if !from.is_dir() {
        return Ok(0);
    }
    create_private_dir(to)?;
    for entry in
        std::fs::read_dir(from).with_context(|| format!("{}: cannot read", from.display()))?
    {
        let entry = entry?;
        let (src, dst) = (entry.path(), to.join(entry.file_name()));
        let kind = entry.file_type()?;
        if kind.is_dir() {
            copied += copy_new_files(&src, &dst)?;
        } else if kind.is_file() && changed(&src, &dst) {
            std::fs::copy(&src, &dst)
                .with_context(|| format!("{} → {}", src.display(), dst.display()))?;
            make_private(&dst)?;
            copied += 1;
        }
    }
    Ok(copied)
}

/// A backup holds password hashes, session-token hashes and the audit log:
/// its directories are the owner's alone (0700), its files too (0600).
fn create_private_dir(dir: &Path) -> Result<()> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700))
        .with_context(|| format!("{}: cannot make it private (0700)", dir.display()))
}

/// Make a backup's file the owner's alone (0600).
fn make_private(file: &Path) -> Result<()> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(file, std::fs::Permissions::from_mode(0o600))
        .with_context(|| format!("{}: cannot make it private (0600)", file.display()))
}

/// Refuse a backup directory inside the data directory or beside the store
/// (a copy of the runs into the runs would copy itself until the path is
/// too long).
fn refuse_inside(dir: &Path, db: &StoreTarget, data: Option<&Path>) -> Result<()> {
    let absolute = |p: &Path| -> std::path::PathBuf {
        let p = if p.is_absolute() {
            p.to_path_buf()
        } else {
            std::env::current_dir().unwrap_or_default().join(p)
        };
        // The deepest part that exists, resolved, with the rest after it.
        let mut existing = p.clone();
        let mut rest = Vec::new();
        while !existing.exists() {
            match (existing.file_name(), existing.parent()) {
                (Some(name), Some(parent)) => {
                    rest.push(name.to_os_string());
                    existing = parent.to_path_buf();
                }
                _ => break,
            }
        }
        let mut resolved = existing.canonicalize().unwrap_or(existing);
        for name in rest.iter().rev() {
            resolved.push(name);
        }
        resolved
    };
    let target = absolute(dir);
    let mut forbidden = Vec::new();
    if let Some(data) = data {
        forbidden.push((absolute(data), "the data directory"));
    }
    if let StoreTarget::File(file) = db
        && let Some(parent) = file.parent()
    {
        let parent = if parent.as_os_str().is_empty() {
            Path::new(".")
        } else {
            parent
        };
        forbidden.push((absolute(parent), "the store's directory"));
    }
    for (inside, what) in forbidden {
        if target.starts_with(&inside) {
            anyhow::bail!(
                "{}: inside {what} ({}); back up to another directory (another disk is best)",
                dir.display(),
                inside.display()
            );
        }
    }
    Ok(())
}

/// `spinbench migrate --db PATH|URL [--history] [--grant ROLE]… [--grant-analyst ROLE]…`:
/// `grants` are the stations' roles and the analysts'.
pub(super) fn migrate(
    db: &StoreTarget,
    history: bool,
    grants: (&[String], &[String]),
    out: &mut dyn Write,
) -> Result<()> {
    let (grant, grant_analyst) = grants;
    // Every role name checked before anything is changed.
    for (option, roles) in [("--grant", grant), ("--grant-analyst", grant_analyst)] {
        if let Some(bad) = roles.iter().find(|r| !spinbench_store::is_role_name(r)) {
            anyhow::bail!(
                "{option} {bad:?}: not a PostgreSQL role name (letters, digits and _, not starting with a digit, at most 63)"
            );
        }
        if !roles.is_empty() && !matches!(db, StoreTarget::Postgres(_)) {
            anyhow::bail!(
                "{option}: an SQLite file has no roles; {option} is for a PostgreSQL store"
            );
        }
    }
    let (store, before, after) = match Store::migrate_target(db) {
        Ok(done) => done,
        // A newer release's store: the store's own words say what to do.
        Err(e) if e.to_string().contains("newer release") => return Err(e.into()),
        Err(e) => {
            let role = db
                .role()
                .map(|r| format!(", not as `{r}`"))
                .unwrap_or_default();
            return Err(anyhow::Error::new(e).context(format!(
                "the schema could not be brought up to date: run `spinbench migrate --db {}` as the database's owner{role} (a role that may create and alter its tables)",
                db.for_owner()
            )));
        }
    };
    if before == after {
        writeln!(
            out,
            "{db}: schema version {after}, this release's; nothing to do"
        )?;
    } else {
        writeln!(
            out,
            "{db}: schema version {before} → {after} ({} migrations applied)",
            after - before
        )?;
    }
    for role in grant {
        store.grant_data_rights(role).with_context(|| {
            format!("run `spinbench migrate --grant {role}` as the store's owner, who may grant its tables")
        })?;
        writeln!(
            out,
            "{db}: role {role} granted its data rights on every table and sequence, and on those later migrations create"
        )?;
    }
    for role in grant_analyst {
        store.grant_analyst_rights(role).with_context(|| {
            format!("run `spinbench migrate --grant-analyst {role}` as the store's owner, who may grant its view")
        })?;
        writeln!(
            out,
            "{db}: role {role} may read analyst_results (and no table)"
        )?;
    }
    if history {
        for m in store.migration_history()? {
            writeln!(
                out,
                "  {:>3}  {}  {:<14}  {}",
                m.version,
                m.applied_at.as_deref().unwrap_or("(before the history)"),
                m.release.as_deref().unwrap_or(""),
                m.what
            )?;
        }
    }
    Ok(())
}

/// `spinbench restore FILE --db PATH|URL`.
pub(super) fn restore(backup: &Path, db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let db = match db {
        StoreTarget::Postgres(_) => {
            spinbench_store::pg_restore(db, backup)?;
            // A dump made by an earlier release is brought up to this one's
            // schema (a restore is the database owner's work, as a migration).
            let (restored, _, _) = Store::migrate_target(db)?;
            writeln!(
                out,
                "restored {} runs into {db} (schema version {})",
                restored.runs()?.len(),
                restored.schema_version()?
            )?;
            return Ok(());
        }
        StoreTarget::File(path) => path.as_path(),
    };
    anyhow::ensure!(
        !db.exists(),
        "{} exists: a restore never replaces a store; move it aside first (with its -wal and -shm files)",
        db.display()
    );
    // A store moved aside without its write-ahead log leaves the log here:
    // a new store would take it over (or SQLite would delete it), and the
    // moved store would lose the writes it holds.
    for suffix in ["-wal", "-shm"] {
        let side = std::path::PathBuf::from(format!("{}{suffix}", db.display()));
        anyhow::ensure!(
            !side.exists(),
            "{} exists: it belongs to a store that was moved aside without it and may hold its last writes; move it beside that store (all three files together), or open that store once to checkpoint it, then restore",
            side.display()
        );
    }
    if let Some(parent) = db.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("{}: cannot create", parent.display()))?;
    }
    let from = Store::open_read_only(&StoreTarget::File(backup.to_path_buf()))
        .with_context(|| format!("{}: not a spinbench backup", backup.display()))?;
    from.backup_to(db)?;
    let restored = Store::connect(&StoreTarget::File(db.to_path_buf()))?;
    writeln!(
        out,
        "restored {} runs into {} (integrity ok)",
        restored.runs()?.len(),
        db.display()
    )?;
    Ok(())
}
