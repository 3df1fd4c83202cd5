//! `spinbench sim`: a virtual bench behind real pseudo-terminals, its
//! device sections printed for a station config, running until stopped.

use anyhow::{Context, Result};
use std::io::Write;
use std::path::PathBuf;

/// Longest `spinbench sim --for` [s].
const MAX_SIM_FOR_S: f64 = 1e7;

/// `spinbench sim`: start a virtual bench and print how to reach it.
pub(super) fn run_sim(
    bench_args: &crate::virtual_bench::BenchArgs,
    speed: Option<f64>,
    tcp: bool,
    truth: Option<PathBuf>,
    run_for: Option<f64>,
    out: &mut dyn Write,
) -> Result<()> {
    if let Some(seconds) = run_for
        && !(seconds.is_finite() && (0.0..=MAX_SIM_FOR_S).contains(&seconds))
    {
        anyhow::bail!(
            "--for {seconds}: expected seconds from 0 to {MAX_SIM_FOR_S} (about 115 days; leave --for out to run until interrupted)"
        );
    }
    let bench = crate::virtual_bench::VirtualBench::open(bench_args, speed, tcp)?;
    if let Some(path) = &truth {
        let json = serde_json::to_string_pretty(&bench.running().with_world(|w| w.truth()))?;
        std::fs::write(path, json)
            .with_context(|| format!("{}: cannot write the truth", path.display()))?;
    }
    writeln!(out, "{}", bench.running().station_config_toml())?;
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
    // Dropped: the bench stops.
    drop(bench);
    Ok(())
}
