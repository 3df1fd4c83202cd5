//! Writing one-second values for 96 instruments through the store's event
//! sink (one transaction per second, as the engine emits them): rows per
//! second, and the database size per hour of test.
//! Prints `bench: <name> = <value> <unit>` lines.
//!
//! Run: `cargo bench -p spinbench-store --bench store_rate`

use spinbench_engine::TestPlan;
use spinbench_engine::event::{Event, EventSink};
use spinbench_engine::plan::CompiledPlan;
use std::time::Instant;

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let seconds = if measuring { 3600 } else { 30 };
    let instruments = 96;
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("bench.db");
    let store = spinbench_store::Store::open(&db).expect("store");
    let mut sink = store.sink().expect("sink");
    let plan = CompiledPlan {
        plan: TestPlan::default(),
        serials: (0..instruments).map(|i| Some(format!("B{i:03}"))).collect(),
        passes: Vec::new(),
        steps: Vec::new(),
        order: Default::default(),
    };
    sink.emit(&Event::RunStarted {
        run_id: "bench".into(),
        station: "bench".into(),
        plan: Box::new(plan),
        resumed: false,
    })
    .expect("run started");
    let start = Instant::now();
    for t in 0..seconds {
        let outputs = (0..instruments)
            .map(|i| Some(1000.0 + i as f64 + t as f64 * 1e-3))
            .collect();
        sink.emit(&Event::Values {
            time_s: f64::from(t),
            rate_deg_s: 1234.5,
            demand_deg_s: 1234.5,
            on_speed: true,
            outputs_hz: outputs,
        })
        .expect("values");
    }
    let elapsed = start.elapsed().as_secs_f64();
    let rows = store.value_count("bench").expect("count");
    assert_eq!(rows, i64::from(seconds) * instruments as i64);
    drop(sink);
    let size: u64 = ["bench.db", "bench.db-wal"]
        .iter()
        .filter_map(|f| std::fs::metadata(dir.path().join(f)).ok())
        .map(|m| m.len())
        .sum();
    if !measuring {
        println!("store bench smoke run: {rows} rows (no figures outside `cargo bench`)");
        return;
    }
    let hours = f64::from(seconds) / 3600.0;
    println!("rows: {rows} ({instruments} instruments × {seconds} s), {elapsed:.2} s");
    println!(
        "bench: store_values_rows_per_second_96_instruments = {:.0} rows/s",
        rows as f64 / elapsed
    );
    println!(
        "bench: store_values_realtime_margin = {:.0} x",
        rows as f64 / elapsed / instruments as f64
    );
    println!(
        "bench: store_database_size_per_hour_96_instruments = {:.1} MB",
        size as f64 / 1e6 / hours
    );
}
