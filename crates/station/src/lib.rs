//! The application layer of spinbench: the `spinbench` command line.
//!
//! * [`cli`] — the command-line interface and its subcommands;
//! * [`export`] — `spinbench export`: a run's points and results as CSV, XLSX or Parquet;
//! * [`points_file`] — reading averaged points from CSV and spreadsheets;
//! * [`render`] — the human-readable output of `spinbench analyze`;
//! * [`replay`] — `spinbench replay`: a run's raw bytes through the decoder again, checked against the store;
//! * [`station_run`] — `spinbench run` and `spinbench demo`: devices, engine, journal, results;
//! * [`web`] — `spinbench serve`: the web UI and the HTTP API.

pub mod cli;
pub mod export;
pub mod points_file;
pub mod render;
pub mod replay;
pub mod signals;
pub mod station_run;
pub mod web;
