//! The `spinbench` command line: argument parsing and the subcommands.

use crate::points_file::read_points_file;
use crate::render::render_dataset;
use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use spinbench_analysis::{AnalysisOptions, DatasetAnalysis, ModelOrder, analyze_dataset};
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
        && !(seconds.is_finite() && seconds >= 0.0)
    {
        anyhow::bail!("--for {seconds}: expected a number of seconds ≥ 0");
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
