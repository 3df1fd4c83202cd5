//! `spinbench run PLAN`: a test plan on a station's devices (or on the
//! virtual bench), set up once ([`crate::run_setup`]) and executed.

use anyhow::{Context, Result};
use spinbench_store::StoreTarget;
use std::io::Write;
use std::path::Path;

/// `spinbench run`.
#[allow(clippy::too_many_arguments)]
pub(super) fn run_plan(
    plan_path: &Path,
    station_path: Option<&Path>,
    simulate: bool,
    bench_choice: &crate::demo::BenchChoice,
    resume: Option<&Path>,
    data: &Path,
    db: Option<StoreTarget>,
    quiet: bool,
    out: &mut dyn Write,
) -> Result<()> {
    use crate::run_setup::{RunDir, Setup, prepare};
    use crate::station_run::{TerminalOperator, connect_bench, execute, sim_station_toml};
    use spinbench_engine::{AbortFlag, StationConfig, TestPlan};
    use spinbench_sim::station::SimOperator;
    let plan_text = std::fs::read_to_string(plan_path)
        .with_context(|| format!("{}: cannot read the plan", plan_path.display()))?;
    let plan = TestPlan::from_toml(&plan_text).with_context(|| plan_path.display().to_string())?;
    // SIGINT, SIGTERM, SIGHUP: the engine stops the table, switches
    // everything off and records the signal.
    let abort = AbortFlag::new();
    crate::signals::abort_on_termination_signals(abort.clone())?;
    // A resumed run: only with its own plan; it keeps writing to its own store.
    let resumed = resume.map(|d| RunDir::resume(d, &plan)).transpose()?;
    let sim;
    let (station, station_toml, operator): (
        StationConfig,
        String,
        Box<dyn spinbench_engine::Operator + '_>,
    ) = if simulate {
        let (bench, mut station) = crate::demo::start_sim(bench_choice)?;
        if let Some(p) = station_path {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("{}: cannot read the station config", p.display()))?;
            let own = StationConfig::from_toml(&text).with_context(|| p.display().to_string())?;
            station.arm = own.arm;
            station.g_local_m_s2 = own.g_local_m_s2;
            station.station = own.station;
        }
        let text = sim_station_toml(&bench);
        sim = Some(bench);
        let bench_ref = sim.as_ref().context("virtual bench")?;
        (station, text, Box::new(SimOperator::new(bench_ref, quiet)))
    } else {
        let p = station_path
            .context("--station CONFIG is needed (or --simulate for the virtual bench)")?;
        let text = std::fs::read_to_string(p)
            .with_context(|| format!("{}: cannot read the station config", p.display()))?;
        (
            StationConfig::from_toml(&text).with_context(|| p.display().to_string())?,
            text,
            Box::new(TerminalOperator::default()),
        )
    };
    let dir = match resumed {
        Some(dir) => dir,
        None => RunDir::create(data)?,
    };
    // Refuse a plan that cannot run before anything is switched on.
    let prepared = prepare(Setup {
        station,
        station_toml,
        plan,
        plan_text: Some(plan_text),
        dir,
        store: db,
    })?;
    let bench = connect_bench(&prepared.station, Some(&prepared.dir.raw_dir()))?;
    let finished = execute(
        prepared,
        bench,
        operator,
        quiet,
        crate::station_run::RunControl::abort_only(abort),
    )?;
    crate::station_run::render_records(out, &finished)?;
    crate::signals::wait_for_unconfirmed_stops();
    if finished.summary.state != spinbench_engine::RunState::Completed {
        anyhow::bail!(
            "the run ended {:?}: {}",
            finished.summary.state,
            finished.summary.reason.unwrap_or_default()
        );
    }
    Ok(())
}
