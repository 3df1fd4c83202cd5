//! The store's outbox: a run's events written to the store on a thread of
//! their own, so that the run never waits on the database.
//!
//! The engine hands each event to an [`OutboxSender`], which only queues
//! it and returns. A writer thread takes the events in order and writes
//! them through a [`StoreSink`]; a write that fails (the server restarting,
//! a network gone, a file locked) is tried again with a growing pause, on
//! a connection made again, the same event, until it is taken: nothing is
//! lost and, since a failed write's transaction is rolled back, nothing is
//! written twice. The queue is bounded in memory ([`MEMORY_EVENTS`]); past
//! that, events go in order to a spill file beside the journal and are
//! written from there when the store is back. Only a failing local disk
//! refuses an event (the engine then holds the run and, at its hold limit,
//! goes to its safe state).
//!
//! At the run's end [`Outbox::finish`] waits, within a bound, for the store
//! to catch up; whatever is still unwritten then is kept in the run
//! directory's [`OUTBOX_FILE`] and written by [`crate::leftover::catch_up`]
//! (checked against the run's journal) at the next start of the station. [`StoreHealth`] says how the store is doing (up,
//! errors, the queue's depth and age) for `/metrics` and the fleet.

use super::{Event, EventSink, Path, Store, StoreError, StoreSink, failed};
use std::collections::VecDeque;
use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Events held in memory before the queue spills to disk (about a day of
/// one-second values: at most a few hundred MB).
pub const MEMORY_EVENTS: usize = 100_000;

/// The file in a run directory that holds the events the store has not
/// taken yet (while the queue spills, and after a run that ended with the
/// store down), one JSON event per line.
pub const OUTBOX_FILE: &str = "store-outbox.jsonl";

/// An event waiting this long means the store is not taking writes (down
/// or stalled), whatever the writer has seen.
pub const STALLED_AFTER: Duration = Duration::from_secs(10);

/// How long a finished run waits for a store that refuses its writes (it
/// answers with an error of its own) before it ends saying so.
pub const REFUSED_WAIT: Duration = Duration::from_secs(5);

/// The longest pause between two tries of a failing write.
pub const RETRY_AT_MOST: Duration = Duration::from_secs(5);

/// How the store is doing, as the outbox sees it: shared with `/metrics`,
/// the heartbeat and the screens.
#[derive(Debug, Default)]
pub struct StoreHealth {
    down: AtomicBool,
    errors: AtomicU64,
    depth: AtomicU64,
    oldest: Mutex<Option<Instant>>,
    last_error: Mutex<String>,
    /// The last failure in which the store answered and refused (a
    /// permission, a constraint), not an outage: waiting does not help.
    refused: Mutex<Option<String>>,
}

/// Every run write that failed in this process, over all its outboxes
/// (`/metrics`' `store_errors_total` counts them with the heartbeat's).
static RUN_WRITE_FAILURES: AtomicU64 = AtomicU64::new(0);

/// The run writes that failed in this process so far, every outbox's.
pub fn run_write_failures() -> u64 {
    RUN_WRITE_FAILURES.load(Ordering::Relaxed)
}

/// A reading of [`StoreHealth`].
#[derive(Debug, Clone, PartialEq)]
pub struct HealthReading {
    /// Whether the last write succeeded (or none has failed yet) and no
    /// event has waited [`STALLED_AFTER`].
    pub up: bool,
    /// Writes that failed since the outbox opened.
    pub errors: u64,
    /// Events waiting to be written.
    pub depth: u64,
    /// How long the oldest waiting event has waited [s] (0 when none).
    pub age_s: f64,
    /// The last failure's message (empty when none).
    pub last_error: String,
    /// The last failure in which the store refused the write (it answered
    /// with an error of its own: a permission, a constraint), which no
    /// waiting mends; `None` when every failure was an outage.
    pub refused: Option<String>,
}

fn locked<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl StoreHealth {
    /// The health now.
    pub fn reading(&self) -> HealthReading {
        let age_s = locked(&self.oldest).map_or(0.0, |t| t.elapsed().as_secs_f64());
        HealthReading {
            // A write that does not come back (a stalled server) is no
            // failure the writer can see: an event waiting this long is.
            up: !self.down.load(Ordering::Relaxed) && age_s < STALLED_AFTER.as_secs_f64(),
            errors: self.errors.load(Ordering::Relaxed),
            depth: self.depth.load(Ordering::Relaxed),
            age_s,
            last_error: locked(&self.last_error).clone(),
            refused: locked(&self.refused).clone(),
        }
    }
    fn failed(&self, why: &str, refused: bool) {
        self.down.store(true, Ordering::Relaxed);
        self.errors.fetch_add(1, Ordering::Relaxed);
        RUN_WRITE_FAILURES.fetch_add(1, Ordering::Relaxed);
        *locked(&self.last_error) = why.to_string();
        if refused {
            *locked(&self.refused) = Some(why.to_string());
        }
    }
    fn succeeded(&self) {
        self.down.store(false, Ordering::Relaxed);
    }
}

/// Why the outbox could not keep an event on disk (the store's own
/// outages are not errors here: they are waited out).
#[derive(Debug, thiserror::Error)]
pub enum OutboxError {
    /// An event could not be written as JSON.
    #[error("an event could not be written as JSON: {0}")]
    Serialise(#[from] serde_json::Error),
    /// The queue could not spill to disk.
    #[error("{path}: cannot spill the store's queue to disk: {source}")]
    Spill {
        /// The spill file, as shown.
        path: String,
        /// The system's error.
        source: std::io::Error,
    },
    /// The spill file could not be written.
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The spill file, as shown.
        path: String,
        /// The system's error.
        source: std::io::Error,
    },
    /// What the store had not taken at the end could not be kept.
    #[error("{path}: cannot keep the {count} events the store {target} has not taken: {source}")]
    Keep {
        /// The outbox file, as shown.
        path: String,
        /// How many events.
        count: usize,
        /// The store, as shown.
        target: String,
        /// The system's error.
        source: std::io::Error,
    },
}

impl From<OutboxError> for spinbench_engine::event::SinkError {
    fn from(e: OutboxError) -> Self {
        e.to_string().into()
    }
}

/// Events past the memory bound, in a file, in order.
struct Spill {
    path: PathBuf,
    file: File,
    reader: BufReader<File>,
    written: u64,
    read: u64,
}

impl Spill {
    fn open(path: PathBuf) -> std::io::Result<Spill> {
        let file = OpenOptions::new()
            .create(true)
            .truncate(true)
            .write(true)
            .read(true)
            .open(&path)?;
        let reader = BufReader::new(File::open(&path)?);
        Ok(Spill {
            path,
            file,
            reader,
            written: 0,
            read: 0,
        })
    }
    fn push(&mut self, event: &Event) -> Result<(), OutboxError> {
        let mut line = serde_json::to_vec(event)?;
        line.push(b'\n');
        self.file
            .write_all(&line)
            .and_then(|()| self.file.flush())
            .map_err(|source| OutboxError::Write {
                path: self.path.display().to_string(),
                source,
            })?;
        self.written += 1;
        Ok(())
    }
    fn next(&mut self) -> Option<Event> {
        if self.read >= self.written {
            return None;
        }
        let mut line = String::new();
        self.reader.read_line(&mut line).ok()?;
        self.read += 1;
        serde_json::from_str(&line).ok()
    }
}

struct Queue {
    memory: VecDeque<(Instant, Event)>,
    spill: Option<Spill>,
    /// The event being written (taken from the queue, not yet accepted).
    writing: Option<Event>,
    /// No more events will come: the writer ends once all are written.
    closing: bool,
    /// The writer is to end now (what is left goes to the outbox file).
    leave: bool,
}

struct Shared {
    queue: Mutex<Queue>,
    wake: Condvar,
    health: Arc<StoreHealth>,
    spill_path: PathBuf,
}

impl Shared {
    fn depth(q: &Queue) -> u64 {
        q.memory.len() as u64
            + q.spill.as_ref().map_or(0, |s| s.written - s.read)
            + u64::from(q.writing.is_some())
    }
    fn publish(&self, q: &Queue) {
        self.health.depth.store(Shared::depth(q), Ordering::Relaxed);
        if q.writing.is_none() && q.memory.is_empty() && q.spill.is_none() {
            *locked(&self.health.oldest) = None;
        } else if let Some((t, _)) = q.memory.front()
            && q.writing.is_none()
        {
            *locked(&self.health.oldest) = Some(*t);
        }
    }
}

/// The engine's side of the outbox: queues each event and returns.
pub struct OutboxSender {
    shared: Arc<Shared>,
}

impl EventSink for OutboxSender {
    fn emit(&mut self, event: &Event) -> Result<(), spinbench_engine::event::SinkError> {
        if matches!(event, Event::Progress { .. }) {
            return Ok(());
        }
        let mut q = locked(&self.shared.queue);
        if q.spill.is_none() && q.memory.len() >= MEMORY_EVENTS {
            q.spill = Some(
                Spill::open(self.shared.spill_path.clone()).map_err(|source| {
                    OutboxError::Spill {
                        path: self.shared.spill_path.display().to_string(),
                        source,
                    }
                })?,
            );
        }
        if let Some(spill) = q.spill.as_mut() {
            spill.push(event)?;
        } else {
            q.memory.push_back((Instant::now(), event.clone()));
        }
        if locked(&self.shared.health.oldest).is_none() {
            *locked(&self.shared.health.oldest) = Some(Instant::now());
        }
        self.shared.publish(&q);
        drop(q);
        self.shared.wake.notify_all();
        Ok(())
    }
}

/// The outbox of one run: its writer thread and health.
pub struct Outbox {
    shared: Arc<Shared>,
    writer: Option<std::thread::JoinHandle<()>>,
    target: String,
}

/// What [`Outbox::finish`] saw.
#[derive(Debug, Clone, PartialEq)]
pub struct Finished {
    /// Events the store had not taken when the wait ended (kept in the
    /// run directory's [`OUTBOX_FILE`]).
    pub left: u64,
    /// The writes that failed during the run.
    pub errors: u64,
    /// The last write the store refused (it answered with an error of its
    /// own: a permission, a constraint), which no waiting mends.
    pub refused: Option<String>,
}

impl Store {
    /// An outbox writing a run's events to this store (a connection of its
    /// own, on a thread of its own); its spill and left-over file is
    /// `run_dir`/[`OUTBOX_FILE`]. Returns the outbox and the engine's sender.
    pub fn outbox(&self, run_dir: &Path) -> Result<(Outbox, OutboxSender), StoreError> {
        let sink = self.sink()?;
        let shared = Arc::new(Shared {
            queue: Mutex::new(Queue {
                memory: VecDeque::new(),
                spill: None,
                writing: None,
                closing: false,
                leave: false,
            }),
            wake: Condvar::new(),
            health: Arc::new(StoreHealth::default()),
            spill_path: run_dir.join(OUTBOX_FILE),
        });
        let for_writer = Arc::clone(&shared);
        let writer = std::thread::Builder::new()
            .name("store-outbox".into())
            .spawn(move || write_all(&for_writer, sink))
            .map_err(|e| {
                StoreError::message(
                    &self.target,
                    "start the store's writer thread",
                    e.to_string(),
                )
            })?;
        Ok((
            Outbox {
                shared: Arc::clone(&shared),
                writer: Some(writer),
                target: self.target.to_string(),
            },
            OutboxSender { shared },
        ))
    }
}

impl Outbox {
    /// The store's health as this outbox sees it (shared: stays current).
    pub fn health(&self) -> Arc<StoreHealth> {
        Arc::clone(&self.shared.health)
    }

    /// The run has ended: wait up to `wait` for the store to take every
    /// event, calling `progress` with the count left about once a second
    /// while it has not; then end the writer. What is left is kept in the
    /// run directory's [`OUTBOX_FILE`] for [`catch_up`].
    pub fn finish(
        mut self,
        wait: Duration,
        mut progress: impl FnMut(&HealthReading),
    ) -> Result<Finished, OutboxError> {
        let until = Instant::now() + wait;
        {
            let mut q = locked(&self.shared.queue);
            q.closing = true;
            self.shared.wake.notify_all();
            let mut told = Instant::now();
            let began = Instant::now();
            while Shared::depth(&q) > 0 && Instant::now() < until {
                // A store that answers and refuses (a permission) does not
                // mend by waiting: after a few tries the run ends saying so.
                let h = self.shared.health.reading();
                if h.refused.is_some() && !h.up && began.elapsed() >= REFUSED_WAIT {
                    break;
                }
                q = self
                    .shared
                    .wake
                    .wait_timeout(q, Duration::from_millis(200))
                    .map(|(g, _)| g)
                    .unwrap_or_else(|e| e.into_inner().0);
                if told.elapsed() >= Duration::from_secs(1) && Shared::depth(&q) > 0 {
                    told = Instant::now();
                    drop(q);
                    progress(&self.shared.health.reading());
                    q = locked(&self.shared.queue);
                }
            }
            q.leave = true;
            self.shared.wake.notify_all();
        }
        // The writer ends at its next look at the queue; one blocked in a
        // database call that does not answer is left behind (its event is
        // kept below, and written again at the catch-up: a transaction the
        // server never committed).
        let writer = self.writer.take();
        let joined_by = Instant::now() + Duration::from_secs(2);
        if let Some(w) = writer {
            while !w.is_finished() && Instant::now() < joined_by {
                std::thread::sleep(Duration::from_millis(20));
            }
            if w.is_finished() {
                let _ = w.join();
            }
        }
        let reading = self.shared.health.reading();
        let left = self.keep_left()?;
        Ok(Finished {
            left,
            errors: reading.errors,
            refused: reading.refused,
        })
    }

    /// Everything not written, in order, into the outbox file.
    fn keep_left(&self) -> Result<u64, OutboxError> {
        let mut q = locked(&self.shared.queue);
        let mut rest: Vec<Event> = q.writing.take().into_iter().collect();
        rest.extend(q.memory.drain(..).map(|(_, e)| e));
        if let Some(mut spill) = q.spill.take() {
            while let Some(e) = spill.next() {
                rest.push(e);
            }
        }
        let path = &self.shared.spill_path;
        if rest.is_empty() {
            let _ = std::fs::remove_file(path);
            return Ok(0);
        }
        let mut text = Vec::new();
        for e in &rest {
            serde_json::to_writer(&mut text, e)?;
            text.push(b'\n');
        }
        let tmp = path.with_extension("jsonl.tmp");
        std::fs::write(&tmp, &text)
            .and_then(|()| File::open(&tmp)?.sync_all())
            .and_then(|()| std::fs::rename(&tmp, path))
            .map_err(|source| OutboxError::Keep {
                path: path.display().to_string(),
                count: rest.len(),
                target: self.target.to_string(),
                source,
            })?;
        Ok(rest.len() as u64)
    }
}

/// The writer thread: each event in order, tried until the store takes it.
fn write_all(shared: &Shared, mut sink: StoreSink) {
    let mut pause = Duration::from_millis(250);
    loop {
        let event = {
            let mut q = locked(&shared.queue);
            loop {
                if q.leave {
                    return;
                }
                if let Some(e) = q.writing.clone() {
                    break e;
                }
                if let Some((_, e)) = q.memory.pop_front() {
                    q.writing = Some(e.clone());
                    break e;
                }
                if let Some(spill) = q.spill.as_mut() {
                    if let Some(e) = spill.next() {
                        q.writing = Some(e.clone());
                        break e;
                    }
                    // Drained: later events go to memory again.
                    let _ = std::fs::remove_file(&spill.path);
                    q.spill = None;
                    continue;
                }
                shared.publish(&q);
                if q.closing {
                    shared.wake.notify_all();
                    return;
                }
                q = shared.wake.wait(q).unwrap_or_else(|e| e.into_inner());
            }
        };
        match sink.write(&event) {
            Ok(()) => {
                shared.health.succeeded();
                pause = Duration::from_millis(250);
                let mut q = locked(&shared.queue);
                q.writing = None;
                *locked(&shared.health.oldest) = q.memory.front().map(|(t, _)| *t);
                shared.publish(&q);
                drop(q);
                shared.wake.notify_all();
            }
            Err(e) => {
                shared.health.failed(
                    &format!("store {}: {}", sink.store.target, crate::whole_reason(&e)),
                    crate::is_refusal(&e),
                );
                // Wait before the next try, waking early to leave.
                let q = locked(&shared.queue);
                let (q, _) = shared
                    .wake
                    .wait_timeout_while(q, pause, |q| !q.leave)
                    .unwrap_or_else(|e| e.into_inner());
                drop(q);
                pause = (pause * 2).min(RETRY_AT_MOST);
            }
        }
    }
}

/// A process killed outright (SIGKILL, a power cut) takes the events its
/// outbox still held in memory with it; its journal, written and synced
/// first, has them. Write into `store` what `journal` (a run directory's
/// events, [`spinbench_engine::journal::read_journal`]) holds of the run's
/// measurements and the store lacks: the run itself if the store never
/// heard of it, every step's points, the radii, and the one-second values
/// after the store's last. Each is an upsert: nothing is doubled, and a
/// step redone after the resume replaces its rows. Returns how many events
/// were written. Called before a run is resumed and when a crashed run is
/// marked interrupted.
pub fn catch_up_from_journal(store: &Store, journal: &[Event]) -> Result<u64, StoreError> {
    let what = "catch up from a run's journal";
    let Some(first) = journal
        .iter()
        .find(|e| matches!(e, Event::RunStarted { .. }))
    else {
        return Ok(0);
    };
    let Event::RunStarted { run_id, .. } = first else {
        return Ok(0);
    };
    let known = store.run(run_id)?.is_some();
    let stored: std::collections::BTreeSet<(i64, i64)> = if known {
        store.point_keys(run_id)?.into_iter().collect()
    } else {
        Default::default()
    };
    let last_value_s = if known {
        store.last_value_time_s(run_id)?
    } else {
        None
    };
    let mut sink = store.sink()?;
    sink.prime(first);
    let mut written = 0;
    let fail = failed(store.target(), what);
    if !known {
        sink.write(first).map_err(&fail)?;
        written += 1;
    }
    for event in journal {
        let missing = match event {
            Event::PointDone { step, points } => points
                .iter()
                .any(|p| !stored.contains(&(*step as i64, p.slot as i64))),
            Event::RadiusDone { .. } => true,
            Event::Values { time_s, .. } => last_value_s.is_none_or(|t| *time_s > t),
            _ => false,
        };
        if missing {
            sink.write(event).map_err(&fail)?;
            written += 1;
        }
    }
    Ok(written)
}
