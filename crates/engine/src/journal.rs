//! The run journal: every event appended as one JSON line and flushed as it
//! is written (points are also synced to disk), so that after the process
//! is killed at any moment the run can continue from the last completed
//! step with no point lost or duplicated.

use crate::event::{Event, EventSink};
use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};

/// File name of the journal inside a run directory.
pub const JOURNAL_FILE: &str = "journal.jsonl";

/// Appends events to a run's journal.
pub struct Journal {
    path: PathBuf,
    file: File,
}

impl Journal {
    /// Open (creating or appending) the journal of the run in `dir`.
    pub fn open(dir: &Path) -> std::io::Result<Journal> {
        std::fs::create_dir_all(dir)?;
        let path = dir.join(JOURNAL_FILE);
        let file = OpenOptions::new().create(true).append(true).open(&path)?;
        Ok(Journal { path, file })
    }

    /// The journal's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl EventSink for Journal {
    fn emit(&mut self, event: &Event) -> Result<(), crate::event::SinkError> {
        // Per-window values are the store's business (raw data); the journal
        // keeps what is needed to resume and to audit.
        if matches!(event, Event::Values { .. } | Event::Progress { .. }) {
            return Ok(());
        }
        let mut line = serde_json::to_vec(event)
            .map_err(|e| format!("journal: cannot encode an event: {e}"))?;
        line.push(b'\n');
        let fail =
            |e: std::io::Error| format!("journal {}: cannot write: {e}", self.path.display());
        self.file.write_all(&line).map_err(fail)?;
        self.file.flush().map_err(fail)?;
        if matches!(
            event,
            Event::PointDone { .. } | Event::StepDone { .. } | Event::RunFinished { .. }
        ) {
            self.file.sync_data().map_err(fail)?;
        }
        Ok(())
    }
}

/// Read a journal back. A last line cut short by a crash is ignored (and
/// reported); any other unreadable line is an error naming the line.
pub fn read_journal(dir: &Path) -> Result<(Vec<Event>, Option<String>), String> {
    let path = dir.join(JOURNAL_FILE);
    let file = File::open(&path)
        .map_err(|e| format!("{}: cannot open the journal: {e}", path.display()))?;
    let lines: Vec<String> = BufReader::new(file)
        .lines()
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let mut events = Vec::with_capacity(lines.len());
    let mut torn = None;
    for (i, line) in lines.iter().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<Event>(line) {
            Ok(e) => events.push(e),
            Err(e) if i + 1 == lines.len() => {
                torn = Some(format!(
                    "{}:{}: last line incomplete ({e}), ignored",
                    path.display(),
                    i + 1
                ))
            }
            Err(e) => {
                return Err(format!(
                    "{}:{}: not a journal event: {e}",
                    path.display(),
                    i + 1
                ));
            }
        }
    }
    Ok((events, torn))
}
