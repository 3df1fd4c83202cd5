//! The run journal: every event appended as one JSON line and flushed as it
//! is written (points are also synced to disk), so that after the process
//! is killed at any moment the run can continue from the last completed
//! step with no point lost or duplicated.
//!
//! Each line carries a chained hash (`"chain"`: SHA-256 of the previous
//! line's chain and this line's event), so an edit, an inserted or a
//! removed line is found when the journal is read back ([`read_journal`]
//! refuses it, naming the line). It is tamper-evident against an edit by
//! hand, not against someone who recomputes the chain: the raw capture,
//! read by `spinbench replay`, is the stronger check of the points.

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
    /// The chain of the last line written (all zeros before the first).
    chain: [u8; 32],
}

/// The key of a line's chained hash; always the line's last field.
const CHAIN_FIELD: &str = ",\"chain\":\"";

/// The chain after `event_json` (an event's JSON, without the chain field).
fn next_chain(previous: &[u8; 32], event_json: &[u8]) -> [u8; 32] {
    use sha2::Digest;
    let mut hasher = sha2::Sha256::new();
    hasher.update(previous);
    hasher.update(event_json);
    hasher.finalize().into()
}

fn hex(bytes: &[u8; 32]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A line split into its event's JSON and its chain, if it has one.
fn split_chain(line: &str) -> Option<(String, &str)> {
    let body = line.trim_end();
    let at = body.rfind(CHAIN_FIELD)?;
    let rest = &body[at + CHAIN_FIELD.len()..];
    let chain = rest.strip_suffix("\"}")?;
    if chain.len() != 64 || !chain.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    Some((format!("{}}}", &body[..at]), chain))
}

impl Journal {
    /// Open (creating or appending) the journal of the run in `dir`.
    pub fn open(dir: &Path) -> std::io::Result<Journal> {
        std::fs::create_dir_all(dir)?;
        let path = dir.join(JOURNAL_FILE);
        // The chain goes on from the last line already there.
        let mut chain = [0u8; 32];
        if let Ok(existing) = File::open(&path) {
            for line in BufReader::new(existing).lines() {
                if let Some((event, _)) = split_chain(&line?) {
                    chain = next_chain(&chain, event.as_bytes());
                }
            }
        }
        let file = OpenOptions::new().create(true).append(true).open(&path)?;
        Ok(Journal { path, file, chain })
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
        let chain = next_chain(&self.chain, &line);
        // The event's object with its chain as the last field.
        line.pop();
        line.extend_from_slice(format!("{CHAIN_FIELD}{}\"}}\n", hex(&chain)).as_bytes());
        let fail =
            |e: std::io::Error| format!("journal {}: cannot write: {e}", self.path.display());
        self.file.write_all(&line).map_err(fail)?;
        self.file.flush().map_err(fail)?;
        self.chain = chain;
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
    /// A line's chained hash does not follow from the lines before it: the
    /// journal was edited, or a line put in or taken out.
    #[error(
        "{path}:{line}: the journal was changed after it was written (its chained hash does not follow from the lines before); the run cannot be continued from it: start a new run, and keep the folder for whoever looks into it"
    )]
    Edited {
        /// The journal's path, as shown.
        path: String,
        /// The first line that does not follow (1-based).
        line: usize,
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
    let mut chain = [0u8; 32];
    let mut chained = false;
    for (i, line) in lines.iter().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let last = i + 1 == lines.len();
        match split_chain(line) {
            Some((event, written)) => {
                chain = next_chain(&chain, event.as_bytes());
                if hex(&chain) != written {
                    return Err(JournalError::Edited {
                        path: path.display().to_string(),
                        line: i + 1,
                    });
                }
                chained = true;
            }
            // A line without its chain after chained ones: put in by hand
            // (or the torn last line, ignored below).
            None if chained && !last => {
                return Err(JournalError::Edited {
                    path: path.display().to_string(),
                    line: i + 1,
                });
            }
            // A journal of a release before the chain.
            None => {}
        }
        match serde_json::from_str::<Event>(line) {
            Ok(e) => events.push(e),
            Err(e) if last => {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn journal_of(events: &[Event]) -> tempfile::TempDir {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut j = Journal::open(dir.path()).expect("open");
        for e in events {
            j.emit(e).expect("write");
        }
        dir
    }

    fn steps(n: usize) -> Vec<Event> {
        (0..n).map(|index| Event::StepDone { index }).collect()
    }

    #[test]
    fn an_edited_inserted_or_removed_line_is_found_and_named() {
        let dir = journal_of(&steps(4));
        let (events, torn) = read_journal(dir.path()).expect("read");
        assert_eq!(events, steps(4));
        assert!(torn.is_none());
        // Reopened, the chain goes on.
        let mut j = Journal::open(dir.path()).expect("reopen");
        j.emit(&Event::StepDone { index: 4 }).expect("write");
        assert_eq!(read_journal(dir.path()).expect("read").0, steps(5));
        let path = dir.path().join(JOURNAL_FILE);
        let text = std::fs::read_to_string(&path).expect("text");
        let lines: Vec<&str> = text.lines().collect();
        let edited_line = |lines: Vec<String>| {
            std::fs::write(&path, lines.join("\n") + "\n").expect("write");
            match read_journal(dir.path()) {
                Err(JournalError::Edited { line, .. }) => line,
                other => panic!("not found: {other:?}"),
            }
        };
        // A value changed.
        let mut changed: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        changed[2] = changed[2].replace("\"index\":2", "\"index\":7");
        assert_eq!(edited_line(changed), 3);
        // A line taken out.
        let mut removed: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        removed.remove(1);
        assert_eq!(edited_line(removed), 2);
        // A line without a chain put in.
        let mut inserted: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        inserted.insert(2, r#"{"event":"step_done","index":9}"#.into());
        assert_eq!(edited_line(inserted), 3);
    }

    #[test]
    fn a_journal_of_a_release_before_the_chain_is_read_as_it_was() {
        let dir = tempfile::tempdir().expect("tempdir");
        let lines: String = steps(3)
            .iter()
            .map(|e| serde_json::to_string(e).expect("json") + "\n")
            .collect();
        std::fs::write(dir.path().join(JOURNAL_FILE), lines).expect("write");
        assert_eq!(read_journal(dir.path()).expect("read").0, steps(3));
    }
}
