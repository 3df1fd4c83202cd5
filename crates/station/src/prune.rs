//! `spinbench prune --older-than DAYS --archive DIR`: retention of the
//! store's bulk rows. For each run that ended and started more than DAYS
//! ago, its one-second values and its event log are written to Parquet
//! files in DIR (`<run>-values.parquet`, `<run>-events.parquet`), synced
//! and read back; only when the files hold every row are the rows deleted
//! from the store, in one transaction that refuses if the run gained rows
//! meanwhile. The run's record (plan, devices, radii, points, results,
//! operator actions, end) stays, so its reports, exports and history are
//! unchanged; `replay` of a pruned run has no values to check against.
//!
//! Each file stands alone: its key-value metadata names the run (id,
//! label, station, start, the software that ran it and the one that
//! archived it, the archive's layout) and maps slots to serials, and the
//! events' time is a Parquet timestamp (UTC, milliseconds).

use anyhow::{Context, Result, bail};
use parquet::basic::Compression;
use parquet::data_type::{BoolType, ByteArray, ByteArrayType, DoubleType, Int64Type};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::reader::{FileReader, SerializedFileReader};
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::parser::parse_message_type;
use spinbench_store::{EventRow, Store, StoreTarget, ValueRow};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The archive files' layout, in their metadata (`spinbench.layout`):
/// 2 added the metadata and the events' timestamp column `at`.
pub const ARCHIVE_LAYOUT: &str = "2";

/// The retention `prune` keeps when not told otherwise [days].
pub const DEFAULT_RETENTION_DAYS: f64 = 365.0;

/// The longest retention `--older-than` takes [days] (a hundred years).
pub const MAX_RETENTION_DAYS: f64 = 36_500.0;

/// Parse `--older-than`: days, finite, from 0 (every ended run) to
/// [`MAX_RETENTION_DAYS`].
pub fn parse_days(text: &str) -> Result<f64, String> {
    let days: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("'{text}' is not a number of days"))?;
    if !days.is_finite() || !(0.0..=MAX_RETENTION_DAYS).contains(&days) {
        return Err(format!(
            "{text} days: from 0 (every ended run) to {MAX_RETENTION_DAYS} days"
        ));
    }
    Ok(days)
}

/// What `prune` did (or, with `dry_run`, would do).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Pruned {
    /// Runs pruned.
    pub runs: usize,
    /// One-second value rows archived and deleted.
    pub values: u64,
    /// Event rows archived and deleted.
    pub events: u64,
}

/// Prune `db`'s ended runs started more than `days` ago into `archive`,
/// saying each run on `out`.
pub fn prune(
    db: &StoreTarget,
    days: f64,
    archive: &Path,
    dry_run: bool,
    out: &mut dyn Write,
) -> Result<Pruned> {
    let store = Store::connect(db)?;
    let before = spinbench_store::now_s() - (days * 86_400.0).round() as i64;
    let runs = store.prunable_runs(before)?;
    let mut done = Pruned::default();
    // Runs not pruned for a problem of their own: said at the end, the others go on.
    let mut left: Vec<String> = Vec::new();
    if runs.is_empty() {
        writeln!(
            out,
            "{db}: no ended run older than {days} days has values or events left; nothing to do"
        )?;
        return Ok(done);
    }
    if !dry_run {
        std::fs::create_dir_all(archive)
            .with_context(|| format!("{}: cannot make the archive directory", archive.display()))?;
    }
    for (i, p) in runs.iter().enumerate() {
        let id = &p.run.id;
        write!(
            out,
            "[{}/{}] {} ({}): {} values, {} events",
            i + 1,
            runs.len(),
            p.run.label(),
            id,
            p.values,
            p.events
        )?;
        if dry_run {
            writeln!(out, " (dry run: kept)")?;
            continue;
        }
        let values = store.values(id)?;
        let events = store.events(id)?;
        if values.len() as i64 != p.values || events.len() as i64 != p.events {
            writeln!(out, " — changed while read; left for the next prune")?;
            continue;
        }
        let metadata = archive_metadata(&store, &p.run)?;
        let values_file = archive.join(format!("{id}-values.parquet"));
        let events_file = archive.join(format!("{id}-events.parquet"));
        // An earlier prune that archived the run (or one of its files) and
        // was stopped before it deleted: a file that holds exactly the run's
        // rows is used, not written again.
        let complete = |f: &Path, n: i64| regular_file(f) && rows_in(f).is_ok_and(|r| r == n);
        let (values_done, events_done) = (
            complete(&values_file, p.values),
            complete(&events_file, p.events),
        );
        if values_done || events_done {
            write!(out, " — archived before, in part or whole")?;
        }
        let mut written = Ok(());
        if !values_done {
            written = write_values(&values, id, &metadata, &values_file);
        }
        if !events_done && written.is_ok() {
            written = write_events(&events, id, &metadata, &events_file);
        }
        if let Err(e) = written {
            writeln!(out, " — not archived: {e:#}; kept in the store")?;
            left.push(format!("{id}: {e:#}"));
            continue;
        }
        // Only what the files are read back to hold is deleted.
        let (in_values, in_events) = (rows_in(&values_file)?, rows_in(&events_file)?);
        if in_values != values.len() as i64 || in_events != events.len() as i64 {
            writeln!(
                out,
                " — {} and {} hold {in_values} values and {in_events} events of {} and {}; nothing deleted",
                values_file.display(),
                events_file.display(),
                values.len(),
                events.len()
            )?;
            left.push(format!("{id}: its archive does not hold its rows"));
            continue;
        }
        let (v, e) = store.delete_values_and_events(id, p.values, p.events)?;
        writeln!(
            out,
            " → {}, {}; deleted",
            values_file.display(),
            events_file.display()
        )?;
        done.runs += 1;
        done.values += v;
        done.events += e;
    }
    writeln!(
        out,
        "pruned {} runs: {} values and {} events archived in {} and deleted from {db}",
        done.runs,
        done.values,
        done.events,
        archive.display()
    )?;
    if !left.is_empty() {
        bail!(
            "{} runs were left in the store (the others were pruned): {}",
            left.len(),
            left.join("; ")
        );
    }
    Ok(done)
}

/// `metadata` and the file's own `spinbench.columns` (each column's meaning
/// and unit).
fn with_columns(metadata: &[KeyValue], columns: &str) -> Vec<KeyValue> {
    let mut all = metadata.to_vec();
    all.push(KeyValue::new(
        "spinbench.columns".into(),
        columns.to_string(),
    ));
    all
}

/// What makes a run's archive files stand alone: the run, its station,
/// start and software, who archived it, and which serial was in each slot
/// (a slot as numbered on the fixtures, from 1).
fn archive_metadata(store: &Store, run: &spinbench_store::RunRow) -> Result<Vec<KeyValue>> {
    let start = store.run_start(&run.id)?;
    let mut slots: std::collections::BTreeMap<i64, String> = std::collections::BTreeMap::new();
    if let Some(plan) = start.as_ref().and_then(|s| s.plan.plan.as_ref()) {
        for (slot, serial) in &plan.serials {
            let serial = serial
                .strip_prefix("P:")
                .or_else(|| serial.strip_prefix("N:"))
                .unwrap_or(serial)
                .trim();
            if let Ok(slot) = slot.trim().parse::<i64>()
                && !serial.is_empty()
            {
                slots.insert(slot, serial.to_string());
            }
        }
    }
    // The serials as the store kept them, where it has them.
    for unit in store.unit_radii(&run.id)? {
        slots.insert(unit.slot + 1, unit.serial);
    }
    let slots: serde_json::Map<String, serde_json::Value> = slots
        .into_iter()
        .map(|(slot, serial)| (slot.to_string(), serial.into()))
        .collect();
    let started = utc_rfc3339(run.started_at);
    let mut kv = vec![
        ("spinbench.layout", ARCHIVE_LAYOUT.to_string()),
        ("spinbench.run", run.id.clone()),
        ("spinbench.label", run.label()),
        ("spinbench.station", run.station.clone()),
        ("spinbench.started_at", started),
        ("spinbench.utc_offset_s", run.utc_offset_s.to_string()),
        (
            "spinbench.archived_by",
            format!("spinbench {}", env!("CARGO_PKG_VERSION")),
        ),
        (
            "spinbench.slots",
            serde_json::Value::Object(slots).to_string(),
        ),
    ];
    if let Some(start) = &start {
        kv.push(("spinbench.software", start.software_version.clone()));
    }
    Ok(kv
        .into_iter()
        .map(|(k, v)| KeyValue::new(k.to_string(), v))
        .collect())
}

/// `at` [Unix s] as RFC 3339 UTC (`2026-12-04T19:21:00Z`).
fn utc_rfc3339(at: i64) -> String {
    let days = at.div_euclid(86_400);
    let secs = at.rem_euclid(86_400);
    let (y, m, d) = spinbench_store::equipment::civil_from_days(days);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        secs / 3600,
        secs % 3600 / 60,
        secs % 60
    )
}

/// A regular file (not a link, not a folder) at `path`.
fn regular_file(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_file())
}

/// A new Parquet file at `path`: written beside it under a name of this
/// prune's own (created exclusively, never through a link), synced, then
/// linked to the final name, which must not exist (a link or a file there
/// is refused, never written through), and the folder synced. A crash leaves
/// no half file under the final name, and a left-over partial file of an
/// interrupted prune blocks nothing. Every error names the file.
fn write_parquet(
    path: &Path,
    schema: &str,
    metadata: &[KeyValue],
    write: impl FnOnce(&mut SerializedFileWriter<std::fs::File>) -> Result<()>,
) -> Result<()> {
    use std::os::unix::fs::OpenOptionsExt;
    if std::fs::symlink_metadata(path).is_ok() {
        bail!(
            "{}: exists already (a run is archived once); move it aside to archive the run again",
            path.display()
        );
    }
    let nonce: u64 = rand::random();
    let partial = PathBuf::from(format!(
        "{}.{}-{nonce:016x}.partial",
        path.display(),
        std::process::id()
    ));
    let file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .custom_flags(nix::fcntl::OFlag::O_NOFOLLOW.bits())
        .mode(0o640)
        .open(&partial)
        .with_context(|| format!("{}: cannot create", partial.display()))?;
    let written = (|| -> Result<()> {
        let props = Arc::new(
            WriterProperties::builder()
                .set_compression(Compression::SNAPPY)
                .set_key_value_metadata(Some(metadata.to_vec()))
                .build(),
        );
        let mut writer =
            SerializedFileWriter::new(file, Arc::new(parse_message_type(schema)?), props)?;
        write(&mut writer)?;
        let file = writer.into_inner()?;
        file.sync_all()?;
        // No-clobber: fails if anything (a file, a link) took the name meanwhile.
        std::fs::hard_link(&partial, path)
            .with_context(|| format!("cannot link it to {}", path.display()))?;
        Ok(())
    })();
    let _ = std::fs::remove_file(&partial);
    written.with_context(|| format!("{}: cannot write", partial.display()))?;
    if let Some(folder) = path.parent() {
        std::fs::File::open(folder)
            .and_then(|f| f.sync_all())
            .with_context(|| format!("{}: cannot sync the folder", folder.display()))?;
    }
    Ok(())
}

/// Rows in a Parquet file.
fn rows_in(path: &Path) -> Result<i64> {
    let file =
        std::fs::File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    Ok(SerializedFileReader::new(file)?
        .metadata()
        .file_metadata()
        .num_rows())
}

/// Definition levels of an optional column: 1 present, 0 missing.
fn present<T: Copy>(values: impl Iterator<Item = Option<T>>) -> (Vec<T>, Vec<i16>) {
    let mut kept = Vec::new();
    let mut levels = Vec::new();
    for v in values {
        levels.push(i16::from(v.is_some()));
        kept.extend(v);
    }
    (kept, levels)
}

fn write_values(
    values: &[ValueRow],
    run_id: &str,
    metadata: &[KeyValue],
    path: &Path,
) -> Result<()> {
    let metadata = with_columns(
        metadata,
        "t_s: seconds from the run's start; slot: numbered from 1, as on the fixtures; output_hz: the instrument's one-second output [Hz]; rate_deg_s: the table's rate [deg/s]; on_speed: the rate within tolerance; temperature_c: the instrument's temperature [°C]",
    );
    write_parquet(
        path,
        "message values_1s {
            REQUIRED BYTE_ARRAY run (UTF8);
            REQUIRED DOUBLE t_s;
            REQUIRED INT64 slot;
            OPTIONAL DOUBLE output_hz;
            REQUIRED DOUBLE rate_deg_s;
            REQUIRED BOOLEAN on_speed;
            OPTIONAL DOUBLE temperature_c;
        }",
        &metadata,
        |writer| {
            let mut group = writer.next_row_group()?;
            let mut column = 0;
            while let Some(mut c) = group.next_column()? {
                match column {
                    0 => {
                        let run: Vec<ByteArray> =
                            values.iter().map(|_| ByteArray::from(run_id)).collect();
                        c.typed::<ByteArrayType>().write_batch(&run, None, None)?;
                    }
                    1 | 4 => {
                        let v: Vec<f64> = values
                            .iter()
                            .map(|v| if column == 1 { v.t_s } else { v.rate_deg_s })
                            .collect();
                        c.typed::<DoubleType>().write_batch(&v, None, None)?;
                    }
                    2 => {
                        // Numbered from 1, as the store and people number slots.
                        let v: Vec<i64> = values.iter().map(|v| v.slot + 1).collect();
                        c.typed::<Int64Type>().write_batch(&v, None, None)?;
                    }
                    3 | 6 => {
                        let (kept, levels) = present(values.iter().map(|v| {
                            if column == 3 {
                                v.output_hz
                            } else {
                                v.temperature_c
                            }
                        }));
                        c.typed::<DoubleType>()
                            .write_batch(&kept, Some(&levels), None)?;
                    }
                    _ => {
                        let v: Vec<bool> = values.iter().map(|v| v.on_speed).collect();
                        c.typed::<BoolType>().write_batch(&v, None, None)?;
                    }
                }
                c.close()?;
                column += 1;
            }
            group.close()?;
            Ok(())
        },
    )
}

fn write_events(
    events: &[EventRow],
    run_id: &str,
    metadata: &[KeyValue],
    path: &Path,
) -> Result<()> {
    let metadata = with_columns(
        metadata,
        "seq: the event's number in the run; at: when it happened (UTC); kind: its name; json: the event as the store kept it",
    );
    write_parquet(
        path,
        "message events {
            REQUIRED BYTE_ARRAY run (UTF8);
            REQUIRED INT64 seq;
            REQUIRED INT64 at (TIMESTAMP(MILLIS, true));
            REQUIRED BYTE_ARRAY kind (UTF8);
            REQUIRED BYTE_ARRAY json (UTF8);
        }",
        &metadata,
        |writer| {
            let mut group = writer.next_row_group()?;
            let mut column = 0;
            while let Some(mut c) = group.next_column()? {
                match column {
                    1 | 2 => {
                        let v: Vec<i64> = events
                            .iter()
                            .map(|e| if column == 1 { e.seq } else { e.at * 1000 })
                            .collect();
                        c.typed::<Int64Type>().write_batch(&v, None, None)?;
                    }
                    _ => {
                        let v: Vec<ByteArray> = events
                            .iter()
                            .map(|e| {
                                ByteArray::from(match column {
                                    0 => run_id,
                                    3 => e.kind.as_str(),
                                    _ => e.json.as_str(),
                                })
                            })
                            .collect();
                        c.typed::<ByteArrayType>().write_batch(&v, None, None)?;
                    }
                }
                c.close()?;
                column += 1;
            }
            group.close()?;
            Ok(())
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn days_are_checked_before_anything_is_read() {
        assert_eq!(parse_days("0"), Ok(0.0));
        assert_eq!(parse_days(" 90 "), Ok(90.0));
        for bad in ["-1", "NaN", "inf", "1e9", "ninety", ""] {
            assert!(parse_days(bad).is_err(), "{bad}");
        }
    }
}
