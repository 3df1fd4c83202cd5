//! Benchmark of `spinbench analyze` on a 10,000-row points file: reading,
//! reducing every unit (fits, scale-factor model, figures, model comparison)
//! and writing the JSON document. Prints `bench: <name> = <value> <unit>` lines.
//!
//! Run: `cargo bench -p spinbench-station --bench analyze`

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use spinbench_analysis::model::ieee1293_output;
use spinbench_analysis::points::{published_levels, up_down};
use spinbench_station::cli::analyze_file;
use spinbench_station::render::render_dataset;
use std::fmt::Write;
use std::time::{Duration, Instant};

const TARGET_ROWS: usize = 10_000;
const REPEATS: usize = 7;

fn write_points(path: &std::path::Path) -> usize {
    let levels = up_down(&published_levels(70.0));
    let per_unit = 2 * levels.len();
    let units = TARGET_ROWS.div_ceil(per_unit);
    let mut rng = ChaCha8Rng::seed_from_u64(10_000);
    let noise = Normal::new(0.0, 2e-6).expect("normal");
    let mut text = String::from("unit,mount,g_nominal,g_applied,output\n");
    let mut rows = 0;
    for u in 0..units {
        let k = [
            0.01 + 1e-4 * u as f64,
            100.0 + 0.1 * u as f64,
            (u as f64 - 80.0) * 0.2e-6,
            0.02e-6,
        ];
        for (mount, sign) in [("P", 1.0), ("N", -1.0)] {
            for &g in &levels {
                let a = g * 1.0003;
                let out = ieee1293_output(k, sign * a) + k[1] * noise.sample(&mut rng);
                let _ = writeln!(text, "SN{u:04},{mount},{g},{a:.6},{out:.6}");
                rows += 1;
            }
        }
    }
    std::fs::write(path, text).expect("write bench file");
    rows
}

fn median(mut times: Vec<Duration>) -> Duration {
    times.sort();
    times[times.len() / 2]
}

fn main() {
    // `cargo bench` passes --bench; `cargo test --all-targets` runs this once
    // unoptimised as a smoke test, whose timings would mislead, so none are printed.
    let measuring = std::env::args().any(|a| a == "--bench");
    let repeats = if measuring { REPEATS } else { 1 };
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("points.csv");
    let rows = write_points(&path);

    let mut total = Vec::new();
    let mut json_bytes = 0;
    for _ in 0..repeats {
        let start = Instant::now();
        let analysis = analyze_file(&path, 3, None).expect("analysis");
        let json = serde_json::to_string(&analysis).expect("json");
        let human = render_dataset("points.csv", &analysis);
        total.push(start.elapsed());
        json_bytes = json.len();
        assert!(human.len() > rows);
        assert_eq!(analysis.units.len(), rows / 62);
    }
    if !measuring {
        println!("analyze bench smoke run: {rows} rows reduced (no figures outside `cargo bench`)");
        return;
    }
    let t = median(total);
    println!(
        "rows: {rows}, units: {}, median of {REPEATS} runs",
        rows / 62
    );
    println!(
        "bench: analyze_10k_rows_time = {:.1} ms",
        t.as_secs_f64() * 1e3
    );
    println!(
        "bench: analyze_rows_per_second = {:.0} rows/s",
        rows as f64 / t.as_secs_f64()
    );
    println!(
        "bench: analyze_json_size = {:.0} KiB",
        json_bytes as f64 / 1024.0
    );
}
