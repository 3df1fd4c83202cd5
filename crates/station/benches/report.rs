//! Reports of a 96-instrument run: a virtual bench with 16 counter modules
//! runs a short test (levels to 20 g, mounting P) through the production
//! engine into an SQLite store; then every report format is written again
//! from the store and timed, and the batch report over the run too.
//! Prints `bench: <name> = <value> <unit>` lines.
//!
//! Run: `cargo bench -p spinbench-station --bench report`

use spinbench_engine::TestPlan;
use spinbench_report::ReportFormat;
use spinbench_sim::SimConfig;
use spinbench_station::run_setup::{RunDir, Setup, prepare};
use spinbench_station::station_run::{RunControl, connect_bench, execute};
use spinbench_station::virtual_bench::VirtualBench;
use spinbench_store::{Store, StoreTarget};
use std::time::Instant;

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let modules = if measuring { 16 } else { 1 };
    let dir = tempfile::tempdir().expect("tempdir");
    let sim = VirtualBench::open_config(
        SimConfig {
            seed: 11,
            speed: 0.0,
            modules,
            ..SimConfig::default()
        },
        false,
    )
    .expect("virtual bench");
    let station = sim.station().expect("station config");
    let slots = station.slots();
    let serials: String = (1..=slots)
        .map(|i| format!("{i} = \"R{i:03}\"\n"))
        .collect();
    let plan = TestPlan::from_toml(&format!(
        "operator = \"bench\"\nrange_g = 20\nlevels = [0, 1, 5, 10, 15, 20]\npasses = [\"P\"]\n\
         warmup_s = 600\ndwell = {{ seconds = 3 }}\nstability = {{ hold_s = 3 }}\n[serials]\n{serials}"
    ))
    .expect("plan");
    let db = StoreTarget::File(dir.path().join("spinbench.db"));
    let started = Instant::now();
    let prepared = prepare(Setup {
        station_toml: sim.station_toml().to_string(),
        station,
        plan,
        plan_text: None,
        dir: RunDir::create(dir.path()).expect("run directory"),
        store: Some(db.clone()),
    })
    .expect("prepare");
    let run_id = prepared.dir.id().to_string();
    let bench = connect_bench(&prepared.station, Some(&prepared.dir.raw_dir())).expect("connect");
    let finished = execute(
        prepared,
        bench,
        sim.operator(true),
        true,
        RunControl::abort_only(spinbench_engine::AbortFlag::new()),
    )
    .expect("run");
    drop(sim);
    let run_s = started.elapsed().as_secs_f64();
    let store = Store::connect(&db).expect("store");
    let run_id = run_id.as_str();
    assert_eq!(store.results(run_id).expect("results").len(), slots);
    println!(
        "{slots} instruments: the simulated run took {run_s:.1} s ({:?})",
        finished.summary.state
    );
    assert_eq!(
        finished.summary.state,
        spinbench_engine::RunState::Completed,
        "{:?}",
        finished.summary.reason
    );
    let out = dir.path().join("reports");
    let mut total = 0.0;
    for format in ReportFormat::ALL {
        let t = Instant::now();
        let files =
            spinbench_report::write_reports(&store, run_id, &[format], &out).expect("report");
        let s = t.elapsed().as_secs_f64();
        total += s;
        let bytes: u64 = files
            .iter()
            .filter_map(|f| std::fs::metadata(f).ok())
            .map(|m| m.len())
            .sum();
        let name = format!("{format:?}").to_lowercase();
        if measuring {
            println!("bench: report_{name}_{slots}_instruments = {s:.3} s");
            println!(
                "bench: report_{name}_{slots}_instruments_size = {:.2} MB",
                bytes as f64 / 1e6
            );
        } else {
            println!("{name}: {bytes} bytes (no figures outside `cargo bench`)");
        }
    }
    // The same in Chinese (every reason and line worded from the catalogue).
    let t = Instant::now();
    let zh = dir.path().join("reports-zh");
    spinbench_report::write_reports_in(
        &store,
        run_id,
        &ReportFormat::ALL,
        &zh,
        spinbench_report::Lang::ZhCn,
    )
    .expect("report in Chinese");
    let total_zh = t.elapsed().as_secs_f64();
    let t = Instant::now();
    spinbench_report::write_batch_reports(
        &store,
        &[],
        spinbench_report::control::DEFAULT_BASELINE_RUNS,
        &ReportFormat::ALL,
        &out,
        spinbench_report::Lang::En,
    )
    .expect("batch report");
    let batch_s = t.elapsed().as_secs_f64();
    if measuring {
        println!("bench: report_all_formats_{slots}_instruments = {total:.3} s");
        println!("bench: report_all_formats_{slots}_instruments_zh = {total_zh:.3} s");
        println!("bench: batch_report_all_formats_{slots}_instruments = {batch_s:.3} s");
    }
}
