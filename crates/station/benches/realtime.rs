//! 96 instruments in real time: a virtual bench with 16 counter modules
//! (400 reciprocal frames/s each) runs as its own process (`spinbench sim
//! --speed 1`); this process runs the production drivers, decoder and
//! engine on it for a warm-up step, and prints the CPU this process used
//! (% of one core) and the spread of the one-second events' arrival times
//! (the largest extra latency of an event beyond the best one).
//! Prints `bench: <name> = <value> <unit>` lines. (The store does not exist
//! yet; it will join this pipeline.)
//!
//! Run: `cargo bench -p spinbench-station --bench realtime`

use spinbench_engine::event::Event;
use spinbench_engine::plan::{Fixture, Step};
use spinbench_engine::{Answer, Executor, Operator, RunOptions, RunState, StationConfig, TestPlan};
use spinbench_station::station_run::connect_bench;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[path = "common/cpu.rs"]
mod cpu;
use cpu::cpu_seconds;

struct NoHands;

impl Operator for NoHands {
    fn ask(&mut self, _: &str, _: &[Option<Fixture>]) -> Answer {
        Answer {
            proceed: true,
            by: "bench".into(),
        }
    }
}

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let seconds = if measuring { 30.0 } else { 3.0 };
    let modules = if measuring { 16 } else { 2 };
    let dir = tempfile::tempdir().expect("tempdir");
    let sim_config = dir.path().join("bench.toml");
    // The bench's realism: SPINBENCH_BENCH_REALISM (ideal, typical, harsh), default typical.
    let realism = std::env::var("SPINBENCH_BENCH_REALISM").unwrap_or_else(|_| "typical".into());
    std::fs::write(
        &sim_config,
        format!("realism = \"{realism}\"\nmodules = {modules}\nspeed = 1\n"),
    )
    .expect("write");
    let mut sim = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["sim", "--for", &format!("{}", seconds + 30.0), "--config"])
        .arg(&sim_config)
        .stdout(Stdio::piped())
        .spawn()
        .expect("start the bench");
    let mut text = String::from(
        "[arm]\nradius_m = 0.8\nmax_g = 100\n\n[power]\ninstrument_supply = \"rails\"\nmodule_supply = \"logic\"\nrail_current_limit_a = 5\n\n",
    );
    for line in BufReader::new(sim.stdout.take().expect("stdout"))
        .lines()
        .map_while(Result::ok)
    {
        if line.starts_with("# virtual bench running") {
            break;
        }
        text.push_str(&line);
        text.push('\n');
    }
    let station = StationConfig::from_toml(&text).expect("station config");
    let slots = station.slots();
    let serials = (1..=slots)
        .map(|i| format!("{i} = \"R{i}\""))
        .collect::<Vec<_>>()
        .join("\n");
    let plan = TestPlan::from_toml(&format!("range_g = 25\n[serials]\n{serials}")).expect("plan");
    let mut compiled = plan.compile(&station).expect("compile");
    compiled.steps = vec![Step::PowerOn, Step::CheckAlive, Step::WarmUp { seconds }];
    let bench = connect_bench(&station, None).expect("connect");
    let arrivals = Arc::new(Mutex::new(Vec::new()));
    let sink = arrivals.clone();
    let options = RunOptions {
        run_id: "realtime".into(),
        abort: spinbench_engine::AbortFlag::new(),
        pause: Arc::new(AtomicBool::new(false)),
        module_silence: Duration::from_secs(5),
        station_config_toml: String::new(),
        sink_hold_limit: Duration::from_secs(600),
    };
    let mut executor = Executor::new(&station, compiled, bench, Box::new(NoHands), options);
    executor.subscribe(move |e: &Event| {
        if let Event::Values { .. } = e
            && let Ok(mut v) = sink.lock()
        {
            v.push(Instant::now());
        }
    });
    let cpu0 = cpu_seconds("self");
    let wall0 = Instant::now();
    let summary = executor.run();
    let wall = wall0.elapsed().as_secs_f64();
    let cpu = cpu_seconds("self") - cpu0;
    let _ = sim.kill();
    let _ = sim.wait();
    assert_eq!(summary.state, RunState::Completed, "{:?}", summary.reason);
    let times = arrivals.lock().map(|v| v.clone()).unwrap_or_default();
    // Event k is due one second after event k−1 of a real-time stream: its
    // lateness is its time minus (first event + k s); the spread is the latency.
    let lateness: Vec<f64> = times
        .iter()
        .enumerate()
        .map(|(k, t)| t.duration_since(times[0]).as_secs_f64() - k as f64)
        .collect();
    let spread = lateness.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        - lateness.iter().copied().fold(f64::INFINITY, f64::min);
    if !measuring {
        println!(
            "realtime bench smoke run: {} events from {modules} modules (no figures outside `cargo bench`)",
            times.len()
        );
        return;
    }
    println!(
        "realism {realism}; events: {}, modules: {modules}, instruments: {slots}, wall {wall:.1} s, windows dropped {}",
        times.len(),
        summary.dropped_windows
    );
    println!(
        "bench: realtime_96_instruments_cpu = {:.1} % of one core",
        cpu / wall * 100.0
    );
    println!(
        "bench: realtime_96_instruments_event_latency_spread = {:.0} ms",
        spread * 1e3
    );
}
