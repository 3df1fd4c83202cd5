//! How fast the virtual bench runs: raw world steps, and simulated time per
//! wall-clock second when the production drivers read every module over
//! real pseudo-terminals and poll the rate once a second, as the station
//! does (speed 0: virtual time in lockstep).
//! Prints `bench: <name> = <value> <unit>` lines.
//!
//! Run: `cargo bench -p spinbench-sim --bench bench_speed`

use spinbench_engine::StationConfig;
use spinbench_sim::serve::{RunningBench, ServeOptions};
use spinbench_sim::station::station_toml;
use spinbench_sim::{Mounting, SimConfig, World};
use spinbench_wire::fmu::{Message, StreamMode, WindowAccumulator, WindowConfig};
use std::time::{Duration, Instant};

fn raw_steps(modules: usize, seconds: f64) -> f64 {
    let mut world = World::new(SimConfig {
        modules,
        ..SimConfig::default()
    });
    for line in ["INST:NSEL 1", "OUTP ON", "INST:NSEL 2", "OUTP ON"] {
        world.handle_supply_line(spinbench_sim::SupplyId::Rails, line);
    }
    for m in 0..modules {
        world.handle_module_message(m, Ok(Message::SetPower { mask: 0x3F }));
        world.handle_module_message(
            m,
            Ok(Message::StartStreaming {
                mode: StreamMode::Reciprocal,
            }),
        );
    }
    world.set_all_mountings(Mounting::ArmP);
    let start = Instant::now();
    let mut ticks = 0u64;
    while start.elapsed().as_secs_f64() < seconds {
        for _ in 0..400 {
            std::hint::black_box(world.step());
        }
        ticks += 400;
    }
    ticks as f64 / 400.0 / start.elapsed().as_secs_f64()
}

fn served(modules: usize, seconds: f64) -> f64 {
    let config = SimConfig {
        modules,
        speed: 0.0,
        ..SimConfig::default()
    };
    let t = Instant::now();
    let bench = RunningBench::start(config, ServeOptions::default()).expect("bench");
    eprintln!(
        "  {modules} modules: bench started in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    let station = StationConfig::from_toml(&station_toml(&bench, "")).expect("station");
    let t = Instant::now();
    let mut devices = station.connect().expect("connect");
    for d in &mut devices.modules {
        d.set_power(0x3F).expect("power");
        d.start(StreamMode::Reciprocal).expect("start");
    }
    eprintln!(
        "  {modules} modules: drivers started in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    let mut accumulators = vec![WindowAccumulator::new(WindowConfig::default()); modules];
    let t0 = bench.with_world(|w| w.now_s());
    let start = Instant::now();
    // As the station does in virtual time: one window from every module,
    // then the rate (which lets the bench produce the next second).
    while start.elapsed().as_secs_f64() < seconds {
        for (d, acc) in devices.modules.iter_mut().zip(&mut accumulators) {
            let mut have = false;
            while !have {
                for msg in d
                    .receive(Instant::now() + Duration::from_millis(5))
                    .expect("receive")
                {
                    acc.feed(&msg);
                }
                while acc.decode().is_some() {
                    have = true;
                }
            }
        }
        std::hint::black_box(devices.centrifuge.read_rate().expect("rate"));
    }
    let simulated = bench.with_world(|w| w.now_s()) - t0;
    let wall = start.elapsed().as_secs_f64();
    drop(devices);
    let t = Instant::now();
    bench.shutdown();
    eprintln!(
        "  {modules} modules: bench shut down in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    simulated / wall
}

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let seconds = if measuring { 3.0 } else { 0.2 };
    let raw_12 = raw_steps(2, seconds);
    let raw_96 = raw_steps(16, seconds);
    let served_12 = served(2, seconds);
    let served_96 = served(16, seconds);
    if !measuring {
        println!("sim bench smoke run done (no figures outside `cargo bench`)");
        return;
    }
    println!("bench: sim_world_speed_12_instruments = {raw_12:.0} x real time");
    println!("bench: sim_world_speed_96_instruments = {raw_96:.0} x real time");
    println!("bench: sim_served_speed_12_instruments_over_pty = {served_12:.0} x real time");
    println!("bench: sim_served_speed_96_instruments_over_pty = {served_96:.0} x real time");
    println!(
        "bench: sim_two_hour_test_96_instruments = {:.0} s wall",
        7200.0 / served_96
    );
}
