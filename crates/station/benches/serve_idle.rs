//! An idle station: `spinbench serve --simulate --sim-speed 0` with no run
//! and no browser. Its CPU use over a window is printed (a hostile test saw
//! 44 % of a core here: the virtual bench raced when nothing read it), then
//! the server is stopped with SIGTERM and must exit.
//! Prints `bench: <name> = <value> <unit>` lines.
//!
//! Run: `cargo bench -p spinbench-station --bench serve_idle`

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[path = "common/cpu.rs"]
mod cpu;
use cpu::cpu_seconds;

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let window = Duration::from_secs(if measuring { 10 } else { 2 });
    let dir = tempfile::tempdir().expect("tempdir");
    let mut server = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args([
            "serve",
            "--simulate",
            "--sim-speed",
            "0",
            "--bind",
            "127.0.0.1:0",
            "--data",
        ])
        .arg(dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("spinbench serve");
    let stdout = server.stdout.take().expect("stdout");
    let mut lines = BufReader::new(stdout).lines();
    // Serving once it says where.
    for line in lines.by_ref() {
        if line.expect("line").contains("http://") {
            break;
        }
    }
    std::thread::spawn(move || for _ in lines {});
    std::thread::sleep(Duration::from_secs(1));
    let pid = server.id().to_string();
    let (cpu0, t0) = (cpu_seconds(&pid), Instant::now());
    std::thread::sleep(window);
    let used = cpu_seconds(&pid) - cpu0;
    let percent = 100.0 * used / t0.elapsed().as_secs_f64();
    println!("bench: serve_idle_cpu_sim_speed_0 = {percent:.1} %");
    let kill = Command::new("kill")
        .args(["-TERM", &pid])
        .status()
        .expect("kill");
    assert!(kill.success());
    let until = Instant::now() + Duration::from_secs(20);
    while server.try_wait().expect("wait").is_none() {
        assert!(Instant::now() < until, "serve did not exit after SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    }
}
