//! `spinbench run` and `spinbench demo`: a station config and a plan, the
//! devices connected through the production drivers (to hardware, or to the
//! virtual bench behind real pseudo-terminals), the engine, its journal,
//! progress on the terminal, and the results.

use anyhow::{Context, Result, bail};
use serde::Serialize;
use spinbench_analysis::Mount;
use spinbench_engine::event::{Event, EventSink};
use spinbench_engine::journal::{Journal, read_journal};
use spinbench_engine::plan::Fixture;
use spinbench_engine::{
    AbortFlag, Answer, Bench, Executor, Operator, Outcome, RunOptions, RunState, RunSummary,
    StationConfig, TestPlan, UnitRecord,
};
use spinbench_sim::SimConfig;
use spinbench_sim::serve::{RunningBench, ServeOptions};
use spinbench_store::StoreTarget;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Where runs are kept unless `--data` says otherwise.
pub const DEFAULT_DATA_DIR: &str = "spinbench-data";

/// The store's file inside the data directory.
pub const DB_FILE: &str = "spinbench.db";

/// The station config (TOML) that goes with the virtual bench's devices.
pub fn sim_station_toml(bench: &RunningBench) -> String {
    spinbench_engine::sim_bench::station_toml(bench, "")
}

/// Connect every device of a station through the production drivers.
/// Connect the station's devices; with `run_dir`, the counter modules' raw
/// bytes are kept in `run_dir/raw` (for `spinbench replay`).
pub fn connect_bench(station: &StationConfig, run_dir: Option<&Path>) -> Result<Bench> {
    let raw = run_dir.map(|d| d.join(RAW_DIR));
    station
        .connect_capturing(raw.as_deref())
        .context("cannot connect the station's devices")
}

/// The raw byte captures of a run, inside its directory.
pub const RAW_DIR: &str = "raw";

pub use spinbench_engine::sim_bench::SimOperator;

/// The terminal operator: shows the prompt, waits for Enter (or `abort`).
/// Standard input is read on its own thread, so the engine keeps reading
/// the counter modules while the operator works at the centrifuge.
#[derive(Default)]
pub struct TerminalOperator {
    lines: Option<std::sync::mpsc::Receiver<Option<String>>>,
}

impl TerminalOperator {
    fn answer_of(line: Option<String>) -> Answer {
        let proceed = line
            .as_deref()
            .is_some_and(|l| !l.trim().eq_ignore_ascii_case("abort"));
        Answer {
            proceed,
            by: "operator at the terminal".into(),
        }
    }
}

impl Operator for TerminalOperator {
    fn ask(&mut self, text: &str, fixtures: &[Option<Fixture>]) -> Answer {
        if let Some(answer) = self.post(text, fixtures) {
            return answer;
        }
        loop {
            if let Some(answer) = self.poll_answer(Duration::from_millis(500)) {
                return answer;
            }
        }
    }

    fn post(&mut self, text: &str, _fixtures: &[Option<Fixture>]) -> Option<Answer> {
        eprintln!(
            "\n>>> {text}\n    Press Enter when done, or type 'abort' and Enter to stop the run safely."
        );
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let read = std::io::stdin().read_line(&mut line);
            // End of input (or an unreadable terminal) is no "done".
            let _ = tx.send(matches!(read, Ok(n) if n > 0).then_some(line));
        });
        self.lines = Some(rx);
        None
    }

    fn poll_answer(&mut self, wait: Duration) -> Option<Answer> {
        let rx = self.lines.as_ref()?;
        match rx.recv_timeout(wait) {
            Ok(line) => {
                self.lines = None;
                Some(Self::answer_of(line))
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => None,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                self.lines = None;
                Some(Self::answer_of(None))
            }
        }
    }
}

/// Progress on stderr: the step, the phase, the rate.
pub struct ProgressPrinter {
    tty: bool,
    step: String,
    steps: (usize, usize),
    phase: String,
    last: Instant,
    quiet: bool,
}

impl ProgressPrinter {
    /// A printer (`quiet` prints nothing but faults).
    pub fn new(quiet: bool) -> Self {
        ProgressPrinter {
            tty: std::io::stderr().is_terminal(),
            step: String::new(),
            steps: (0, 0),
            phase: String::new(),
            last: Instant::now(),
            quiet,
        }
    }
}

impl EventSink for ProgressPrinter {
    fn emit(&mut self, event: &Event) -> Result<(), String> {
        match event {
            Event::Fault { reason } => {
                eprintln!("\r\x1b[2K  FAULT: {reason} — bringing the station to the safe state")
            }
            _ if self.quiet => {}
            Event::Notice { message } => eprintln!("\r\x1b[2K  note: {message}"),
            Event::StepStarted { index, of, label } => {
                self.steps = (*index + 1, *of);
                self.step = label.clone();
                if !self.tty {
                    eprintln!("  [{:>3}/{}] {label}", index + 1, of);
                }
            }
            Event::Progress { phase, done, of } => self.phase = format!("{phase} {done}/{of}"),
            Event::UnitFailed { slot, reason } => {
                eprintln!("\r\x1b[2K  slot {}: FAILED — {reason}", slot + 1)
            }
            Event::Values {
                time_s,
                rate_deg_s,
                on_speed,
                ..
            } if self.tty && self.last.elapsed() > Duration::from_millis(100) => {
                self.last = Instant::now();
                let (i, n) = self.steps;
                let bar_len = 20;
                let filled = (i * bar_len).checked_div(n).unwrap_or(0).min(bar_len);
                eprint!(
                    "\r\x1b[2K  [{}{}] {i}/{n} {} | {} | t = {:.0} s | {:.2} deg/s {}",
                    "#".repeat(filled),
                    ".".repeat(bar_len - filled),
                    self.step,
                    self.phase,
                    time_s,
                    rate_deg_s,
                    if *on_speed { "on speed" } else { "settling" }
                );
            }
            Event::RunFinished { state, reason } => {
                eprintln!(
                    "\r\x1b[2K  run {state:?}{}",
                    reason
                        .as_ref()
                        .map(|r| format!(": {r}"))
                        .unwrap_or_default()
                );
            }
            _ => {}
        }
        Ok(())
    }
}

/// A new run identifier: the clock and 48 random bits, so that stations
/// sharing one database never pick the same one.
pub fn new_run_id() -> String {
    let t = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap_or_default();
    let random: u64 = rand::random::<u64>() & 0xffff_ffff_ffff;
    format!("run-{}-{random:012x}", t.as_secs())
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
}

impl RunControl {
    /// Abort only (the terminal's Ctrl-C); no pause, no other subscriber.
    pub fn abort_only(abort: AbortFlag) -> RunControl {
        RunControl {
            abort,
            pause: Arc::new(AtomicBool::new(false)),
            sinks: Vec::new(),
        }
    }
}

/// A boxed subscriber, passed on (a `Box<dyn EventSink>` is not itself one:
/// the closure impl of `EventSink` would overlap).
struct BoxedSink(Box<dyn EventSink + Send>);

impl EventSink for BoxedSink {
    fn emit(&mut self, event: &Event) -> Result<(), String> {
        self.0.emit(event)
    }
}

/// Check that `dir` is a run that can be resumed with `plan`: it holds a
/// journal that starts a run and the plan the run was started with, and
/// `plan` is that very plan. Refuses otherwise, naming what differs, so two
/// tests are never merged into one record.
pub fn check_resume(dir: &Path, plan: &TestPlan) -> Result<()> {
    use spinbench_engine::journal::JOURNAL_FILE;
    if !dir.is_dir() {
        bail!("--resume {}: no such run directory", dir.display());
    }
    let plan_path = dir.join("plan.toml");
    if !dir.join(JOURNAL_FILE).is_file() || !plan_path.is_file() {
        bail!(
            "--resume {}: not a run directory (it has no {JOURNAL_FILE} and plan.toml); give the directory of the run to continue, under DATA/runs",
            dir.display()
        );
    }
    let (events, _) = read_journal(dir).map_err(anyhow::Error::msg)?;
    if !events.iter().any(|e| matches!(e, Event::RunStarted { .. })) {
        bail!(
            "--resume {}: its journal never started a run; start a new run instead",
            dir.display()
        );
    }
    let text = std::fs::read_to_string(&plan_path)
        .with_context(|| format!("{}: cannot read the run's plan", plan_path.display()))?;
    let own = TestPlan::from_toml(&text).with_context(|| plan_path.display().to_string())?;
    let differences = plan_differences(&own, plan);
    if !differences.is_empty() {
        bail!(
            "--resume {}: the plan given is not the run's own plan ({}); resume with {} or start a new run",
            dir.display(),
            differences.join("; "),
            plan_path.display()
        );
    }
    Ok(())
}

/// The keys in which two plans differ, with both values ("range_g: 70 in the run, 10 given").
pub fn plan_differences(run: &TestPlan, given: &TestPlan) -> Vec<String> {
    fn walk(prefix: &str, a: &toml::Value, b: &toml::Value, out: &mut Vec<String>) {
        let shown = |v: &toml::Value| spinbench_engine::bounds::shown(&v.to_string());
        match (a, b) {
            (toml::Value::Table(x), toml::Value::Table(y)) => {
                let keys: std::collections::BTreeSet<&String> = x.keys().chain(y.keys()).collect();
                for k in keys {
                    let key = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    match (x.get(k), y.get(k)) {
                        (Some(va), Some(vb)) => walk(&key, va, vb, out),
                        (Some(va), None) => {
                            out.push(format!("{key}: {} in the run, none given", shown(va)))
                        }
                        (None, Some(vb)) => {
                            out.push(format!("{key}: none in the run, {} given", shown(vb)))
                        }
                        (None, None) => {}
                    }
                }
            }
            _ if a != b => out.push(format!(
                "{prefix}: {} in the run, {} given",
                shown(a),
                shown(b)
            )),
            _ => {}
        }
    }
    let mut out = Vec::new();
    match (toml::Value::try_from(run), toml::Value::try_from(given)) {
        (Ok(a), Ok(b)) => walk("", &a, &b, &mut out),
        _ if run != given => out.push("the plans differ".into()),
        _ => {}
    }
    out
}

/// Run (or resume) a plan on a connected bench, journaling into `dir`.
#[allow(clippy::too_many_arguments)]
pub fn execute(
    station: &StationConfig,
    plan: &TestPlan,
    bench: Bench,
    operator: Box<dyn Operator + '_>,
    dir: &Path,
    db: &StoreTarget,
    resume: bool,
    quiet: bool,
    control: RunControl,
) -> Result<Finished> {
    let compiled = plan.compile(station)?;
    let run_id = dir
        .file_name()
        .map_or_else(new_run_id, |n| n.to_string_lossy().into_owned());
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
        run_id,
        abort: control.abort,
        pause: control.pause,
        module_silence: Duration::from_secs(5),
        // The run directory holds the station config the run was started with.
        sink_hold_limit: Duration::from_secs(600),
        station_config_toml: std::fs::read_to_string(dir.join("station.toml")).unwrap_or_default(),
    };
    let store = spinbench_store::Store::connect(db)?;
    let mut executor = Executor::new(station, compiled, bench, operator, options);
    if let Some(events) = &past {
        executor.restore(events);
        if let Some(t) = store.last_value_time_s(&run_id_of(dir))? {
            executor.continue_time_after(t);
        }
    }
    executor.subscribe(journal);
    executor.subscribe(store.sink()?);
    executor.subscribe(ProgressPrinter::new(quiet));
    for sink in control.sinks {
        executor.subscribe(BoxedSink(sink));
    }
    let summary = executor.run();
    drop(executor);
    let results = serde_json::to_string_pretty(&summary.records)?;
    std::fs::write(dir.join("results.json"), results)
        .with_context(|| format!("{}: cannot write results.json", dir.display()))?;
    // The run's report, written at the end of every run (a failed report
    // does not lose the run: it is in the store and can be made again).
    use spinbench_report::ReportFormat;
    match spinbench_report::write_reports(&store, &run_id_of(dir), &ReportFormat::ALL, dir) {
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

fn run_id_of(dir: &Path) -> String {
    dir.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

/// One line of the demo's comparison with the truth.
#[derive(Debug, Clone, Serialize)]
pub struct DemoUnit {
    /// Serial number.
    pub serial: String,
    /// Slot (1-based).
    pub slot: usize,
    /// Mounting.
    pub mount: Mount,
    /// Radius found [m].
    pub radius_m: Option<f64>,
    /// The simulator's true radius [m].
    pub true_radius_m: f64,
    /// Drawing radius [m].
    pub drawing_radius_m: f64,
    /// Measured k2 in this mounting [µg/g²].
    pub k2_ug_per_g2: Option<f64>,
    /// Its 95 % interval.
    pub k2_ci95: Option<[f64; 2]>,
    /// The truth in the same per-mounting convention (N flips the sign).
    pub true_k2_ug_per_g2: f64,
    /// Measured k1 [Hz/g] in this mounting.
    pub k1_hz_per_g: Option<f64>,
    /// True k1 in this convention.
    pub true_k1_hz_per_g: f64,
    /// The instrument's k2_max [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// Pass, fail or marginal.
    pub outcome: Outcome,
}

/// Compare a finished demo run with the simulator's truth.
pub fn compare_with_truth(records: &[UnitRecord], truth: &spinbench_sim::Truth) -> Vec<DemoUnit> {
    let mut out = Vec::new();
    for r in records {
        let Some(t) = truth.instruments.get(r.slot) else {
            continue;
        };
        for mount in [Mount::P, Mount::N] {
            let fit = r
                .analysis
                .as_ref()
                .and_then(|a| a.fits.get(&mount))
                .map(|f| &f.fit);
            if fit.is_none() && !r.radius_m.contains_key(&mount) {
                continue;
            }
            let sign = mount.input_sign();
            out.push(DemoUnit {
                serial: r.serial.clone(),
                slot: r.slot + 1,
                mount,
                radius_m: r.radius_m.get(&mount).copied(),
                true_radius_m: match mount {
                    Mount::P => t.position.radius_p_m,
                    Mount::N => t.position.radius_n_m,
                },
                drawing_radius_m: t.position.drawing_radius_m,
                k2_ug_per_g2: fit.and_then(|f| f.k2_ug_per_g2),
                k2_ci95: fit.and_then(|f| f.ci95.k2_ug_per_g2),
                true_k2_ug_per_g2: sign * t.vba.k2_ug_per_g2,
                k1_hz_per_g: fit.map(|f| f.k1),
                true_k1_hz_per_g: sign * t.vba.k1_hz_per_g,
                k2_max_ug_per_g2: r.k2_max_ug_per_g2,
                outcome: r.outcome,
            });
        }
    }
    out
}

/// The demo's plan: every slot, ±70 g (both mountings), published levels,
/// a 10-minute warm-up (virtual time is cheap).
pub fn demo_plan(slots: usize) -> TestPlan {
    TestPlan {
        name: "demo: ±70 g, mountings P and N".into(),
        operator: "demo".into(),
        serials: (1..=slots)
            .map(|i| (i.to_string(), format!("SIM-{i:02}")))
            .collect(),
        passes: vec![Mount::P, Mount::N],
        warmup_s: 600.0,
        ..TestPlan::default()
    }
}

/// Start the virtual bench and the station config that reaches it.
pub fn start_sim(seed: u64) -> Result<(RunningBench, StationConfig)> {
    let sim = SimConfig {
        seed,
        speed: 0.0,
        ..SimConfig::default()
    };
    let bench = RunningBench::start(sim, ServeOptions::default())
        .context("cannot start the virtual bench")?;
    let text = sim_station_toml(&bench);
    let station = StationConfig::from_toml(&text)
        .with_context(|| format!("the virtual bench's station config:\n{text}"))?;
    Ok((bench, station))
}

/// `spinbench demo`.
pub fn demo(
    seed: u64,
    json: bool,
    data_dir: &Path,
    db: Option<&StoreTarget>,
    out: &mut dyn Write,
) -> Result<()> {
    let wall = Instant::now();
    let (sim, station) = start_sim(seed)?;
    let plan = demo_plan(station.slots());
    if !json {
        writeln!(
            out,
            "spinbench demo: a virtual bench (seed {seed}) with {} instruments on {} counter modules, a 0.8 m centrifuge,\n\
             ±70 g in mountings P and N, in virtual time. Operator prompts are answered by the simulator.\n",
            station.slots(),
            station.fmu.len()
        )?;
        out.flush()?;
    }
    let dir = data_dir.join("runs").join(new_run_id());
    std::fs::create_dir_all(&dir)?;
    let bench = connect_bench(&station, Some(&dir))?;
    std::fs::write(dir.join("station.toml"), sim_station_toml(&sim))?;
    std::fs::write(dir.join("plan.toml"), toml::to_string(&plan)?)?;
    let operator = Box::new(SimOperator::new(&sim, json));
    let abort = AbortFlag::new();
    crate::signals::abort_on_termination_signals(abort.clone())?;
    let finished = execute(
        &station,
        &plan,
        bench,
        operator,
        &dir,
        &db.cloned()
            .unwrap_or_else(|| StoreTarget::File(data_dir.join(DB_FILE))),
        false,
        json,
        RunControl::abort_only(abort),
    )?;
    let truth = sim.with_world(|w| w.truth());
    sim.shutdown();
    let units = compare_with_truth(&finished.summary.records, &truth);
    std::fs::write(
        dir.join("truth.json"),
        serde_json::to_string_pretty(&truth)?,
    )?;
    let wall_s = wall.elapsed().as_secs_f64();
    if json {
        let doc = serde_json::json!({
            "run": {
                "dir": finished.dir,
                "state": finished.summary.state,
                "reason": finished.summary.reason,
                "seed": seed,
                "virtual_duration_s": finished.summary.duration_s,
                "wall_duration_s": wall_s,
            },
            "units": units,
        });
        serde_json::to_writer_pretty(&mut *out, &doc)?;
        writeln!(out)?;
    } else {
        render_demo(out, &finished, &units, wall_s)?;
    }
    if finished.summary.state != RunState::Completed {
        bail!(
            "the demo run did not complete: {}",
            finished.summary.reason.unwrap_or_default()
        );
    }
    Ok(())
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
        "{:<10} {:>4} {:>12} {:>12} {:>24} {:>9}  reasons",
        "serial", "slot", "R P [mm]", "R N [mm]", "k2_max [µg/g²]", "outcome"
    )?;
    for r in &s.records {
        let radius = |m: Mount| {
            r.radius_m
                .get(&m)
                .map_or("—".into(), |v| format!("{:.3}", v * 1e3))
        };
        writeln!(
            out,
            "{:<10} {:>4} {:>12} {:>12} {:>24} {:>9}  {}",
            r.serial,
            r.slot + 1,
            radius(Mount::P),
            radius(Mount::N),
            r.k2_max_ug_per_g2.map_or("—".into(), |k| format!("{k:.3}")),
            format!("{:?}", r.outcome).to_lowercase(),
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

fn render_demo(
    out: &mut dyn Write,
    finished: &Finished,
    units: &[DemoUnit],
    wall_s: f64,
) -> Result<()> {
    let s = &finished.summary;
    writeln!(
        out,
        "\nRun {:?} in {:.0} s of virtual time ({:.1} h), {:.1} s of wall-clock time.\n",
        s.state,
        s.duration_s,
        s.duration_s / 3600.0,
        wall_s
    )?;
    writeln!(
        out,
        "{:<7} {:>4} {:>5} | {:>10} {:>10} {:>9} | {:>22} {:>9} {:>6} | {:>8} {:>9}",
        "serial",
        "slot",
        "mount",
        "R [mm]",
        "true R",
        "R0 − true",
        "k2 ± 95 % [µg/g²]",
        "true k2",
        "in CI",
        "k2_max",
        "outcome"
    )?;
    let (mut covered, mut total) = (0, 0);
    for u in units {
        let r = u.radius_m.map_or("—".into(), |r| format!("{:.3}", r * 1e3));
        let k2 = match (u.k2_ug_per_g2, u.k2_ci95) {
            (Some(k), Some([lo, hi])) => format!("{k:+.3} ± {:.3}", (hi - lo) / 2.0),
            _ => "—".into(),
        };
        let inside = u
            .k2_ci95
            .map(|[lo, hi]| lo <= u.true_k2_ug_per_g2 && u.true_k2_ug_per_g2 <= hi);
        if let Some(i) = inside {
            total += 1;
            covered += usize::from(i);
        }
        writeln!(
            out,
            "{:<7} {:>4} {:>5} | {:>10} {:>10.3} {:>+9.3} | {:>22} {:>+9.3} {:>6} | {:>8} {:>9}",
            u.serial,
            u.slot,
            u.mount.to_string(),
            r,
            u.true_radius_m * 1e3,
            (u.drawing_radius_m - u.true_radius_m) * 1e3,
            k2,
            u.true_k2_ug_per_g2,
            inside.map_or("—", |i| if i { "yes" } else { "NO" }),
            u.k2_max_ug_per_g2.map_or("—".into(), |k| format!("{k:.3}")),
            format!("{:?}", u.outcome).to_lowercase(),
        )?;
    }
    let radius_err: Vec<f64> = units
        .iter()
        .filter_map(|u| u.radius_m.map(|r| (r - u.true_radius_m).abs() * 1e6))
        .collect();
    let r0_err: Vec<f64> = units
        .iter()
        .map(|u| (u.drawing_radius_m - u.true_radius_m).abs() * 1e6)
        .collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    writeln!(
        out,
        "\nk2: the true value lies inside the reported 95 % interval for {covered} of {total} instrument-mountings.\n\
         Radius: found within {:.1} µm of the truth on average; the drawing radius R0 is off by {:.1} µm on average.",
        mean(&radius_err),
        mean(&r0_err)
    )?;
    writeln!(
        out,
        "\nResults: {}/results.json (per-instrument records), journal.jsonl (every event), truth.json (the simulator's truth);\n\
         the run is also in the store {}/spinbench.db (`spinbench runs list --db …`).",
        finished.dir.display(),
        finished
            .dir
            .parent()
            .and_then(Path::parent)
            .map_or_else(|| ".".into(), |p| p.display().to_string())
    )?;
    Ok(())
}
