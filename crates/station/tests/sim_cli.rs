//! `spinbench sim` as its own process: the station (here, this test) reads
//! the printed config and reaches the bench's devices over real PTYs.

use serde::Deserialize;
use spinbench_devices::config::{CentrifugeConfig, FmuConfig, PowerSupplyConfig};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

#[derive(Deserialize)]
struct Devices {
    centrifuge: CentrifugeConfig,
    fmu: Vec<FmuConfig>,
    power_supply: Vec<PowerSupplyConfig>,
}

#[test]
fn a_second_process_drives_the_bench_through_the_printed_config() {
    let dir = tempfile::tempdir().expect("tempdir");
    let truth_path = dir.path().join("truth.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["sim", "--for", "20", "--truth"])
        .arg(&truth_path)
        .stdout(Stdio::piped())
        .spawn()
        .expect("start spinbench sim");
    let stdout = child.stdout.take().expect("stdout");
    let mut text = String::new();
    for line in BufReader::new(stdout).lines() {
        let line = line.expect("line");
        if line.starts_with("# virtual bench running") {
            break;
        }
        text.push_str(&line);
        text.push('\n');
    }
    let devices: Devices = toml::from_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert_eq!(devices.fmu.len(), 2);

    let result = std::panic::catch_unwind(|| {
        let mut table = devices.centrifuge.connect().expect("centrifuge over a pty");
        assert!(
            table
                .identify()
                .expect("idn")
                .starts_with("ACUTRONIC,SPINBENCH-SIM")
        );
        let mut rails = devices.power_supply[0].connect().expect("rails");
        rails.configure(1, 15.0, 0.5).expect("configure");
        let mut fmu = devices.fmu[1].connect(1).expect("fmu2");
        let status = fmu.status().expect("status");
        assert_eq!(status.firmware_id, 0x5101);
    });
    let _ = child.kill();
    let _ = child.wait();
    result.expect("the bench answered");

    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&truth_path).expect("truth file"))
            .expect("json");
    let instruments = truth["instruments"].as_array().expect("instruments");
    assert_eq!(instruments.len(), 12);
    assert!(instruments.iter().all(|i| {
        i["k2_ug_per_g2"]
            .as_f64()
            .is_some_and(|k2| (1.0..=30.0).contains(&k2.abs()))
    }));
}

#[test]
fn a_bad_bench_config_names_the_key() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bench.toml");
    std::fs::write(&path, "modules = 40\n").expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["sim", "--for", "0", "--config"])
        .arg(&path)
        .output()
        .expect("run");
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("modules: must be 1 to 16, got 40"),
        "{stderr}"
    );
    std::fs::write(&path, "[centrifuge]\nradius = 1\n").expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["sim", "--for", "0", "--config"])
        .arg(&path)
        .output()
        .expect("run");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("radius"), "unknown key named: {stderr}");
}
