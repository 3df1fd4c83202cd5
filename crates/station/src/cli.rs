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
    }
    Ok(())
}
