//! What a station finds at its start (`run`, `serve`) of the runs its
//! processes left behind: events the store had not taken when a
//! run ended (the run directory's outbox file, written now), and runs the
//! store still has `running` whose process ended without finishing them (a
//! crash, a power cut), marked `interrupted` with how to resume them.
//!
//! Only this data directory's runs are looked at, and only those no
//! process runs now (their directory's lock is free): another station of
//! the fleet, or a run in progress, is never touched.

use crate::run_setup::RUNS_DIR;
use spinbench_engine::RunState;
use spinbench_engine::event::Event;
use spinbench_engine::journal::read_journal;
use spinbench_store::Store;
use spinbench_store::leftover::catch_up;
use spinbench_store::outbox::OUTBOX_FILE;
use std::path::{Path, PathBuf};

/// What [`recover`] did, a line each, for the terminal and the log.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Recovered {
    /// Runs whose left-over events were written (run id, events).
    pub caught_up: Vec<(String, u64)>,
    /// Runs marked interrupted (run id, directory).
    pub interrupted: Vec<(String, PathBuf)>,
    /// What could not be done, and why (tried again at the next start).
    pub problems: Vec<String>,
}

impl Recovered {
    /// The lines to print (none when nothing was found).
    pub fn lines(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (id, n) in &self.caught_up {
            out.push(format!(
                "run {id}: wrote the {n} events the store had not taken when the run ended"
            ));
        }
        for (id, dir) in &self.interrupted {
            out.push(format!(
                "run {id} was left running by a process that ended without finishing it: marked interrupted; \
                 continue it with `spinbench run --resume {}` (or start a new run)",
                dir.display()
            ));
        }
        for p in &self.problems {
            out.push(format!("warning: {p}"));
        }
        out
    }
}

/// Whether no process runs the run in `dir` now (its lock is free).
fn idle(dir: &Path) -> bool {
    held(dir).is_some()
}

/// The run folder's lock, held until the answer is dropped, when no other
/// process (a run, another start catching up) holds it.
fn held(dir: &Path) -> Option<std::fs::File> {
    let folder = std::fs::File::open(dir).ok()?;
    folder.try_lock().ok()?;
    Some(folder)
}

/// Whether the journal in `dir` finished the run it last started.
fn journal_finished(dir: &Path) -> bool {
    let Ok((events, _)) = read_journal(dir) else {
        return false;
    };
    let last_start = events
        .iter()
        .rposition(|e| matches!(e, Event::RunStarted { .. }));
    last_start.is_some_and(|i| {
        events[i..].iter().any(|e| {
            matches!(
                e,
                Event::RunFinished {
                    state: RunState::Completed | RunState::Aborted | RunState::Faulted,
                    ..
                }
            )
        })
    })
}

/// Catch up and mark, for station `station` with data directory `data`.
pub fn recover(data: &Path, station: &str, store: &Store) -> Recovered {
    let mut out = catch_up_left_over_files(data, station, store, &mut |_, _| {});
    let marked = mark_crashed_runs(data, station, store);
    out.interrupted = marked.interrupted;
    out.problems.extend(marked.problems);
    out
}

/// The run folders of `data` that hold a left-over file now.
pub fn left_over_files(data: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(data.join(RUNS_DIR))
        .map(|entries| {
            entries
                .flatten()
                .map(|e| e.path())
                .filter(|d| d.join(OUTBOX_FILE).is_file())
                .collect()
        })
        .unwrap_or_default()
}

/// Write the left-over files of this station's runs no process runs now
/// (checked, [`catch_up`]); `progress` is told (done, of) after each.
pub fn catch_up_left_over_files(
    data: &Path,
    station: &str,
    store: &Store,
    progress: &mut dyn FnMut(usize, usize),
) -> Recovered {
    let mut out = Recovered::default();
    let folders = left_over_files(data);
    let of = folders.len();
    for (done, dir) in folders.into_iter().enumerate() {
        progress(done, of);
        {
            if !dir.join(OUTBOX_FILE).is_file() {
                continue;
            }
            // Under the folder's lock, the file looked at again: a second
            // start that waited finds it written and gone.
            let Some(_lock) = held(&dir) else {
                continue;
            };
            if !dir.join(OUTBOX_FILE).is_file() {
                continue;
            }
            let id = dir
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            match catch_up(store, &dir, station) {
                Ok(done) => {
                    if let Some(why) = done.refused {
                        out.problems.push(format!(
                            "run {id}: its left-over file was not written ({why}); it is kept as {}{} and the refusal audited",
                            OUTBOX_FILE,
                            spinbench_store::leftover::REFUSED_SUFFIX
                        ));
                    }
                    if done.torn_kept {
                        out.problems.push(format!(
                            "run {id}: the left-over file's last line was torn; kept as {OUTBOX_FILE}{}",
                            spinbench_store::leftover::TORN_SUFFIX
                        ));
                    }
                    if done.written > 0 {
                        out.caught_up.push((id, done.written));
                    }
                }
                Err(e) => out.problems.push(e.to_string()),
            }
        }
    }
    progress(of, of);
    out
}

/// Mark this station's runs the store still has `running` whose process
/// ended without finishing them (their folder's lock free, their journal
/// unfinished) `interrupted`, first writing what their journal measured.
pub fn mark_crashed_runs(data: &Path, station: &str, store: &Store) -> Recovered {
    let mut out = Recovered::default();
    let runs = data.join(RUNS_DIR);
    match store.running_runs(station) {
        Ok(rows) => {
            for row in rows {
                let dir = runs.join(&row.id);
                if !dir.is_dir() || !idle(&dir) || journal_finished(&dir) {
                    continue;
                }
                // What the crashed process's outbox held in memory: the
                // record keeps every measurement its journal has.
                if let Ok((events, _)) = read_journal(&dir)
                    && let Err(e) = spinbench_store::outbox::catch_up_from_journal(store, &events)
                {
                    out.problems.push(e.to_string());
                }
                let why = "the station's process ended without finishing the run (a crash or a power cut)";
                match store.mark_interrupted(&row.id, why) {
                    Ok(true) => out.interrupted.push((row.id, dir)),
                    Ok(false) => {}
                    Err(e) => out.problems.push(e.to_string()),
                }
            }
        }
        Err(e) => out.problems.push(e.to_string()),
    }
    out
}
