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

use crate::chamber::ChamberModel;
use crate::config::{SimConfig, SimDialect};
use crate::vba::Mounting;
use crate::world::{SupplyId, TICK_S, World};
use serialport::{SerialPort, TTYPort};
use spinbench_wire::fmu::{FrameDecoder, Message};
use std::collections::VecDeque;
use std::io::{self, BufRead, BufReader, Read, Write};
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

    /// Stop every thread.
    pub fn shutdown(mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
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

fn control_command(world: &mut World, line: &str) -> Option<String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    Some(match words.as_slice() {
        ["MOUNT", who, how] | ["mount", who, how] => match Mounting::parse(how) {
            None => format!("ERR unknown mounting '{how}': UP, DOWN, P or N"),
            Some(m) if who.eq_ignore_ascii_case("ALL") => {
                world.set_all_mountings(m);
                "OK".into()
            }
            Some(m) => match who.parse::<usize>() {
                Ok(i) if i < world.instrument_count() => {
                    world.set_mounting(i, m);
                    "OK".into()
                }
                _ => format!("ERR no instrument '{who}'"),
            },
        },
        ["TIME?"] => format!("{:.4}", world.now_s()),
        ["TRUTH?"] => serde_json::to_string(&world.truth()).unwrap_or_else(|e| format!("ERR {e}")),
        _ => "ERR commands: MOUNT ALL|<index> UP|DOWN|P|N, TIME?, TRUTH?".into(),
    })
}

/// How long a thread that found nothing to do sleeps: 100 µs at first,
/// doubling up to 20 ms while it stays idle, back to 100 µs on progress.
struct IdleBackoff(Duration);

impl Default for IdleBackoff {
    fn default() -> Self {
        IdleBackoff(IdleBackoff::SHORTEST)
    }
}

impl IdleBackoff {
    const SHORTEST: Duration = Duration::from_micros(100);
    const LONGEST: Duration = Duration::from_millis(20);

    /// The next sleep, after a round that made progress or not.
    fn next(&mut self, progressed: bool) -> Duration {
        self.0 = if progressed {
            Self::SHORTEST
        } else {
            (self.0 * 2).min(Self::LONGEST)
        };
        self.0
    }
}

fn run_clock(
    world: Shared<World>,
    buffers: Vec<Shared<VecDeque<u8>>>,
    speed: f64,
    stop: Arc<AtomicBool>,
    stats: Arc<ServeStats>,
) -> JoinHandle<()> {
    thread::spawn(move || {
        if speed == 0.0 {
            lockstep_clock(&world, &buffers, &stop);
            return;
        }
        let start = Instant::now();
        let mut ticks_done: u64 = 0;
        while !stop.load(Ordering::Relaxed) {
            let due = (start.elapsed().as_secs_f64() * speed / TICK_S) as u64;
            let mut stepped = 0;
            while ticks_done < due && stepped < 400 {
                let out = lock(&world).step();
                for (bytes, buffer) in out.iter().zip(&buffers) {
                    let mut b = lock(buffer);
                    if b.len() > MODULE_BUFFER_LIMIT {
                        stats
                            .overrun_bytes
                            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
                    } else {
                        b.extend(bytes);
                    }
                }
                ticks_done += 1;
                stepped += 1;
            }
            thread::sleep(Duration::from_millis(1));
        }
    })
}

/// The clock of virtual time. The world moves on the station's steps (see
/// [`crate::world`]); this thread only runs it in real time while it is
/// free-running (after a run: a table left spinning must slow down), and
/// keeps a station that never polls the rate fed ([`LOCKSTEP_LIVENESS`]).
fn lockstep_clock(world: &Shared<World>, buffers: &[Shared<VecDeque<u8>>], stop: &AtomicBool) {
    let mut free: Option<(Instant, u64)> = None;
    let mut last_second = (0u64, Instant::now());
    while !stop.load(Ordering::Relaxed) {
        {
            let mut w = lock(world);
            if w.free_running() {
                let (since, done) = free.get_or_insert_with(|| (Instant::now(), 0));
                let due = (since.elapsed().as_secs_f64() / TICK_S) as u64;
                let mut stepped = 0;
                while *done < due && stepped < 400 {
                    // Nothing streams: the bytes are empty.
                    let _ = w.step();
                    *done += 1;
                    stepped += 1;
                }
            } else {
                free = None;
                let seconds = w.seconds_produced();
                if seconds != last_second.0 {
                    last_second = (seconds, Instant::now());
                } else if w.streaming_any()
                    && w.outbox_empty()
                    && last_second.1.elapsed() > LOCKSTEP_LIVENESS
                    && buffers.iter().all(|b| lock(b).is_empty())
                {
                    w.advance_second();
                }
            }
        }
        // Nothing here needs to be quick: the station's own steps move the
        // world; this thread only paces real time after a run and liveness.
        thread::sleep(LOCKSTEP_CLOCK_PERIOD);
    }
}

/// Make a pty master non-blocking: a blocking write to a pty whose reader
/// stopped never returns, and the bench could then never shut down.
fn set_nonblocking(port: &TTYPort) -> io::Result<()> {
    use nix::fcntl::{FcntlArg, OFlag, fcntl};
    use std::os::fd::AsRawFd;
    let fd = port.as_raw_fd();
    let flags = fcntl(fd, FcntlArg::F_GETFL).map_err(io::Error::from)?;
    fcntl(
        fd,
        FcntlArg::F_SETFL(OFlag::from_bits_truncate(flags) | OFlag::O_NONBLOCK),
    )
    .map_err(io::Error::from)?;
    Ok(())
}

/// Serves one counter module on a pty: replies to its commands, and the
/// bytes the clock (paced) or the world itself (lockstep) produced.
fn serve_module(
    m: usize,
    master: TTYPort,
    world: Shared<World>,
    buffer: Shared<VecDeque<u8>>,
    stop: Arc<AtomicBool>,
) -> io::Result<Vec<JoinHandle<()>>> {
    set_nonblocking(&master)?;
    let mut reader = master
        .try_clone_native()
        .map_err(|e| io::Error::other(e.to_string()))?;
    let mut writer = master;
    let _ = reader.set_timeout(Duration::from_millis(20));
    let _ = writer.set_timeout(Duration::from_millis(200));
    let rx_buffer = buffer.clone();
    let rx_stop = stop.clone();
    let rx_world = world.clone();
    let rx = thread::spawn(move || {
        let mut decoder = FrameDecoder::new();
        let mut bytes = [0u8; 512];
        while !rx_stop.load(Ordering::Relaxed) {
            let n = match reader.read(&mut bytes) {
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::TimedOut => continue,
                // No station has the port open (EIO on a pty): wait for one.
                Err(_) => {
                    thread::sleep(Duration::from_millis(10));
                    continue;
                }
            };
            let mut messages = Vec::new();
            decoder.decode(&bytes[..n], |f| {
                messages.push(Message::decode(f).map_err(|_| ()))
            });
            for message in messages {
                let reply = lock(&rx_world).handle_module_message(m, message);
                lock(&rx_buffer).extend(reply);
            }
        }
    });
    let tx = thread::spawn(move || {
        let mut chunk = Vec::with_capacity(8192);
        let mut idle = IdleBackoff::default();
        let lockstep = lock(&world).lockstep();
        while !stop.load(Ordering::Relaxed) {
            {
                let produced = if lockstep {
                    lock(&world).take_outbox(m)
                } else {
                    Vec::new()
                };
                let mut b = lock(&buffer);
                b.extend(produced);
                let n = b.len().min(8192);
                chunk.clear();
                chunk.extend(b.drain(..n));
            }
            if chunk.is_empty() {
                thread::sleep(idle.next(false));
                continue;
            }
            idle.next(true);
            let mut sent = 0;
            while sent < chunk.len() && !stop.load(Ordering::Relaxed) {
                match writer.write(&chunk[sent..]) {
                    Ok(n) => sent += n,
                    // The kernel's buffer is full: the station is reading it.
                    Err(_) => thread::sleep(Duration::from_micros(200)),
                }
            }
        }
    });
    Ok(vec![rx, tx])
}

/// Split `pending` into complete lines (terminated by CR, LF or CR LF).
fn take_lines(pending: &mut Vec<u8>) -> Vec<String> {
    let mut lines = Vec::new();
    while let Some(i) = pending.iter().position(|&b| b == b'\n' || b == b'\r') {
        let line: Vec<u8> = pending.drain(..=i).take(i).collect();
        if !line.is_empty() {
            lines.push(String::from_utf8_lossy(&line).into_owned());
        }
    }
    lines
}

/// Which Modbus device of the chamber answers on a pty: the controller or
/// the purge relay module.
type ModbusAnswer = fn(&mut ChamberModel, &[u8]) -> Option<Vec<u8>>;

/// Serves the chamber's controller (or its purge relay) on a pty: Modbus RTU requests, framed by
/// their length (rmodbus's guess from the function code) and by the line
/// falling silent (a partial frame is dropped after 50 ms, as RTU's 3.5
/// characters of silence end a frame).
fn serve_pty_modbus(
    master: TTYPort,
    world: Shared<World>,
    stop: Arc<AtomicBool>,
    answer: ModbusAnswer,
) -> JoinHandle<()> {
    thread::spawn(move || {
        let mut port = master;
        let _ = set_nonblocking(&port);
        let _ = port.set_timeout(Duration::from_millis(20));
        let mut pending: Vec<u8> = Vec::new();
        let mut last_byte = Instant::now();
        let mut bytes = [0u8; 256];
        while !stop.load(Ordering::Relaxed) {
            match port.read(&mut bytes) {
                Ok(n) => {
                    pending.extend_from_slice(&bytes[..n]);
                    last_byte = Instant::now();
                }
                Err(e) if e.kind() == io::ErrorKind::TimedOut => {}
                Err(_) => {
                    thread::sleep(Duration::from_millis(10));
                    continue;
                }
            }
            if !pending.is_empty() && last_byte.elapsed() > Duration::from_millis(50) {
                pending.clear();
            }
            while pending.len() >= 8 {
                let Ok(len) = rmodbus::guess_request_frame_len(&pending, rmodbus::ModbusProto::Rtu)
                else {
                    pending.clear();
                    break;
                };
                let len = usize::from(len);
                if pending.len() < len {
                    break;
                }
                let frame: Vec<u8> = pending.drain(..len).collect();
                let reply = lock(&world).chamber_mut().and_then(|c| answer(c, &frame));
                if let Some(r) = reply {
                    let _ = port.write_all(&r);
                }
            }
        }
    })
}

fn serve_pty_lines(
    master: TTYPort,
    world: Shared<World>,
    handler: LineHandler,
    stop: Arc<AtomicBool>,
) -> JoinHandle<()> {
    thread::spawn(move || {
        let mut port = master;
        let _ = set_nonblocking(&port);
        let _ = port.set_timeout(Duration::from_millis(20));
        let mut pending = Vec::new();
        let mut bytes = [0u8; 256];
        while !stop.load(Ordering::Relaxed) {
            match port.read(&mut bytes) {
                Ok(n) => pending.extend_from_slice(&bytes[..n]),
                Err(e) if e.kind() == io::ErrorKind::TimedOut => continue,
                Err(_) => {
                    thread::sleep(Duration::from_millis(10));
                    continue;
                }
            }
            if pending.len() > 4096 {
                pending.clear();
            }
            for line in take_lines(&mut pending) {
                let reply = (handler.handle)(&mut lock(&world), &line);
                if let Some(r) = reply {
                    let _ = port.write_all(format!("{r}{}", handler.ending).as_bytes());
                }
            }
        }
    })
}

fn serve_tcp_lines(
    listener: TcpListener,
    world: Shared<World>,
    handler: LineHandler,
    stop: Arc<AtomicBool>,
) -> JoinHandle<()> {
    let handler = Arc::new(handler);
    thread::spawn(move || {
        let _ = listener.set_nonblocking(true);
        while !stop.load(Ordering::Relaxed) {
            match listener.accept() {
                Ok((stream, _)) => {
                    let (world, handler, stop) = (world.clone(), handler.clone(), stop.clone());
                    thread::spawn(move || serve_tcp_connection(stream, &world, &handler, &stop));
                }
                Err(_) => thread::sleep(Duration::from_millis(10)),
            }
        }
    })
}

fn serve_tcp_connection(
    stream: TcpStream,
    world: &Shared<World>,
    handler: &LineHandler,
    stop: &AtomicBool,
) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(100)));
    let Ok(mut writer) = stream.try_clone() else {
        return;
    };
    let mut reader = BufReader::new(stream);
    let mut line = String::new();
    while !stop.load(Ordering::Relaxed) {
        match reader.read_line(&mut line) {
            Ok(0) => return,
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                continue;
            }
            Err(_) => return,
        }
        let text = line.trim_end_matches(['\r', '\n']).to_string();
        line.clear();
        if text.is_empty() {
            continue;
        }
        if let Some(r) = (handler.handle)(&mut lock(world), &text)
            && writer
                .write_all(format!("{r}{}", handler.ending).as_bytes())
                .is_err()
        {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_split_on_any_terminator() {
        let mut p = b"*IDN?\r\nRATE?\rILK".to_vec();
        assert_eq!(
            take_lines(&mut p),
            vec!["*IDN?".to_string(), "RATE?".to_string()]
        );
        assert_eq!(p, b"ILK".to_vec());
    }

    #[test]
    fn control_commands() {
        let mut w = World::new(SimConfig::default());
        assert_eq!(
            control_command(&mut w, "MOUNT ALL UP").as_deref(),
            Some("OK")
        );
        assert_eq!(control_command(&mut w, "MOUNT 3 N").as_deref(), Some("OK"));
        assert!(control_command(&mut w, "MOUNT 99 N").is_some_and(|r| r.starts_with("ERR")));
        assert!(control_command(&mut w, "TRUTH?").is_some_and(|r| r.contains("k2_ug_per_g2")));
        assert_eq!(control_command(&mut w, "TIME?").as_deref(), Some("0.0000"));
    }
}
