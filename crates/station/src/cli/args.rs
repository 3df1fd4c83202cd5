//! The command line, parsed in one place: every command and option with
//! its help and its value parser (the dispatch is in `mod.rs`).

use super::{Parser, PathBuf, StoreTarget, Subcommand, parse_store};

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
        /// it, its misfit in the budget as model inadequacy), exclude
        /// (leave it out, say so, the change in the budget) or own (exclude
        /// a level flagged in one mounting only, flag one flagged in both).
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
    #[cfg(feature = "sim")]
    Demo {
        /// Which virtual bench.
        #[command(flatten)]
        bench: crate::virtual_bench::BenchArgs,
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
        /// Design the levels, the readings on the way down and the dwell for
        /// this K2 U95 [µg/g²] from the station's model of its own runs in
        /// the store (the plan's `levels = "auto"`; default 8, the shipped
        /// check plan's, unless `--levels`, `--temperatures` or `--published`).
        #[arg(long, value_name = "UG_PER_G2", conflicts_with = "levels")]
        target_k2_u95: Option<f64>,
        /// What the reduction does with a level found off the curve: own
        /// (leave out a level flagged in one mounting only, the
        /// instrument's own dip; keep one flagged in both, the table's),
        /// flag or exclude (the plan key `anomalies`).
        #[arg(long, default_value = "own")]
        anomalies: spinbench_analysis::AnomalyRule,
        /// What the k2 limit judges: K2 (the instrument's own) or k2_max
        /// (the published convention; the plan key `limits.decide_on`).
        #[arg(long, default_value = "K2")]
        decide_on: spinbench_engine::plan::Measurand,
        /// Measure until the verdict is certain: after each mounting's
        /// levels, at most N levels chosen by the data for the instruments
        /// still undecided (the plan's `[sequential] max_levels_per_pass`;
        /// 0: only the planned levels; default 12 on a designed plan, else 0).
        #[arg(long, value_name = "N")]
        sequential: Option<u32>,
        /// The published plan as it was (0, 1, 5, then every 5 g to 70,
        /// 10-s dwell, nothing added), for comparison with a designed plan
        /// measured until the verdict is certain.
        #[arg(long, conflicts_with_all = ["levels", "target_k2_u95", "sequential"])]
        published: bool,
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
    /// Test plans: design one for a K2 uncertainty target.
    Plan {
        /// What to do.
        #[command(subcommand)]
        action: PlanAction,
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
        /// With --simulate: which virtual bench.
        #[command(flatten)]
        bench: crate::virtual_bench::BenchArgs,
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
    /// Test again the inconclusive, incomplete and flagged instruments of a
    /// finished run: same serials, slots and plan, the new run linked to RUN
    /// in the store and both reports. A clear fail is set aside.
    Retest {
        /// The run to retest (its identifier, as `spinbench runs list` shows).
        run: String,
        /// Test the clear fails again too (a doubted fixture or cable): a
        /// fail was decided with its U95 and the same instrument fails again.
        #[arg(long)]
        include_fails: bool,
        /// The station config (TOML); default: the one RUN used. With
        /// --simulate its device sections are replaced by the bench's.
        #[arg(long)]
        station: Option<PathBuf>,
        /// Run against the virtual bench in this process (real pseudo-terminals).
        #[arg(long)]
        simulate: bool,
        /// With --simulate: which virtual bench.
        #[command(flatten)]
        bench: crate::virtual_bench::BenchArgs,
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
    #[cfg(feature = "sim")]
    Sim {
        /// Which virtual bench (its config: every key has a default).
        #[command(flatten)]
        bench: crate::virtual_bench::BenchArgs,
        /// Time: 1 = real time, N = N× faster, 0 = virtual time in lockstep with the station.
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
    /// Manage the API tokens of machine clients (an MES calls the API with
    /// `Authorization: Bearer <secret>` instead of a person's login).
    Token {
        /// What to do.
        #[command(subcommand)]
        action: TokenAction,
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
        /// With --simulate: which virtual bench.
        #[command(flatten)]
        bench: crate::virtual_bench::BenchArgs,
        /// Where runs are kept (its free disk is checked).
        #[arg(long, default_value = crate::run_setup::DEFAULT_DATA_DIR)]
        data: PathBuf,
        /// The store (default DATA/spinbench.db).
        #[arg(long, value_parser = parse_store)]
        db: Option<StoreTarget>,
    },
    /// Bring a store's schema up to this release (each migration once, in
    /// its own transaction, recorded in the migration history). Run it as
    /// the database's owner: `run` and `serve` never change a PostgreSQL
    /// schema, so they can work with a role that has data rights only, and
    /// refuse a store that is not migrated. The Debian package runs it on
    /// install and upgrade. An SQLite file is migrated when it is opened.
    Migrate {
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
        /// Also list every migration the store has, with when and by which release.
        #[arg(long)]
        history: bool,
        /// A PostgreSQL role (the stations' data-only role) to grant its
        /// data rights on every table and sequence after migrating, and by
        /// default on what later migrations create; may be repeated.
        #[arg(long, value_name = "ROLE")]
        grant: Vec<String>,
        /// A PostgreSQL role (an analyst's) to grant read access to the
        /// view analyst_results only, never a table; may be repeated.
        #[arg(long, value_name = "ROLE")]
        grant_analyst: Vec<String>,
    },
    /// Retention: for each run that ended and started more than DAYS ago,
    /// archive its one-second values and events to Parquet files in the
    /// archive directory, read them back, then delete those rows from the
    /// store. The run's record (plan, devices, points, results, actions)
    /// stays: its reports and exports are unchanged.
    Prune {
        /// Age of the runs to prune [days]: 0 (every ended run) to 36500.
        #[arg(long, default_value_t = crate::prune::DEFAULT_RETENTION_DAYS, value_parser = crate::prune::parse_days, allow_hyphen_values = true)]
        older_than: f64,
        /// Where the Parquet files go (created if missing).
        #[arg(long, default_value = "spinbench-data/archive")]
        archive: PathBuf,
        /// Only say what would be pruned.
        #[arg(long)]
        dry_run: bool,
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
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
    /// Every device in the register with its station and status today.
    List {
        /// Only this station's devices (its config's `station`).
        #[arg(long)]
        station: Option<String>,
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
        /// The station the device belongs to (its config's `station`);
        /// needed unless the store knows only one station.
        #[arg(long)]
        station: Option<String>,
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

/// Actions of `spinbench token`.
#[derive(Debug, Subcommand)]
pub enum TokenAction {
    /// Make a token; its secret is printed this once (the store keeps its hash).
    Add {
        /// The machine it is for (a name like a user's, never reused).
        name: String,
        /// operator, engineer or admin: what its calls may do.
        #[arg(long, default_value = "operator")]
        role: String,
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
    /// List the tokens, revoked ones too (never a secret).
    List {
        /// The store.
        #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
        db: StoreTarget,
    },
    /// Revoke a token: its calls are refused on every server within seconds.
    Revoke {
        /// The token's name.
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
    pub(super) format: Vec<String>,
    /// Directory for the files (default: the current directory).
    #[arg(long, default_value = ".")]
    pub(super) out: PathBuf,
    /// The reports' language: en or zh-CN (the CSV's headers stay machine names).
    #[arg(long, default_value = "en", value_parser = parse_lang)]
    pub(super) lang: spinbench_report::Lang,
    /// The store.
    #[arg(long, default_value = "spinbench-data/spinbench.db", value_parser = parse_store)]
    pub(super) db: StoreTarget,
}

/// `--lang`: a language the station speaks.
pub(super) fn parse_lang(text: &str) -> Result<spinbench_report::Lang, String> {
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

/// `spinbench plan …`.
#[derive(Debug, Subcommand)]
pub enum PlanAction {
    /// Design the plan of least centrifuge time whose predicted K2 U95 meets
    /// a target, from the station's model of its own completed runs in the
    /// store (the defaults of a station with no history), and print it
    /// beside the published plan's prediction. Nothing moves.
    Design {
        /// The K2 U95 to reach [µg/g²] (default: the plan's
        /// target_k2_u95_ug_per_g2).
        #[arg(long, value_name = "UG_PER_G2")]
        target_k2_u95: Option<f64>,
        /// A plan (TOML) whose range, mountings and hysteresis limit the
        /// design keeps (default: ±70 g, mountings P and N).
        #[arg(long, value_name = "PLAN_TOML")]
        plan: Option<PathBuf>,
        /// The station config (TOML) whose runs the model learns from
        /// (default: the station of the newest completed run in the store).
        #[arg(long, value_name = "STATION_TOML")]
        station: Option<PathBuf>,
        /// How many of its newest completed runs the model learns from.
        #[arg(long, default_value_t = crate::station_model::DEFAULT_MODEL_RUNS as u64,
              value_parser = clap::value_parser!(u64).range(1..=crate::station_model::MAX_MODEL_RUNS as u64))]
        runs: u64,
        /// Where runs are kept.
        #[arg(long, default_value = crate::run_setup::DEFAULT_DATA_DIR)]
        data: PathBuf,
        /// The store: an SQLite file or a PostgreSQL server (postgres://…); default DATA/spinbench.db.
        #[arg(long, value_parser = parse_store)]
        db: Option<StoreTarget>,
        /// Print one JSON document instead of text.
        #[arg(long)]
        json: bool,
    },
}
