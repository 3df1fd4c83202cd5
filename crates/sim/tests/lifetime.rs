//! A virtual bench lives as long as its owner: dropped, it stops serving
//! (no bench leaked for the life of the process).

use spinbench_sim::SimConfig;
use spinbench_sim::serve::{RunningBench, ServeOptions};
use std::net::TcpStream;

#[test]
fn a_bench_dropped_stops_serving_its_devices() {
    let bench = RunningBench::start(
        SimConfig {
            speed: 0.0,
            ..SimConfig::default()
        },
        ServeOptions::default(),
    )
    .expect("a virtual bench");
    let control = bench.endpoints().control.clone();
    TcpStream::connect(&control).expect("the control socket answers while the bench lives");
    drop(bench);
    assert!(
        TcpStream::connect(&control).is_err(),
        "the control socket {control} still answers after the bench was dropped"
    );
}
