//! `spinbench plan design`: the plan of least predicted centrifuge time for
//! a K2 U95 target, from the station's model of its own runs
//! ([`crate::station_model`]), printed beside the published plan's
//! prediction. Nothing moves.

use anyhow::{Context, Result, bail};
use spinbench_engine::plan::TestPlan;
use spinbench_store::StoreTarget;
use std::io::Write;
use std::path::Path;

/// What `plan design` was asked.
pub struct DesignArgs<'a> {
    /// The target [µg/g²] (else the plan's).
    pub target_k2_u95: Option<f64>,
    /// A plan whose range, mountings and hysteresis limit the design keeps.
    pub plan: Option<&'a Path>,
    /// The station config whose runs the model learns from.
    pub station: Option<&'a Path>,
    /// Newest completed runs to learn from.
    pub runs: usize,
    /// The store.
    pub db: &'a StoreTarget,
    /// One JSON document.
    pub json: bool,
}

/// The station the model is learned for: the config's, else the newest
/// completed run's in the store, else the default name.
fn station_name(args: &DesignArgs) -> Result<String> {
    if let Some(path) = args.station {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read the station config", path.display()))?;
        let config = spinbench_engine::StationConfig::from_toml(&text)
            .with_context(|| path.display().to_string())?;
        return Ok(config.station);
    }
    let newest = match args.db {
        StoreTarget::File(p) if !p.exists() => None,
        db => spinbench_store::Store::open_read_only(db)
            .ok()
            .and_then(|s| s.runs().ok())
            .and_then(|runs| {
                runs.into_iter()
                    .find(|r| r.state == spinbench_store::StoredState::Completed)
            })
            .map(|r| r.station),
    };
    Ok(newest.unwrap_or_else(|| "spinbench".into()))
}

/// `spinbench plan design`.
pub fn design(args: DesignArgs, out: &mut dyn Write) -> Result<()> {
    let mut plan = match args.plan {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("{}: cannot read the plan", path.display()))?;
            TestPlan::from_toml(&text).with_context(|| path.display().to_string())?
        }
        None => TestPlan {
            passes: vec![spinbench_analysis::Mount::P, spinbench_analysis::Mount::N],
            ..TestPlan::default()
        },
    };
    let Some(target) = args.target_k2_u95.or(plan.target_k2_u95_ug_per_g2) else {
        bail!("no target: give --target-k2-u95 (µg/g²), or a --plan with target_k2_u95_ug_per_g2");
    };
    plan.set_target(target)?;
    let station = station_name(&args)?;
    let learned = crate::station_model::learn(args.db, &station, args.runs);
    let designed = plan.designed(&learned.model)?;
    let prediction = designed
        .prediction
        .clone()
        .context("the design gave no prediction")?;
    if args.json {
        let doc = serde_json::json!({
            "station": station,
            "model_source": learned.source,
            "model": learned.model,
            "levels_g": designed.level_table(),
            "down_levels_g": designed.down_levels,
            "dwell_s": designed.dwell.seconds,
            "prediction": prediction,
        });
        serde_json::to_writer_pretty(&mut *out, &doc)?;
        writeln!(out)?;
        return Ok(());
    }
    let m = &learned.model;
    writeln!(out, "station '{station}': model {}", learned.source)?;
    writeln!(
        out,
        "  noise (median instrument; {}): white {:.1} µg at 1 s at the levels ({} at rest), flicker {:.1} µg, random walk {:.3} µg²/s; a level's readings up and down differ beyond it by {:.1} µg\n  table: settle {:.1} s + {:.2} s/g per level step\n  between-level scatter of K2's half-difference (model inadequacy): {:.0} µg",
        if m.noise.at_rest_series > 0 {
            format!(
                "Allan deviation of {} instrument-runs' one-second values at rest",
                m.noise.at_rest_series
            )
        } else {
            "no values at rest: the dwells' scatter".to_string()
        },
        m.noise.white_ug,
        m.noise
            .white_at_rest_ug
            .map_or_else(|| "—".to_string(), |w| format!("{w:.1} µg")),
        m.noise.flicker_ug,
        m.noise.random_walk_ug2_per_s,
        m.noise.level_floor_ug,
        m.settle_s,
        m.settle_s_per_g,
        m.between_level_ug
    )?;
    let levels = designed.level_table();
    let down = designed.down_levels.clone().unwrap_or_default();
    writeln!(
        out,
        "\ndesigned for K2 U95 ≤ {:.3} µg/g²: {} levels 0–{} g, {} read again on the way down, {} s dwell",
        prediction.target_k2_u95_ug_per_g2.unwrap_or(f64::NAN),
        levels.len(),
        designed.range_g,
        down.len(),
        designed.dwell.seconds
    )?;
    writeln!(
        out,
        "{:<22} {:>18} {:>22}",
        "", "predicted K2 U95", "centrifuge time"
    )?;
    writeln!(
        out,
        "{:<22} {:>12.3} µg/g² {:>18.0} s",
        "designed plan", prediction.k2_u95_ug_per_g2, prediction.centrifuge_time_s
    )?;
    if let Some([low, high]) = prediction.k2_u95_run_range_ug_per_g2 {
        writeln!(
            out,
            "{:<22} {:>12} µg/g²   a run's median K2 U95 with {:.0} % probability (its instruments' anomalies differ)",
            "",
            format!("{low:.3}–{high:.3}"),
            100.0 * spinbench_analysis::design::RUN_RANGE_PROBABILITY,
        )?;
    }
    match (
        prediction.published_k2_u95_ug_per_g2,
        prediction.published_centrifuge_time_s,
    ) {
        (Some(u), Some(t)) => {
            writeln!(
                out,
                "{:<22} {:>12.3} µg/g² {:>18.0} s",
                "published plan", u, t
            )?;
            writeln!(
                out,
                "time ratio (designed / published): {:.2}",
                prediction.centrifuge_time_s / t
            )?;
        }
        _ => writeln!(
            out,
            "published plan: too few levels to ±{} g to fit the cubic",
            designed.range_g
        )?,
    }
    let list = |v: &[f64]| {
        v.iter()
            .map(|g| format!("{g}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    writeln!(
        out,
        "\nin a plan (or levels = \"auto\" with target_k2_u95_ug_per_g2, designed when the run starts):\nlevels = [{}]\ndown_levels = [{}]\n[dwell]\nseconds = {}",
        list(&levels),
        list(&down),
        designed.dwell.seconds
    )?;
    Ok(())
}
