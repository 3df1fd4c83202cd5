//! `spinbench run PLAN`: a test plan on a station's devices (or on the
//! virtual bench), set up once ([`crate::run_setup`]) and executed.

use anyhow::{Context, Result};
use spinbench_store::StoreTarget;
use std::io::Write;
use std::path::Path;

/// A text and where it came from (a file's path, or "the plan of run X").
pub(super) struct Source {
    /// The TOML text.
    pub text: String,
    /// Where it came from, for error messages.
    pub label: String,
}

impl Source {
    /// Read a file.
    pub fn file(path: &Path, what: &str) -> Result<Source> {
        Ok(Source {
            text: std::fs::read_to_string(path)
                .with_context(|| format!("{}: cannot read the {what}", path.display()))?,
            label: path.display().to_string(),
        })
    }
}

/// `spinbench run`: the plan and (optional) station config already read.
#[allow(clippy::too_many_arguments)]
pub(super) fn run_plan(
    plan_source: Source,
    station_source: Option<Source>,
    simulate: bool,
    bench_choice: &crate::demo::BenchChoice,
    resume: Option<&Path>,
    data: &Path,
    db: Option<StoreTarget>,
    quiet: bool,
    override_overdue: Option<&str>,
    out: &mut dyn Write,
) -> Result<()> {
    use crate::run_setup::{RunDir, Setup, prepare};
    use crate::station_run::{TerminalOperator, connect_bench, execute, sim_station_toml};
    use spinbench_engine::{AbortFlag, StationConfig, TestPlan};
    use spinbench_sim::station::SimOperator;
    let plan_text = plan_source.text;
    let plan = TestPlan::from_toml(&plan_text).with_context(|| plan_source.label.clone())?;
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
        if let Some(source) = &station_source {
            let own =
                StationConfig::from_toml(&source.text).with_context(|| source.label.clone())?;
            station.arm = own.arm;
            station.g_local_m_s2 = own.g_local_m_s2;
            station.station = own.station;
        }
        let text = sim_station_toml(&bench);
        sim = Some(bench);
        let bench_ref = sim.as_ref().context("virtual bench")?;
        (station, text, Box::new(SimOperator::new(bench_ref, quiet)))
    } else {
        let source = station_source
            .context("--station CONFIG is needed (or --simulate for the virtual bench)")?;
        (
            StationConfig::from_toml(&source.text).with_context(|| source.label.clone())?,
            source.text,
            Box::new(TerminalOperator::default()),
        )
    };
    // The equipment register: no new run while a device is overdue, unless
    // overridden with a reason (kept in the audit log).
    if resumed.is_none() {
        let target = db
            .clone()
            .unwrap_or_else(|| crate::paths::default_store(data));
        let store = spinbench_store::Store::connect(&target)
            .with_context(|| format!("cannot open the store {target}"))?;
        let list = crate::equipment::station_equipment(&store, &station)?;
        if let Some(late) = crate::equipment::overdue(&list) {
            match override_overdue.map(str::trim).filter(|r| !r.is_empty()) {
                None => anyhow::bail!(
                    "{late} overdue for calibration: calibrate it and update the register \
                     (`spinbench equipment set`), or start anyway with --override-overdue REASON"
                ),
                Some(reason) => {
                    let who = std::env::var("USER").unwrap_or_else(|_| "spinbench".into());
                    store.audit(
                        &who,
                        "override overdue calibration",
                        &format!("a run started with {late} overdue: {reason}"),
                    )?;
                    writeln!(
                        out,
                        "warning: {late} overdue for calibration; started anyway: {reason}"
                    )?;
                }
            }
        }
    }
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

/// `spinbench retest RUN`: the run's failed, inconclusive, incomplete and
/// flagged instruments tested again with the same serials, slots and plan
/// (`retest_of` links the new run to RUN), on the station config given or,
/// without one, the config RUN used.
#[allow(clippy::too_many_arguments)]
pub(super) fn retest(
    run_id: &str,
    station_path: Option<&Path>,
    simulate: bool,
    bench_choice: &crate::demo::BenchChoice,
    data: &Path,
    db: Option<StoreTarget>,
    quiet: bool,
    out: &mut dyn Write,
) -> Result<()> {
    let target = db
        .clone()
        .unwrap_or_else(|| crate::paths::default_store(data));
    let (plan, serials, station_config) = {
        let store = spinbench_store::Store::open_read_only(&target)
            .with_context(|| format!("cannot open the store {target} to find run {run_id}"))?;
        crate::retest::retest_plan_from_store(&store, run_id)?
    };
    writeln!(
        out,
        "retesting {} instrument(s) of run {run_id}: {}",
        serials.len(),
        serials.join(", ")
    )?;
    let plan_source = Source {
        text: toml::to_string(&plan).context("the retest plan as TOML")?,
        label: format!("the retest plan of run {run_id}"),
    };
    let station_source = match station_path {
        Some(p) => Some(Source::file(p, "station config")?),
        None => station_config.map(|text| Source {
            text,
            label: format!("the station config run {run_id} used"),
        }),
    };
    run_plan(
        plan_source,
        station_source,
        simulate,
        bench_choice,
        None,
        data,
        db,
        quiet,
        None,
        out,
    )
}
