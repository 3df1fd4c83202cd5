//! Running a prepared test ([`crate::run_setup::prepare`]) on connected
//! devices: the engine with its journal, the store and the progress
//! printer as subscribers (and any more, such as the web UI's hub), the
//! results file and the report at the end.

use crate::run_setup::Prepared;
use crate::terminal::ProgressPrinter;
use anyhow::{Context, Result, bail};
use spinbench_analysis::Mount;
use spinbench_engine::event::{Event, EventSink};
use spinbench_engine::journal::{Journal, read_journal};
use spinbench_engine::{
    AbortFlag, Bench, Executor, Operator, RunOptions, RunState, RunSummary, StationConfig,
};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

pub use crate::run_setup::{DB_FILE, DEFAULT_DATA_DIR, new_run_id};
pub use crate::terminal::TerminalOperator;

/// Connect every device of a station through the production drivers; with
/// `raw_dir` (a run's [`crate::run_setup::RunDir::raw_dir`]), the counter
/// modules' raw bytes are kept there (for `spinbench replay`).
pub fn connect_bench(station: &StationConfig, raw_dir: Option<&Path>) -> Result<Bench> {
    station
        .connect_capturing(raw_dir)
        .context("cannot connect the station's devices")
}

/// What a run produced.
pub struct Finished {
    /// The run's directory.
    pub dir: PathBuf,
    /// The summary.
    pub summary: RunSummary,
}

/// How a run is steered from outside and who else hears its events.
pub struct RunControl {
    /// Set to abort (a termination signal, the web UI), naming who asked.
    pub abort: AbortFlag,
    /// While set, the run holds between steps (the web UI's pause).
    pub pause: Arc<AtomicBool>,
    /// More subscribers to the event stream (the web UI's hub).
    pub sinks: Vec<Box<dyn EventSink + Send>>,
    /// Where the run publishes its store's health (the outbox's) while it
    /// runs, for `/metrics` and the fleet.
    pub store_health: StoreHealthSlot,
}

/// The store's health of the run that runs now, if any (shared).
pub type StoreHealthSlot = Arc<std::sync::Mutex<Option<Arc<spinbench_store::outbox::StoreHealth>>>>;

/// How long a completed run waits at its end for the store to take what
/// it has not yet (the store down at the end); what is left is kept in the
/// run directory and written at the station's next start.
pub const STORE_CATCH_UP_WAIT: Duration = Duration::from_secs(60);

/// The same wait for a run that did not complete (an abort, a signal: the
/// process may have to end within a service manager's stop time-out).
pub const STORE_CATCH_UP_WAIT_STOPPING: Duration = Duration::from_secs(10);

impl RunControl {
    /// Abort only (the terminal's Ctrl-C); no pause, no other subscriber.
    pub fn abort_only(abort: AbortFlag) -> RunControl {
        RunControl {
            abort,
            pause: Arc::new(AtomicBool::new(false)),
            sinks: Vec::new(),
            store_health: StoreHealthSlot::default(),
        }
    }
}

/// A boxed subscriber, passed on (a `Box<dyn EventSink>` is not itself one:
/// the closure impl of `EventSink` would overlap).
struct BoxedSink(Box<dyn EventSink + Send>);

impl EventSink for BoxedSink {
    fn emit(&mut self, event: &Event) -> Result<(), spinbench_engine::event::SinkError> {
        self.0.emit(event)
    }
}

/// Run (or resume) a prepared test on a connected bench, journaling into
/// its run directory.
pub fn execute(
    prepared: Prepared,
    bench: Bench,
    operator: Box<dyn Operator + '_>,
    quiet: bool,
    control: RunControl,
) -> Result<Finished> {
    let Prepared {
        dir: run,
        station,
        station_toml,
        compiled,
        store,
        resume,
        ..
    } = prepared;
    let dir = run.path();
    let run_id = run.id().to_string();
    let journal = Journal::open(dir)
        .with_context(|| format!("{}: cannot create the run directory", dir.display()))?;
    let past = if resume {
        let (events, torn) = read_journal(dir).map_err(anyhow::Error::msg)?;
        if let Some(t) = torn {
            eprintln!("  note: {t}");
        }
        if events.iter().any(|e| {
            matches!(
                e,
                Event::RunFinished {
                    state: RunState::Completed,
                    ..
                }
            )
        }) {
            bail!(
                "{}: this run already completed; nothing to resume",
                dir.display()
            );
        }
        Some(events)
    } else {
        None
    };
    let options = RunOptions {
        run_id: run_id.clone(),
        abort: control.abort,
        pause: control.pause,
        module_silence: Duration::from_secs(5),
        sink_hold_limit: Duration::from_secs(600),
        station_config_toml: station_toml,
    };
    let db = spinbench_store::Store::connect(&store)?;
    // The store's word on the run's end stands over a journal's (one cut
    // short by hand would otherwise take more points into an ended record).
    if resume
        && let Some(row) = db.run(&run_id)?
        && row.state == spinbench_store::StoredState::Completed
    {
        bail!(
            "{}: the store holds run {run_id} as completed; nothing to resume",
            dir.display()
        );
    }
    let mut executor = Executor::new(&station, compiled, bench, operator, options);
    if let Some(events) = &past {
        // What the killed process's outbox held in memory, from its journal
        // (before the station time goes on from the store's last value).
        let restored = spinbench_store::outbox::catch_up_from_journal(&db, events)
            .context("the store must hold what the journal measured before the run is resumed")?;
        if restored > 0 && !quiet {
            eprintln!(
                "  wrote the {restored} measurement events the store had not taken when the run's process ended"
            );
        }
        executor.restore(events);
        if let Some(t) = db.last_value_time_s(&run_id)? {
            executor.continue_time_after(t);
        }
    }
    // What the store did not take of this run's earlier start comes first.
    let earlier = spinbench_store::leftover::catch_up(&db, dir, &station.station).with_context(|| {
        format!(
            "the store must take the events of this run's earlier start first ({}): bring it back, then resume again",
            dir.join(spinbench_store::outbox::OUTBOX_FILE).display()
        )
    })?;
    if let Some(why) = &earlier.refused {
        eprintln!(
            "  warning: the run's left-over file was not written ({why}); it is kept aside and audited"
        );
    }
    if earlier.written > 0 && !quiet {
        eprintln!(
            "  wrote the {} events the store had not taken when this run last ended",
            earlier.written
        );
    }
    // The store through its outbox: the run never waits on the database.
    let (outbox, to_store) = db.outbox(dir)?;
    *control
        .store_health
        .lock()
        .unwrap_or_else(|e| e.into_inner()) = Some(outbox.health());
    executor.subscribe(journal);
    executor.subscribe(to_store);
    executor.subscribe(ProgressPrinter::new(quiet));
    for sink in control.sinks {
        executor.subscribe(BoxedSink(sink));
    }
    let summary = executor.run();
    drop(executor);
    let results = serde_json::to_string_pretty(&summary.records)?;
    std::fs::write(dir.join("results.json"), results)
        .with_context(|| format!("{}: cannot write results.json", dir.display()))?;
    // The hardware is safe; the store catches up (within a bound).
    let wait = if summary.state == RunState::Completed {
        STORE_CATCH_UP_WAIT
    } else {
        STORE_CATCH_UP_WAIT_STOPPING
    };
    let caught_up = outbox.finish(wait, |h| {
        if !quiet {
            eprintln!(
                "  the store has {} events of this run to write (oldest {:.0} s; {}) — waiting",
                h.depth, h.age_s, h.last_error
            );
        }
    });
    match caught_up {
        Ok(f) if f.left == 0 => {}
        Ok(f) if f.refused.is_some() => {
            // The store answered and refused (a permission, a constraint):
            // no outage, and waiting mends nothing. Never "completed, exit 0".
            anyhow::bail!(
                "the store {store} refused this run's events ({}): {} of them are kept in {} and written at the \
                 station's next start once the store takes them; the run's results are in {}. If the store was \
                 upgraded, its owner grants the station's role its rights: `spinbench migrate --db {} --grant ROLE`",
                f.refused.as_deref().unwrap_or_default(),
                f.left,
                dir.join(spinbench_store::outbox::OUTBOX_FILE).display(),
                dir.join("results.json").display(),
                store.for_owner()
            );
        }
        Ok(f) => {
            eprintln!(
                "  note: the store {store} did not take {} events of this run within {} s; they are kept in {} \
                 and written at the station's next start (spinbench run or serve); the report waits for them",
                f.left,
                wait.as_secs(),
                dir.join(spinbench_store::outbox::OUTBOX_FILE).display()
            );
            return Ok(Finished {
                dir: dir.to_path_buf(),
                summary,
            });
        }
        Err(e) => eprintln!("  warning: {e}"),
    }
    // The run's report, written at the end of every run (a failed report
    // does not lose the run: it is in the store and can be made again).
    use spinbench_report::ReportFormat;
    match spinbench_report::write_reports(&db, &run_id, &ReportFormat::ALL, dir) {
        Ok(files) => {
            if !quiet {
                for f in files {
                    eprintln!("  report: {}", f.display());
                }
            }
        }
        Err(e) => eprintln!(
            "  note: the report could not be written ({e}); `spinbench report RUN` makes it from the store"
        ),
    }
    Ok(Finished {
        dir: dir.to_path_buf(),
        summary,
    })
}

/// The results table of a run.
pub fn render_records(out: &mut dyn Write, finished: &Finished) -> Result<()> {
    let s = &finished.summary;
    writeln!(
        out,
        "\nRun {:?} after {:.0} s of station time.\n",
        s.state, s.duration_s
    )?;
    writeln!(
        out,
        "{:<10} {:>4} {:>12} {:>12} {:>12}  {:<48}  reasons",
        "serial", "slot", "R P [mm]", "R N [mm]", "outcome", "judged"
    )?;
    for r in &s.records {
        let radius = |m: Mount| {
            r.radius_m
                .get(&m)
                .map_or("—".into(), |v| format!("{:.3}", v * 1e3))
        };
        writeln!(
            out,
            "{:<10} {:>4} {:>12} {:>12} {:>12}  {:<48}  {}",
            r.serial,
            r.slot + 1,
            radius(Mount::P),
            radius(Mount::N),
            r.outcome.as_str(),
            r.judged_text(),
            r.reasons.join("; ")
        )?;
    }
    writeln!(
        out,
        "\nResults: {}/results.json; journal: {}/journal.jsonl",
        finished.dir.display(),
        finished.dir.display()
    )?;
    Ok(())
}
