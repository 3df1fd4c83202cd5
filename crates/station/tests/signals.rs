//! Whatever ends the process, the table stops: `spinbench run` drives a
//! separate `spinbench sim` process through the real drivers (real PTYs),
//! answers its prompts as an operator would (remounting through the bench's
//! control socket), and is sent SIGTERM, SIGHUP or SIGINT while the table
//! spins. After the station exits, this test reads the controller's rate
//! and the rails through the same drivers, and the run's record from the
//! store.

use serde::Deserialize;
use spinbench_devices::config::{CentrifugeConfig, PowerSupplyConfig};
use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

#[derive(Deserialize)]
struct Devices {
    centrifuge: CentrifugeConfig,
    power_supply: Vec<PowerSupplyConfig>,
}

/// A `spinbench sim` child; killed when dropped.
struct Sim {
    child: Child,
    /// The printed device sections.
    devices_toml: String,
    /// The control socket's address.
    control: String,
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start_sim(speed: &str) -> Sim {
    let mut child = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["sim", "--for", "600", "--speed", speed])
        .stdout(Stdio::piped())
        .spawn()
        .expect("start spinbench sim");
    let stdout = child.stdout.take().expect("stdout");
    let mut text = String::new();
    let mut control = String::new();
    for line in BufReader::new(stdout).lines() {
        let line = line.expect("line");
        if line.starts_with("# virtual bench running") {
            break;
        }
        if let Some(addr) = line.strip_prefix("# control socket") {
            control = addr.rsplit(' ').next().unwrap_or_default().to_string();
        }
        text.push_str(&line);
        text.push('\n');
    }
    assert!(!control.is_empty(), "no control socket printed:\n{text}");
    Sim {
        child,
        devices_toml: text,
        control,
    }
}

/// Send one line to the bench's control socket and read its answer.
fn control(addr: &str, line: &str) -> String {
    let mut stream = TcpStream::connect(addr).expect("control socket");
    stream
        .set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    writeln!(stream, "{line}").expect("send");
    let mut reply = String::new();
    let _ = BufReader::new(stream).read_line(&mut reply);
    reply.trim().to_string()
}

/// The bench's mounting for a prompt of the station ("input axis UP", "mounting P").
fn mounting_asked(prompt: &str) -> Option<&'static str> {
    [
        ("input axis UP", "UP"),
        ("input axis DOWN", "DOWN"),
        ("in mounting P", "P"),
        ("in mounting N", "N"),
    ]
    .into_iter()
    .find(|(text, _)| prompt.contains(text))
    .map(|(_, m)| m)
}

const PLAN: &str = r#"
range_g = 20
levels = [0, 1, 5, 10, 15, 20]
passes = ["P"]
warmup_s = 0
dwell = { seconds = 10 }
stability = { hold_s = 3 }
[serials]
1 = "SIG1"
2 = "SIG2"
"#;

/// Run a plan against a separate bench, signal the station at a level,
/// and check the table, the rails and the record afterwards.
fn signal_while_spinning(signal: &str, name: &str) {
    let dir = tempfile::tempdir().expect("tempdir");
    let sim = start_sim("10");
    let station = dir.path().join("station.toml");
    std::fs::write(
        &station,
        format!(
            "station = \"signal test\"\n[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\n\
             instrument_supply = \"rails\"\nmodule_supply = \"logic\"\n\n{}",
            sim.devices_toml
        ),
    )
    .expect("station");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, PLAN).expect("plan");
    let data = dir.path().join("data");
    let mut run = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["run", "--station"])
        .arg(&station)
        .arg("--data")
        .arg(&data)
        .arg(&plan)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spinbench run");
    let mut stdin = run.stdin.take().expect("stdin");
    let stderr = run.stderr.take().expect("stderr");
    let (lines_tx, lines) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if lines_tx.send(line).is_err() {
                return;
            }
        }
    });
    // The operator: remount as asked, press Enter; wait for a level above 1 g.
    let deadline = Instant::now() + Duration::from_secs(120);
    let mut seen = Vec::new();
    let mut spinning = false;
    while Instant::now() < deadline && !spinning {
        let Ok(line) = lines.recv_timeout(Duration::from_secs(1)) else {
            continue;
        };
        if let Some(m) = line.strip_prefix(">>> ").and_then(mounting_asked) {
            assert_eq!(control(&sim.control, &format!("MOUNT ALL {m}")), "OK");
            writeln!(stdin,).expect("Enter");
        }
        spinning = line.contains("10 g Up");
        seen.push(line);
    }
    assert!(spinning, "the run never reached 10 g:\n{}", seen.join("\n"));
    // Let the table reach speed, then the signal.
    std::thread::sleep(Duration::from_millis(1500));
    let kill = Command::new("kill")
        .args([&format!("-{signal}"), &run.id().to_string()])
        .status()
        .expect("kill");
    assert!(kill.success());
    let ended = Instant::now();
    let status = loop {
        if let Some(status) = run.try_wait().expect("wait") {
            break status;
        }
        assert!(
            ended.elapsed() < Duration::from_secs(60),
            "spinbench run did not exit within 60 s of {name}"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let rest: Vec<String> = lines.try_iter().collect();
    assert!(!status.success(), "an aborted run is not a success");
    assert!(
        rest.iter().any(|l| l.contains(name)),
        "the signal is named on screen:\n{}",
        rest.join("\n")
    );

    // The station is gone: its ports are free, read the devices ourselves.
    let devices: Devices = toml::from_str(&sim.devices_toml).expect("devices");
    let mut table = devices.centrifuge.connect().expect("centrifuge");
    let mut rate = f64::NAN;
    let stopping = Instant::now();
    while stopping.elapsed() < Duration::from_secs(30) {
        rate = table.read_rate().expect("rate");
        if rate.abs() < 0.05 {
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    assert!(
        rate.abs() < 0.05,
        "the table still turns at {rate} deg/s after {name}"
    );
    let rails = devices
        .power_supply
        .iter()
        .find(|p| p.name == "rails")
        .expect("rails");
    let mut rails = rails.connect().expect("rails");
    for ch in [1, 2] {
        let out = rails.measure(ch).expect("measure");
        assert!(
            out.volts.abs() < 0.5,
            "rail {ch} at {} V after {name}",
            out.volts
        );
    }
    check_recorded(&data, name);
}

/// The store says `aborted`, naming the signal.
fn check_recorded(data: &Path, name: &str) {
    let store = spinbench_store::Store::open_read_only(&spinbench_store::StoreTarget::File(
        data.join("spinbench.db"),
    ))
    .expect("store");
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 1);
    assert_eq!(runs[0].state, "aborted", "{:?}", runs[0].reason);
    let reason = runs[0].reason.clone().unwrap_or_default();
    assert!(reason.contains(name), "{reason}");
    for r in store.results(&runs[0].id).expect("results") {
        assert_eq!(r.outcome.as_str(), "incomplete", "{}", r.serial);
    }
}

#[test]
fn sigterm_stops_the_table_switches_off_and_records_the_signal() {
    signal_while_spinning("TERM", "SIGTERM");
}

#[test]
fn sighup_stops_the_table_switches_off_and_records_the_signal() {
    signal_while_spinning("HUP", "SIGHUP");
}

#[test]
fn sigint_stops_the_table_switches_off_and_records_the_signal() {
    signal_while_spinning("INT", "SIGINT");
}
