//! `spinbench backup DIR` and `spinbench restore FILE` (issue 17, part 5).

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
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
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
        let file = dir.join(format!("spinbench-{stamp}.dump"));
        spinbench_store::pg_dump(db, &file)?;
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
        let file = dir.join(format!("spinbench-{stamp}.db"));
        store.backup_to(&file)?;
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
        let copied = copy_new_files(&from, &to)?;
        writeln!(out, "runs' files: {copied} copied to {}", to.display())?;
    }
    Ok(())
}

/// Copy every file under `from` to the same place under `to` that is not
/// there yet (runs' files do not change once written); how many.
fn copy_new_files(from: &Path, to: &Path) -> Result<usize> {
    let mut copied = 0;
    if !from.is_dir() {
        return Ok(0);
    }
    std::fs::create_dir_all(to).with_context(|| format!("{}: cannot create", to.display()))?;
    for entry in
        std::fs::read_dir(from).with_context(|| format!("{}: cannot read", from.display()))?
    {
        let entry = entry?;
        let (src, dst) = (entry.path(), to.join(entry.file_name()));
        let kind = entry.file_type()?;
        if kind.is_dir() {
            copied += copy_new_files(&src, &dst)?;
        } else if kind.is_file() && !dst.exists() {
            std::fs::copy(&src, &dst)
                .with_context(|| format!("{} → {}", src.display(), dst.display()))?;
            copied += 1;
        }
    }
    Ok(copied)
}

/// `spinbench restore FILE --db PATH|URL`.
pub(super) fn restore(backup: &Path, db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let db = match db {
        StoreTarget::Postgres(_) => {
            spinbench_store::pg_restore(db, backup)?;
            let restored = Store::connect(db)?;
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
        "{} exists: a restore never replaces a store; move it aside first",
        db.display()
    );
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
