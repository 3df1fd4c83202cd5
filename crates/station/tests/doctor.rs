//! `spinbench doctor`: on the virtual bench every check
//! passes; on a station config naming a port that does not exist, it says
//! which port and what to check, and exits with an error.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

fn doctor(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .arg("doctor")
        .args(args)
        .output()
        .expect("spinbench doctor");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

/// Every failing line is the disk's (a machine short of space here).
fn only_disk_failed(out: &str) -> bool {
    let failing: Vec<&str> = out.lines().filter(|l| l.starts_with("FAIL")).collect();
    !failing.is_empty()
        && failing
            .iter()
            .all(|l| l.starts_with("FAIL  disk") && l.contains("GB free"))
}

#[test]
fn the_virtual_bench_is_ready() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let (ok, out, err) = doctor(&["--simulate", "--data", data.to_str().expect("utf-8")]);
    // A machine short of disk fails that line alone (and says so): the rest
    // must still pass.
    let short_of_disk = only_disk_failed(&out);
    assert!(ok || short_of_disk, "{out}\n{err}");
    for what in [
        "config: the virtual bench",
        "centrifuge (/dev/pts/",
        "fmu 1 (/dev/pts/",
        "instrument supply (",
        "store (",
        "clock: ",
        "disk (",
    ] {
        assert!(out.contains(what), "{what} in\n{out}");
    }
    // Every device identified; no store yet, and none made (
    // item 12: doctor changes nothing).
    assert!(
        out.contains("ACUTRONIC") && out.contains("firmware 0x"),
        "{out}"
    );
    assert!(out.contains("no store yet"), "{out}");
    assert!(!data.join("spinbench.db").exists(), "doctor made the store");
    // Once a store exists: migrated and writable.
    let made = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["user", "add", "admin", "--role", "admin", "--db"])
        .arg(data.join("spinbench.db"))
        .env("SPINBENCH_PASSWORD", "admin-password")
        .output()
        .expect("user add");
    assert!(made.status.success());
    let (ok, out, err) = doctor(&["--simulate", "--data", data.to_str().expect("utf-8")]);
    assert!(ok || only_disk_failed(&out), "{out}\n{err}");
    assert!(out.contains("writable, schema version"), "{out}");
    assert!(
        out.lines()
            .filter(|l| l.starts_with("FAIL"))
            .all(|l| l.starts_with("FAIL  disk")),
        "{out}"
    );
    if !short_of_disk {
        assert!(
            out.lines().last().is_some_and(|l| l.starts_with("ready")),
            "{out}"
        );
    }
    // The bench's default name is warned of; so, louder,
    // is a name another station (another identity) holds in the store.
    assert!(
        out.contains("WARN  station name: 'spinbench virtual bench' is a default name"),
        "{out}"
    );
    let store = spinbench_store::Store::open(&data.join("spinbench.db")).expect("store");
    let claim = store
        .claim_station(&spinbench_store::fleet::Heartbeat {
            station: "spinbench virtual bench".into(),
            instance: "0123456789abcdef0123456789abcdef".into(),
            state: "idle".into(),
            run_id: None,
            progress: None,
            address: Some("http://10.0.0.7:8080/".into()),
        })
        .expect("claim");
    assert!(matches!(
        claim,
        spinbench_store::fleet::Claim::Taken { previous: None }
    ));
    let (_, out, _) = doctor(&["--simulate", "--data", data.to_str().expect("utf-8")]);
    assert!(
        out.contains("held in the store by another station (identity 0123456789abcdef0123456789abcdef, at http://10.0.0.7:8080/"),
        "{out}"
    );
}

#[test]
fn a_port_that_does_not_exist_is_named_with_what_to_check() {
    let dir = tempfile::tempdir().expect("tempdir");
    // A real bench's devices (its own process), then the centrifuge moved
    // to a port that is not there.
    let mut sim = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["sim", "--for", "120"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("spinbench sim");
    let stdout = sim.stdout.take().expect("stdout");
    let mut devices = String::new();
    for line in BufReader::new(stdout).lines() {
        let line = line.expect("line");
        if line.starts_with("# virtual bench running") {
            break;
        }
        devices.push_str(&line);
        devices.push('\n');
    }
    let header = "station = \"doctor test\"\n[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\n\
                  instrument_supply = \"rails\"\nmodule_supply = \"logic\"\n\n";
    let good = dir.path().join("good.toml");
    std::fs::write(&good, format!("{header}{devices}")).expect("good.toml");
    let data = dir.path().join("data");
    let data_s = data.to_str().expect("utf-8");
    let (ok, out, err) = doctor(&["--station", good.to_str().expect("utf-8"), "--data", data_s]);
    assert!(
        ok || only_disk_failed(&out),
        "the bench's own config: {out}\n{err}"
    );

    // The centrifuge's section names its port first: move it.
    let start = devices
        .find("[centrifuge]")
        .expect("a [centrifuge] section");
    let port_at = start + devices[start..].find("/dev/pts/").expect("its port");
    let end = port_at + devices[port_at..].find('"').expect("the port's end");
    let mut bad_devices = devices.clone();
    bad_devices.replace_range(port_at..end, "/dev/ttyUSB-not-there");
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, format!("{header}{bad_devices}")).expect("bad.toml");
    let (ok, out, err) = doctor(&["--station", bad.to_str().expect("utf-8"), "--data", data_s]);
    let _ = sim.kill();
    let _ = sim.wait();
    assert!(!ok, "a missing port passed:\n{out}");
    let line = out
        .lines()
        .find(|l| l.starts_with("FAIL") && l.contains("centrifuge"))
        .unwrap_or_else(|| panic!("no failing centrifuge line:\n{out}"));
    assert!(
        line.contains("/dev/ttyUSB-not-there")
            && line.contains("does not exist")
            && line.contains("check the cable"),
        "{line}"
    );
    // The other devices are still checked, and the last word says what failed.
    assert!(out.contains("ok    fmu 1 (/dev/pts/"), "{out}");
    assert!(
        err.contains("not ready") && err.contains("centrifuge"),
        "{err}"
    );
}
