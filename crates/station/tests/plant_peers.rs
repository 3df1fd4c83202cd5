//! The station against implementations someone else wrote:
//! a temperature chamber served by pymodbus (`scripts/plant/chamber.py`,
//! Modbus TCP) and a power supply served by scpipy
//! (`scripts/plant/supply.py`), both in `scripts/test-tools`' virtual
//! environment (`target/venv-plant`), with faults injected: busy, an
//! outage, an alarm during a measuring pass, a stale error queue.

#[path = "common/bench.rs"]
mod bench;

use bench::{Operated, start_sim};
use spinbench_devices::chamber::ChamberConfig;
use spinbench_devices::config::PowerSupplyConfig;
use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::{Duration, Instant};

/// The plant tools' Python, or None (said) outside `scripts/test`.
fn python() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/venv-plant/bin/python");
    if p.is_file() {
        return Some(p);
    }
    assert!(
        std::env::var(spinbench_store::testing::POSTGRES_ENV).is_err(),
        "{}: missing; scripts/test-tools makes it",
        p.display()
    );
    eprintln!("skipped: no {} (run ./scripts/test)", p.display());
    None
}

fn script(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../scripts/plant")
        .join(name)
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// A plant peer in a child process, told faults on its stdin; killed when dropped.
struct Peer {
    child: Child,
    stdin: ChildStdin,
    lines: std::io::Lines<BufReader<std::process::ChildStdout>>,
    port: u16,
}

impl Peer {
    fn start(python: &PathBuf, name: &str, args: &[&str]) -> Peer {
        let port = free_port();
        let mut child = Command::new(python)
            .arg(script(name))
            .arg(port.to_string())
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("start the plant peer");
        let stdin = child.stdin.take().expect("stdin");
        let mut lines = BufReader::new(child.stdout.take().expect("stdout")).lines();
        let first = lines.next().expect("a line").expect("text");
        assert!(first.starts_with("listening"), "{first}");
        Peer {
            child,
            stdin,
            lines,
            port,
        }
    }

    /// Tell it a fault; returns once it has taken it (an outage: once it is down).
    /// (An earlier command's last word, e.g. an outage's end, is passed over.)
    fn tell(&mut self, command: &str) -> String {
        writeln!(self.stdin, "{command}").expect("tell");
        loop {
            let line = self.lines.next().expect("an answer").expect("text");
            if line.starts_with(&format!("ok {command}")) {
                return line;
            }
            assert!(line.starts_with("ok "), "{line}");
        }
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn chamber_section(port: u16, setpoint_register: u16) -> String {
    format!(
        "[chamber]\nname = \"pymodbus chamber\"\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:{port}\" }}\n\
         protocol = {{ kind = \"modbus-tcp\", setpoint = {setpoint_register}, process_value = 101, run = 102, \
         alarms = 103, purge = 104 }}\n"
    )
}

#[test]
fn the_chamber_driver_rides_busy_and_an_outage_of_a_pymodbus_server_and_names_its_exceptions() {
    let Some(python) = python() else { return };
    let mut peer = Peer::start(&python, "chamber.py", &[]);
    let config: ChamberConfig = toml::from_str::<toml::Table>(&chamber_section(peer.port, 100))
        .expect("toml")["chamber"]
        .clone()
        .try_into()
        .expect("section");
    let mut chamber = config.connect().expect("connect");
    assert_eq!(chamber.temperature_c().expect("air"), 23.0);
    // Busy twice: asked again, answered.
    peer.tell("busy 2");
    chamber
        .set_setpoint_c(30.0)
        .expect("asked again while busy");
    assert_eq!(chamber.setpoint_c().expect("read back"), 30.0);
    // Away for 3 s (connections refused): waited for, with back-off.
    peer.tell("outage 3");
    let away = Instant::now();
    assert_eq!(chamber.setpoint_c().expect("rode the outage"), 30.0);
    assert!(
        away.elapsed() >= Duration::from_secs(2),
        "{:?}",
        away.elapsed()
    );
    let _ = peer.lines.next();
    // An alarm is read as the controller's word.
    peer.tell("alarm 4");
    assert_eq!(chamber.alarms().expect("alarms"), 4);
    // A register the controller does not have: exception 02, named.
    let config: ChamberConfig = toml::from_str::<toml::Table>(&chamber_section(peer.port, 250))
        .expect("toml")["chamber"]
        .clone()
        .try_into()
        .expect("section");
    let mut wrong = config.connect().expect("connect");
    let e = wrong.setpoint_c().expect_err("no such register");
    assert!(e.to_string().contains("wrong register address"), "{e}");
}

#[test]
fn the_supply_driver_clears_what_another_program_left_in_an_scpipy_servers_queue() {
    let Some(python) = python() else { return };
    let peer = Peer::start(&python, "supply.py", &["--stale-error"]);
    let config: PowerSupplyConfig = toml::from_str(&format!(
        "name = \"scpipy supply\"\nchannels = 2\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:{}\" }}\n",
        peer.port
    ))
    .expect("section");
    let mut supply = config.connect().expect("connect");
    assert!(supply.identify().expect("*IDN?").contains("scpipy"));
    let stale = supply.clear_errors().expect("the queue read and cleared");
    assert_eq!(stale.len(), 1, "{stale:?}");
    assert_eq!(stale[0].0, -222, "{stale:?}");
    // Its own settings after: not blamed on the stale error.
    supply.configure(1, 15.0, 0.5).expect("configured");
    supply.set_output(1, true).expect("on");
    let out = supply.measure(1).expect("measured");
    assert_eq!(out.volts, 15.0);
    supply.set_output(1, false).expect("off");
    assert!(supply.clear_errors().expect("empty").is_empty());
}

/// `spinbench run` of the 20-g plan at 30 °C on a separate `spinbench sim`
/// whose chamber is `peer`.
fn run_with_chamber(dir: &std::path::Path, peer: &Peer, sim: &bench::Sim) -> Operated {
    Operated::run_on(
        dir,
        sim,
        "plant test",
        &chamber_section(peer.port, 100),
        &bench::plan_to_20g(
            "PLANT",
            "temperatures_c = [30]\nsoak = { tolerance_c = 0.5, window_s = 15, max_soak_s = 300 }",
        ),
        &[],
    )
}

#[test]
fn a_run_soaks_through_busy_an_outage_silence_and_a_reboot_and_an_alarm_while_measuring_fails_it() {
    let Some(python) = python() else { return };
    // Busy and away during the soak: the run completes.
    let dir = tempfile::tempdir().expect("tempdir");
    let sim = start_sim("10");
    let mut peer = Peer::start(&python, "chamber.py", &[]);
    let mut run = run_with_chamber(dir.path(), &peer, &sim);
    assert!(
        run.operate_until(&sim, Duration::from_secs(120), |l| l.contains("soaking at")),
        "no soak:\n{}",
        run.transcript()
    );
    // Six busy replies in a row: each asked again, and the operator told.
    peer.tell("busy 6");
    assert!(
        run.operate_until(&sim, Duration::from_secs(60), |l| l
            .contains("answered busy")
            && l.contains("times in this run")),
        "no notice of the busy replies:\n{}",
        run.transcript()
    );
    // Longer than the soak's 5-s poll, so that a poll meets it.
    peer.tell("outage 6");
    // 3 s with no reply at all, the connection up (a link dropping
    // bytes), inside the chamber's outage_s (30 s): ridden. Answered once
    // a poll has met it and it is over.
    let said = peer.tell("silence 3");
    assert!(!said.contains("dropped 0 "), "{said}");
    let status = run
        .wait(&sim, Duration::from_secs(300))
        .unwrap_or_else(|| panic!("the run did not end:\n{}", run.transcript()));
    assert!(status.success(), "{}", run.transcript());
    drop(run);
    drop(sim);

    // A controller that restarts during the soak and comes back at its
    // power-on 23 °C, stopped: the setpoint and the run are written again
    // and the run completes.
    let dir = tempfile::tempdir().expect("tempdir");
    let sim = start_sim("10");
    let mut peer = Peer::start(&python, "chamber.py", &[]);
    let mut run = run_with_chamber(dir.path(), &peer, &sim);
    assert!(
        run.operate_until(&sim, Duration::from_secs(120), |l| l.contains("soaking at")),
        "no soak:\n{}",
        run.transcript()
    );
    peer.tell("reboot 1");
    let status = run
        .wait(&sim, Duration::from_secs(300))
        .unwrap_or_else(|| panic!("the run did not end:\n{}", run.transcript()));
    assert!(status.success(), "{}", run.transcript());
    assert!(
        run.seen
            .iter()
            .any(|l| l.contains("held 23.0 °C") && l.contains("written again")),
        "{}",
        run.transcript()
    );
    drop(run);
    drop(sim);

    // An alarm while a pass measures: not completed, exit non-zero.
    let dir = tempfile::tempdir().expect("tempdir");
    let sim = start_sim("10");
    let mut peer = Peer::start(&python, "chamber.py", &[]);
    let mut run = run_with_chamber(dir.path(), &peer, &sim);
    assert!(
        run.operate_until(&sim, Duration::from_secs(180), |l| l.contains("10 g Up")),
        "never measured 10 g:\n{}",
        run.transcript()
    );
    peer.tell("alarm 4");
    let status = run
        .wait(&sim, Duration::from_secs(120))
        .unwrap_or_else(|| panic!("the run did not end:\n{}", run.transcript()));
    assert!(!status.success(), "{}", run.transcript());
    assert!(
        run.seen.iter().any(|l| l.contains("alarm word")),
        "{}",
        run.transcript()
    );
}
