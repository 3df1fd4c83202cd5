//! The application layer of spinbench: the `spinbench` command line.
//!
//! * [`cli`] — the command-line interface and its subcommands;
//! * [`points_file`] — reading averaged points from CSV and spreadsheets;
//! * [`render`] — the human-readable output of `spinbench analyze`;
//! * [`station_run`] — `spinbench run` and `spinbench demo`: devices, engine, journal, results.

pub mod cli;
pub mod points_file;
pub mod render;
pub mod station_run;
