//! The bench behind real operating-system endpoints: every counter module,
//! the centrifuge controller and both supplies on pseudo-terminals (the
//! station opens the `/dev/pts/N` paths exactly as it opens real ports), or
//! the controller and supplies on TCP. A control socket lets a simulated
//! operator remount instruments and read the truth.
//!
//! A clock thread advances the [`World`] in 2.5 ms ticks at `speed` × real
//! time; at speed 0 the world runs in virtual time, in lockstep with the
//! station (see [`crate::world`]): a two-hour test runs in seconds with the
//! same station code, and a seed gives the same results on every run. A
//! module's output is buffered; in a paced mode a station that stops
//! reading loses frames (counted as overruns), as with hardware.

mod clock;
mod control;
mod ports;
#[cfg(test)]
mod tests;

use clock::run_clock;
use control::control_command;
use ports::{ModbusAnswer, serve_module, serve_pty_lines, serve_pty_modbus, serve_tcp_lines};

use crate::chamber::ChamberModel;
use crate::config::{SimConfig, SimDialect};
use crate::vba::Mounting;
use crate::world::{SupplyId, TICK_S, World};
use serialport::{SerialPort, TTYPort};
use spinbench_wire::fmu::{FrameDecoder, Message};
use std::collections::VecDeque;
use std::io::{self, BufReader};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// Bytes a module may have waiting before a paced bench drops them.
const MODULE_BUFFER_LIMIT: usize = 8 * 1024;
/// Lockstep: wall time without a rate query, while the station has read
/// everything, after which the bench produces the next second anyway (a
/// client that reads the modules but never polls the rate still gets data;
/// such a run is not reproducible).
const LOCKSTEP_LIVENESS: Duration = Duration::from_secs(2);
/// How often the virtual-time clock looks at the world.
const LOCKSTEP_CLOCK_PERIOD: Duration = Duration::from_millis(5);

/// Where a device can be reached.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Endpoint {
    /// A pseudo-terminal path (`/dev/pts/N`).
    Pty(String),
    /// A TCP address (`127.0.0.1:port`).
    Tcp(String),
}

impl Endpoint {
    fn transport_toml(&self, baud: u32) -> String {
        match self {
            Endpoint::Pty(p) => format!("{{ kind = \"serial\", path = \"{p}\", baud = {baud} }}"),
            Endpoint::Tcp(a) => format!("{{ kind = \"tcp\", address = \"{a}\" }}"),
        }
    }
}

/// Where the station finds the bench's devices.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Endpoints {
    /// One per counter module.
    pub modules: Vec<Endpoint>,
    /// The centrifuge controller.
    pub centrifuge: Endpoint,
    /// The ±15 V instrument supply.
    pub rails: Endpoint,
    /// The +5 V module supply.
    pub logic: Endpoint,
    /// The control socket (`MOUNT`, `TIME?`, `TRUTH?`).
    pub control: String,
    /// The temperature chamber's controller (Modbus RTU), if the bench has one.
    pub chamber: Option<Endpoint>,
    /// The chamber's purge relay module (Modbus RTU), if its valve is on one.
    pub purge_relay: Option<Endpoint>,
}

/// How to expose the bench.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ServeOptions {
    /// Put the centrifuge controller and the supplies on TCP (loopback)
    /// instead of pseudo-terminals.
    pub line_devices_on_tcp: bool,
}

/// Counters of the serving layer.
#[derive(Debug, Default)]
pub struct ServeStats {
    /// Bytes dropped because a module's reader fell behind (paced modes).
    pub overrun_bytes: AtomicU64,
}

type Shared<T> = Arc<Mutex<T>>;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panicked thread leaves the bench in a usable state: keep serving.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// A running bench.
pub struct RunningBench {
    world: Shared<World>,
    endpoints: Endpoints,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    stats: Arc<ServeStats>,
    /// Keeps the pseudo-terminals' slave ends open, so a station may close
    /// and reopen its port without the bench seeing an end of file.
    _slaves: Vec<TTYPort>,
}

impl RunningBench {
    /// Build the world and start serving it.
    pub fn start(config: SimConfig, options: ServeOptions) -> io::Result<RunningBench> {
        config
            .validate()
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e.to_string()))?;
        let speed = config.speed;
        let dialect = config.centrifuge.dialect;
        let world = Arc::new(Mutex::new(World::new(config)));
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(ServeStats::default());
        let mut threads = Vec::new();
        let mut slaves = Vec::new();
        let n_modules = lock(&world).config().modules;

        // Counter modules: one pty each, with an output buffer the clock fills.
        let buffers: Vec<Shared<VecDeque<u8>>> = (0..n_modules)
            .map(|_| Arc::new(Mutex::new(VecDeque::new())))
            .collect();
        let mut modules = Vec::new();
        for (m, buffer) in buffers.iter().enumerate() {
            let (master, slave) = TTYPort::pair().map_err(|e| io::Error::other(e.to_string()))?;
            modules.push(Endpoint::Pty(slave.name().unwrap_or_default()));
            slaves.push(slave);
            threads.extend(serve_module(
                m,
                master,
                world.clone(),
                buffer.clone(),
                stop.clone(),
            )?);
        }

        let ending = match dialect {
            SimDialect::Acutrol => "\n",
            SimDialect::Mnemonic => "\r\n",
        };
        let line_device = |handler: LineHandler,
                           threads: &mut Vec<JoinHandle<()>>,
                           slaves: &mut Vec<TTYPort>|
         -> io::Result<Endpoint> {
            if options.line_devices_on_tcp {
                let listener = TcpListener::bind("127.0.0.1:0")?;
                let addr = listener.local_addr()?.to_string();
                threads.push(serve_tcp_lines(
                    listener,
                    world.clone(),
                    handler,
                    stop.clone(),
                ));
                Ok(Endpoint::Tcp(addr))
            } else {
                let (master, slave) =
                    TTYPort::pair().map_err(|e| io::Error::other(e.to_string()))?;
                let path = slave.name().unwrap_or_default();
                slaves.push(slave);
                threads.push(serve_pty_lines(
                    master,
                    world.clone(),
                    handler,
                    stop.clone(),
                ));
                Ok(Endpoint::Pty(path))
            }
        };
        let centrifuge = line_device(
            LineHandler {
                ending,
                handle: Box::new(|w: &mut World, l: &str| w.handle_centrifuge_line(l)),
            },
            &mut threads,
            &mut slaves,
        )?;
        let rails = line_device(
            LineHandler {
                ending: "\n",
                handle: Box::new(|w: &mut World, l: &str| w.handle_supply_line(SupplyId::Rails, l)),
            },
            &mut threads,
            &mut slaves,
        )?;
        let logic = line_device(
            LineHandler {
                ending: "\n",
                handle: Box::new(|w: &mut World, l: &str| w.handle_supply_line(SupplyId::Logic, l)),
            },
            &mut threads,
            &mut slaves,
        )?;

        // The chamber's controller: Modbus RTU on its own pty.
        let (has_chamber, has_relay) = {
            let w = lock(&world);
            let chamber = w.chamber();
            (
                chamber.is_some(),
                chamber.is_some_and(ChamberModel::purge_on_relay),
            )
        };
        let mut modbus_pty = |answer: ModbusAnswer| -> io::Result<Endpoint> {
            let (master, slave) = TTYPort::pair().map_err(|e| io::Error::other(e.to_string()))?;
            let path = slave.name().unwrap_or_default();
            slaves.push(slave);
            threads.push(serve_pty_modbus(
                master,
                world.clone(),
                stop.clone(),
                answer,
            ));
            Ok(Endpoint::Pty(path))
        };
        let chamber = if has_chamber {
            Some(modbus_pty(ChamberModel::answer_rtu)?)
        } else {
            None
        };
        let purge_relay = if has_relay {
            Some(modbus_pty(ChamberModel::answer_relay_rtu)?)
        } else {
            None
        };

        let control_listener = TcpListener::bind("127.0.0.1:0")?;
        let control = control_listener.local_addr()?.to_string();
        threads.push(serve_tcp_lines(
            control_listener,
            world.clone(),
            LineHandler {
                ending: "\n",
                handle: Box::new(control_command),
            },
            stop.clone(),
        ));

        threads.push(run_clock(
            world.clone(),
            buffers,
            speed,
            stop.clone(),
            stats.clone(),
        ));
        Ok(RunningBench {
            world,
            endpoints: Endpoints {
                modules,
                centrifuge,
                rails,
                logic,
                control,
                chamber,
                purge_relay,
            },
            stop,
            threads,
            stats,
            _slaves: slaves,
        })
    }

    /// Where the devices are.
    pub fn endpoints(&self) -> &Endpoints {
        &self.endpoints
    }

    /// Run `f` on the world (e.g. to remount instruments or read the truth).
    pub fn with_world<R>(&self, f: impl FnOnce(&mut World) -> R) -> R {
        f(&mut lock(&self.world))
    }

    /// Bytes dropped because the station did not keep up.
    pub fn overrun_bytes(&self) -> u64 {
        self.stats.overrun_bytes.load(Ordering::Relaxed)
    }

    /// The device sections of a station config that reach this bench.
    pub fn station_config_toml(&self) -> String {
        let w = lock(&self.world);
        let c = w.config();
        let e = &self.endpoints;
        let mut out = String::from(
            "# Devices of the spinbench virtual bench\n\n[centrifuge]\nname = \"sim-table\"\n",
        );
        out.push_str(&format!(
            "max_rate_deg_s = {}\n",
            c.centrifuge.max_rate_deg_s
        ));
        out.push_str(&format!(
            "transport = {}\n",
            e.centrifuge.transport_toml(9600)
        ));
        match c.centrifuge.dialect {
            SimDialect::Acutrol => out.push_str("dialect = { kind = \"acutrol\", axis = 1 }\n"),
            SimDialect::Mnemonic => out.push_str(MNEMONIC_DIALECT_TOML),
        }
        for (m, endpoint) in e.modules.iter().enumerate() {
            out.push_str(&format!(
                "\n[[fmu]]\nname = \"fmu{}\"\nmode = \"reciprocal\"\nreference_hz = {}\ntransport = {}\n",
                m + 1,
                c.reference_hz,
                endpoint.transport_toml(921_600)
            ));
        }
        for (name, channels, endpoint) in [("rails", 2, &e.rails), ("logic", 1, &e.logic)] {
            out.push_str(&format!(
                "\n[[power_supply]]\nname = \"{name}\"\nchannels = {channels}\ntransport = {}\n",
                endpoint.transport_toml(115_200)
            ));
        }
        if let Some(endpoint) = &e.chamber {
            let r = &crate::chamber::SIM_REGISTERS;
            // The purge register only when the valve is on the controller.
            let purge = match e.purge_relay {
                Some(_) => String::new(),
                None => format!("purge = {}, ", r.purge),
            };
            out.push_str(&format!(
                "\n[chamber]\nname = \"sim-chamber\"\ntransport = {}\nprotocol = {{ kind = \"modbus-rtu\", unit_id = {}, setpoint = {}, process_value = {}, process_value_is_input = true, run = {}, alarms = {}, {purge}counts_per_c = {} }}\n",
                endpoint.transport_toml(19_200),
                r.unit_id,
                r.setpoint,
                r.process_value,
                r.run,
                r.alarms,
                r.counts_per_c
            ));
            if let Some(relay) = &e.purge_relay {
                out.push_str(&format!(
                    "\n[chamber.purge_relay]\nname = \"sim-purge-relay\"\ntransport = {}\nprotocol = {{ kind = \"modbus-rtu\", unit_id = 1, coil = {} }}\n",
                    relay.transport_toml(19_200),
                    crate::chamber::SIM_RELAY_COIL
                ));
            }
        }
        out.push_str(&format!(
            "\n# control socket (MOUNT ALL UP|DOWN|P|N, TIME?, TRUTH?): {}\n",
            e.control
        ));
        out
    }

    /// Stop every thread (what dropping the bench does too).
    pub fn shutdown(self) {
        drop(self);
    }
}

impl Drop for RunningBench {
    /// A bench dropped stops serving: every thread is told and waited for,
    /// so no virtual device outlives its owner.
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            // A thread that panicked has stopped all the same.
            let _ = t.join();
        }
    }
}

/// The station-config dialect block for the simulated mnemonic controller.
pub const MNEMONIC_DIALECT_TOML: &str = r#"[centrifuge.dialect]
kind = "line"
name = "SIM-TABLE MNEMONIC"
line_ending = "\r\n"
rate_unit = "rpm"
rate_decimals = 4
commands = { identify = "ID?", arm = "ENA", disarm = "DIS", reset_interlocks = "RST", set_rate = "JOG {rate}", read_rate = "RATE?", read_interlocks = "ILK?", stop = "STO" }
replies = { read_rate = '^RATE (?P<rate>\S+)$', read_interlocks = '^ILK (?P<closed>[01])$', ack = '^OK$', error = '^ERR (?P<message>.*)$' }
"#;

/// Answers one command line of a device, if the command has a reply.
type LineFn = dyn Fn(&mut World, &str) -> Option<String> + Send + Sync;

struct LineHandler {
    ending: &'static str,
    handle: Box<LineFn>,
}
