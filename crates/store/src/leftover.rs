//! The left-over file of a run ([`OUTBOX_FILE`]: events the store did not
//! take before the run's process ended), written into the store at a later
//! start, and never trusted whole.
//!
//! A file in a run folder is whatever is on the disk: a copy of another
//! station's folder, an edit, a second process catching up the same file.
//! So the events are written only when the file is this station's own
//! unfinished run's: the folder is named for the run its journal started,
//! on this station; the store does not hold the run's end already, nor the
//! run under another station; and every event in the file is one the
//! run's journal (written and synced first) holds. Anything else is set
//! aside as [`REFUSED_SUFFIX`], named in an audit entry, and nothing of it
//! is written. A torn last line (a process killed while writing it) is kept
//! aside as [`TORN_SUFFIX`] and the lines before it are written. Every
//! catch-up is audited. The caller holds the run folder's lock (one
//! catch-up per file).

use crate::outbox::OUTBOX_FILE;
use crate::{Event, Path, Store, StoreError, StoredState};
use std::collections::HashSet;

/// A left-over file refused whole is renamed with this suffix (kept for
/// whoever looks into it; never written, never tried again).
pub const REFUSED_SUFFIX: &str = ".refused";

/// A torn last line of a left-over file is kept in a file with this suffix.
pub const TORN_SUFFIX: &str = ".torn";

/// Who the station's own audit entries are by.
const STATION_ACTOR: &str = "spinbench";

/// What a catch-up did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CatchUp {
    /// Events written into the store.
    pub written: u64,
    /// Why the file was refused whole, if it was (nothing written).
    pub refused: Option<String>,
    /// A torn last line was kept aside.
    pub torn_kept: bool,
}

/// Write what the run folder `run_dir`'s [`OUTBOX_FILE`] holds into `store`,
/// after the checks of the module documentation, for station `station`;
/// then remove the file. A failing write leaves the rest of the file for the
/// next try (nothing written twice).
pub fn catch_up(store: &Store, run_dir: &Path, station: &str) -> Result<CatchUp, StoreError> {
    let path = run_dir.join(OUTBOX_FILE);
    let what = "catch up from a run's left-over file";
    let io = |e: std::io::Error| {
        StoreError::message(store.target(), what, format!("{}: {e}", path.display()))
    };
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(CatchUp::default()),
        Err(e) => return Err(io(e)),
    };
    let mut lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .collect();
    let mut done = CatchUp::default();
    // A last line that does not parse is a torn write: kept aside.
    if let Some((_, last)) = lines.last()
        && serde_json::from_str::<Event>(last).is_err()
    {
        let torn = format!("{}{TORN_SUFFIX}", path.display());
        std::fs::write(&torn, format!("{last}\n")).map_err(io)?;
        lines.pop();
        done.torn_kept = true;
    }
    let mut events = Vec::with_capacity(lines.len());
    for (i, line) in &lines {
        match serde_json::from_str::<Event>(line) {
            Ok(e) => events.push(e),
            Err(e) => {
                return refuse(
                    store,
                    &path,
                    format!("line {} is not an event ({e})", i + 1),
                    done,
                );
            }
        }
    }
    if let Err(why) = check_against_run(store, run_dir, station, &events)? {
        return refuse(store, &path, why, done);
    }
    let mut sink = store.sink()?;
    if let Ok((journal, _)) = spinbench_engine::journal::read_journal(run_dir)
        && let Some(started) = journal
            .iter()
            .rev()
            .find(|e| matches!(e, Event::RunStarted { .. }))
    {
        sink.prime(started);
    }
    let run_id = folder_id(run_dir);
    for (written, event) in events.iter().enumerate() {
        if let Err(reason) = sink.write(event) {
            // What was written is not written again next time: the file
            // keeps only the rest.
            let mut rest = Vec::new();
            for e in &events[written..] {
                if serde_json::to_writer(&mut rest, e).is_ok() {
                    rest.push(b'\n');
                }
            }
            let tmp = path.with_extension("jsonl.tmp");
            if std::fs::write(&tmp, &rest).is_ok() {
                let _ = std::fs::rename(&tmp, &path);
            }
            if written > 0 {
                let _ = store.audit(
                    STATION_ACTOR,
                    "catch up left-over events",
                    &format!(
                        "run {run_id}: {written} of {} events written, the rest kept",
                        events.len()
                    ),
                );
            }
            return Err(StoreError {
                target: store.target().to_string(),
                what: format!(
                    "catch up from {} ({written} of {} events written; the rest kept)",
                    path.display(),
                    events.len()
                ),
                reason,
            });
        }
    }
    done.written = events.len() as u64;
    store.audit(
        STATION_ACTOR,
        "catch up left-over events",
        &format!(
            "run {run_id}: {} events from {}{}",
            done.written,
            path.display(),
            if done.torn_kept {
                format!(" (a torn last line kept in {OUTBOX_FILE}{TORN_SUFFIX})")
            } else {
                String::new()
            }
        ),
    )?;
    let _ = std::fs::remove_file(&path);
    Ok(done)
}

/// The run id a run folder is named for.
fn folder_id(run_dir: &Path) -> String {
    run_dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Whether the left-over `events` are this station's own unfinished run's
/// (the outer error is the store's; the inner, why not).
fn check_against_run(
    store: &Store,
    run_dir: &Path,
    station: &str,
    events: &[Event],
) -> Result<Result<(), String>, StoreError> {
    let id = folder_id(run_dir);
    let Ok((journal, _)) = spinbench_engine::journal::read_journal(run_dir) else {
        return Ok(Err(
            "the run folder has no journal to check it against".into()
        ));
    };
    let Some(Event::RunStarted {
        run_id,
        station: recorded_on,
        ..
    }) = journal
        .iter()
        .find(|e| matches!(e, Event::RunStarted { .. }))
    else {
        return Ok(Err("the run's journal never started a run".into()));
    };
    if *run_id != id {
        return Ok(Err(format!(
            "the folder is named for run {id}, its journal started run {run_id}"
        )));
    }
    if recorded_on != station {
        return Ok(Err(format!(
            "the run was recorded by station '{recorded_on}', this is station '{station}'"
        )));
    }
    if let Some(row) = store.run(&id)? {
        if row.station != station {
            return Ok(Err(format!(
                "the store holds run {id} as station '{}''s",
                row.station
            )));
        }
        if matches!(
            row.state,
            StoredState::Completed | StoredState::Faulted | StoredState::Aborted
        ) {
            return Ok(Err(format!(
                "the store holds run {id}'s end already ({:?}): its result is not written over",
                row.state
            )));
        }
    }
    // Every event must be one the journal holds (its canonical JSON); the
    // one-second values, which the journal does not keep, only after the
    // store's last (raw values are never written over).
    let canonical = |e: &Event| serde_json::to_string(e).unwrap_or_default();
    let journaled: HashSet<String> = journal.iter().map(canonical).collect();
    let last_value_s = store.last_value_time_s(&id)?;
    for (i, e) in events.iter().enumerate() {
        match e {
            Event::Progress { .. } => continue,
            Event::Values { time_s, .. } => {
                if last_value_s.is_some_and(|t| *time_s <= t) {
                    return Ok(Err(format!(
                        "event {} holds values at {time_s} s, where the store has the run's values already",
                        i + 1
                    )));
                }
                continue;
            }
            _ => {}
        }
        if let Event::RunStarted {
            run_id, station: s, ..
        } = e
            && (*run_id != id || s != station)
        {
            return Ok(Err(format!(
                "event {} starts run {run_id} of station '{s}', not this folder's run",
                i + 1
            )));
        }
        if !journaled.contains(&canonical(e)) {
            return Ok(Err(format!(
                "event {} ({}) is not in the run's journal",
                i + 1,
                e.name()
            )));
        }
    }
    Ok(Ok(()))
}

/// Set the file aside as refused, audited; nothing of it is written.
fn refuse(store: &Store, path: &Path, why: String, done: CatchUp) -> Result<CatchUp, StoreError> {
    let aside = format!("{}{REFUSED_SUFFIX}", path.display());
    std::fs::rename(path, &aside).map_err(|e| {
        StoreError::message(
            store.target(),
            "set a refused left-over file aside",
            format!("{}: {e}", path.display()),
        )
    })?;
    store.audit(
        STATION_ACTOR,
        "refuse left-over events",
        &format!(
            "{}: {why}; kept as {aside}, nothing written",
            path.display()
        ),
    )?;
    Ok(CatchUp {
        refused: Some(why),
        ..done
    })
}
