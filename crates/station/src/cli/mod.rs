//! The `spinbench` command line: the arguments (parsed in one place, here)
//! and the dispatch to one module per command.
//!
//! | module | commands |
//! |---|---|
//! | this | `analyze`, `demo`, `serve` (their work lives in [`crate::points_file`], [`crate::demo`], [`crate::web`]) |
//! | `run` | `run` |
//! | `records` | `runs list`, `runs show`, `unit`, `export` |
//! | `reports` | `report`, `batch-report`, `replay` |
//! | `sim` | `sim` |
//! | `user` | `user add`, `user list` |

use crate::paths::parse_store;
use crate::points_file::read_points_file;
use crate::render::render_dataset;
use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use spinbench_analysis::exclusion::LevelExclusion;
use spinbench_analysis::uncertainty::TypeBInputs;
use spinbench_analysis::{AnalysisOptions, DatasetAnalysis, ModelOrder, analyze_dataset};
use spinbench_store::StoreTarget;
use std::io::Write;
use std::path::{Path, PathBuf};

mod backup;
mod equipment;
mod records;
mod reports;
mod run;
mod sim;
mod user;

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
        /// Leave a level out of the fits: MOUNT:LEVEL (every unit, e.g. P:40)
        /// or UNIT:MOUNT:LEVEL; repeatable; needs --reason. The exclusion,
        /// its reason and who made it are printed with the results.
        #[arg(long = "exclude-level", value_name = "[UNIT:]MOUNT:LEVEL")]
        exclude_level: Vec<String>,
        /// Why the levels are excluded (required with --exclude-level).
        #[arg(long)]
        reason: Option<String>,
        /// Type B inputs of the GUM budget for legacy data: a TOML file with
        /// the keys of a station config's [uncertainty] section (radius_ppm,
        /// rate_accuracy_ppm, rate_resolution_deg_s with arm_radius_m,
        /// g_local_ppm, timebase_ppm, arm_stretch_u_ug_per_g2,
        /// temperature_rise_c_at_100g, k0_tempco_ug_per_c,
        /// k1_tempco_ppm_per_c, arm_expansion_ppm_per_c). Without it the
        /// budget is Type A only, and says so.
        #[arg(long = "type-b", value_name = "FILE")]
        type_b: Option<PathBuf>,
        /// What to do with a level found off the curve: flag (keep it, name
        /// it, its misfit in the budget as model inadequacy) or exclude
        /// (leave it out, say so, the change in the budget).
        #[arg(long, default_value = "flag")]
        anomalies: spinbench_analysis::AnomalyRule,
        /// Who makes the --exclude-level exclusions (recorded with them;
        /// default: the logged-in user).
        #[arg(long, value_name = "NAME")]
        by: Option<String>,
    },
    /// The main job, with no hardware: a complete simulated station (virtual
    /// bench, 12 instruments, ±70 g in both mountings) runs a real test end
    /// to end in virtual time and compares what it measured with the truth.
    Demo {
        /// Seed of the virtual bench (same seed and realism, same results).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// How real the virtual bench is: ideal, typical (the error sources
        /// of precision centrifuge testing) or harsh (typical with drift, a
        /// dead and a noisy instrument and line faults).
        #[arg(long)]
        realism: Option<spinbench_sim::Realism>,
        /// Bench configuration (TOML) to start from (its keys over its realism preset).
        #[arg(long, value_name = "FILE")]
        sim_config: Option<PathBuf>,
        /// Tumble positions: 2 (IA up and down, the published method) or 4
        /// (also the two cross-axis positions, which take gravity across the
        /// axis out of each radius).
        #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(2..=4))]
        tumble_positions: u8,
        /// Run the range test at these chamber temperatures [°C], e.g.
        /// `--temperatures=-20,25,60`: the bench's instruments sit in a
        /// temperature chamber, and the JSON gains each instrument's
        /// temperature coefficients beside the bench's truth.
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        temperatures: Vec<f64>,
        /// The levels of the range test [g], e.g. `--levels=0,2,8,14,…,66`
        /// (ascending from 0, at least 6; default 0, 1, 5, then every 5 g to 70).
        #[arg(long, value_delimiter = ',')]
        levels: Vec<f64>,
        /// What the reduction does with a level found off the curve: flag or exclude
        /// (the plan key `anomalies`).
        #[arg(long, default_value = "flag")]
        anomalies: spinbench_analysis::AnomalyRule,
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
        /// With --simulate: how real the virtual bench is (ideal, typical, harsh).
        #[arg(long)]
        realism: Option<spinbench_sim::Realism>,
        /// With --simulate: a bench config (TOML) whose keys go over the
        /// realism preset's (as `spinbench sim --config`).
        #[arg(long, value_name = "BENCH_TOML", requires = "simulate")]
        bench: Option<PathBuf>,
        /// Continue the run in this directory from its journal.
        #[arg(long, value_name = "RUN_DIR")]
        resume: Option<PathBuf>,
        /// Start although a device is overdue for calibration, with the
        /// reason (recorded in the audit log).
        #[arg(long, value_name = "REASON")]
        override_overdue: Option<String>,
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
    /// Test again the failed, inconclusive, incomplete and flagged
    /// instruments of a finished run: same serials, slots and plan, the new
    /// run linked to RUN in the store and both reports.
    Retest {
        /// The run to retest (its identifier, as `spinbench runs list` shows).
        run: String,
        /// The station config (TOML); default: the one RUN used. With
        /// --simulate its device sections are replaced by the bench's.
        #[arg(long)]
        station: Option<PathBuf>,
        /// Run against the virtual bench in this process (real pseudo-terminals).
        #[arg(long)]
        simulate: bool,
        /// Seed of the virtual bench.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// With --simulate: how real the virtual bench is (ideal, typical, harsh).
        #[arg(long)]
        realism: Option<spinbench_sim::Realism>,
        /// Where runs are kept.
        #[arg(long, default_value = crate::run_setup::DEFAULT_DATA_DIR)]
        data: PathBuf,
        /// Print only faults and the results.
        #[arg(long)]
        quiet: bool,
        /// The store RUN is in, where the retest is written too: an SQLite
        /// file or a PostgreSQL server (postgres://…); default DATA/spinbench.db.
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
        /// The control charts' baseline period: their limits come from the
        /// first this many runs (1 to 100,000).
        #[arg(long, default_value_t = spinbench_report::control::DEFAULT_BASELINE_RUNS as u32,
              value_parser = clap::value_parser!(u32).range(1..=100_000))]
        baseline_runs: u32,
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
        /// Time: 1 = real time, N = N× faster, 0 = virtual time in lockstep with the station.
        #[arg(long)]
        speed: Option<f64>,
        /// How real the bench is (ideal, typical, harsh); replaces the config's `realism`.
        #[arg(long)]
        realism: Option<spinbench_sim::Realism>,
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
    /// Back the store up into DIR while the station may run: an SQLite
    /// store through SQLite's online backup API, checked; a PostgreSQL
    /// store through pg_dump (custom format), checked by pg_restore --list;
    /// with --data, the runs' files too (raw captures, reports).
    Backup {
        /// Where the backup goes (created if missing).
        dir: PathBuf,
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
        /// Also copy this data directory's runs (DATA/runs).
        #[arg(long)]
        data: Option<PathBuf>,
    },
    /// Is the station ready to run? Checks the station config, every port
    /// and device (opened, identified, answering in time), the store, the
    /// clock and the free disk, and says what to fix. Nothing moves.
    Doctor {
        /// Station config (TOML).
        #[arg(long)]
        station: Option<PathBuf>,
        /// Check the virtual bench instead of hardware.
        #[arg(long)]
        simulate: bool,
        /// Where runs are kept (its free disk is checked).
        #[arg(long, default_value = crate::run_setup::DEFAULT_DATA_DIR)]
        data: PathBuf,
        /// The store (default DATA/spinbench.db).
        #[arg(long, value_parser = parse_store)]
        db: Option<StoreTarget>,
    },
    /// Restore a backup made by `spinbench backup` into a store file that
    /// does not exist yet (move the old one aside first).
    Restore {
        /// The backup file.
        backup: PathBuf,
        /// The store file to create, or a PostgreSQL URL of an empty
        /// database (a `.dump` from a PostgreSQL backup).
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
    /// The equipment register: each device's calibration certificate and
    /// due date (a run does not start while one is overdue).
    Equipment {
        /// What to do.
        #[command(subcommand)]
        action: EquipmentAction,
    },
}

/// Actions of `spinbench equipment`.
#[derive(Debug, Subcommand)]
pub enum EquipmentAction {
    /// Every device in the register with its status today.
    List {
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
    /// Add or replace a device's entry (recorded in the audit log).
    Set {
        /// Its role in a run: centrifuge, fmu 1, fmu 2 …, instrument supply, module supply.
        role: String,
        /// What it is (model and serial number).
        #[arg(long)]
        identity: String,
        /// The calibration certificate's number.
        #[arg(long)]
        certificate: String,
        /// Calibrated on (YYYY-MM-DD).
        #[arg(long)]
        calibrated: String,
        /// Due on (YYYY-MM-DD).
        #[arg(long)]
        due: String,
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
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
    /// Change a user's role; their sessions end on every server.
    Role {
        /// Login name.
        name: String,
        /// operator, engineer or admin.
        role: String,
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
    /// Change a user's password (read as for `add`); their sessions end on every server.
    Passwd {
        /// Login name.
        name: String,
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
    /// Remove a user; their sessions end on every server.
    Remove {
        /// Login name.
        name: String,
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
    /// The reports' language: en or zh-CN (the CSV's headers stay machine names).
    #[arg(long, default_value = "en", value_parser = parse_lang)]
    lang: spinbench_report::Lang,
    /// The store.
    #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
    db: StoreTarget,
}

/// `--lang`: a language the station speaks.
fn parse_lang(text: &str) -> Result<spinbench_report::Lang, String> {
    spinbench_report::Lang::parse(text).ok_or_else(|| format!("'{text}': en or zh-CN"))
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
    analyze_file_excluding(file, order, sheet, Vec::new(), AnalysisOptions::default())
}

/// Read and check a Type B inputs file (`analyze --type-b`).
pub fn read_type_b(file: &Path) -> Result<TypeBInputs> {
    let text = std::fs::read_to_string(file)
        .with_context(|| format!("cannot read the Type B inputs {}", file.display()))?;
    anyhow::ensure!(
        text.len() <= 64 * 1024,
        "{}: a Type B inputs file is a few lines; this one is {} bytes",
        file.display(),
        text.len()
    );
    let inputs: TypeBInputs =
        toml::from_str(&text).with_context(|| format!("{}: not Type B inputs", file.display()))?;
    inputs
        .validate()
        .map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))?;
    Ok(inputs)
}

/// Read a points file, leave out the excluded levels, reduce it; the
/// exclusions (with how many readings each removed) are in the result.
pub fn analyze_file_excluding(
    file: &Path,
    order: u8,
    sheet: Option<&str>,
    mut exclusions: Vec<LevelExclusion>,
    options: AnalysisOptions,
) -> Result<DatasetAnalysis> {
    let order = ModelOrder::from_degree(order)
        .with_context(|| format!("model order {order} is not 1, 2 or 3"))?;
    let mut points = read_points_file(file, sheet)?;
    for w in &points.warnings {
        eprintln!("warning: {w}");
    }
    spinbench_analysis::exclusion::apply_all(&mut points.units, &mut exclusions)
        .with_context(|| file.display().to_string())?;
    let mut analysis = analyze_dataset(&points.units, AnalysisOptions { order, ..options });
    analysis.exclusions = exclusions;
    for r in points.rejected {
        analysis.failed.push(spinbench_analysis::unit::UnitFailure {
            unit: r.unit,
            run: r.run,
            error: format!(
                "bad row(s), the unit is not reduced: {}",
                r.errors.join("; ")
            ),
        });
    }
    Ok(analysis)
}

/// Run a parsed command line, writing its output to `out`.
pub fn run(cli: Cli, out: &mut dyn Write) -> Result<()> {
    match cli.command {
        Command::Analyze {
            file,
            json,
            order,
            sheet,
            exclude_level,
            reason,
            type_b,
            anomalies,
            by,
        } => {
            let type_b = type_b
                .as_deref()
                .map(read_type_b)
                .transpose()?
                .unwrap_or_default();
            let by = match by {
                Some(name) if !name.trim().is_empty() => name.trim().to_string(),
                Some(_) => bail!("--by: give the name of who makes the exclusion"),
                None => crate::users::os_user(),
            };
            let exclusions = exclude_level
                .iter()
                .map(|e| LevelExclusion::parse(e, reason.as_deref().unwrap_or(""), &by))
                .collect::<Result<Vec<_>, _>>()?;
            let analysis = analyze_file_excluding(
                &file,
                order,
                sheet.as_deref(),
                exclusions,
                AnalysisOptions {
                    type_b,
                    anomalies,
                    ..AnalysisOptions::default()
                },
            )?;
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
            // Every unit that could be reduced is printed; the exit status
            // says whether some could not (each named above, and here).
            if !analysis.failed.is_empty() {
                out.flush()?;
                let names: Vec<String> = analysis
                    .failed
                    .iter()
                    .map(|f| format!("{}: {}", f.unit, f.error))
                    .collect();
                anyhow::bail!(
                    "{}: {} of {} unit(s) could not be reduced (the others are above):\n  {}",
                    file.display(),
                    analysis.failed.len(),
                    analysis.failed.len() + analysis.units.len(),
                    names.join("\n  ")
                );
            }
            Ok(())
        }
        Command::Demo {
            seed,
            realism,
            sim_config,
            tumble_positions,
            temperatures,
            levels,
            anomalies,
            json,
            data,
            db,
        } => {
            let bench = crate::demo::BenchChoice {
                seed,
                realism,
                config: sim_config,
                chamber: !temperatures.is_empty(),
            };
            crate::demo::demo(
                &bench,
                crate::demo::DemoPlanChoice {
                    tumble_positions,
                    temperatures_c: temperatures,
                    levels_g: (!levels.is_empty()).then_some(levels),
                    anomalies,
                },
                json,
                &data,
                db.as_ref(),
                out,
            )
        }
        Command::Run {
            plan,
            station,
            simulate,
            seed,
            realism,
            bench,
            resume,
            override_overdue,
            data,
            quiet,
            db,
        } => run::run_plan(
            run::Source::file(&plan, "plan")?,
            station
                .as_deref()
                .map(|p| run::Source::file(p, "station config"))
                .transpose()?,
            simulate,
            &crate::demo::BenchChoice {
                seed,
                realism,
                config: bench,
                chamber: false,
            },
            resume.as_deref(),
            &data,
            db,
            quiet,
            override_overdue.as_deref(),
            out,
        ),
        Command::Retest {
            run,
            station,
            simulate,
            seed,
            realism,
            data,
            quiet,
            db,
        } => run::retest(
            &run,
            station.as_deref(),
            simulate,
            &crate::demo::BenchChoice {
                seed,
                realism,
                config: None,
                chamber: false,
            },
            &data,
            db,
            quiet,
            out,
        ),
        Command::Runs {
            action: RunsAction::List { db },
        } => records::runs_list(&db, out),
        Command::Runs {
            action: RunsAction::Show { run, db },
        } => records::runs_show(&run, &db, out),
        Command::Unit { serial, db } => records::unit(&serial, &db, out),
        Command::Export {
            run,
            format,
            out: file,
            force,
            db,
        } => records::export(&run, &format, file, force, &db, out),
        Command::Report { run, output } => reports::report(&run, &output, out),
        Command::BatchReport {
            runs,
            baseline_runs,
            output,
        } => reports::batch_report(&runs, baseline_runs as usize, &output, out),
        Command::Replay { run, data, db } => reports::replay(&run, &data, db, out),
        Command::Serve { args } => crate::web::serve(args, out),
        Command::Backup { dir, db, data } => backup::backup(&dir, &db, data.as_deref(), out),
        Command::Doctor {
            station,
            simulate,
            data,
            db,
        } => {
            let db = db.unwrap_or_else(|| StoreTarget::File(data.join(crate::run_setup::DB_FILE)));
            crate::doctor::run(station.as_deref(), simulate, &db, &data, out)
        }
        Command::Restore { backup, db } => backup::restore(&backup, &db, out),
        Command::Equipment { action } => match action {
            EquipmentAction::List { db } => equipment::list(&db, out),
            EquipmentAction::Set {
                role,
                identity,
                certificate,
                calibrated,
                due,
                db,
            } => equipment::set(&role, &identity, &certificate, &calibrated, &due, &db, out),
        },
        Command::User { action } => match action {
            UserAction::Add { name, role, db } => user::add(&name, &role, &db, out),
            UserAction::List { db } => user::list(&db, out),
            UserAction::Role { name, role, db } => {
                user::change(&name, Some(&role), false, &db, out)
            }
            UserAction::Passwd { name, db } => user::change(&name, None, true, &db, out),
            UserAction::Remove { name, db } => user::remove(&name, &db, out),
        },
        Command::Sim {
            config,
            speed,
            realism,
            tcp,
            truth,
            run_for,
        } => sim::run_sim(config, speed, realism, tcp, truth, run_for, out),
    }
}
