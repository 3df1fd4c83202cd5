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

/// Station config `own` with its device sections replaced by `devices`'s
/// (those `devices` lacks are removed), everything else kept.
fn with_devices_of(own: &str, devices: &str) -> Result<String> {
    let mut table: toml::Table = own.parse().context("the station config")?;
    let devices: toml::Table = devices
        .parse()
        .context("the virtual bench's station config")?;
    for key in crate::run_setup::DEVICE_SECTIONS
        .iter()
        .copied()
        .chain(["simulated"])
    {
        match devices.get(key) {
            Some(v) => table.insert(key.to_string(), v.clone()),
            None => table.remove(key),
        };
    }
    toml::to_string(&table).context("the station config with the bench's devices")
}

/// `spinbench run`: the plan and (optional) station config already read.
#[allow(clippy::too_many_arguments)]
pub(super) fn run_plan(
    plan_source: Source,
    station_source: Option<Source>,
    simulate: bool,
    bench_args: &crate::virtual_bench::BenchArgs,
    resume: Option<&Path>,
    data: &Path,
    db: Option<StoreTarget>,
    quiet: bool,
    override_overdue: Option<&str>,
    out: &mut dyn Write,
) -> Result<()> {
    use crate::run_setup::{RunDir, Setup, prepare};
    use crate::station_run::{TerminalOperator, connect_bench, execute};
    use crate::virtual_bench::VirtualBench;
    use spinbench_engine::{AbortFlag, StationConfig, TestPlan};
    let plan_text = plan_source.text;
    let plan = TestPlan::from_toml(&plan_text).with_context(|| plan_source.label.clone())?;
    // SIGINT, SIGTERM, SIGHUP: the engine stops the table, switches
    // everything off and records the signal.
    let abort = AbortFlag::new();
    crate::signals::abort_on_termination_signals(abort.clone())?;
    // A resumed run: only with its own plan; it keeps writing to its own store.
    let resumed = resume
        .map(|d| RunDir::resume(d, &plan).with_context(|| format!("--resume {}", d.display())))
        .transpose()?;
    let virtual_bench;
    let (station, station_toml, operator): (
        StationConfig,
        String,
        Box<dyn spinbench_engine::Operator + '_>,
    ) = if simulate {
        // The station's virtual bench, in virtual time (reproducible).
        let bench = VirtualBench::open(bench_args, Some(0.0), false)?;
        let mut station = bench.station()?;
        let mut text = bench.station_toml().to_string();
        if let Some(source) = &station_source {
            // Only the device sections are the bench's:
            // the rest of the station's own config (its temperature limit,
            // Type B inputs, arm, name) stays as written.
            StationConfig::from_toml(&source.text).with_context(|| source.label.clone())?;
            text = with_devices_of(&source.text, &text).with_context(|| source.label.clone())?;
            station = StationConfig::from_toml(&text)
                .with_context(|| format!("{} with the virtual bench's devices", source.label))?;
        }
        virtual_bench = bench;
        (station, text, virtual_bench.operator(quiet))
    } else {
        let source = station_source
            .context("--station CONFIG is needed (or --simulate for the virtual bench)")?;
        (
            StationConfig::from_toml(&source.text).with_context(|| source.label.clone())?,
            source.text,
            Box::new(TerminalOperator::default()),
        )
    };
    // A resume only on the station and arm it was recorded with, before
    // anything else is asked of it.
    if let Some(dir) = &resumed {
        dir.check_same_station(&station_toml)
            .with_context(|| format!("--resume {}", dir.path().display()))?;
    }
    // The equipment register: no run moves the table (a new one, a retest
    // or a resume) while a device is overdue, unless overridden with a
    // reason (kept in the audit log).
    {
        let target = db
            .clone()
            .unwrap_or_else(|| crate::paths::default_store(data));
        let store = spinbench_store::Store::connect(&target)
            .with_context(|| format!("cannot open the store {target}"))?;
        // The name is this station's identity's, or the run is refused (a
        // run under a name another station holds would join its history).
        std::fs::create_dir_all(data)
            .with_context(|| format!("{}: cannot make the data folder", data.display()))?;
        let identity = crate::paths::station_identity(data)?;
        if let Some(other) = store.look_alike_station(&station.station)? {
            anyhow::bail!(
                "the name '{}' looks like the fleet's station '{}': the two would read as one station on every page; \
                 give this station a name that is plainly its own (`station` in its station.toml)",
                spinbench_engine::bounds::shown(&station.station),
                spinbench_engine::bounds::shown(&other)
            );
        }
        if let Some(holder) = store.name_held_by_another(&station.station, &identity)? {
            anyhow::bail!(
                "another station holds the name '{}' (identity {}, at {}): a run under it would join that \
                 station's history, register and yield. Give this station its own name (`station` in its \
                 station.toml); if that station is gone for good, an admin retires it on the Fleet page first",
                station.station,
                holder.instance,
                holder.address.as_deref().unwrap_or("no address")
            );
        }
        if store.take_over_retired_name(&station.station, &identity)? {
            writeln!(
                out,
                "warning: the name '{}' was a retired station's; its equipment register is kept under its old identity, and this station's register starts empty",
                station.station
            )?;
        }
        if resumed.is_none() {
            // Runs this station's processes left behind (left-over events
            // written, crashed runs marked interrupted).
            for line in crate::recovery::recover(data, &station.station, &store).lines() {
                writeln!(out, "{line}")?;
            }
            crate::retest::check_retest_of(&store, &plan)
                .with_context(|| plan_source.label.clone())?;
        }
        let what = match &resumed {
            Some(dir) => format!("run {} resumed", dir.id()),
            None => "a run started".to_string(),
        };
        let list = crate::equipment::station_equipment(&store, &station)?;
        // The one admission gate; at the station's own
        // terminal whoever starts a run may override, with a reason.
        use crate::equipment::{Admission, Refusal};
        match crate::equipment::admit(
            &list,
            station.equipment.require_registered,
            override_overdue,
            true,
        ) {
            Ok(Admission::Clear) => {}
            Ok(admitted @ Admission::Overridden { .. }) => {
                let who = std::env::var("USER").unwrap_or_else(|_| "spinbench".into());
                let detail = admitted.audit_detail(&what).unwrap_or_default();
                store.audit(&who, crate::equipment::OVERRIDE_ACTION, &detail)?;
                if let Admission::Overridden { devices, reason } = &admitted {
                    writeln!(
                        out,
                        "warning: {devices}: calibration not cleared; started anyway: {reason}"
                    )?;
                }
            }
            Err(Refusal::BadReason { why }) => {
                anyhow::bail!("--override-overdue: {why}")
            }
            Err(refused) => anyhow::bail!(
                "{refused}; calibrate it and update the register \
                 (`spinbench equipment set`), or start anyway with --override-overdue REASON"
            ),
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
    // Whether the plan can decide, said before anything moves.
    if let Some(w) = prepared.plan.decision_warning() {
        writeln!(out, "warning: {w}")?;
    }
    let bench = match connect_bench(&prepared.station, Some(&prepared.dir.raw_dir())) {
        Ok(bench) => bench,
        Err(e) => {
            // Nothing ran: leave no run directory behind.
            prepared.dir.discard();
            return Err(e);
        }
    };
    let finished = execute(
        prepared,
        bench,
        operator,
        quiet,
        crate::station_run::RunControl::abort_only(abort),
    )?;
    crate::station_run::render_records(out, &finished)?;
    let safe = crate::signals::wait_for_unconfirmed_stops();
    if !finished.summary.safe_devices_confirmed {
        if !safe.all_confirmed {
            anyhow::bail!(
                "the run ended {:?} and its safe state is still not confirmed: {}",
                finished.summary.state,
                finished.summary.reason.unwrap_or_default()
            );
        }
        // Confirmed by the keeper after the run's end: said as it happened,
        // not as the run's end found it.
        anyhow::bail!(
            "the run ended {:?}: {}; its safe state was confirmed {:.0} s after the run's end, by trying again",
            finished.summary.state,
            finished.summary.reason.unwrap_or_default(),
            safe.waited_s
        );
    }
    if finished.summary.state != spinbench_engine::RunState::Completed {
        anyhow::bail!(
            "the run ended {:?}: {}",
            finished.summary.state,
            finished.summary.reason.unwrap_or_default()
        );
    }
    Ok(())
}

/// `spinbench retest RUN`: the run's inconclusive, incomplete and flagged
/// instruments (and, chosen, its fails) tested again with the same
/// serials, slots and plan (`retest_of` links the new run to RUN), on the
/// station config given or, without one, the config RUN used.
#[allow(clippy::too_many_arguments)] // each is one of `retest`'s options
pub(super) fn retest(
    run_id: &str,
    choice: spinbench_engine::retest::RetestChoice,
    station_path: Option<&Path>,
    simulate: bool,
    bench_args: &crate::virtual_bench::BenchArgs,
    data: &Path,
    db: Option<StoreTarget>,
    quiet: bool,
    out: &mut dyn Write,
) -> Result<()> {
    let target = db
        .clone()
        .unwrap_or_else(|| crate::paths::default_store(data));
    let (run_id, retest) = {
        let store = spinbench_store::Store::open_read_only(&target)
            .with_context(|| format!("cannot open the store {target} to find run {run_id}"))?;
        // A run id or a label (`2026-11-24 · station 1 · #7`).
        let run_id = store.id_of_label(run_id)?;
        let retest = crate::retest::retest_plan_from_store(&store, &run_id, choice)?;
        (run_id, retest)
    };
    let crate::retest::Retest {
        plan,
        serials,
        station_config,
        advice,
    } = retest;
    writeln!(
        out,
        "retesting {} instrument(s) of run {run_id}: {}",
        serials.len(),
        serials.join(", ")
    )?;
    for a in &advice {
        writeln!(out, "  {}", a.text())?;
    }
    if let Some(sequential) = plan.sequential {
        writeln!(
            out,
            "  measured until the verdict is certain: up to {} level(s) per mounting chosen by the data",
            sequential.max_levels_per_pass
        )?;
    }
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
        bench_args,
        None,
        data,
        db,
        quiet,
        None,
        out,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use spinbench_engine::StationConfig;

    fn devices(address: &str, extra: &str) -> String {
        let transport = format!("transport = {{ kind = \"tcp\", address = \"{address}\" }}");
        format!(
            "station = \"{address}\"\n[arm]\nradius_m = 0.8\nmax_g = 100\n\
             [power]\ninstrument_supply = \"rails\"\n{extra}\
             [centrifuge]\nname = \"t\"\nmax_rate_deg_s = 2400\n{transport}\ndialect = {{ kind = \"acutrol\" }}\n\
             [[fmu]]\nname = \"f\"\n{transport}\n\
             [[power_supply]]\nname = \"rails\"\nchannels = 2\n{transport}\n"
        )
    }

    #[test]
    fn the_bench_replaces_only_the_device_sections() {
        // The station's own temperature limit (and name,
        // arm, Type B inputs) stay; the devices are the bench's.
        let own = devices("10.0.0.5:1", "[temperature]\ninstrument_max_c = 40\n")
            .replace("radius_m = 0.8", "radius_m = 0.75");
        let bench = devices("127.0.0.1:4000", "");
        let merged = StationConfig::from_toml(&with_devices_of(&own, &bench).expect("merged"))
            .expect("valid");
        assert_eq!(merged.temperature.instrument_max_c, Some(40.0));
        assert_eq!(merged.arm.radius_m, 0.75);
        assert_eq!(merged.station, "10.0.0.5:1");
        let text = with_devices_of(&own, &bench).expect("merged");
        // The station's own address is left only in its name.
        assert_eq!(text.matches("127.0.0.1:4000").count(), 3, "{text}");
        assert_eq!(text.matches("10.0.0.5:1").count(), 1, "{text}");
    }
}
