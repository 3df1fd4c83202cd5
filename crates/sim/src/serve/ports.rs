//! The serving loops: each counter module on its pseudo-terminal, the line
//! devices and the chamber's Modbus on theirs, line devices over TCP.

use super::{
    Arc, AtomicBool, BufReader, ChamberModel, Duration, FrameDecoder, Instant, JoinHandle,
    LineHandler, Message, Ordering, Shared, TTYPort, TcpListener, TcpStream, VecDeque, World, io,
    lock, thread,
};
use serialport::SerialPort;
use std::io::BufRead;
use std::io::Read;
use std::io::Write;

/// How long a thread that found nothing to do sleeps: 100 µs at first,
/// doubling up to 20 ms while it stays idle, back to 100 µs on progress.
pub(super) struct IdleBackoff(Duration);

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

/// Make a pty master non-blocking: a blocking write to a pty whose reader
/// stopped never returns, and the bench could then never shut down.
pub(super) fn set_nonblocking(port: &TTYPort) -> io::Result<()> {
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
pub(super) fn serve_module(
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
pub(super) fn take_lines(pending: &mut Vec<u8>) -> Vec<String> {
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
pub(super) type ModbusAnswer = fn(&mut ChamberModel, &[u8]) -> Option<Vec<u8>>;

/// Serves the chamber's controller (or its purge relay) on a pty: Modbus RTU requests, framed by
/// their length (rmodbus's guess from the function code) and by the line
/// falling silent (a partial frame is dropped after 50 ms, as RTU's 3.5
/// characters of silence end a frame).
pub(super) fn serve_pty_modbus(
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

pub(super) fn serve_pty_lines(
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

pub(super) fn serve_tcp_lines(
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

pub(super) fn serve_tcp_connection(
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
