//! Writing one-second values for 96 instruments through the store's event
//! sink (one transaction per second, as the engine emits them): rows per
//! second, and the database size per hour of test, for SQLite and (when
//! `SPINBENCH_TEST_POSTGRES` names a server, as `scripts/test` and
//! `scripts/postgres` provide) PostgreSQL.
//! With PostgreSQL also the fleet: 8 stations × 96 instruments,
//! each on its own connection, writing their one-second values into one
//! server at once as fast as it takes them — the write margin (capacity
//! over the fleet's load of 8 writes a second) and the p99 of one write.
//! Prints `bench: <name> = <value> <unit>` lines.
//!
//! Run: `cargo bench -p spinbench-store --bench store_rate`

use spinbench_engine::TestPlan;
use spinbench_engine::event::{Event, EventSink};
use spinbench_engine::plan::CompiledPlan;
use spinbench_store::{Store, StoreTarget};
use std::time::Instant;

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join("bench.db");
    bench(
        "sqlite",
        &StoreTarget::File(file.clone()),
        measuring,
        &|| {
            ["bench.db", "bench.db-wal"]
                .iter()
                .filter_map(|f| std::fs::metadata(dir.path().join(f)).ok())
                .map(|m| m.len())
                .sum()
        },
    );
    match spinbench_store::testing::postgres_url() {
        Ok(admin) => {
            let url = spinbench_store::testing::fresh_postgres_database(&admin).expect("database");
            let target = StoreTarget::Postgres(url.clone());
            bench("postgres", &target, measuring, &|| {
                let mut c = postgres::Client::connect(&url, postgres::NoTls).expect("connect");
                c.query_one("SELECT pg_database_size(current_database())", &[])
                    .map(|r| r.get::<_, i64>(0) as u64)
                    .unwrap_or(0)
            });
            let fleet_url =
                spinbench_store::testing::fresh_postgres_database(&admin).expect("database");
            fleet(&StoreTarget::Postgres(fleet_url), measuring);
        }
        Err(e) => println!("postgres: not measured: {e}"),
    }
}

/// A run of `instruments` started on `sink` as station `station`.
fn start_run(
    sink: &mut spinbench_store::StoreSink,
    station: &str,
    run_id: &str,
    instruments: usize,
) {
    let plan = CompiledPlan {
        plan: TestPlan::default(),
        serials: (0..instruments).map(|i| Some(format!("B{i:03}"))).collect(),
        passes: Vec::new(),
        steps: Vec::new(),
        order: Default::default(),
        table_prior: None,
    };
    sink.emit(&Event::RunStarted {
        run_id: run_id.into(),
        station: station.into(),
        plan: Box::new(plan),
        resumed: false,
        station_config: String::new(),
    })
    .expect("run started");
}

/// One second's values of `instruments`.
fn values(t: u32, instruments: usize) -> Event {
    Event::Values {
        time_s: f64::from(t),
        rate_deg_s: 1234.5,
        demand_deg_s: 1234.5,
        on_speed: true,
        outputs_hz: (0..instruments)
            .map(|i| Some(1000.0 + i as f64 + f64::from(t) * 1e-3))
            .collect(),
        temperatures_c: (0..instruments)
            .map(|i| Some(25.0 + i as f64 * 0.01))
            .collect(),
    }
}

/// 8 stations × 96 instruments writing into one server at once.
fn fleet(target: &StoreTarget, measuring: bool) {
    const STATIONS: usize = 8;
    const INSTRUMENTS: usize = 96;
    let seconds: u32 = if measuring { 600 } else { 10 };
    let start = Instant::now();
    let threads: Vec<_> = (0..STATIONS)
        .map(|k| {
            let target = target.clone();
            std::thread::spawn(move || {
                let store = Store::connect(&target).expect("store");
                let mut sink = store.sink().expect("sink");
                start_run(
                    &mut sink,
                    &format!("station-{k}"),
                    &format!("fleet-{k}"),
                    INSTRUMENTS,
                );
                let mut latencies = Vec::with_capacity(seconds as usize);
                for t in 0..seconds {
                    let one = Instant::now();
                    sink.emit(&values(t, INSTRUMENTS)).expect("values");
                    latencies.push(one.elapsed().as_secs_f64());
                }
                latencies
            })
        })
        .collect();
    let mut latencies: Vec<f64> = threads
        .into_iter()
        .flat_map(|t| t.join().expect("a station's writer"))
        .collect();
    let elapsed = start.elapsed().as_secs_f64();
    let store = Store::connect(target).expect("store");
    for k in 0..STATIONS {
        let rows = store.value_count(&format!("fleet-{k}")).expect("count");
        assert_eq!(
            rows,
            i64::from(seconds) * INSTRUMENTS as i64,
            "station {k} lost rows"
        );
    }
    if !measuring {
        println!(
            "fleet bench smoke run: {STATIONS} stations, nothing lost (no figures outside `cargo bench`)"
        );
        return;
    }
    latencies.sort_by(f64::total_cmp);
    let p99 = latencies[(latencies.len() * 99 / 100).min(latencies.len() - 1)];
    let writes_per_s = latencies.len() as f64 / elapsed;
    println!(
        "fleet: {STATIONS} stations × {INSTRUMENTS} instruments × {seconds} s of values in {elapsed:.1} s"
    );
    println!(
        "bench: store_postgres_fleet_8x96_write_margin = {:.0} x",
        writes_per_s / STATIONS as f64
    );
    println!(
        "bench: store_postgres_fleet_8x96_p99_write_latency = {:.1} ms",
        p99 * 1e3
    );
}

fn bench(name: &str, target: &StoreTarget, measuring: bool, size_bytes: &dyn Fn() -> u64) {
    let seconds = if measuring { 3600 } else { 30 };
    let instruments = 96;
    let store = Store::connect(target).expect("store");
    let mut sink = store.sink().expect("sink");
    let empty = size_bytes();
    let plan = CompiledPlan {
        plan: TestPlan::default(),
        serials: (0..instruments).map(|i| Some(format!("B{i:03}"))).collect(),
        passes: Vec::new(),
        steps: Vec::new(),
        order: Default::default(),
        table_prior: None,
    };
    sink.emit(&Event::RunStarted {
        run_id: "bench".into(),
        station: "bench".into(),
        plan: Box::new(plan),
        resumed: false,
        station_config: String::new(),
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
            temperatures_c: (0..instruments)
                .map(|i| Some(25.0 + i as f64 * 0.01))
                .collect(),
        })
        .expect("values");
    }
    let elapsed = start.elapsed().as_secs_f64();
    let rows = store.value_count("bench").expect("count");
    assert_eq!(rows, i64::from(seconds) * instruments as i64);
    drop(sink);
    let size = size_bytes().saturating_sub(empty);
    if !measuring {
        println!("store bench smoke run ({name}): {rows} rows (no figures outside `cargo bench`)");
        return;
    }
    let hours = f64::from(seconds) / 3600.0;
    println!("{name}: {rows} rows ({instruments} instruments × {seconds} s), {elapsed:.2} s");
    println!(
        "bench: store_{name}_rows_per_second_96_instruments = {:.0} rows/s",
        rows as f64 / elapsed
    );
    println!(
        "bench: store_{name}_realtime_margin = {:.0} x",
        rows as f64 / elapsed / instruments as f64
    );
    println!(
        "bench: store_{name}_size_per_hour_96_instruments = {:.1} MB",
        size as f64 / 1e6 / hours
    );
}
