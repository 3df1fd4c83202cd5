//! Test duration and k2 uncertainty: this station's stability detection with
//! adaptive dwell, against the published practice (a fixed settle, then a
//! fixed 10-s dwell), on the same virtual bench (seed) and the default
//! level table (0–70 g up and down, mounting P, 12 instruments), on the
//! bench's `typical` realism (SPINBENCH_BENCH_REALISM = ideal, typical or
//! harsh chooses another). Prints `bench: <name> = <value> <unit>` lines.
//!
//! Run: `cargo bench -p spinbench-engine --bench dwell`

use spinbench_analysis::Mount;
use spinbench_engine::plan::{DwellConfig, StabilityConfig};
use spinbench_engine::{Executor, RunOptions, RunState, StationConfig, TestPlan};
use spinbench_sim::serve::{RunningBench, ServeOptions};
use spinbench_sim::station::{SimOperator, station_toml};
use spinbench_sim::{Realism, SimConfig};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// Returns (virtual seconds, mean k2 95 % half-width [µg/g²], wall seconds).
fn run(
    realism: Realism,
    stability: StabilityConfig,
    dwell: DwellConfig,
    range_g: f64,
) -> (f64, f64, f64) {
    let wall = Instant::now();
    let bench = RunningBench::start(
        SimConfig {
            seed: 7,
            speed: 0.0,
            ..realism.config()
        },
        ServeOptions::default(),
    )
    .expect("bench");
    let text = station_toml(&bench, "");
    let station = StationConfig::from_toml(&text).expect("station");
    let serials = (1..=12)
        .map(|i| format!("{i} = \"S{i}\""))
        .collect::<Vec<_>>()
        .join("\n");
    let mut plan = TestPlan::from_toml(&format!(
        "passes = [\"P\"]\nwarmup_s = 300\nrange_g = {range_g}\n[serials]\n{serials}"
    ))
    .expect("plan");
    plan.stability = stability;
    plan.dwell = dwell;
    let compiled = plan.compile(&station).expect("compile");
    let devices = station.connect().expect("connect");
    let options = RunOptions {
        run_id: "bench".into(),
        abort: spinbench_engine::AbortFlag::new(),
        pause: Arc::new(AtomicBool::new(false)),
        module_silence: Duration::from_secs(5),
        station_config_toml: String::new(),
        sink_hold_limit: Duration::from_secs(600),
    };
    let summary = Executor::new(
        &station,
        compiled,
        devices,
        Box::new(SimOperator::new(&bench, true)),
        options,
    )
    .run();
    assert_eq!(summary.state, RunState::Completed, "{:?}", summary.reason);
    let widths: Vec<f64> = summary
        .records
        .iter()
        .filter_map(|r| {
            r.analysis
                .as_ref()?
                .fits
                .get(&Mount::P)?
                .fit
                .ci95
                .k2_ug_per_g2
        })
        .map(|[lo, hi]| (hi - lo) / 2.0)
        .collect();
    bench.shutdown();
    (
        summary.duration_s,
        widths.iter().sum::<f64>() / widths.len().max(1) as f64,
        wall.elapsed().as_secs_f64(),
    )
}

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let range = if measuring { 70.0 } else { 25.0 };
    let realism: Realism = std::env::var("SPINBENCH_BENCH_REALISM")
        .unwrap_or_else(|_| "typical".into())
        .parse()
        .expect("SPINBENCH_BENCH_REALISM: ideal, typical or harsh");
    // The published practice: wait a fixed 30 s after each rate command, then 10 one-second values.
    let published = StabilityConfig {
        rate_tolerance_ppm: 10_000.0,
        hold_s: 30,
        drift_limit_ug_per_s: 1e6,
        ..StabilityConfig::default()
    };
    let fixed = DwellConfig {
        seconds: 10,
        ..DwellConfig::default()
    };
    let (t_pub, k2_pub, wall_pub) = run(realism, published, fixed, range);
    // This station: stability detection (20 ppm for 5 s and no drift), adaptive dwell to 1 µg.
    let adaptive = DwellConfig {
        seconds: 10,
        sem_target_ug: Some(1.0),
        min_seconds: 5,
        max_seconds: 20,
    };
    let (t_ada, k2_ada, wall_ada) = run(realism, StabilityConfig::default(), adaptive, range);
    if !measuring {
        println!(
            "dwell bench smoke run done ({t_pub:.0} s and {t_ada:.0} s virtual; no figures outside `cargo bench`)"
        );
        return;
    }
    println!("realism: {realism}");
    println!("bench: dwell_published_fixed_settle_test_duration = {t_pub:.0} s virtual");
    println!("bench: dwell_published_fixed_settle_k2_ci95_halfwidth = {k2_pub:.3} ug/g2");
    println!("bench: dwell_adaptive_test_duration = {t_ada:.0} s virtual");
    println!("bench: dwell_adaptive_k2_ci95_halfwidth = {k2_ada:.3} ug/g2");
    println!("bench: dwell_wall_time_published = {wall_pub:.1} s");
    println!("bench: dwell_wall_time_adaptive = {wall_ada:.1} s");
}
