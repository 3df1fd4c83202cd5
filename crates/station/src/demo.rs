//! `spinbench demo`: the virtual bench started in this process, a complete
//! test run on it through the production drivers, and what was measured
//! beside the simulator's truth.

use crate::run_setup::{RunDir, Setup, prepare};
use crate::station_run::{Finished, RunControl, connect_bench, execute};
use crate::virtual_bench::{BenchArgs, VirtualBench};
use anyhow::{Result, bail};
use serde::Serialize;
use spinbench_analysis::Mount;
use spinbench_engine::{AbortFlag, Outcome, RunState, TestPlan, UnitRecord};
use spinbench_store::StoreTarget;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// One line of the demo's comparison with the truth.
#[derive(Debug, Clone, Serialize)]
pub struct DemoUnit {
    /// Serial number.
    pub serial: String,
    /// Slot (1-based).
    pub slot: usize,
    /// Mounting.
    pub mount: Mount,
    /// Radius found [m].
    pub radius_m: Option<f64>,
    /// The simulator's true radius [m].
    pub true_radius_m: f64,
    /// Drawing radius [m].
    pub drawing_radius_m: f64,
    /// The radius's relative standard uncertainty from its readings [ppm].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius_reading_u_ppm: Option<f64>,
    /// Sensitivity to gravity across the input axis found by a four-position
    /// tumble [µg/g] (absent with two positions).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cross_axis_ug_per_g: Option<f64>,
    /// The simulator's true cross-axis sensitivity [µg/g].
    pub true_cross_axis_ug_per_g: f64,
    /// Temperature coefficients found (a plan with temperatures).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temperature_coefficients: Option<spinbench_analysis::temperature::TemperatureCoefficients>,
    /// The simulator's true temperature coefficients (with temperatures).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub true_temperature_coefficients: Option<TrueTemperatureCoefficients>,
    /// Measured k2 in this mounting [µg/g²].
    pub k2_ug_per_g2: Option<f64>,
    /// Its 95 % interval.
    pub k2_ci95: Option<[f64; 2]>,
    /// Its expanded GUM uncertainty at 95 % (Type A and the station's Type B).
    #[serde(rename = "k2_U95")]
    pub k2_u95: Option<f64>,
    /// K2 of both mountings together (method.md (15)), on the instrument's entries of both mountings.
    pub k2_even_ug_per_g2: Option<f64>,
    /// Its expanded GUM uncertainty at 95 %.
    #[serde(rename = "k2_even_U95")]
    pub k2_even_u95: Option<f64>,
    /// The instrument's K2 in the same per-mounting convention (N flips the sign).
    pub true_k2_ug_per_g2: f64,
    /// The instrument's own K2 (the even, IEEE value; the same in both mountings).
    pub true_instrument_k2_ug_per_g2: f64,
    /// What a perfect per-mounting fit would return here: the instrument's
    /// K2 (sign by mounting) plus the centrifuge's common part, arm stretch
    /// and Koq (method.md (15)).
    pub true_mounting_k2_ug_per_g2: f64,
    /// Measured k1 [Hz/g] in this mounting.
    pub k1_hz_per_g: Option<f64>,
    /// True k1 in this convention.
    pub true_k1_hz_per_g: f64,
    /// The instrument's k2_max [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// Pass, marginal, inconclusive, fail or incomplete.
    pub outcome: Outcome,
    /// What the k2 verdict judged: the quantity, its limit and the rule.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decision: Option<spinbench_engine::plan::Decision>,
}

/// The bench's true temperature coefficients of one instrument.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct TrueTemperatureCoefficients {
    /// Bias [µg/°C].
    pub k0_ug_per_c: f64,
    /// Scale factor [ppm/°C].
    pub k1_ppm_per_c: f64,
    /// K2 [µg/g²/°C].
    pub k2_ug_per_g2_per_c: f64,
}

/// Compare a finished demo run with the simulator's truth; `perfect_k2`
/// gives what a perfect per-mounting fit would return for (slot, mounting)
/// (`None`: the analytic sum of method.md (15)).
pub fn compare_with_truth(
    records: &[UnitRecord],
    truth: &spinbench_sim::Truth,
    perfect_k2: &dyn Fn(usize, Mount) -> Option<f64>,
) -> Vec<DemoUnit> {
    let mut out = Vec::new();
    for r in records {
        let Some(t) = truth.instruments.get(r.slot) else {
            continue;
        };
        for mount in [Mount::P, Mount::N] {
            let mounting = r.analysis.as_ref().and_then(|a| a.fits.get(&mount));
            let fit = mounting.map(|f| &f.fit);
            let joint = r.analysis.as_ref().and_then(|a| a.joint.as_ref());
            if fit.is_none() && !r.radius_m.contains_key(&mount) {
                continue;
            }
            let sign = mount.input_sign();
            out.push(DemoUnit {
                serial: r.serial.clone(),
                slot: r.slot + 1,
                mount,
                radius_m: r.radius_m.get(&mount).copied(),
                true_radius_m: match mount {
                    Mount::P => t.position.radius_p_m,
                    Mount::N => t.position.radius_n_m,
                },
                drawing_radius_m: t.position.drawing_radius_m,
                radius_reading_u_ppm: r.radius_reading_u_ppm.get(&mount).copied(),
                cross_axis_ug_per_g: r.cross_axis_ug_per_g,
                true_cross_axis_ug_per_g: t.vba.cross_axis_ug_per_g,
                temperature_coefficients: r.temperature_coefficients,
                true_temperature_coefficients: r.temperature_coefficients.map(|_| {
                    TrueTemperatureCoefficients {
                        k0_ug_per_c: t.vba.temp_coeff_ug_per_c,
                        k1_ppm_per_c: t.vba.k1_temp_coeff_ppm_per_c,
                        k2_ug_per_g2_per_c: t.vba.k2_temp_coeff_ug_per_g2_per_c,
                    }
                }),
                k2_ug_per_g2: fit.and_then(|f| f.k2_ug_per_g2),
                k2_ci95: fit.and_then(|f| f.ci95.k2_ug_per_g2),
                k2_u95: mounting
                    .and_then(|f| f.uncertainty.as_ref())
                    .and_then(|u| u.k2_ug_per_g2.as_ref())
                    .map(|u| u.u95),
                k2_even_ug_per_g2: joint.map(|j| j.k2_even_ug_per_g2),
                k2_even_u95: joint.and_then(|j| j.k2_even_u95),
                true_k2_ug_per_g2: sign * t.vba.k2_ug_per_g2,
                true_instrument_k2_ug_per_g2: t.instrument_k2_ug_per_g2,
                true_mounting_k2_ug_per_g2: perfect_k2(r.slot, mount).unwrap_or(match mount {
                    Mount::P => t.per_mounting_k2.p_ug_per_g2,
                    Mount::N => t.per_mounting_k2.n_ug_per_g2,
                }),
                k1_hz_per_g: fit.map(|f| f.k1),
                true_k1_hz_per_g: sign * t.vba.k1_hz_per_g,
                k2_max_ug_per_g2: r.k2_max_ug_per_g2,
                outcome: r.outcome,
                decision: r.decision,
            });
        }
    }
    out
}

/// What of the demo's plan the command line chooses.
#[derive(Debug, Clone, Default)]
pub struct DemoPlanChoice {
    /// 2 or 4 tumble positions.
    pub tumble_positions: u8,
    /// Chamber temperatures (none: the room).
    pub temperatures_c: Vec<f64>,
    /// The levels (none: the published levels to 70 g); the plan checks them.
    pub levels_g: Option<Vec<f64>>,
    /// Design the levels for this K2 U95 [µg/g²] (`levels = "auto"`).
    pub target_k2_u95: Option<f64>,
    /// What the reduction does with a level found off the curve.
    pub anomalies: spinbench_analysis::AnomalyRule,
    /// What the k2 limit judges.
    pub decide_on: spinbench_engine::plan::Measurand,
    /// Levels chosen by the data per mounting (the plan's `[sequential]`;
    /// 0: none; absent: [`DEFAULT_SEQUENTIAL_LEVELS`] on the default design).
    pub sequential_levels_per_pass: Option<u32>,
    /// The published plan as it was: its levels, nothing designed or added.
    pub published: bool,
}

/// The demo's default budget of levels chosen by the data per mounting.
pub const DEFAULT_SEQUENTIAL_LEVELS: u32 = 12;

/// The K2 U95 the demo's default plan is designed for [µg/g²]: the shipped
/// check plan's (`packaging/plans/check-70g.toml`), two fifths of its limit.
pub const DEFAULT_TARGET_K2_U95_UG_PER_G2: f64 = 8.0;

impl DemoPlanChoice {
    /// The design target and the sequential budget the demo runs: the
    /// default (no levels, temperatures or `--published` given) is the
    /// check design measured until the verdict is certain.
    fn resolved(&self) -> (Option<f64>, u32) {
        let designed = !self.published && self.levels_g.is_none() && self.temperatures_c.is_empty();
        let target = self
            .target_k2_u95
            .or(designed.then_some(DEFAULT_TARGET_K2_U95_UG_PER_G2));
        let sequential = self.sequential_levels_per_pass.unwrap_or(
            if target.is_some() && self.temperatures_c.is_empty() {
                DEFAULT_SEQUENTIAL_LEVELS
            } else {
                0
            },
        );
        (target, sequential)
    }
}

/// The demo's plan: every slot, ±70 g (both mountings), published levels,
/// a 10-minute warm-up (virtual time is cheap), `tumble_positions` (2 or 4),
/// at the chamber `temperatures_c` (none: the room).
pub fn demo_plan(slots: usize, tumble_positions: u8, temperatures_c: &[f64]) -> TestPlan {
    TestPlan {
        name: "demo: ±70 g, mountings P and N".into(),
        operator: "demo".into(),
        serials: (1..=slots)
            .map(|i| (i.to_string(), format!("SIM-{i:02}")))
            .collect(),
        passes: vec![Mount::P, Mount::N],
        warmup_s: 600.0,
        tumble_positions,
        temperatures_c: temperatures_c.to_vec(),
        ..TestPlan::default()
    }
}

/// The demo's virtual bench: `args`' in virtual time (lockstep:
/// reproducible); with `chamber`, the instruments in a temperature chamber
/// (the config's own `[chamber]`, else the default one), with temperature
/// coefficients of k1 (15 ppm/°C) and K2 (0.05 µg/g²/°C) where the preset
/// has none.
pub fn open_bench(args: &BenchArgs, chamber: bool) -> Result<VirtualBench> {
    let mut config = args.config(Some(0.0))?;
    if chamber {
        config.chamber.get_or_insert_with(Default::default);
        let p = &mut config.instruments;
        if p.k1_temp_coeff_ppm_per_c == 0.0 {
            p.k1_temp_coeff_ppm_per_c = 15.0;
        }
        if p.k2_temp_coeff_ug_per_g2_per_c == 0.0 {
            p.k2_temp_coeff_ug_per_g2_per_c = 0.05;
        }
    }
    VirtualBench::open_config(config, false)
}

/// `spinbench demo`.
pub fn demo(
    bench: &BenchArgs,
    plan_choice: DemoPlanChoice,
    json: bool,
    data_dir: &Path,
    db: Option<&StoreTarget>,
    out: &mut dyn Write,
) -> Result<()> {
    let wall = Instant::now();
    let virtual_bench = open_bench(bench, !plan_choice.temperatures_c.is_empty())?;
    let station = virtual_bench.station()?;
    let sim = virtual_bench.running();
    let seed = sim.with_world(|w| w.config().seed);
    let realism = sim.with_world(|w| w.config().realism);
    let mut plan = demo_plan(
        station.slots(),
        plan_choice.tumble_positions,
        &plan_choice.temperatures_c,
    );
    plan.anomalies = plan_choice.anomalies;
    plan.limits.decide_on = plan_choice.decide_on;
    let (target_k2_u95, sequential) = plan_choice.resolved();
    if sequential > 0 {
        plan.sequential = Some(spinbench_engine::plan::SequentialConfig {
            max_levels_per_pass: sequential,
        });
    }
    if let Some(levels) = plan_choice.levels_g {
        plan.range_g = levels.iter().copied().fold(0.0, f64::max);
        plan.levels = Some(spinbench_engine::plan::LevelTable::List(levels));
    }
    if let Some(target) = target_k2_u95 {
        plan.set_target(target)?;
    }
    let plan_order = spinbench_analysis::ModelOrder::from_degree(plan.order).unwrap_or_default();
    let arm_radius_m = sim.with_world(|w| w.config().centrifuge.arm_radius_m);
    if !json {
        writeln!(
            out,
            "spinbench demo: a virtual bench (seed {seed}, realism {realism}) with {} instruments on {} counter modules, a {arm_radius_m} m centrifuge,\n\
             ±{} g in mountings P and N, in virtual time. Operator prompts are answered by the simulator.\n",
            station.slots(),
            station.fmu.len(),
            plan.range_g
        )?;
        out.flush()?;
    }
    let prepared = prepare(Setup {
        station_toml: virtual_bench.station_toml().to_string(),
        station,
        plan,
        plan_text: None,
        dir: RunDir::create(data_dir)?,
        store: db.cloned(),
    })?;
    // The plan as it runs (designed when `auto`): its levels and the way
    // down, as its fits see them, and its prediction.
    let levels = prepared.plan.level_sequence();
    let prediction = prepared.plan.prediction.clone();
    let decision_warning = prepared.plan.decision_warning();
    let bench = connect_bench(&prepared.station, Some(&prepared.dir.raw_dir()))?;
    let operator = virtual_bench.operator(json);
    let abort = AbortFlag::new();
    crate::signals::abort_on_termination_signals(abort.clone())?;
    let finished = execute(
        prepared,
        bench,
        operator,
        json,
        RunControl::abort_only(abort),
    )?;
    let truth = sim.with_world(|w| w.truth());
    let achieved = spinbench_engine::planning::achieved(&finished.summary.records);
    let perfect = |slot: usize, mount: Mount| {
        sim.with_world(|w| w.perfect_fit_k2(slot, mount, &levels, plan_order))
    };
    let units = compare_with_truth(&finished.summary.records, &truth, &perfect);
    std::fs::write(
        finished.dir.join("truth.json"),
        serde_json::to_string_pretty(&truth)?,
    )?;
    let wall_s = wall.elapsed().as_secs_f64();
    if json {
        let doc = serde_json::json!({
            "run": {
                "dir": finished.dir,
                "state": finished.summary.state,
                "reason": finished.summary.reason,
                "seed": seed,
                "realism": realism,
                "virtual_duration_s": finished.summary.duration_s,
                "wall_duration_s": wall_s,
                "prediction": prediction,
                "decision_warning": decision_warning,
                "achieved": achieved,
            },
            "units": units,
        });
        serde_json::to_writer_pretty(&mut *out, &doc)?;
        writeln!(out)?;
    } else {
        render_demo(out, &finished, &units, wall_s)?;
        if let Some(p) = &prediction {
            writeln!(out, "{}", prediction_line(p, &achieved))?;
            if let Some(w) = &decision_warning {
                writeln!(out, "Warning: {w}.")?;
            }
        }
    }
    if finished.summary.state != RunState::Completed {
        bail!(
            "the demo run did not complete: {}",
            finished.summary.reason.unwrap_or_default()
        );
    }
    Ok(())
}

fn render_demo(
    out: &mut dyn Write,
    finished: &Finished,
    units: &[DemoUnit],
    wall_s: f64,
) -> Result<()> {
    let s = &finished.summary;
    writeln!(
        out,
        "\nRun {:?} in {:.0} s of virtual time ({:.1} h), {:.1} s of wall-clock time.\n",
        s.state,
        s.duration_s,
        s.duration_s / 3600.0,
        wall_s
    )?;
    writeln!(
        out,
        "{:<7} {:>4} {:>5} | {:>10} {:>10} {:>9} | {:>22} {:>9} {:>6} | {:>8} {:>18} {:>8} {:>12}",
        "serial",
        "slot",
        "mount",
        "R [mm]",
        "true R",
        "R0 − true",
        "k2 ± U95 [µg/g²]",
        "true k2",
        "in U95",
        "k2_max",
        "K2 ± U95 [µg/g²]",
        "true K2",
        "outcome"
    )?;
    let (mut covered, mut total) = (0, 0);
    let (mut k2_covered, mut k2_total) = (0, 0);
    let mut instruments_seen = std::collections::BTreeSet::new();
    for u in units {
        let r = u.radius_m.map_or("—".into(), |r| format!("{:.3}", r * 1e3));
        // One "95 %" everywhere: the budget's U95, the value the
        // verdict, the live board and the reports use; the fit's Type A
        // interval only where a mounting has no budget. Its truth is what
        // this mounting's k2 is on this centrifuge: the instrument's K2 with
        // the centrifuge's own term (method (15)), not K2 alone.
        let half = u.k2_u95.or(u.k2_ci95.map(|[lo, hi]| (hi - lo) / 2.0));
        let k2 = match (u.k2_ug_per_g2, half) {
            (Some(k), Some(h)) => format!("{k:+.3} ± {h:.3}"),
            _ => "—".into(),
        };
        let inside = u
            .k2_ug_per_g2
            .zip(half)
            .map(|(k, h)| (k - u.true_mounting_k2_ug_per_g2).abs() <= h);
        if let Some(i) = inside {
            total += 1;
            covered += usize::from(i);
        }
        if instruments_seen.insert(u.slot)
            && let (Some(k), Some(h)) = (u.k2_even_ug_per_g2, u.k2_even_u95)
        {
            k2_total += 1;
            k2_covered += usize::from((k - u.true_instrument_k2_ug_per_g2).abs() <= h);
        }
        writeln!(
            out,
            "{:<7} {:>4} {:>5} | {:>10} {:>10.3} {:>+9.3} | {:>22} {:>+9.3} {:>6} | {:>8} {:>18} {:>+8.3} {:>12}",
            u.serial,
            u.slot,
            u.mount.to_string(),
            r,
            u.true_radius_m * 1e3,
            (u.drawing_radius_m - u.true_radius_m) * 1e3,
            k2,
            u.true_mounting_k2_ug_per_g2,
            inside.map_or("—", |i| if i { "yes" } else { "NO" }),
            u.k2_max_ug_per_g2.map_or("—".into(), |k| format!("{k:.3}")),
            match (u.k2_even_ug_per_g2, u.k2_even_u95) {
                (Some(k), Some(u)) => format!("{k:+.3} ± {u:.3}"),
                (Some(k), None) => format!("{k:+.3}"),
                _ => "—".into(),
            },
            u.true_instrument_k2_ug_per_g2,
            u.outcome.as_str(),
        )?;
    }
    let radius_err: Vec<f64> = units
        .iter()
        .filter_map(|u| u.radius_m.map(|r| (r - u.true_radius_m).abs() * 1e6))
        .collect();
    let r0_err: Vec<f64> = units
        .iter()
        .map(|u| (u.drawing_radius_m - u.true_radius_m).abs() * 1e6)
        .collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    writeln!(
        out,
        "\nk2 per mounting (the instrument's K2 with this centrifuge's own term, method (15)): \
         the true value lies within the reported U95 for {covered} of {total} instrument-mountings.\n\
         K2 (the instrument's own): the true value lies within the reported U95 for {k2_covered} of {k2_total} instruments.\n\
         Radius: found within {:.1} µm of the truth on average; the drawing radius R0 is off by {:.1} µm on average.",
        mean(&radius_err),
        mean(&r0_err)
    )?;
    writeln!(out, "{}", verdict_line(units))?;
    writeln!(
        out,
        "\nResults: {}/results.json (per-instrument records), journal.jsonl (every event), truth.json (the simulator's truth);\n\
         the run is also in the store {}/spinbench.db (`spinbench runs list --db …`).",
        finished.dir.display(),
        finished
            .dir
            .parent()
            .and_then(Path::parent)
            .map_or_else(|| ".".into(), |p| p.display().to_string())
    )?;
    Ok(())
}

/// How many instruments got each outcome, and what was judged: one line.
pub fn verdict_line(units: &[DemoUnit]) -> String {
    let mut seen = std::collections::BTreeSet::new();
    let mut counts: std::collections::BTreeMap<&'static str, usize> = Default::default();
    let mut decision = None;
    for u in units {
        if seen.insert(u.slot) {
            *counts.entry(u.outcome.as_str()).or_default() += 1;
            decision = decision.or(u.decision);
        }
    }
    let tally = Outcome::ALL
        .iter()
        .filter_map(|o| {
            counts
                .get(o.as_str())
                .map(|n| format!("{n} {}", o.as_str()))
        })
        .collect::<Vec<_>>()
        .join(", ");
    match decision {
        Some(d) => format!(
            "Verdicts of {} instruments on {} against {} µg/g² ({} rule): {tally}.",
            seen.len(),
            d.measurand.name(),
            d.limit_ug_per_g2,
            d.rule.name()
        ),
        None => format!("Verdicts of {} instruments: {tally}.", seen.len()),
    }
}

/// The plan's prediction beside what the run achieved, one line.
pub fn prediction_line(
    p: &spinbench_engine::plan::PlanPrediction,
    a: &spinbench_engine::planning::Achieved,
) -> String {
    let shown =
        |v: Option<f64>, digits: usize| v.map_or_else(|| "—".into(), |v| format!("{v:.digits$}"));
    let range = p
        .k2_u95_run_range_ug_per_g2
        .map_or_else(String::new, |[low, high]| {
            format!(
                " (the run's median with {:.0} % probability in {low:.3}–{high:.3})",
                100.0 * spinbench_analysis::design::RUN_RANGE_PROBABILITY
            )
        });
    let sequential = p
        .sequential_centrifuge_time_max_s
        .map_or_else(String::new, |t| {
            format!(" plus at most {t:.0} s of levels chosen by the data")
        });
    format!(
        "Plan: predicted K2 U95 {:.3} µg/g²{range} (achieved median {}), centrifuge time {:.0} s{sequential} (achieved {} s); the published plan's prediction {} µg/g² in {} s; {}.",
        p.k2_u95_ug_per_g2,
        shown(a.k2_u95_ug_per_g2, 3),
        p.centrifuge_time_s,
        shown(a.centrifuge_time_s, 0),
        shown(p.published_k2_u95_ug_per_g2, 3),
        shown(p.published_centrifuge_time_s, 0),
        if p.model_runs == 0 {
            "the station's model: the defaults of a station with no history (the typical bench's); it learns from each run".to_string()
        } else {
            format!("the station's model learned from {} run(s)", p.model_runs)
        }
    )
}
