//! End to end over real operating-system I/O: a pseudo-terminal pair (the
//! encoder on the master end plays the counter module, the driver opens the
//! `/dev/pts/N` path exactly as it would a real port) and TCP sockets on
//! loopback (the ACUTROL dialect, a SCPI supply, a dropped connection).

use serialport::{SerialPort, TTYPort};
use spinbench_devices::{
    Centrifuge, CounterModule, DialectCentrifuge, FmuDriver, IoPolicy, PowerSupply,
    ScpiPowerSupply, SerialSettings, SerialTransport, TcpTransport,
};
use spinbench_wire::centrifuge::{AcutrolDialect, acutrol_headers as h};
use spinbench_wire::fmu::{
    FrameDecoder, FrameEncoder, Message, ReciprocalCount, StreamMode, WindowAccumulator,
    WindowConfig,
};
use spinbench_wire::scpi::{HeaderSpec, parse_line};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpListener;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

const POLICY: IoPolicy = IoPolicy {
    timeout_ms: 1000,
    retries: 2,
};

/// A minimal counter module on the master end of a pty: acks commands and
/// streams `ticks` reciprocal frames after a start command.
fn fake_fmu(mut master: TTYPort, ticks: u16, done: Arc<AtomicBool>) -> thread::JoinHandle<()> {
    thread::spawn(move || {
        let _ = master.set_timeout(Duration::from_millis(20));
        let mut decoder = FrameDecoder::new();
        let mut encoder = FrameEncoder::new();
        let mut buf = [0u8; 512];
        while !done.load(Ordering::Relaxed) {
            let n = match master.read(&mut buf) {
                Ok(n) => n,
                Err(_) => continue,
            };
            let mut commands = Vec::new();
            decoder.decode(&buf[..n], |f| commands.push(Message::decode(f)));
            for command in commands.into_iter().flatten() {
                let ack = Message::Ack {
                    cmd: command.command() as u8,
                    result: 0,
                };
                let mut out = Vec::new();
                let _ = ack.encode(&mut out);
                if let Message::StartStreaming { .. } = command {
                    for seq in 0..ticks {
                        // Two resonators per instrument: 30 kHz and 29.9 kHz, exact to the clock.
                        let inputs = (0..12)
                            .map(|i| {
                                if i % 2 == 0 {
                                    ReciprocalCount {
                                        periods: 75,
                                        span: 250_000,
                                    }
                                } else {
                                    ReciprocalCount {
                                        periods: 299,
                                        span: 1_000_000,
                                    }
                                }
                            })
                            .collect();
                        let m = Message::ReciprocalCounts {
                            seq,
                            status: 0,
                            inputs,
                        };
                        if let Ok(bytes) = encoder.encode(m.command() as u8, &m.payload()) {
                            out.extend_from_slice(bytes);
                        }
                    }
                }
                let _ = master.write_all(&out);
            }
        }
    })
}

#[test]
fn counter_module_over_a_real_pseudo_terminal() {
    let (master, slave) = TTYPort::pair().expect("a pseudo-terminal pair");
    let path = slave.name().expect("the slave end has a /dev/pts name");
    // The driver opens the path itself, exactly as it would a real port.
    drop(slave);
    let done = Arc::new(AtomicBool::new(false));
    let fmu_thread = fake_fmu(master, 800, done.clone());

    let transport = SerialTransport::open(SerialSettings::new(path.clone(), 460_800))
        .expect("open the pty by path");
    let mut fmu = FmuDriver::new(transport, "fmu-pty", POLICY);
    fmu.set_power(0x3F).expect("relays");
    fmu.start(StreamMode::Reciprocal).expect("start");

    let mut windows = Vec::new();
    let mut acc = WindowAccumulator::new(WindowConfig::default());
    let deadline = Instant::now() + Duration::from_secs(10);
    while windows.len() < 2 && Instant::now() < deadline {
        for m in fmu
            .receive(Instant::now() + Duration::from_millis(200))
            .expect("receive")
        {
            windows.extend(acc.push(&m));
        }
        if acc.stats().ticks == 800 {
            windows.extend(acc.flush());
        }
    }
    fmu.stop().expect("stop");
    done.store(true, Ordering::Relaxed);
    fmu_thread.join().expect("fake module thread");

    assert_eq!(
        windows.len(),
        2,
        "two one-second windows from 800 ticks over {path}"
    );
    for w in &windows {
        assert!(w.is_complete());
        let i = w.instruments[0];
        assert_eq!(i.f1_hz, Some(30_000.0));
        assert_eq!(i.f2_hz, Some(29_900.0));
        assert!((i.df_hz.expect("dF") - 100.0).abs() < 1e-9);
    }
    let s = fmu.link_stats();
    assert_eq!(
        (
            s.decoder.bad_crc,
            s.decoder.bad_tail,
            s.decoder.bytes_skipped
        ),
        (0, 0, 0),
        "binary-clean line"
    );
}

/// An ACUTROL-speaking table on loopback: accepts long and short forms.
fn fake_acutrol(
    listener: TcpListener,
    drop_first_connection: bool,
) -> thread::JoinHandle<Vec<String>> {
    thread::spawn(move || {
        let mut seen = Vec::new();
        let mut rate = 0.0_f64;
        let mut closed = false;
        let mut first = true;
        for stream in listener
            .incoming()
            .take(if drop_first_connection { 2 } else { 1 })
        {
            let Ok(stream) = stream else { continue };
            let mut writer = stream.try_clone().expect("clone");
            let reader = BufReader::new(stream);
            for line in reader.lines() {
                let Ok(line) = line else { break };
                seen.push(line.clone());
                if first && drop_first_connection {
                    first = false;
                    break; // drop the connection without answering
                }
                let Ok(cmd) = parse_line(&line) else { continue };
                let is = |spec: &str| HeaderSpec::new(spec).matches(&cmd);
                let reply = if is(h::IDN) {
                    Some("ACUTRONIC,SIM,0,1".to_string())
                } else if is(h::DEMAND_RATE) {
                    rate = cmd.args.get(1).and_then(|a| a.parse().ok()).unwrap_or(rate);
                    None
                } else if is(h::READ_RATE) {
                    Some(format!("{rate:.4}"))
                } else if is(h::INTERLOCK_CLOSE) {
                    closed = true;
                    None
                } else if is(h::INTERLOCK_OPEN) {
                    closed = false;
                    None
                } else if is(h::INTERLOCK_QUERY) {
                    Some(if closed { "1" } else { "0" }.to_string())
                } else if is(h::MODE_OFF) {
                    rate = 0.0;
                    None
                } else {
                    None
                };
                if let Some(r) = reply {
                    let _ = writer.write_all(format!("{r}\n").as_bytes());
                }
                if line.to_ascii_uppercase().starts_with(":INT") && line.contains("OPEN") {
                    break;
                }
            }
        }
        seen
    })
}

#[test]
fn acutrol_over_tcp_in_short_form() {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr").to_string();
    let server = fake_acutrol(listener, false);
    let transport = TcpTransport::connect(addr, Duration::from_secs(1)).expect("connect");
    let dialect = AcutrolDialect {
        axis: 1,
        short_form: true,
    };
    let mut c = DialectCentrifuge::new(transport, dialect, "table", POLICY, 3600.0);
    assert_eq!(c.identify().expect("idn"), "ACUTRONIC,SIM,0,1");
    c.arm().expect("arm");
    assert!(c.read_interlocks().expect("closed"));
    c.set_rate(1234.5).expect("rate");
    assert_eq!(c.read_rate().expect("read"), 1234.5);
    c.stop().expect("stop");
    assert_eq!(c.read_rate().expect("read"), 0.0);
    c.disarm().expect("disarm");
    let seen = server.join().expect("server");
    assert!(seen.contains(&":DEM:RAT 1,1234.5".to_string()), "{seen:?}");
}

#[test]
fn a_dropped_tcp_connection_is_reconnected() {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr").to_string();
    let server = fake_acutrol(listener, true);
    let transport = TcpTransport::connect(addr, Duration::from_secs(1)).expect("connect");
    let mut c = DialectCentrifuge::new(
        transport,
        AcutrolDialect::default(),
        "table",
        POLICY,
        3600.0,
    );
    // The first query is swallowed and the connection dropped; the driver
    // reconnects and asks again.
    assert_eq!(c.identify().expect("after reconnect"), "ACUTRONIC,SIM,0,1");
    c.disarm().expect("disarm");
    let seen = server.join().expect("server");
    assert_eq!(seen.iter().filter(|l| *l == "*IDN?").count(), 2, "{seen:?}");
}

#[test]
fn scpi_supply_over_tcp() {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr").to_string();
    let server = thread::spawn(move || {
        let (stream, _) = listener.accept().expect("accept");
        let mut writer = stream.try_clone().expect("clone");
        let mut volts = [0.0_f64; 3];
        let mut on = [false; 3];
        let mut ch = 1usize;
        for line in BufReader::new(stream).lines() {
            let Ok(line) = line else { break };
            let Ok(cmd) = parse_line(&line) else { continue };
            let is = |spec: &str| HeaderSpec::new(spec).matches(&cmd);
            let arg = |i: usize| cmd.args.get(i).cloned().unwrap_or_default();
            let reply = if is("*IDN?") {
                Some("SIM,PSU,0,1".to_string())
            } else if is("INSTrument:NSELect") {
                ch = arg(0).parse().unwrap_or(1).clamp(1, 2);
                None
            } else if is("VOLTage") {
                volts[ch] = arg(0).parse().unwrap_or(0.0);
                None
            } else if is("OUTPut") {
                on[ch] = arg(0) == "ON";
                None
            } else if is("SYSTem:ERRor?") {
                Some("0,\"No error\"".to_string())
            } else if is("MEASure:VOLTage?") {
                Some(format!("{}", if on[ch] { volts[ch] } else { 0.0 }))
            } else if is("MEASure:CURRent?") {
                Some(format!("{}", if on[ch] { 0.12 } else { 0.0 }))
            } else {
                None
            };
            if let Some(r) = reply {
                let _ = writer.write_all(format!("{r}\n").as_bytes());
            }
        }
    });
    let transport = TcpTransport::connect(addr, Duration::from_secs(1)).expect("connect");
    let mut psu = ScpiPowerSupply::new(transport, "rails", 2, POLICY);
    assert_eq!(psu.identify().expect("idn"), "SIM,PSU,0,1");
    psu.configure(1, 15.0, 0.5).expect("configure");
    psu.set_output(1, true).expect("on");
    let m = psu.measure(1).expect("measure");
    assert_eq!((m.volts, m.amps), (15.0, 0.12));
    assert_eq!(psu.measure(2).expect("measure").volts, 0.0);
    drop(psu);
    server.join().expect("server");
}
