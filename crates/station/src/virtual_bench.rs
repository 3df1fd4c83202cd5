//! The virtual bench, opened in one place: one set of
//! bench arguments ([`BenchArgs`], flattened into every command that can
//! run on it), resolved into one [`VirtualBench`] that serves its devices
//! behind real pseudo-terminals and stops when dropped. `demo`, `run`,
//! `retest`, `serve`, `sim` and `doctor` all open it here.
//!
//! The simulator is the cargo feature `sim` (on by default). A station
//! built without it (`cargo build -p spinbench-station
//! --no-default-features`) has the same arguments and types, and
//! [`VirtualBench::open`] says that this build has no virtual bench.

use crate::web::runner::Hands;
use anyhow::Result;
use spinbench_engine::plan::Fixture;
use spinbench_engine::{Operator, StationConfig};

/// How the virtual bench is chosen on a command line.
#[cfg(feature = "sim")]
#[derive(Debug, Clone, Default, clap::Args)]
pub struct BenchArgs {
    /// Seed of the virtual bench (same seed and realism, same results);
    /// default: the bench config's, else 1.
    #[arg(long)]
    pub seed: Option<u64>,
    /// How real the virtual bench is: ideal, typical (the error sources of
    /// precision centrifuge testing) or harsh (typical with drift, a dead
    /// and a noisy instrument and line faults); replaces the bench config's
    /// `realism`.
    #[arg(long)]
    pub realism: Option<spinbench_sim::Realism>,
    /// A virtual bench config (TOML) whose keys go over the realism
    /// preset's (also spelt --sim-config and, for `sim`, --config).
    #[arg(
        long = "bench",
        alias = "sim-config",
        alias = "config",
        value_name = "BENCH_TOML"
    )]
    pub bench: Option<std::path::PathBuf>,
}

/// How the virtual bench is chosen on a command line: nothing, in a
/// build without the simulator.
#[cfg(not(feature = "sim"))]
#[derive(Debug, Clone, Default, clap::Args)]
pub struct BenchArgs {}

impl BenchArgs {
    /// A bench config file was named.
    pub fn names_a_file(&self) -> bool {
        #[cfg(feature = "sim")]
        return self.bench.is_some();
        #[cfg(not(feature = "sim"))]
        false
    }
}

/// The virtual bench's configuration, resolved from [`BenchArgs`].
#[cfg(feature = "sim")]
pub type BenchConfig = spinbench_sim::SimConfig;

#[cfg(feature = "sim")]
impl BenchArgs {
    /// The bench's config: the realism preset, the file's keys over it, the
    /// seed when given; at `speed` (1 = real time, 0 = virtual time in
    /// lockstep) when given, else the file's.
    pub fn config(&self, speed: Option<f64>) -> Result<BenchConfig> {
        use anyhow::Context;
        use spinbench_sim::SimConfig;
        let mut config = match &self.bench {
            Some(path) => {
                let text = std::fs::read_to_string(path)
                    .with_context(|| format!("{}: cannot read the bench config", path.display()))?;
                SimConfig::from_toml_with(&text, self.realism)
                    .with_context(|| path.display().to_string())?
            }
            None => self.realism.unwrap_or_default().config(),
        };
        if let Some(seed) = self.seed {
            config.seed = seed;
        }
        if let Some(speed) = speed {
            config.speed = speed;
        }
        config.validate()?;
        Ok(config)
    }
}

/// A virtual bench serving its devices; dropped, it stops.
#[cfg(feature = "sim")]
pub struct VirtualBench {
    running: spinbench_sim::serve::RunningBench,
    station_toml: String,
}

/// A virtual bench: none can exist in a build without the simulator.
#[cfg(not(feature = "sim"))]
pub enum VirtualBench {}

/// What a build without the simulator says when asked for the virtual bench.
#[cfg(not(feature = "sim"))]
pub const NO_VIRTUAL_BENCH: &str = "this spinbench was built without the virtual bench (the cargo \
     feature `sim`); name the station's hardware with --station CONFIG, or use a build with it";

impl VirtualBench {
    /// Start a virtual bench of `args`, at `speed` when given; its devices
    /// on loopback TCP instead of pseudo-terminals where `tcp`.
    #[cfg(feature = "sim")]
    pub fn open(args: &BenchArgs, speed: Option<f64>, tcp: bool) -> Result<VirtualBench> {
        VirtualBench::open_config(args.config(speed)?, tcp)
    }

    /// Start a virtual bench of `args` (a build without the simulator: an error).
    #[cfg(not(feature = "sim"))]
    pub fn open(args: &BenchArgs, speed: Option<f64>, tcp: bool) -> Result<VirtualBench> {
        let _ = (args, speed, tcp);
        anyhow::bail!(NO_VIRTUAL_BENCH)
    }

    /// Start a virtual bench of `config`.
    #[cfg(feature = "sim")]
    pub fn open_config(config: BenchConfig, tcp: bool) -> Result<VirtualBench> {
        use anyhow::Context;
        let running = spinbench_sim::serve::RunningBench::start(
            config,
            spinbench_sim::serve::ServeOptions {
                line_devices_on_tcp: tcp,
            },
        )
        .context("cannot start the virtual bench")?;
        let station_toml = spinbench_sim::station::station_toml(&running, "");
        Ok(VirtualBench {
            running,
            station_toml,
        })
    }

    /// The station config (TOML) that reaches the bench's devices.
    pub fn station_toml(&self) -> &str {
        #[cfg(feature = "sim")]
        return &self.station_toml;
        #[cfg(not(feature = "sim"))]
        match *self {}
    }

    /// The station config that reaches the bench's devices, read.
    pub fn station(&self) -> Result<StationConfig> {
        use anyhow::Context;
        let text = self.station_toml();
        StationConfig::from_toml(text)
            .with_context(|| format!("the virtual bench's station config:\n{text}"))
    }

    /// The operator at the terminal of a run on this bench: the simulator
    /// remounts its instruments as each prompt asks (each prompt shown
    /// with its answer unless `quiet`).
    pub fn operator(&self, quiet: bool) -> Box<dyn Operator + '_> {
        #[cfg(feature = "sim")]
        return Box::new(spinbench_sim::station::SimOperator::new(
            &self.running,
            quiet,
        ));
        #[cfg(not(feature = "sim"))]
        {
            let _ = quiet;
            match *self {}
        }
    }

    /// The running simulator (the world, its truth).
    #[cfg(feature = "sim")]
    pub fn running(&self) -> &spinbench_sim::serve::RunningBench {
        &self.running
    }
}

impl Hands for VirtualBench {
    fn carry_out(&self, text: &str, fixtures: &[Option<Fixture>]) {
        #[cfg(feature = "sim")]
        spinbench_sim::station::SimOperator::new(&self.running, true).ask(text, fixtures);
        #[cfg(not(feature = "sim"))]
        {
            let _ = (text, fixtures);
            match *self {}
        }
    }
}
