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

/// Why a journal could not be read back.
#[derive(Debug, thiserror::Error)]
pub enum JournalError {
    /// The file could not be opened or read.
    #[error("{path}: cannot {doing}: {source}")]
    Io {
        /// The journal's path, as shown.
        path: String,
        /// What was being done ("open the journal", "read").
        doing: &'static str,
        /// The system's error.
        source: std::io::Error,
    },
    /// A line before the last is not an event.
    #[error("{path}:{line}: not a journal event: {problem}")]
    NotAnEvent {
        /// The journal's path, as shown.
        path: String,
        /// The line (1-based).
        line: usize,
        /// The parser's words.
        problem: String,
    },
}

/// Read a journal back. A last line cut short by a crash is ignored (and
/// reported); any other unreadable line is an error naming the line.
pub fn read_journal(dir: &Path) -> Result<(Vec<Event>, Option<String>), JournalError> {
    let path = dir.join(JOURNAL_FILE);
    let io = |doing: &'static str| {
        let path = path.display().to_string();
        move |source: std::io::Error| JournalError::Io {
            path,
            doing,
            source,
        }
    };
    let file = File::open(&path).map_err(io("open the journal"))?;
    let lines: Vec<String> = BufReader::new(file)
        .lines()
        .collect::<Result<_, _>>()
        .map_err(io("read"))?;
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
                return Err(JournalError::NotAnEvent {
                    path: path.display().to_string(),
                    line: i + 1,
                    problem: e.to_string(),
                });
            }
        }
    }
    Ok((events, torn))
}
