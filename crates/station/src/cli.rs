//! The `spinbench` command line: argument parsing and the subcommands.

use crate::points_file::read_points_file;
use crate::render::render_dataset;
use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use spinbench_analysis::{AnalysisOptions, DatasetAnalysis, ModelOrder, analyze_dataset};
use spinbench_store::StoreTarget;
use std::io::Write;
use std::path::{Path, PathBuf};

/// spinbench: automatic centrifuge test station for vibrating-beam accelerometers.
#[derive(Debug, Parser)]
#[command(name = "spinbench", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Reduce the averaged points of a centrifuge test (CSV or XLSX) to the
    /// model coefficients with uncertainties, per unit and mounting.
    ///
    /// FILE has a header row and the columns unit,mount,g_nominal,g_applied,output
    /// (mount is P or N; an empty g_applied equals g_nominal). Optional
    /// columns: direction (up/down) and run (a label for repeated tests).
    Analyze {
        /// The points file (.csv, or a spreadsheet: .xlsx, .xls, .ods).
        file: PathBuf,
        /// Print one JSON document instead of tables.
        #[arg(long)]
        json: bool,
        /// Model order: 1 (k0, k1), 2 (+k2) or 3 (+k3, the published station's model).
        #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=3))]
        order: u8,
        /// Spreadsheet sheet to read (default: the first).
        #[arg(long)]
        sheet: Option<String>,
    },
    /// The main job, with no hardware: a complete simulated station (virtual
    /// bench, 12 instruments, ±70 g in both mountings) runs a real test end
    /// to end in virtual time and compares what it measured with the truth.
    Demo {
        /// Seed of the virtual bench (same seed, same instruments).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Print one JSON document instead of tables.
        #[arg(long)]
        json: bool,
        /// Where runs are kept.
        #[arg(long, default_value = crate::run_setup::DEFAULT_DATA_DIR)]
        data: PathBuf,
        /// The store: an SQLite file or a PostgreSQL server (postgres://…); default DATA/spinbench.db.
        #[arg(long, value_parser = parse_store)]
        db: Option<StoreTarget>,
    },
    /// Run a test plan on a station (or, with --simulate, on the virtual bench).
    Run {
        /// The test plan (TOML).
        plan: PathBuf,
        /// The station config (TOML); with --simulate its device sections are replaced by the bench's.
        #[arg(long)]
        station: Option<PathBuf>,
        /// Run against the virtual bench in this process (real pseudo-terminals).
        #[arg(long)]
        simulate: bool,
        /// Seed of the virtual bench.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Continue the run in this directory from its journal.
        #[arg(long, value_name = "RUN_DIR")]
        resume: Option<PathBuf>,
        /// Where runs are kept.
        #[arg(long, default_value = crate::run_setup::DEFAULT_DATA_DIR)]
        data: PathBuf,
        /// Print only faults and the results.
        #[arg(long)]
        quiet: bool,
        /// The store: an SQLite file or a PostgreSQL server (postgres://…);
        /// default DATA/spinbench.db (with --resume, the run's own).
        #[arg(long, value_parser = parse_store)]
        db: Option<StoreTarget>,
    },
    /// List the runs in the store, or show one run's results.
    Runs {
        /// `list` or `show`.
        #[command(subcommand)]
        action: RunsAction,
    },
    /// Every run of one instrument (by serial number), with the repeatability of its scale factor.
    Unit {
        /// Serial number.
        serial: String,
        /// The store (default: spinbench-data/spinbench.db).
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
    /// Export a run's points (the input format of `spinbench analyze`) and results.
    Export {
        /// Run identifier.
        run: String,
        /// Format: csv (points), xlsx (points and results sheets) or parquet (points).
        #[arg(long, default_value = "csv")]
        format: String,
        /// Write to this file instead of standard output (an existing file
        /// only with --force; never the store or a run's own files).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace an existing --out file.
        #[arg(long)]
        force: bool,
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
    /// Write a run's report: PDF, HTML (self-contained, plots inline), XLSX and/or CSV.
    Report {
        /// Run identifier.
        run: String,
        /// Formats, directory and store.
        #[command(flatten)]
        output: ReportOutput,
    },
    /// Write the batch report of many runs: distributions of k2 and the
    /// scale-factor figures, outliers, repeatability of serials tested more than once.
    BatchReport {
        /// Run identifiers (default: every run in the store).
        runs: Vec<String>,
        /// Formats, directory and store.
        #[command(flatten)]
        output: ReportOutput,
    },
    /// Replay a run's raw counter-module bytes through the decoder and show
    /// that they give the one-second values and points the store holds.
    Replay {
        /// Run identifier (a directory under DATA/runs) or a run directory.
        run: String,
        /// Where runs are kept.
        #[arg(long, default_value = crate::run_setup::DEFAULT_DATA_DIR)]
        data: PathBuf,
        /// The store (default DATA/spinbench.db).
        #[arg(long, value_parser = parse_store)]
        db: Option<StoreTarget>,
    },
    /// Start a virtual bench (simulated centrifuge, instruments, counter
    /// modules and supplies) behind real pseudo-terminals, and print the
    /// device sections of a station config that reach it. Runs until
    /// interrupted (Ctrl-C).
    Sim {
        /// Bench configuration (TOML); every key has a default.
        #[arg(long)]
        config: Option<PathBuf>,
        /// Time: 1 = real time, N = N× faster, 0 = as fast as the station reads.
        #[arg(long)]
        speed: Option<f64>,
        /// Put the centrifuge controller and the supplies on TCP (loopback).
        #[arg(long)]
        tcp: bool,
        /// Write the instruments' true coefficients and radii to this JSON file.
        #[arg(long)]
        truth: Option<PathBuf>,
        /// Stop after this many seconds of wall-clock time (default: run until interrupted).
        #[arg(long = "for", value_name = "SECONDS")]
        run_for: Option<f64>,
    },
    /// Serve the station's web UI and HTTP API (loopback by default): status,
    /// live curves, run control and prompts, new runs, history and reports.
    Serve {
        /// Where and how to serve.
        #[command(flatten)]
        args: crate::web::ServeArgs,
    },
    /// Manage the web UI's users (the first admin is made here).
    User {
        /// What to do.
        #[command(subcommand)]
        action: UserAction,
    },
}

/// Actions of `spinbench user`.
#[derive(Debug, Subcommand)]
pub enum UserAction {
    /// Add a user; the password is read from standard input (one line) or
    /// from the environment variable SPINBENCH_PASSWORD.
    Add {
        /// Login name.
        name: String,
        /// operator, engineer or admin.
        #[arg(long, default_value = "operator")]
        role: String,
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
    /// List the users.
    List {
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
}

/// Where reports go, in which formats, from which store.
#[derive(Debug, clap::Args)]
pub struct ReportOutput {
    /// pdf, html, xlsx or csv; repeat or comma-separate for several (default: all four).
    #[arg(long, value_delimiter = ',')]
    format: Vec<String>,
    /// Directory for the files (default: the current directory).
    #[arg(long, default_value = ".")]
    out: PathBuf,
    /// The store.
    #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
    db: StoreTarget,
}

/// Actions of `spinbench runs`.
#[derive(Debug, Subcommand)]
pub enum RunsAction {
    /// Every run, newest first.
    List {
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
    /// One run's per-instrument results.
    Show {
        /// Run identifier.
        run: String,
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
}

/// `--db`: a file path, or a PostgreSQL URL.
pub(crate) fn parse_store(text: &str) -> Result<StoreTarget, String> {
    if text.trim().is_empty() {
        return Err("empty: give a file path or postgres://user@host:port/database".into());
    }
    Ok(StoreTarget::parse(text))
}

/// Open an existing store to read it (a missing file is an error, not a
/// new empty store; a read-only file or disk can be read).
fn open_store(db: &StoreTarget) -> Result<spinbench_store::Store> {
    if let StoreTarget::File(path) = db
        && !path.exists()
    {
        anyhow::bail!(
            "{}: no store here; runs are stored under --data (default spinbench-data), or give --db",
            path.display()
        );
    }
    Ok(spinbench_store::Store::open_read_only(db)?)
}

/// Read and reduce a points file.
pub fn analyze_file(file: &Path, order: u8, sheet: Option<&str>) -> Result<DatasetAnalysis> {
    let order = ModelOrder::from_degree(order)
        .with_context(|| format!("model order {order} is not 1, 2 or 3"))?;
    let points = read_points_file(file, sheet)?;
    analyze_dataset(&points.units, AnalysisOptions { order })
        .with_context(|| format!("{}: cannot reduce the points", file.display()))
}

/// Run a parsed command line, writing its output to `out`.
pub fn run(cli: Cli, out: &mut dyn Write) -> Result<()> {
    match cli.command {
        Command::Analyze {
            file,
            json,
            order,
            sheet,
        } => {
            let analysis = analyze_file(&file, order, sheet.as_deref())?;
            if json {
                serde_json::to_writer_pretty(&mut *out, &analysis)?;
                writeln!(out)?;
            } else {
                write!(
                    out,
                    "{}",
                    render_dataset(&file.display().to_string(), &analysis)
                )?;
            }
        }
        Command::Demo {
            seed,
            json,
            data,
            db,
        } => crate::demo::demo(seed, json, &data, db.as_ref(), out)?,
        Command::Run {
            plan,
            station,
            simulate,
            seed,
            resume,
            data,
            quiet,
            db,
        } => run_plan(
            &plan,
            station.as_deref(),
            simulate,
            seed,
            resume.as_deref(),
            &data,
            db,
            quiet,
            out,
        )?,
        Command::Runs {
            action: RunsAction::List { db },
        } => {
            let store = open_store(&db)?;
            writeln!(
                out,
                "{:<28} {:<10} {:>6} {:>7}  station",
                "run", "state", "units", "points"
            )?;
            for r in store.runs()? {
                writeln!(
                    out,
                    "{:<28} {:<10} {:>6} {:>7}  {}",
                    r.id, r.state, r.units, r.points, r.station
                )?;
            }
        }
        Command::Runs {
            action: RunsAction::Show { run, db },
        } => {
            let store = open_store(&db)?;
            let Some(r) = store.run(&run)? else {
                anyhow::bail!("{db}: no run '{run}' (see `spinbench runs list`)");
            };
            writeln!(
                out,
                "run {} — {} — {}{}",
                r.id,
                r.station,
                r.state,
                r.reason.map(|x| format!(": {x}")).unwrap_or_default()
            )?;
            for u in store.results(&run)? {
                writeln!(
                    out,
                    "  slot {:>2} {:<12} {:<9} k2_max {}",
                    u.slot + 1,
                    u.serial,
                    u.outcome,
                    u.k2_max_ug_per_g2
                        .map_or("—".into(), |k| format!("{k:.3} µg/g²"))
                )?;
            }
        }
        Command::Unit { serial, db } => {
            let store = open_store(&db)?;
            let history = store.unit_history(&serial)?;
            if history.is_empty() {
                anyhow::bail!("{db}: no results for serial '{serial}'");
            }
            for h in &history {
                let p_k1 = h
                    .record
                    .analysis
                    .as_ref()
                    .and_then(|a| a.fits.get(&spinbench_analysis::Mount::P))
                    .map(|f| f.fit.k1);
                writeln!(
                    out,
                    "{:<28} slot {:>2} {:<9} k2_max {:>10} k1(P) {}",
                    h.run_id,
                    h.slot + 1,
                    h.outcome,
                    h.k2_max_ug_per_g2.map_or("—".into(), |k| format!("{k:.3}")),
                    p_k1.map_or("—".into(), |v| format!("{v:.6}"))
                )?;
            }
            // The one definition of repeatability (as `analyze` and the batch
            // report give it), over the tests measured whole.
            let measured: Vec<&spinbench_analysis::UnitAnalysis> = history
                .iter()
                .filter(|h| h.outcome != spinbench_engine::Outcome::Incomplete)
                .filter_map(|h| h.record.analysis.as_ref())
                .collect();
            match spinbench_analysis::unit::repeatability_of(&measured) {
                Some(r) => writeln!(
                    out,
                    "scale-factor repeatability over {} runs: {:.3} ppm (bias {:.1} µg)",
                    r.runs, r.scale_factor_ppm, r.bias_ug
                )?,
                None => writeln!(out, "scale-factor repeatability: needs at least two runs")?,
            }
        }
        Command::Export {
            run,
            format,
            out: file,
            force,
            db,
        } => {
            let format = crate::export::ExportFormat::parse(&format)?;
            if let Some(f) = &file {
                crate::export::check_out_path(f, &db, force)?;
            }
            let store = open_store(&db)?;
            if store.run(&run)?.is_none() {
                anyhow::bail!("{db}: no run '{run}' (see `spinbench runs list`)");
            }
            match (file, format) {
                (Some(f), _) => crate::export::export_run(&store, &run, format, &f)?,
                (None, crate::export::ExportFormat::Csv) => {
                    write!(out, "{}", store.points_csv(&run)?)?
                }
                (None, _) => {
                    anyhow::bail!("--out FILE is needed for xlsx and parquet (binary formats)")
                }
            }
        }
        Command::Report { run, output: o } => {
            let store = open_store(&o.db)?;
            let files =
                spinbench_report::write_reports(&store, &run, &report_formats(&o.format)?, &o.out)
                    .with_context(|| format!("{}: report of run '{run}'", o.db))?;
            print_paths(out, &files)?;
        }
        Command::BatchReport { runs, output: o } => {
            let store = open_store(&o.db)?;
            let files = spinbench_report::write_batch_reports(
                &store,
                &runs,
                &report_formats(&o.format)?,
                &o.out,
            )
            .with_context(|| format!("{}: batch report", o.db))?;
            print_paths(out, &files)?;
        }
        Command::Serve { args } => crate::web::serve(args, out)?,
        Command::User { action } => match action {
            UserAction::Add { name, role, db } => {
                use crate::web::auth;
                let role = auth::Role::parse(&role)
                    .with_context(|| format!("--role {role}: use operator, engineer or admin"))?;
                let password = match std::env::var("SPINBENCH_PASSWORD") {
                    Ok(p) => p,
                    Err(_) => {
                        eprintln!("password for {name} (one line on standard input):");
                        let mut line = String::new();
                        std::io::stdin()
                            .read_line(&mut line)
                            .context("cannot read the password")?;
                        line.trim_end_matches(['\r', '\n']).to_string()
                    }
                };
                auth::check_new_user(&name, &password).map_err(anyhow::Error::msg)?;
                if let StoreTarget::File(path) = &db
                    && let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
                {
                    std::fs::create_dir_all(dir)
                        .with_context(|| format!("{}: cannot create", dir.display()))?;
                }
                let store = spinbench_store::Store::connect(&db)?;
                if store.user(&name)?.is_some() {
                    anyhow::bail!("user '{name}' exists in {db}");
                }
                let hash = auth::hash_password(&password).map_err(anyhow::Error::msg)?;
                store.add_user(&name, role.as_str(), &hash)?;
                store.audit(
                    "spinbench (command line)",
                    "add user",
                    &format!("{name} ({})", role.as_str()),
                )?;
                writeln!(out, "user {name} added as {} in {db}", role.as_str())?;
            }
            UserAction::List { db } => {
                let store = open_store(&db)?;
                for u in store.users()? {
                    writeln!(out, "{:<24} {}", u.name, u.role)?;
                }
            }
        },
        Command::Replay { run, data, db } => {
            let given = Path::new(&run);
            let dir = if given.join("station.toml").exists() {
                given.to_path_buf()
            } else {
                data.join("runs").join(&run)
            };
            if !dir.is_dir() {
                anyhow::bail!(
                    "{}: no such run directory (give a run id under --data, or the run's directory)",
                    dir.display()
                );
            }
            let db = db.unwrap_or_else(|| {
                StoreTarget::File(
                    dir.parent()
                        .and_then(Path::parent)
                        .unwrap_or(&data)
                        .join(crate::run_setup::DB_FILE),
                )
            });
            let store = open_store(&db)?;
            let report = crate::replay::replay(&dir, &store)?;
            for m in &report.modules {
                writeln!(
                    out,
                    "module {}: {} bytes, {} frames ({} bad), {} whole one-second windows{}",
                    m.module,
                    m.bytes,
                    m.frames,
                    m.bad_frames,
                    m.windows,
                    if m.cut_short {
                        " (capture cut short: read up to its last flush)"
                    } else {
                        ""
                    }
                )?;
            }
            writeln!(
                out,
                "one-second values: {} of {} stored found bit-exact in the replay",
                report.values_matched, report.values_stored
            )?;
            writeln!(
                out,
                "points: {} of {} stored re-derived from the replayed values (largest difference {:.3e} Hz)",
                report.points_matched, report.points_stored, report.max_point_diff_hz
            )?;
            if !report.all_match() {
                anyhow::bail!("the replay does not reproduce everything the store holds");
            }
            writeln!(out, "the raw bytes reproduce the stored run")?;
        }
        Command::Sim {
            config,
            speed,
            tcp,
            truth,
            run_for,
        } => run_sim(config, speed, tcp, truth, run_for, out)?,
    }
    Ok(())
}

/// `spinbench run`.
#[allow(clippy::too_many_arguments)]
fn run_plan(
    plan_path: &Path,
    station_path: Option<&Path>,
    simulate: bool,
    seed: u64,
    resume: Option<&Path>,
    data: &Path,
    db: Option<StoreTarget>,
    quiet: bool,
    out: &mut dyn Write,
) -> Result<()> {
    use crate::run_setup::{RunDir, Setup, prepare};
    use crate::station_run::{TerminalOperator, connect_bench, execute, sim_station_toml};
    use spinbench_engine::{AbortFlag, StationConfig, TestPlan};
    use spinbench_sim::station::SimOperator;
    let plan_text = std::fs::read_to_string(plan_path)
        .with_context(|| format!("{}: cannot read the plan", plan_path.display()))?;
    let plan = TestPlan::from_toml(&plan_text).with_context(|| plan_path.display().to_string())?;
    // SIGINT, SIGTERM, SIGHUP: the engine stops the table, switches
    // everything off and records the signal.
    let abort = AbortFlag::new();
    crate::signals::abort_on_termination_signals(abort.clone())?;
    // A resumed run: only with its own plan; it keeps writing to its own store.
    let resumed = resume.map(|d| RunDir::resume(d, &plan)).transpose()?;
    let sim;
    let (station, station_toml, operator): (
        StationConfig,
        String,
        Box<dyn spinbench_engine::Operator + '_>,
    ) = if simulate {
        let (bench, mut station) = crate::demo::start_sim(seed)?;
        if let Some(p) = station_path {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("{}: cannot read the station config", p.display()))?;
            let own = StationConfig::from_toml(&text).with_context(|| p.display().to_string())?;
            station.arm = own.arm;
            station.g_local_m_s2 = own.g_local_m_s2;
            station.station = own.station;
        }
        let text = sim_station_toml(&bench);
        sim = Some(bench);
        let bench_ref = sim.as_ref().context("virtual bench")?;
        (station, text, Box::new(SimOperator::new(bench_ref, quiet)))
    } else {
        let p = station_path
            .context("--station CONFIG is needed (or --simulate for the virtual bench)")?;
        let text = std::fs::read_to_string(p)
            .with_context(|| format!("{}: cannot read the station config", p.display()))?;
        (
            StationConfig::from_toml(&text).with_context(|| p.display().to_string())?,
            text,
            Box::new(TerminalOperator::default()),
        )
    };
    let dir = match resumed {
        Some(dir) => dir,
        None => RunDir::create(data)?,
    };
    // Refuse a plan that cannot run before anything is switched on.
    let prepared = prepare(Setup {
        station,
        station_toml,
        plan,
        plan_text: Some(plan_text),
        dir,
        store: db,
    })?;
    let bench = connect_bench(&prepared.station, Some(&prepared.dir.raw_dir()))?;
    let finished = execute(
        prepared,
        bench,
        operator,
        quiet,
        crate::station_run::RunControl::abort_only(abort),
    )?;
    crate::station_run::render_records(out, &finished)?;
    crate::signals::wait_for_unconfirmed_stops();
    if finished.summary.state != spinbench_engine::RunState::Completed {
        anyhow::bail!(
            "the run ended {:?}: {}",
            finished.summary.state,
            finished.summary.reason.unwrap_or_default()
        );
    }
    Ok(())
}

/// Longest `spinbench sim --for` [s].
const MAX_SIM_FOR_S: f64 = 1e7;

/// `spinbench sim`: start a virtual bench and print how to reach it.
fn run_sim(
    config: Option<PathBuf>,
    speed: Option<f64>,
    tcp: bool,
    truth: Option<PathBuf>,
    run_for: Option<f64>,
    out: &mut dyn Write,
) -> Result<()> {
    use spinbench_sim::SimConfig;
    use spinbench_sim::serve::{RunningBench, ServeOptions};
    let mut sim_config = match &config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("{}: cannot read the bench config", path.display()))?;
            SimConfig::from_toml(&text).with_context(|| path.display().to_string())?
        }
        None => SimConfig::default(),
    };
    if let Some(s) = speed {
        sim_config.speed = s;
    }
    sim_config.validate()?;
    if let Some(seconds) = run_for
        && !(seconds.is_finite() && (0.0..=MAX_SIM_FOR_S).contains(&seconds))
    {
        anyhow::bail!(
            "--for {seconds}: expected seconds from 0 to {MAX_SIM_FOR_S} (about 115 days; leave --for out to run until interrupted)"
        );
    }
    let bench = RunningBench::start(
        sim_config,
        ServeOptions {
            line_devices_on_tcp: tcp,
        },
    )
    .context("cannot start the virtual bench")?;
    if let Some(path) = &truth {
        let json = serde_json::to_string_pretty(&bench.with_world(|w| w.truth()))?;
        std::fs::write(path, json)
            .with_context(|| format!("{}: cannot write the truth", path.display()))?;
    }
    writeln!(out, "{}", bench.station_config_toml())?;
    if let Some(path) = &truth {
        writeln!(out, "# truth written to {}", path.display())?;
    }
    writeln!(out, "# virtual bench running; Ctrl-C stops it")?;
    out.flush()?;
    match run_for {
        Some(seconds) => std::thread::sleep(std::time::Duration::from_secs_f64(seconds)),
        None => loop {
            std::thread::sleep(std::time::Duration::from_secs(3600));
        },
    }
    bench.shutdown();
    Ok(())
}

/// The report formats of `--format` (all four when none is given).
fn report_formats(given: &[String]) -> Result<Vec<spinbench_report::ReportFormat>> {
    use spinbench_report::ReportFormat;
    if given.is_empty() {
        return Ok(ReportFormat::ALL.to_vec());
    }
    given
        .iter()
        .map(|f| {
            ReportFormat::parse(f)
                .with_context(|| format!("--format {f}: use pdf, html, xlsx or csv"))
        })
        .collect()
}

/// One path per line.
fn print_paths(out: &mut dyn Write, paths: &[PathBuf]) -> Result<()> {
    for path in paths {
        writeln!(out, "{}", path.display())?;
    }
    Ok(())
}
