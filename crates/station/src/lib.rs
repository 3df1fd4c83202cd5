//! The application layer of spinbench: the `spinbench` command line.
//!
//! * [`cli`] — the command-line interface and its subcommands;
//! * [`export`] — `spinbench export`: a run's points and results as CSV, XLSX or Parquet;
//! * [`points_file`] — reading averaged points from CSV and spreadsheets;
//! * [`render`] — the human-readable output of `spinbench analyze`;
//! * [`replay`] — `spinbench replay`: a run's raw bytes through the decoder again, checked against the store;
//! * [`run_setup`] — one run set-up: the run directory, the plan compiled once, the store path;
//! * [`station_run`] — a prepared run executed: engine, journal, store, results, report;
//! * [`demo`] — `spinbench demo`: the virtual bench, a whole test, the truth beside it (feature `sim`);
//! * [`virtual_bench`] — the virtual bench's arguments, opened in one place, stopped when dropped;
//! * [`terminal`] — the operator at the terminal and the progress printer;
//! * [`signals`] — SIGINT, SIGTERM and SIGHUP abort the run, naming the signal;
//! * [`users`] — adding a user, the one way the CLI and the web API do it;
//! * [`tokens`] — API tokens for machine clients, made and revoked the same way;
//! * [`paths`] — where things live: the data directory, the store, a run's files;
//! * [`web`] — `spinbench serve`: the web UI and the HTTP API.

pub mod cli;
#[cfg(feature = "sim")]
pub mod demo;
pub mod doctor;
pub mod equipment;
pub mod export;
pub mod paths;
pub mod points_file;
pub mod prune;
pub mod recovery;
pub mod render;
pub mod replay;
pub mod retest;
pub mod run_setup;
pub mod signals;
pub mod station_model;
pub mod station_run;
pub mod terminal;
pub mod tokens;
pub mod users;
pub mod virtual_bench;
pub mod web;
