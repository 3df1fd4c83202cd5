//! The station's web UI and HTTP API (`spinbench serve`): an axum server in
//! the station process. The browser page (`assets/`) and a line's MES use
//! the same JSON API (documented in `openapi.json`); live data reach the
//! browser as server-sent events from the engine's event stream ([`hub`]).
//! The UI never touches a driver: it starts runs through [`runner`] and
//! hears the engine's events, like the store and the journal do.

pub mod api;
pub mod auth;
pub mod hub;
pub mod runner;

use anyhow::{Context, Result};
use spinbench_engine::StationConfig;
use spinbench_sim::SimConfig;
use spinbench_sim::serve::{RunningBench, ServeOptions};
use spinbench_store::{Store, StoreTarget};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// The OpenAPI document of the HTTP API.
pub const OPENAPI: &str = include_str!("openapi.json");

/// Everything a request handler may reach.
pub struct AppState {
    /// The store (one connection; queries are short).
    pub store: Mutex<Store>,
    /// Where the store lives (report downloads open their own connection).
    pub db: StoreTarget,
    /// Open sessions.
    pub sessions: auth::Sessions,
    /// The engine's events.
    pub hub: Arc<hub::Hub>,
    /// Starts and steers runs.
    pub runner: runner::Runner,
    /// Where test plans are kept (`<data>/plans/*.toml`).
    pub plans_dir: PathBuf,
    /// The station config file an engineer's edit is saved to (none on the virtual bench).
    pub station_path: Option<PathBuf>,
}

/// How `spinbench serve` was asked to run (its command-line options).
#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    /// Station config (TOML).
    #[arg(long)]
    pub station: Option<PathBuf>,
    /// Run on the virtual bench instead of hardware.
    #[arg(long)]
    pub simulate: bool,
    /// The virtual bench's time: 1 = real time, N = N× faster, 0 = as fast as read.
    #[arg(long, default_value_t = 1.0)]
    pub sim_speed: f64,
    /// The virtual bench's configuration (TOML, as for `spinbench sim --config`).
    #[arg(long)]
    pub sim_config: Option<PathBuf>,
    /// Seed of the virtual bench.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Address to listen on (port 0: any free port).
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub bind: SocketAddr,
    /// Where runs and plans are kept.
    #[arg(long, default_value = crate::station_run::DEFAULT_DATA_DIR)]
    pub data: PathBuf,
    /// The store (default DATA/spinbench.db).
    #[arg(long, value_parser = crate::cli::parse_store)]
    pub db: Option<StoreTarget>,
}

/// The plan a fresh data directory starts with, so a new station has one to run.
const EXAMPLE_PLAN: &str = r#"# A short test: ±10 g in both mountings (edit or add plans as an engineer).
name = "short ±10 g"
range_g = 10
levels = [0, 1, 2, 4, 6, 8, 10]
passes = ["P", "N"]
warmup_s = 0
dwell = { seconds = 3 }
stability = { hold_s = 3 }
[serials]
1 = "SN-001"
"#;

/// Start the server and serve until Ctrl-C; then abort any run into the safe state.
pub fn serve(args: ServeArgs, out: &mut dyn std::io::Write) -> Result<()> {
    std::fs::create_dir_all(&args.data)
        .with_context(|| format!("{}: cannot create the data directory", args.data.display()))?;
    let db = args
        .db
        .clone()
        .unwrap_or_else(|| StoreTarget::File(args.data.join(crate::station_run::DB_FILE)));
    let (station_toml, sim) = if args.simulate {
        let base = match &args.sim_config {
            Some(p) => {
                let text = std::fs::read_to_string(p)
                    .with_context(|| format!("{}: cannot read the bench config", p.display()))?;
                SimConfig::from_toml(&text).with_context(|| p.display().to_string())?
            }
            None => SimConfig::default(),
        };
        let config = SimConfig {
            seed: args.seed,
            speed: args.sim_speed,
            ..base
        };
        let bench = RunningBench::start(config, ServeOptions::default())
            .context("cannot start the virtual bench")?;
        // The virtual bench lives as long as the server.
        let bench: &'static RunningBench = Box::leak(Box::new(bench));
        (crate::station_run::sim_station_toml(bench), Some(bench))
    } else {
        let path = args
            .station
            .as_ref()
            .context("--station CONFIG is needed (or --simulate for the virtual bench)")?;
        (
            std::fs::read_to_string(path)
                .with_context(|| format!("{}: cannot read the station config", path.display()))?,
            None,
        )
    };
    let station = StationConfig::from_toml(&station_toml).context("the station config")?;
    let plans_dir = args.data.join("plans");
    std::fs::create_dir_all(&plans_dir)
        .with_context(|| format!("{}: cannot create the plans directory", plans_dir.display()))?;
    if std::fs::read_dir(&plans_dir).map_or(true, |mut d| d.next().is_none()) {
        std::fs::write(plans_dir.join("short.toml"), EXAMPLE_PLAN)?;
    }
    let store = Store::connect(&db)?;
    if store.users()?.is_empty() {
        writeln!(
            out,
            "note: no users yet; create the first admin with `spinbench user add NAME --role admin`"
        )?;
    }
    let slots = station.slots().max(1);
    let r0 = (0..slots).map(|i| station.drawing_radius_m(i)).sum::<f64>() / slots as f64;
    let hub = Arc::new(hub::Hub::new(r0, station.g_local_m_s2));
    let runner = runner::Runner::new(
        station,
        station_toml,
        sim,
        args.data.clone(),
        db.clone(),
        hub.clone(),
    );
    let state = Arc::new(AppState {
        store: Mutex::new(store),
        db: db.clone(),
        sessions: auth::Sessions::default(),
        hub,
        runner,
        plans_dir,
        station_path: if args.simulate {
            None
        } else {
            args.station.clone()
        },
    });
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the server's runtime")?;
    let listener = runtime
        .block_on(tokio::net::TcpListener::bind(args.bind))
        .with_context(|| format!("cannot listen on {} (in use? use --bind)", args.bind))?;
    let local = listener.local_addr()?;
    writeln!(
        out,
        "spinbench serve: http://{local}/ ({}; data in {}, store {})",
        if args.simulate {
            "virtual bench"
        } else {
            "station hardware"
        },
        args.data.display(),
        db
    )?;
    out.flush()?;
    let app = api::router(state.clone());
    let served = runtime.block_on(async move {
        axum::serve(listener, app)
            .with_graceful_shutdown(async {
                let _ = tokio::signal::ctrl_c().await;
            })
            .await
    });
    // Whatever runs goes to its safe state before the process ends.
    state.runner.shutdown();
    served.context("the server stopped")
}
