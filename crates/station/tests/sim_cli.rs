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

#[test]
fn realism_chooses_the_presets_error_sources_and_the_truth_says_which() {
    let dir = tempfile::tempdir().expect("tempdir");
    let truth_path = dir.path().join("truth.json");
    let config = dir.path().join("bench.toml");
    // The file asks for ideal with one key of its own; --realism replaces the preset only.
    std::fs::write(&config, "realism = \"ideal\"\nlatitude_deg = -30\n").expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["sim", "--for", "0", "--realism", "typical", "--config"])
        .arg(&config)
        .arg("--truth")
        .arg(&truth_path)
        .output()
        .expect("run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&truth_path).expect("truth")).expect("json");
    let c = &truth["centrifuge"];
    assert_eq!(c["realism"], "typical");
    assert_eq!(c["latitude_deg"], -30.0);
    assert!(
        c["earth_rate_vertical_rad_s"]
            .as_f64()
            .is_some_and(|w| w < 0.0)
    );
    assert!(
        c["arm_stretch_m_per_rad2_s2"]
            .as_f64()
            .is_some_and(|k| k > 0.0)
    );
    assert_eq!(c["disturbances"].as_array().map(Vec::len), Some(2));
    let first = &truth["instruments"][0];
    for key in [
        "koq_ug_per_g2",
        "asymmetry_ppm",
        "k1_temp_coeff_ppm_per_c",
        "instrument_k2_ug_per_g2",
        "azimuth_rad",
    ] {
        assert!(first[key].is_number(), "{key} missing: {first}");
    }
    assert!(first["per_mounting_k2"]["common_ug_per_g2"].is_number());
    // An unknown preset is named.
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["sim", "--for", "0", "--realism", "dirty"])
        .output()
        .expect("run");
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("ideal, typical or harsh"), "{stderr}");
}

/// One set of bench arguments for every command: the
/// same flags mean the same bench on `sim`, `run`, `retest` and `doctor`,
/// and a bench config file without `--simulate` is refused, saying how.
#[test]
fn every_command_takes_the_same_bench_arguments() {
    let dir = tempfile::tempdir().expect("tempdir");
    let bench = dir.path().join("bench.toml");
    std::fs::write(&bench, "realism = \"typical\"\nseed = 5\n").expect("bench config");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, "range_g = 10\n[serials]\n1 = \"A\"\n").expect("plan");
    // A bench file on hardware: refused before anything is opened.
    for args in [
        vec!["run", plan.to_str().expect("utf-8"), "--bench"],
        vec!["retest", "no-such-run", "--bench"],
        vec!["doctor", "--bench"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
            .args(&args)
            .arg(&bench)
            .arg("--data")
            .arg(dir.path().join("data"))
            .output()
            .expect("spinbench");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}: {stderr}");
        assert!(stderr.contains("add --simulate"), "{args:?}: {stderr}");
    }
    // The bench's own spelling on `sim` (--config) and the shared one
    // (--bench) both open the bench the file describes.
    for flag in ["--config", "--bench"] {
        let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
            .args(["sim", "--for", "0", flag])
            .arg(&bench)
            .output()
            .expect("spinbench sim");
        assert!(
            out.status.success(),
            "{flag}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            String::from_utf8_lossy(&out.stdout).contains("[centrifuge]"),
            "{flag}: the station config's device sections are printed"
        );
    }
    // The doctor opens the virtual bench through the same arguments.
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args([
            "doctor",
            "--simulate",
            "--realism",
            "harsh",
            "--seed",
            "2",
            "--data",
        ])
        .arg(dir.path().join("data"))
        .output()
        .expect("spinbench doctor");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("the virtual bench"), "{stdout}");
}
