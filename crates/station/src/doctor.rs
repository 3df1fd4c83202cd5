//! `spinbench doctor`: is this station ready to run? Checks the station
//! config, every port and device (opened, identified, answering in time),
//! the store (reachable, writable, migrated, sound), the clock and the free
//! disk, one line each, and says what to fix. Nothing moves: no rate is
//! commanded, no rail switched.

use anyhow::{Context, Result};
use spinbench_devices::config::TransportConfig;
use spinbench_engine::StationConfig;
use spinbench_store::{Store, StoreTarget};
use std::io::Write;
use std::path::Path;
use std::time::{Duration, Instant};

/// A device that answers slower than this is reported (it still passes).
const SLOW_ANSWER: Duration = Duration::from_millis(1000);
/// Less free disk than this under the data directory is a failure (a run's
/// raw captures and one-second values need room).
const MIN_FREE_BYTES: u64 = 1 << 30;
/// Less than this is a warning.
const LOW_FREE_BYTES: u64 = 10 << 30;

/// How a check came out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Ready.
    Ok,
    /// Works, but look at it.
    Warn,
    /// Not ready: the line says what to fix.
    Fail,
}

/// One check's line.
#[derive(Debug, Clone)]
pub struct Finding {
    /// How it came out.
    pub verdict: Verdict,
    /// What was checked (`centrifuge`, `store`, `clock`).
    pub what: String,
    /// What was found, and what to do when it is not ok.
    pub detail: String,
}

impl Finding {
    fn new(verdict: Verdict, what: impl Into<String>, detail: impl Into<String>) -> Finding {
        Finding {
            verdict,
            what: what.into(),
            detail: detail.into(),
        }
    }
}

/// Every check of a station: its config text (`source` names where it came
/// from), its store and its data directory.
pub fn check(station_toml: &str, source: &str, store: &StoreTarget, data: &Path) -> Vec<Finding> {
    let mut found = Vec::new();
    match StationConfig::from_toml(station_toml) {
        Ok(station) => {
            found.push(Finding::new(
                Verdict::Ok,
                "config",
                format!(
                    "{source}: station '{}', {} slot(s) on {} counter module(s){}",
                    station.station,
                    station.slots(),
                    station.fmu.len(),
                    if station.chamber.is_some() {
                        ", a temperature chamber"
                    } else {
                        ""
                    }
                ),
            ));
            found.extend(devices(&station));
            found.push(name_check(&station.station, store, data));
        }
        Err(e) => found.push(Finding::new(
            Verdict::Fail,
            "config",
            format!("{source}: {e} (fix that key; the devices were not checked)"),
        )),
    }
    found.push(store_check(store));
    found.push(clock_check());
    found.push(disk_check(data));
    found
}

/// Each device opened on its own transport and asked who it is.
fn devices(station: &StationConfig) -> Vec<Finding> {
    let mut found = Vec::new();
    let c = &station.centrifuge;
    found.push(device("centrifuge", &c.transport, || {
        let mut d = c.connect()?;
        Ok(d.identify()?)
    }));
    for (i, f) in station.fmu.iter().enumerate() {
        found.push(device(&format!("fmu {}", i + 1), &f.transport, || {
            let mut d = f.connect(i)?;
            Ok(d.status()
                .map(|s| format!("firmware {:#06x}", s.firmware_id))?)
        }));
    }
    for p in &station.power_supply {
        let role = if p.name == station.power.instrument_supply {
            "instrument supply".to_string()
        } else if station.power.module_supply.as_deref() == Some(p.name.as_str()) {
            "module supply".to_string()
        } else {
            format!("supply '{}'", p.name)
        };
        found.push(device(&role, &p.transport, || {
            let mut d = p.connect()?;
            let identity = d.identify()?;
            // What another program left in its error queue, read and cleared.
            let stale = d.clear_errors()?;
            Ok(if stale.is_empty() {
                identity
            } else {
                format!(
                    "{identity}; {} error(s) another program left in its queue, read and cleared (*CLS): {}",
                    stale.len(),
                    stale
                        .iter()
                        .map(|(code, text)| format!("{code}, \"{text}\""))
                        .collect::<Vec<_>>()
                        .join("; ")
                )
            })
        }));
    }
    if let Some(ch) = &station.chamber {
        found.push(device("chamber", &ch.transport, || {
            // Every register the run reads: the air, the setpoint (a wrong
            // setpoint register or scale shows here), the alarm word.
            let mut d = ch.connect()?;
            let air = d.temperature_c()?;
            let setpoint = d.setpoint_c()?;
            let alarms = d.alarms()?;
            if !(PLAUSIBLE_SETPOINT_C.0..=PLAUSIBLE_SETPOINT_C.1).contains(&setpoint) {
                anyhow::bail!(
                    "its setpoint reads {setpoint:.1} °C, outside {} to {} °C: check the map's \
                     setpoint register, counts_per_c and signed",
                    PLAUSIBLE_SETPOINT_C.0,
                    PLAUSIBLE_SETPOINT_C.1
                );
            }
            if alarms != 0 {
                anyhow::bail!(
                    "air {air:.1} °C, setpoint {setpoint:.1} °C, and an alarm is active \
                     (alarm word {alarms:#06x}): clear it at the controller before a run"
                );
            }
            Ok(format!(
                "air {air:.1} °C, setpoint {setpoint:.1} °C, no alarm"
            ))
        }));
    }
    found
}

/// The setpoints a chamber's controller plausibly holds [°C]; one read
/// outside them is a wrong register, scale or sign in the map.
pub const PLAUSIBLE_SETPOINT_C: (f64, f64) = (-80.0, 180.0);

/// One device: its port looked at first (so a missing one is named plainly),
/// then opened and asked, timed.
fn device(
    role: &str,
    transport: &TransportConfig,
    ask: impl FnOnce() -> anyhow::Result<String>,
) -> Finding {
    let place = match transport {
        TransportConfig::Serial(s) => s.path.clone(),
        TransportConfig::Tcp { address, .. } => address.clone(),
    };
    let what = format!("{role} ({place})");
    if let TransportConfig::Serial(s) = transport
        && let Some(problem) = port_problem(Path::new(&s.path))
    {
        return Finding::new(Verdict::Fail, what, problem);
    }
    let started = Instant::now();
    match ask() {
        Ok(identity) => {
            let took = started.elapsed();
            let verdict = if took > SLOW_ANSWER {
                Verdict::Warn
            } else {
                Verdict::Ok
            };
            let slow = if verdict == Verdict::Warn {
                " — slow: check the cable, the baud rate and the line's load"
            } else {
                ""
            };
            Finding::new(
                verdict,
                what,
                format!("{identity}, answered in {} ms{slow}", took.as_millis()),
            )
        }
        Err(e) => Finding::new(
            Verdict::Fail,
            what,
            format!(
                "{e} — check that it is switched on, its cable, and the {} in the station config",
                match transport {
                    TransportConfig::Serial(_) => "port's baud rate and protocol",
                    TransportConfig::Tcp { .. } =>
                        "address (and that nothing else holds the connection)",
                }
            ),
        ),
    }
}

/// Why a serial port cannot be used, if that can be told without opening it.
fn port_problem(path: &Path) -> Option<String> {
    match std::fs::metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Some(format!(
            "the port {} does not exist — check the cable and the USB adapter (ls /dev/serial/by-id/ \
             lists the ports present; prefer those stable names in the station config)",
            path.display()
        )),
        Err(e) => Some(format!("the port {}: {e}", path.display())),
        Ok(_) => match std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
        {
            Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => Some(format!(
                "the port {} cannot be opened by this user — add it to the port's group \
                 (usually dialout: sudo usermod -aG dialout USER, then log in again)",
                path.display()
            )),
            // Opened (then closed at once), or busy: the driver says more.
            _ => None,
        },
    }
}

/// Names a station is shipped or started with when none is given: a
/// second install left with one joins the first's fleet row.
const DEFAULT_NAMES: [&str; 3] = [
    "centrifuge station 1",
    "spinbench",
    "spinbench virtual bench",
];

/// The station's name in the fleet: held by another
/// station (another identity) in the store, or a default name a second
/// install would share. Doctor changes nothing: no identity is made, no
/// store created.
fn name_check(name: &str, target: &StoreTarget, data: &Path) -> Finding {
    let what = "station name";
    let own = std::fs::read_to_string(data.join(crate::paths::STATION_ID_FILE))
        .ok()
        .and_then(|t| t.lines().next().map(|l| l.trim().to_string()));
    let exists = match target {
        StoreTarget::File(p) => p.exists(),
        StoreTarget::Postgres(_) => true,
    };
    let holder = if exists {
        Store::connect(target)
            .ok()
            .and_then(|s| s.station_holder(name).ok().flatten())
    } else {
        None
    };
    if let Some(h) = holder
        && !h.instance.is_empty()
        && own.as_deref() != Some(h.instance.as_str())
    {
        let ago = (spinbench_store::now_s() - h.last_seen).max(0);
        return Finding::new(
            Verdict::Warn,
            what,
            format!(
                "'{name}' is held in the store by another station (identity {}, at {}, last heard {ago} s ago): \
                 two stations with one name merge in the fleet, its yield and run numbers, and `serve` refuses \
                 to start while the other is live. Give this station its own name (`station` in its station.toml, or serve --name)",
                h.instance,
                h.address.as_deref().unwrap_or("no address")
            ),
        );
    }
    if DEFAULT_NAMES.contains(&name) {
        return Finding::new(
            Verdict::Warn,
            what,
            format!(
                "'{name}' is a default name: a second station left with it would share this one's fleet row; \
                 give this station its own name (`station` in its station.toml, or serve --name)"
            ),
        );
    }
    Finding::new(Verdict::Ok, what, format!("'{name}' is this station's own"))
}

/// The store: reachable, migrated (each migration applied), writable, sound.
fn store_check(target: &StoreTarget) -> Finding {
    let what = format!("store ({target})");
    // Doctor changes nothing: a store that does not exist yet is not made
    // here (made by root, it would lock the service's user out later).
    if let StoreTarget::File(path) = target
        && !path.exists()
    {
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(std::path::Path::new("."));
        let (verdict, says) = match std::fs::metadata(dir) {
            Ok(m) if m.is_dir() && !m.permissions().readonly() => (
                Verdict::Ok,
                format!("no store yet; the first run makes it in {}", dir.display()),
            ),
            Ok(_) => (
                Verdict::Fail,
                format!(
                    "no store yet, and {} cannot be written; give it to the user that runs spinbench",
                    dir.display()
                ),
            ),
            Err(_) => (
                Verdict::Ok,
                format!(
                    "no store yet; the first run makes {} and the store in it",
                    dir.display()
                ),
            ),
        };
        return Finding::new(verdict, what, says);
    }
    let store = match Store::connect(target) {
        Ok(s) => s,
        Err(e) => {
            return Finding::new(
                Verdict::Fail,
                what,
                format!(
                    "{e} — check the path or the PostgreSQL URL, that the directory exists and is \
                     writable by this user, or that the server runs"
                ),
            );
        }
    };
    let latest = spinbench_store::MIGRATIONS.len() as i64;
    let version = match store.schema_version() {
        Ok(v) => v,
        Err(e) => return Finding::new(Verdict::Fail, what, e.to_string()),
    };
    if version != latest {
        return Finding::new(
            Verdict::Fail,
            what,
            format!(
                "schema version {version}, this software's is {latest} — run a newer spinbench, or restore a backup made by this version"
            ),
        );
    }
    // Every right the release uses, on every table and sequence: a role an
    // upgrade left without the new table's rights passes a write check on
    // the old ones.
    match store.missing_rights() {
        Ok(missing) if !missing.is_empty() => {
            let shown: Vec<String> = missing
                .iter()
                .take(8)
                .map(|(on, right)| format!("{right} on {on}"))
                .collect();
            let more = missing.len().saturating_sub(shown.len());
            let more = if more > 0 {
                format!(" and {more} more")
            } else {
                String::new()
            };
            return Finding::new(
                Verdict::Fail,
                what,
                format!(
                    "this role lacks {}{more} — the store's owner grants them: `spinbench migrate --db {} --grant {}`",
                    shown.join(", "),
                    target.for_owner(),
                    target.role().unwrap_or("ROLE")
                ),
            );
        }
        Ok(_) => {}
        Err(e) => return Finding::new(Verdict::Fail, what, e.to_string()),
    }
    let writable = store.check_writable();
    let integrity = store.integrity_check();
    match (writable, integrity) {
        (Ok(()), Ok(i)) if i == "ok" => Finding::new(
            Verdict::Ok,
            what,
            format!("writable, schema version {version} of {latest}, integrity ok"),
        ),
        (Ok(()), Ok(i)) => Finding::new(
            Verdict::Fail,
            what,
            format!("integrity check: {i} — restore the last backup (spinbench restore)"),
        ),
        (Err(e), _) | (_, Err(e)) => Finding::new(
            Verdict::Fail,
            what,
            format!("{e} — check that this user may write the store"),
        ),
    }
}

/// The clock: a run's times and the calibration due dates need it right.
fn clock_check() -> Finding {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0);
    // This software was written in 2026: a clock before that is wrong.
    const EARLIEST: i64 = 1_767_225_600; // 2026-01-01 00:00 UTC
    let shown = spinbench_report::lang::date_time(spinbench_report::Lang::En, now);
    if now < EARLIEST {
        return Finding::new(
            Verdict::Fail,
            "clock",
            format!(
                "{shown}: before this software was written — set the clock (timedatectl set-ntp true)"
            ),
        );
    }
    match std::fs::metadata("/run/systemd/timesync/synchronized") {
        Ok(_) => Finding::new(
            Verdict::Ok,
            "clock",
            format!("{shown}, synchronised (systemd-timesyncd)"),
        ),
        Err(_) => Finding::new(
            Verdict::Warn,
            "clock",
            format!(
                "{shown}; no time synchronisation seen — check `timedatectl` (due dates and run times follow this clock)"
            ),
        ),
    }
}

/// Free disk under the data directory (or its nearest existing parent).
fn disk_check(data: &Path) -> Finding {
    let mut at = data.to_path_buf();
    while !at.exists() {
        if !at.pop() {
            at = Path::new(".").to_path_buf();
            break;
        }
    }
    let what = format!("disk ({})", data.display());
    match nix::sys::statvfs::statvfs(&at) {
        Ok(s) => {
            let free = s.blocks_available().saturating_mul(s.fragment_size());
            let gb = free as f64 / 1e9;
            if free < MIN_FREE_BYTES {
                Finding::new(
                    Verdict::Fail,
                    what,
                    format!(
                        "{gb:.2} GB free — a run needs at least 1 GB: free space or move --data"
                    ),
                )
            } else if free < LOW_FREE_BYTES {
                Finding::new(
                    Verdict::Warn,
                    what,
                    format!("{gb:.1} GB free — back up and clear old runs' raw captures soon"),
                )
            } else {
                Finding::new(Verdict::Ok, what, format!("{gb:.1} GB free"))
            }
        }
        Err(e) => Finding::new(
            Verdict::Warn,
            what,
            format!("cannot tell the free space: {e}"),
        ),
    }
}

/// Print the findings, one line each, and a last line; an error when any failed.
pub fn report(findings: &[Finding], out: &mut dyn Write) -> Result<()> {
    for f in findings {
        let mark = match f.verdict {
            Verdict::Ok => "ok  ",
            Verdict::Warn => "WARN",
            Verdict::Fail => "FAIL",
        };
        writeln!(out, "{mark}  {}: {}", f.what, f.detail)?;
    }
    let failed: Vec<&str> = findings
        .iter()
        .filter(|f| f.verdict == Verdict::Fail)
        .map(|f| f.what.as_str())
        .collect();
    let warned = findings
        .iter()
        .filter(|f| f.verdict == Verdict::Warn)
        .count();
    if failed.is_empty() {
        writeln!(
            out,
            "ready{}",
            if warned > 0 {
                format!(" ({warned} warning(s) above)")
            } else {
                String::new()
            }
        )?;
        Ok(())
    } else {
        anyhow::bail!(
            "not ready: {} — fix what the line(s) above say, then run spinbench doctor again",
            failed.join("; ")
        )
    }
}

/// `spinbench doctor`: the station at `station` (or the virtual bench).
pub fn run(
    station: Option<&Path>,
    simulate: Option<&crate::virtual_bench::BenchArgs>,
    store: &StoreTarget,
    data: &Path,
    out: &mut dyn Write,
) -> Result<()> {
    if let Some(bench_args) = simulate {
        let bench = crate::virtual_bench::VirtualBench::open(bench_args, None, false)?;
        let findings = check(bench.station_toml(), "the virtual bench", store, data);
        return report(&findings, out);
    }
    let path =
        station.context("--station CONFIG is needed (or --simulate for the virtual bench)")?;
    let toml = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the station config", path.display()))?;
    let findings = check(&toml, &path.display().to_string(), store, data);
    report(&findings, out)
}
