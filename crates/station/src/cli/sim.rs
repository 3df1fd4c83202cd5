//! `spinbench sim`: a virtual bench behind real pseudo-terminals, its
//! device sections printed for a station config, running until stopped.

use anyhow::{Context, Result};
use std::io::Write;
use std::path::PathBuf;

/// Longest `spinbench sim --for` [s].
const MAX_SIM_FOR_S: f64 = 1e7;

/// `spinbench sim`: start a virtual bench and print how to reach it.
pub(super) fn run_sim(
    config: Option<PathBuf>,
    speed: Option<f64>,
    realism: Option<spinbench_sim::Realism>,
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
            SimConfig::from_toml_with(&text, realism).with_context(|| path.display().to_string())?
        }
        None => realism.unwrap_or_default().config(),
    };
    if let Some(s) = speed {
        sim_config.speed = s;
    }
    sim_config.validate()?;
    if let Some(seconds) = run_for
        && !(seconds.is_finite() && (0.0..=MAX_SIM_FOR_S).contains(&seconds))
    {
        anyhow::bail!(
            "--for {seconds}: expected seconds from 0 to {MAX_SIM_FOR_S} (about 115 days; leave --for out to run until interrupted)"
        );
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
