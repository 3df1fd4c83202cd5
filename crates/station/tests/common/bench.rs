//! A separate `spinbench sim` process (real PTYs) for tests that drive it
//! with `spinbench run` as an operator would, and read its devices after.

// Shared by the signal and the store-outage tests; each uses a part.
#![allow(dead_code)]

use serde::Deserialize;
use spinbench_devices::config::{CentrifugeConfig, PowerSupplyConfig};
use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The device sections `spinbench sim` prints.
#[derive(Deserialize)]
pub struct Devices {
    /// The table.
    pub centrifuge: CentrifugeConfig,
    /// The supplies.
    pub power_supply: Vec<PowerSupplyConfig>,
}

/// A `spinbench sim` child; killed when dropped.
pub struct Sim {
    pub child: Child,
    /// The printed device sections.
    pub devices_toml: String,
    /// The control socket's address.
    pub control: String,
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub fn start_sim(speed: &str) -> Sim {
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
pub fn control(addr: &str, line: &str) -> String {
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
pub fn mounting_asked(prompt: &str) -> Option<&'static str> {
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

impl Sim {
    /// Read the table's rate until it is at rest (30 s at most) and the
    /// instrument rails' voltages, through the station's own drivers (the
    /// station process must have ended: the ports are free). (rate, rails).
    pub fn read_back(&self) -> (f64, Vec<f64>) {
        let devices: Devices = toml::from_str(&self.devices_toml).expect("devices");
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
        let rails = devices
            .power_supply
            .iter()
            .find(|p| p.name == "rails")
            .expect("rails");
        let mut rails = rails.connect().expect("rails");
        let volts = [1, 2]
            .into_iter()
            .map(|ch| rails.measure(ch).expect("measure").volts)
            .collect();
        (rate, volts)
    }
}

/// A `spinbench run` child whose prompts are answered as an operator
/// would (remount on the bench's control socket, press Enter), its
/// stderr lines kept.
pub struct Operated {
    /// The run's process.
    pub run: Child,
    stdin: std::process::ChildStdin,
    lines: std::sync::mpsc::Receiver<String>,
    /// Every stderr line seen so far.
    pub seen: Vec<String>,
}

impl Operated {
    /// Start `spinbench run` with `args`, operated on `sim`.
    pub fn start(args: &[&std::ffi::OsStr]) -> Operated {
        let mut run = Command::new(env!("CARGO_BIN_EXE_spinbench"))
            .arg("run")
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spinbench run");
        let stdin = run.stdin.take().expect("stdin");
        let stderr = run.stderr.take().expect("stderr");
        let (tx, lines) = std::sync::mpsc::channel::<String>();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    return;
                }
            }
        });
        Operated {
            run,
            stdin,
            lines,
            seen: Vec::new(),
        }
    }

    /// Answer prompts until a line satisfies `until` (true) or `limit`
    /// passes, or the process ends (false).
    pub fn operate_until(
        &mut self,
        sim: &Sim,
        limit: Duration,
        until: impl Fn(&str) -> bool,
    ) -> bool {
        let deadline = Instant::now() + limit;
        while Instant::now() < deadline {
            let Ok(line) = self.lines.recv_timeout(Duration::from_millis(200)) else {
                if self.run.try_wait().ok().flatten().is_some() {
                    self.seen.extend(self.lines.try_iter());
                    return false;
                }
                continue;
            };
            if let Some(m) = line.strip_prefix(">>> ").and_then(mounting_asked) {
                assert_eq!(control(&sim.control, &format!("MOUNT ALL {m}")), "OK");
                let _ = writeln!(self.stdin);
            }
            let hit = until(&line);
            self.seen.push(line);
            if hit {
                return true;
            }
        }
        false
    }

    /// Wait for the process to end, answering prompts, at most `limit`:
    /// its status, or None when it did not end in time.
    pub fn wait(&mut self, sim: &Sim, limit: Duration) -> Option<std::process::ExitStatus> {
        let deadline = Instant::now() + limit;
        while Instant::now() < deadline {
            if let Some(status) = self.run.try_wait().expect("wait") {
                self.seen.extend(self.lines.try_iter());
                return Some(status);
            }
            self.operate_until(sim, Duration::from_millis(300), |_| false);
        }
        None
    }

    /// Every line seen, for a failure's message.
    pub fn transcript(&self) -> String {
        self.seen.join("\n")
    }
}

/// The plan the signal, outage and plant tests run: mounting P, 0 to 20 g
/// in six levels, 10 s dwell, instruments `{prefix}1` and `{prefix}2`, with
/// `extra` lines (keys of the plan's top level).
pub fn plan_to_20g(prefix: &str, extra: &str) -> String {
    format!(
        "range_g = 20\nlevels = [0, 1, 5, 10, 15, 20]\npasses = [\"P\"]\nwarmup_s = 0\n\
         dwell = {{ seconds = 10 }}\nstability = {{ hold_s = 3 }}\n{extra}\n\
         [serials]\n1 = \"{prefix}1\"\n2 = \"{prefix}2\"\n"
    )
}

impl Operated {
    /// `spinbench run` of `plan` on `sim`'s devices as station `name` (its
    /// config with `sections` added), in `dir` (its data in `dir/data`),
    /// with `more` arguments.
    pub fn run_on(
        dir: &std::path::Path,
        sim: &Sim,
        name: &str,
        sections: &str,
        plan: &str,
        more: &[&std::ffi::OsStr],
    ) -> Operated {
        let station = dir.join("station.toml");
        std::fs::write(
            &station,
            format!(
                "station = \"{name}\"\n[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\n\
                 instrument_supply = \"rails\"\nmodule_supply = \"logic\"\n\n{}\n{sections}",
                sim.devices_toml
            ),
        )
        .expect("station");
        let plan_path = dir.join("plan.toml");
        std::fs::write(&plan_path, plan).expect("plan");
        let data = dir.join("data");
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "--station".as_ref(),
            station.as_os_str(),
            "--data".as_ref(),
            data.as_os_str(),
        ];
        args.extend_from_slice(more);
        args.push(plan_path.as_os_str());
        Operated::start(&args)
    }
}
