//! The station's web UI and HTTP API (`spinbench serve`): an axum server in
//! the station process. The browser page (`assets/`) and a line's MES use
//! the same JSON API (its OpenAPI document generated from the handlers, `api::doc`); live data reach the
//! browser as server-sent events from the engine's event stream ([`hub`]).
//! The UI never touches a driver: it starts runs through [`runner`] and
//! hears the engine's events, like the store and the journal do.

pub mod api;
pub mod auth;
pub mod eta;
pub mod hub;
mod left_over;
pub mod machine_tokens;
pub mod metrics;
mod plans_shipped;
pub mod runner;
pub mod server;
pub mod throttle;
pub mod tls;
pub mod webhooks;

use anyhow::{Context, Result};
use spinbench_engine::StationConfig;
use spinbench_store::{Store, StoreTarget};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// The OpenAPI document of the HTTP API, generated from the handlers.
pub fn openapi() -> &'static str {
    api::doc::json()
}

/// Everything a request handler may reach.
pub struct AppState {
    /// The store (one connection; queries are short).
    pub store: Mutex<Store>,
    /// Where the store lives (report downloads open their own connection).
    pub db: StoreTarget,
    /// Open sessions.
    pub sessions: auth::Sessions,
    /// The API tokens of machine clients seen lately.
    pub machine_tokens: machine_tokens::MachineTokens,
    /// Failed logins per name and address.
    pub logins: throttle::LoginThrottle,
    /// The engine's events.
    pub hub: Arc<hub::Hub>,
    /// Starts and steers runs.
    pub runner: runner::Runner,
    /// Where test plans are kept (`<data>/plans/*.toml`).
    pub plans_dir: PathBuf,
    /// The station config file an engineer's edit is saved to (none on the virtual bench).
    pub station_path: Option<PathBuf>,
    /// Served over TLS: session cookies are `Secure`.
    pub secure_cookies: bool,
    /// What `/metrics` tells the plant's monitoring.
    pub metrics: metrics::Metrics,
    /// The runs' start, end and faults pushed to the plant's receiver.
    pub webhooks: Arc<webhooks::Webhooks>,
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
    /// The virtual bench's time: 1 = real time, N = N× faster, 0 = virtual time in lockstep.
    #[arg(long, default_value_t = 1.0)]
    pub sim_speed: f64,
    /// With --simulate: which virtual bench.
    #[command(flatten)]
    pub bench: crate::virtual_bench::BenchArgs,
    /// Address to listen on (port 0: any free port).
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub bind: SocketAddr,
    /// Where runs and plans are kept.
    #[arg(long, default_value = crate::run_setup::DEFAULT_DATA_DIR)]
    pub data: PathBuf,
    /// The store (default DATA/spinbench.db).
    #[arg(long, value_parser = crate::paths::parse_store)]
    pub db: Option<StoreTarget>,
    /// Most HTTP connections open at once (1 to 10000); more are closed at once.
    #[arg(long, default_value_t = 256)]
    pub max_connections: usize,
    /// Seconds a client has to send a request's headers (1 to 300).
    #[arg(long, default_value_t = 10.0)]
    pub header_timeout_s: f64,
    /// Seconds a connection may stay silent both ways before it is closed (1 to 3600).
    #[arg(long, default_value_t = 60.0)]
    pub idle_timeout_s: f64,
    /// Serve HTTPS with this PEM certificate chain (the server's first; with --tls-key).
    #[arg(long, requires = "tls_key")]
    pub tls_cert: Option<PathBuf>,
    /// The PEM private key of --tls-cert.
    #[arg(long, requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
    /// The station's id in the fleet, instead of the station config's
    /// `station` (several virtual benches on one store need their own).
    #[arg(long)]
    pub name: Option<String>,
    /// POST each run's start, end and faults (JSON, HMAC-SHA256 signed) to
    /// this http(s) URL; with --webhook-secret-file.
    #[arg(long, requires = "webhook_secret_file")]
    pub webhook_url: Option<String>,
    /// The file holding the webhooks' shared secret (16 to 1024 bytes;
    /// keep it readable by the station's user only).
    #[arg(long, requires = "webhook_url")]
    pub webhook_secret_file: Option<PathBuf>,
}

impl ServeArgs {
    /// The connection limits, each checked against its bound.
    pub fn connection_limits(&self) -> Result<server::ConnectionLimits> {
        let seconds = |name: &str, v: f64, max: f64| -> Result<std::time::Duration> {
            if !(v.is_finite() && (1.0..=max).contains(&v)) {
                anyhow::bail!("--{name} {v}: expected seconds from 1 to {max}");
            }
            Ok(std::time::Duration::from_secs_f64(v))
        };
        if !(1..=10_000).contains(&self.max_connections) {
            anyhow::bail!(
                "--max-connections {}: expected 1 to 10000",
                self.max_connections
            );
        }
        Ok(server::ConnectionLimits {
            max_connections: self.max_connections,
            header_timeout: seconds("header-timeout-s", self.header_timeout_s, 300.0)?,
            idle_timeout: seconds("idle-timeout-s", self.idle_timeout_s, 3600.0)?,
            ..server::ConnectionLimits::default()
        })
    }
}

/// Start the server and serve until Ctrl-C; then abort any run into the safe state.
pub fn serve(args: ServeArgs, out: &mut dyn std::io::Write) -> Result<()> {
    // Checked before anything is opened or made.
    let webhook_target = match (&args.webhook_url, &args.webhook_secret_file) {
        (Some(url), Some(file)) => Some(webhooks::WebhookTarget::from_args(url, file)?),
        _ => None,
    };
    std::fs::create_dir_all(&args.data)
        .with_context(|| format!("{}: cannot create the data directory", args.data.display()))?;
    let db = args
        .db
        .clone()
        .unwrap_or_else(|| StoreTarget::File(args.data.join(crate::run_setup::DB_FILE)));
    // The virtual bench lives as long as the server (this function) and
    // the runs it hands to; it stops when the last of them drops it.
    let (station_toml, virtual_bench) = if args.simulate {
        let bench = std::sync::Arc::new(crate::virtual_bench::VirtualBench::open(
            &args.bench,
            Some(args.sim_speed),
            false,
        )?);
        (bench.station_toml().to_string(), Some(bench))
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
    let station_toml = match &args.name {
        Some(name) => renamed(&station_toml, name)?,
        None => station_toml,
    };
    let station = StationConfig::from_toml(&station_toml).context("the station config")?;
    spinbench_store::name_connections(&station.station);
    let identity = crate::paths::station_identity(&args.data)?;
    let plans_dir = args.data.join("plans");
    std::fs::create_dir_all(&plans_dir)
        .with_context(|| format!("{}: cannot create the plans directory", plans_dir.display()))?;
    plans_shipped::offer_shipped_plans(&plans_dir)?;
    // TLS first: a wrong certificate is said before anything starts.
    let tls = match (&args.tls_cert, &args.tls_key) {
        (Some(cert), Some(key)) => Some(tls::server_config(cert, key)?),
        _ => None,
    };
    let store = Store::connect(&db).map_err(|e| {
        anyhow::anyhow!(
            "{e}\nthe store {db} cannot be opened and brought up to date by this user ({}); check that it may read and write it (the file and its directory, or the database user's privileges), then start again",
            crate::users::os_user()
        )
    })?;
    // A store this user can open but not write (made by root, say) would
    // fail every login and every run with a 500: refuse to start instead.
    store.check_writable().map_err(|e| {
        anyhow::anyhow!(
            "{e}\nthe store {db} cannot be written by this user ({}); give it (and its directory) to the user that runs `spinbench serve` (chown), or grant the database user write access, then start again",
            crate::users::os_user()
        )
    })?;
    // Runs this station's processes left behind: crashed runs marked
    // interrupted now (History must show them so at once); their left-over
    // files written in the background once the server listens.
    for line in crate::recovery::mark_crashed_runs(&args.data, &station.station, &store).lines() {
        writeln!(out, "{line}")?;
    }
    if store.users()?.is_empty() {
        writeln!(
            out,
            "note: no users yet; create the first admin with `spinbench user add NAME --role admin --db {db}`"
        )?;
    }
    let slots = station.slots().max(1);
    let r0 = (0..slots).map(|i| station.drawing_radius_m(i)).sum::<f64>() / slots as f64;
    let hub = Arc::new(hub::Hub::in_zone(
        r0,
        station.g_local_m_s2,
        station.time_zone,
    ));
    let hands = virtual_bench
        .clone()
        .map(|bench| bench as Arc<dyn runner::Hands>);
    let runner = runner::Runner::new(
        station,
        station_toml,
        hands,
        args.data.clone(),
        db.clone(),
        hub.clone(),
    );
    let state = Arc::new(AppState {
        store: Mutex::new(store),
        db: db.clone(),
        sessions: auth::Sessions::default(),
        machine_tokens: machine_tokens::MachineTokens::default(),
        logins: throttle::LoginThrottle::default(),
        hub,
        runner,
        plans_dir,
        station_path: if args.simulate {
            None
        } else {
            args.station.clone()
        },
        secure_cookies: tls.is_some(),
        metrics: metrics::Metrics::new().context("the metrics")?,
        webhooks: Arc::new(webhooks::Webhooks::new(webhook_target)),
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
    let address = format!(
        "{}://{local}/",
        if tls.is_some() { "https" } else { "http" }
    );
    // The station's name is its own in the fleet: not
    // while another live station holds it.
    claim_name(&state, &address, &identity, out)?;
    writeln!(
        out,
        "spinbench serve: {}://{local}/ ({}; data in {}, store {})",
        if tls.is_some() { "https" } else { "http" },
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
    let limits = args.connection_limits()?;
    let signals = {
        let _in_runtime = runtime.enter();
        termination_signals()
            .context("cannot install the handlers of SIGINT, SIGTERM and SIGHUP")?
    };
    let heartbeat = spawn_heartbeat(state.clone(), db.clone(), address, identity)?;
    left_over::spawn_catch_up(state.clone(), db.clone(), args.data.clone())?;
    state.webhooks.spawn(state.clone())?;
    let stopping = state.clone();
    let gated = state.clone();
    let gate = move |router| api::gate_sessions(router, gated);
    runtime.block_on(server::serve(
        listener,
        app,
        limits,
        tls,
        gate,
        async move {
            let reason = signals.await;
            eprintln!("{reason}: stopping the run (safe state), then closing the connections…");
            // The run first: it goes to its safe state and is recorded while the
            // server still answers; then the event streams end.
            let runner_state = stopping.clone();
            let why = reason.clone();
            let stopped = tokio::task::spawn_blocking(move || {
                runner_state.runner.shutdown(&why, RUN_STOP_LIMIT)
            })
            .await
            .unwrap_or(false);
            if !stopped {
                eprintln!(
                    "the run did not reach its safe state within {} s: check the centrifuge",
                    RUN_STOP_LIMIT.as_secs()
                );
            }
            stopping.hub.close();
        },
    ));
    // Whatever still runs goes to its safe state before the process ends.
    state.runner.shutdown("the server stopping", RUN_STOP_LIMIT);
    state.hub.close();
    if state.webhooks.url().is_some() && !state.webhooks.drain(webhooks::DRAIN_LIMIT) {
        eprintln!(
            "webhooks not delivered within {} s were dropped (GET /api/webhooks listed them): the runs' records are in the store",
            webhooks::DRAIN_LIMIT.as_secs()
        );
    }
    // A store that does not answer holds the heartbeat's last write (and
    // any request's call): the process does not wait for it beyond
    // STOP_STORE_WAIT (a service manager's stop time-out is 90 s).
    let until = std::time::Instant::now() + STOP_STORE_WAIT;
    while !heartbeat.is_finished() && std::time::Instant::now() < until {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    if heartbeat.is_finished() {
        let _ = heartbeat.join();
    } else {
        eprintln!(
            "the store did not answer within {} s: the station is not marked offline in it",
            STOP_STORE_WAIT.as_secs()
        );
    }
    runtime.shutdown_timeout(std::time::Duration::from_secs(2));
    Ok(())
}

/// The station config with its `station` (the fleet id) set to `name`.
fn renamed(station_toml: &str, name: &str) -> Result<String> {
    let name = spinbench_engine::bounds::person_text(name)
        .map_err(|why| anyhow::anyhow!("--name: {why}"))?;
    if name.is_empty() || name.chars().count() > 64 {
        anyhow::bail!(
            "--name '{}': 1 to 64 characters",
            spinbench_engine::bounds::shown(&name)
        );
    }
    let mut table: toml::Table = station_toml.parse().context("the station config")?;
    table.insert("station".into(), toml::Value::String(name));
    toml::to_string(&table).context("the station config")
}

/// Claim the station's name in the fleet for this identity; refused
/// (naming the holder and how to rename) while another live station holds
/// it, warned when another identity held it before.
fn claim_name(
    state: &AppState,
    address: &str,
    identity: &str,
    out: &mut dyn std::io::Write,
) -> Result<()> {
    let station = state.runner.station().0.station;
    if let Some(other) = state
        .store
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .look_alike_station(&station)?
    {
        anyhow::bail!(
            "the name '{}' looks like the fleet's station '{}': the two would read as one station on every page. \
             Give this station a name that is plainly its own (`station` in its station.toml, or `serve --name NAME`)",
            spinbench_engine::bounds::shown(&station),
            spinbench_engine::bounds::shown(&other)
        );
    }
    let beat = heartbeat_now(state, &station, address, identity);
    let claim = state
        .store
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .claim_station(&beat)?;
    match claim {
        spinbench_store::fleet::Claim::Taken { previous: None } => Ok(()),
        spinbench_store::fleet::Claim::Taken {
            previous: Some(before),
        } => {
            writeln!(
                out,
                "warning: the name '{station}' was last used by another station (identity {}, at {}, last heard {}); this one (identity {identity}) takes it over, with a register of its own (the old station's is kept under its identity). If that is another centrifuge, give this one its own name (`station` in its station.toml, or --name)",
                before.instance,
                before.address.as_deref().unwrap_or("no address"),
                spinbench_store::equipment::civil_date(before.last_seen)
            )?;
            Ok(())
        }
        spinbench_store::fleet::Claim::HeldBy(holder) => {
            let heard = (spinbench_store::now_s() - holder.last_seen).max(0);
            let at = holder.address.as_deref().unwrap_or("no address");
            anyhow::bail!(
                "another station already holds the name '{station}' (identity {}, at {at}, heard {heard} s ago): \
                 two stations with one name would merge in the fleet, its register, its yield and its run numbers. \
                 Give this station its own name: `station = \"…\"` in its station.toml, or `serve --name NAME`; \
                 if that station is gone for good, an admin retires it on another station's Fleet page first",
                if holder.instance.is_empty() {
                    "unknown"
                } else {
                    holder.instance.as_str()
                },
            )
        }
    }
}

/// How long a stopping server waits for the store's last writes.
const STOP_STORE_WAIT: std::time::Duration = std::time::Duration::from_secs(5);

/// How often a server writes its station's heartbeat into the store.
const HEARTBEAT_EVERY: std::time::Duration = std::time::Duration::from_secs(2);

/// Write the station's heartbeat (state, run, progress, address) into the
/// store every [`HEARTBEAT_EVERY`] on a thread of its own with its own
/// connection (a store that does not answer is tried again at the next
/// beat); once the hub closes, mark the station offline and end.
fn spawn_heartbeat(
    state: Arc<AppState>,
    db: StoreTarget,
    address: String,
    identity: String,
) -> Result<std::thread::JoinHandle<()>> {
    let station = state.runner.station().0.station;
    std::thread::Builder::new()
        .name("heartbeat".into())
        .spawn(move || {
            let closing = state.hub.closing();
            let mut store: Option<Store> = None;
            let mut warned = false;
            while !*closing.borrow() {
                if store.is_none() {
                    store = Store::connect(&db).ok();
                }
                let beat = heartbeat_now(&state, &station, &address, &identity);
                let started = std::time::Instant::now();
                *state
                    .metrics
                    .store_write_since
                    .lock()
                    .unwrap_or_else(|e| e.into_inner()) = Some(started);
                let written = store.as_ref().map(|s| s.heartbeat(&beat));
                *state
                    .metrics
                    .store_write_since
                    .lock()
                    .unwrap_or_else(|e| e.into_inner()) = None;
                // Up while the heartbeat's write and the run's (if one runs)
                // are taken.
                let run_up = state.runner.store_health().is_none_or(|h| h.up);
                state
                    .metrics
                    .store_up
                    .set(i64::from(matches!(written, Some(Ok(()))) && run_up));
                if let Some(Ok(())) = written {
                    warned = false;
                    state
                        .metrics
                        .store_write_s
                        .observe(started.elapsed().as_secs_f64());
                }
                if !matches!(written, Some(Ok(()))) {
                    state.metrics.store_errors.inc();
                }
                if let Some(Err(e)) = written {
                    if !warned {
                        eprintln!(
                            "warning: {e} (tried again every {} s)",
                            HEARTBEAT_EVERY.as_secs()
                        );
                        warned = true;
                    }
                    store = None;
                }
                let until = std::time::Instant::now() + HEARTBEAT_EVERY;
                while std::time::Instant::now() < until && !*closing.borrow() {
                    std::thread::sleep(std::time::Duration::from_millis(100));
                }
            }
            if let Some(s) = store.or_else(|| Store::connect(&db).ok()) {
                let _ = s.station_offline(&station);
            }
        })
        .context("cannot start the heartbeat thread")
}

/// The station's state for the fleet and the monitoring: `faulted` (the
/// last run faulted, until the next starts), `waiting` (a run waits for the
/// operator's answer to a prompt), `running` (a run is active), else `idle`.
pub(crate) fn station_state(state: &AppState, status: &hub::StatusSnapshot) -> &'static str {
    use spinbench_engine::RunState;
    match (state.runner.active().is_some(), status.state) {
        (_, Some(RunState::Faulted)) => "faulted",
        (true, Some(RunState::Prompting)) => "waiting",
        (true, _) => "running",
        _ => "idle",
    }
}

/// The station's heartbeat now, from the hub and the runner.
fn heartbeat_now(
    state: &AppState,
    station: &str,
    address: &str,
    identity: &str,
) -> spinbench_store::fleet::Heartbeat {
    let status = state.hub.status();
    let active = state.runner.active().is_some();
    let what = station_state(state, &status);
    spinbench_store::fleet::Heartbeat {
        station: station.to_string(),
        instance: identity.to_string(),
        state: what.to_string(),
        run_id: status.run_id.clone(),
        progress: status
            .step
            .as_ref()
            .filter(|_| active)
            .map(|step| ((step.index as i64 + 1).min(step.of as i64), step.of as i64)),
        address: Some(address.to_string()),
    }
}

/// How long shutdown waits for a run to reach its safe state.
const RUN_STOP_LIMIT: std::time::Duration = std::time::Duration::from_secs(60);

/// A future that completes with the reason (naming the signal) at the first
/// SIGINT, SIGTERM or SIGHUP.
fn termination_signals() -> std::io::Result<impl std::future::Future<Output = String>> {
    use tokio::signal::unix::{SignalKind, signal};
    let mut int = signal(SignalKind::interrupt())?;
    let mut term = signal(SignalKind::terminate())?;
    let mut hup = signal(SignalKind::hangup())?;
    Ok(async move {
        let signal = tokio::select! {
            _ = int.recv() => signal_hook::consts::SIGINT,
            _ = term.recv() => signal_hook::consts::SIGTERM,
            _ = hup.recv() => signal_hook::consts::SIGHUP,
        };
        crate::signals::reason_of(signal)
    })
}

/// `mutex` locked, waiting at most `within` for another holder (one whose
/// database call does not come back must not stall every request).
pub(crate) fn lock_within<T>(
    mutex: &std::sync::Mutex<T>,
    within: std::time::Duration,
) -> Option<std::sync::MutexGuard<'_, T>> {
    let until = std::time::Instant::now() + within;
    loop {
        match mutex.try_lock() {
            Ok(guard) => return Some(guard),
            Err(std::sync::TryLockError::Poisoned(e)) => return Some(e.into_inner()),
            Err(std::sync::TryLockError::WouldBlock) => {
                if std::time::Instant::now() >= until {
                    return None;
                }
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
        }
    }
}
