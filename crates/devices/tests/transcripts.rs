//! Transcript tests (expected writes, scripted replies) for every driver
//! command, including timeouts, garbage replies, retries, refusals and
//! reconnection.

use spinbench_devices::{
    Centrifuge, CounterModule, DeviceError, DeviceErrorKind, DialectCentrifuge, FmuDriver,
    IoPolicy, PowerSupply, ScpiPowerSupply, Step, Transcript,
};
use spinbench_wire::centrifuge::{AcutrolDialect, LineDialect, LineDialectConfig};
use spinbench_wire::fmu::{Message, ReciprocalCount, StatusReply, StreamMode};
use std::time::{Duration, Instant};

const POLICY: IoPolicy = IoPolicy {
    timeout_ms: 50,
    retries: 2,
};

fn acutrol(steps: Vec<Step>) -> (DialectCentrifuge<Transcript, AcutrolDialect>, Transcript) {
    let t = Transcript::new(steps);
    (
        DialectCentrifuge::new(t.clone(), AcutrolDialect::default(), "spin", POLICY, 3600.0),
        t,
    )
}

fn w(s: &str) -> Step {
    Step::write(&format!("{s}\n"))
}

fn r(s: &str) -> Step {
    Step::reply(&format!("{s}\n"))
}

#[test]
fn acutrol_every_command() {
    let (mut c, t) = acutrol(vec![
        w("*IDN?"),
        r("ACUTRONIC,ACUTROL3000,SN42,4.1"),
        w(":INTERLOCK:RESET 1"),
        w(":INTERLOCK:CLOSE 1"),
        w(":INTERLOCK?"),
        r("1"),
        w(":DEMAND:RATE 1,360"),
        w(":MODE:RATE 1"),
        w(":READ:RATE? 1"),
        Step::reply("+3.5999"),
        Step::reply("8E+02\n"),
        w(":MODE:OFF 1"),
        w(":INTERLOCK:OPEN 1"),
    ]);
    assert_eq!(c.identify().expect("idn"), "ACUTRONIC,ACUTROL3000,SN42,4.1");
    c.reset_interlocks().expect("reset");
    c.arm().expect("arm");
    assert!(c.read_interlocks().expect("interlocks"));
    c.set_rate(360.0).expect("rate");
    assert_eq!(c.read_rate().expect("read"), 359.998);
    c.stop().expect("stop");
    c.disarm().expect("disarm");
    t.verify().expect("transcript followed");
}

#[test]
fn a_lost_reply_is_retried_after_discarding_stale_input() {
    let (mut c, t) = acutrol(vec![
        w(":READ:RATE? 1"),
        Step::Silence,
        w(":READ:RATE? 1"),
        r("90"),
    ]);
    assert_eq!(c.read_rate().expect("second attempt"), 90.0);
    t.verify().expect("transcript followed");
    assert_eq!(t.discards(), 1);
}

#[test]
fn a_garbled_reply_is_retried() {
    let (mut c, t) = acutrol(vec![
        w(":READ:RATE? 1"),
        r("\u{1}#%garbage"),
        w(":READ:RATE? 1"),
        r("90.5"),
    ]);
    assert_eq!(c.read_rate().expect("second attempt"), 90.5);
    t.verify().expect("transcript followed");
}

#[test]
fn silence_on_every_attempt_is_a_timeout_naming_device_and_command() {
    let steps = (0..3)
        .flat_map(|_| [w(":READ:RATE? 1"), Step::Silence])
        .collect();
    let (mut c, t) = acutrol(steps);
    let e = c.read_rate().expect_err("no reply");
    assert_eq!(
        e.kind,
        DeviceErrorKind::Timeout {
            waited: Duration::from_millis(50),
            attempts: 3
        }
    );
    let text = e.to_string();
    assert!(text.starts_with("centrifuge 'spin' (ACUTROL) (transcript): ':READ:RATE? 1': no reply within 50 ms (3 attempt(s))"), "{text}");
    t.verify().expect("transcript followed");
}

#[test]
fn garbage_on_every_attempt_is_garbled() {
    let steps = (0..3)
        .flat_map(|_| [w(":INTERLOCK?"), r("maybe")])
        .collect();
    let (mut c, t) = acutrol(steps);
    let e = c.read_interlocks().expect_err("garbage");
    assert!(
        matches!(e.kind, DeviceErrorKind::Garbled { attempts: 3, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("garbled reply 'maybe'"), "{e}");
    t.verify().expect("transcript followed");
}

#[test]
fn a_port_that_disappears_is_reopened() {
    let (mut c, t) = acutrol(vec![
        Step::Disconnect,
        Step::Reopen,
        w(":READ:RATE? 1"),
        r("12"),
    ]);
    assert_eq!(c.read_rate().expect("after reconnect"), 12.0);
    t.verify().expect("transcript followed");
}

#[test]
fn a_port_that_stays_away_is_an_io_error() {
    let (mut c, _t) = acutrol(vec![Step::Disconnect]);
    let e = c.read_rate().expect_err("gone");
    assert!(matches!(e.kind, DeviceErrorKind::Io(_)), "{e}");
    assert!(e.to_string().contains("could not be reopened"), "{e}");
}

#[test]
fn rates_above_the_limit_are_never_sent() {
    let (mut c, t) = acutrol(vec![]);
    for bad in [3600.1, -4000.0, f64::NAN, f64::INFINITY] {
        let e = c.set_rate(bad).expect_err("refused");
        assert!(matches!(e.kind, DeviceErrorKind::Rejected(_)), "{e}");
    }
    t.verify().expect("nothing was written");
}

fn turnmaster(steps: Vec<Step>) -> (DialectCentrifuge<Transcript, LineDialect>, Transcript) {
    let config: LineDialectConfig = toml::from_str(
        r#"
        name = "TurnMaster"
        line_ending = "\r"
        rate_unit = "rpm"
        [commands]
        identify = "ID?"
        arm = "ENA"
        set_rate = "JOG {rate}"
        read_rate = "RATE?"
        stop = "STO"
        [replies]
        read_rate = '^RATE (?P<rate>\S+)$'
        ack = '^OK$'
        error = '^ERR (?P<message>.*)$'
        "#,
    )
    .expect("toml");
    let t = Transcript::new(steps);
    (
        DialectCentrifuge::new(
            t.clone(),
            LineDialect::new(config).expect("valid"),
            "tm",
            POLICY,
            3600.0,
        ),
        t,
    )
}

#[test]
fn configured_dialect_every_command() {
    let (mut c, t) = turnmaster(vec![
        Step::write("ID?\r"),
        Step::reply("TM3000 v2\r"),
        Step::write("ENA\r"),
        Step::reply("OK\r"),
        Step::write("JOG 60.000\r"),
        Step::reply("OK\r"),
        Step::write("RATE?\r"),
        Step::reply("RATE 59.99\r"),
        Step::write("STO\r"),
        Step::reply("OK\r"),
    ]);
    assert_eq!(c.identify().expect("id"), "TM3000 v2");
    c.arm().expect("arm");
    c.set_rate(360.0).expect("60 rpm");
    assert!((c.read_rate().expect("rate") - 359.94).abs() < 1e-9);
    c.stop().expect("stop");
    // No disarm and no interlock query in this dialect: disarm is a no-op, the query is refused.
    c.disarm().expect("no-op");
    let e = c.read_interlocks().expect_err("not in dialect");
    assert!(
        e.to_string()
            .contains("has no command to read the interlocks"),
        "{e}"
    );
    t.verify().expect("transcript followed");
}

#[test]
fn a_refusal_is_final_and_not_retried() {
    let (mut c, t) = turnmaster(vec![
        Step::write("JOG 600.000\r"),
        Step::reply("ERR overspeed\r"),
    ]);
    let e = c.set_rate(3600.0).expect_err("refused");
    assert_eq!(e.kind, DeviceErrorKind::Refused("overspeed".into()));
    t.verify().expect("one attempt only");
}

fn psu(steps: Vec<Step>) -> (ScpiPowerSupply<Transcript>, Transcript) {
    let t = Transcript::new(steps);
    (ScpiPowerSupply::new(t.clone(), "rails", 2, POLICY), t)
}

#[test]
fn power_supply_every_command() {
    let ok = || r("0,\"No error\"");
    let (mut p, t) = psu(vec![
        w("*IDN?"),
        r("RIGOL TECHNOLOGIES,DP832,DP8A1234,00.01.16"),
        w("INST:NSEL 2"),
        w("VOLT 15"),
        w("SYST:ERR?"),
        ok(),
        w("CURR 0.5"),
        w("SYST:ERR?"),
        ok(),
        w("INST:NSEL 2"),
        w("OUTP ON"),
        w("SYST:ERR?"),
        ok(),
        w("INST:NSEL 2"),
        w("MEAS:VOLT?"),
        r("15.002"),
        w("MEAS:CURR?"),
        r("0.1234"),
        w("INST:NSEL 2"),
        w("OUTP OFF"),
        w("SYST:ERR?"),
        ok(),
    ]);
    assert!(p.identify().expect("idn").starts_with("RIGOL"));
    p.configure(2, 15.0, 0.5).expect("configure");
    p.set_output(2, true).expect("on");
    let m = p.measure(2).expect("measure");
    assert_eq!((m.volts, m.amps), (15.002, 0.1234));
    p.set_output(2, false).expect("off");
    t.verify().expect("transcript followed");
}

#[test]
fn power_supply_reads_and_clears_errors_left_from_before() {
    // Another program left a refusal in the queue: read (to be reported),
    // then cleared, so the station's own correct setting is not blamed.
    let (mut p, t) = psu(vec![
        w("SYST:ERR?"),
        r("-222,\"Data out of range\""),
        w("SYST:ERR?"),
        r("-113,\"Undefined header\""),
        w("SYST:ERR?"),
        r("0,\"No error\""),
        w("*CLS"),
    ]);
    let stale = p.clear_errors().expect("cleared");
    assert_eq!(
        stale,
        vec![
            (-222, "Data out of range".to_string()),
            (-113, "Undefined header".to_string())
        ]
    );
    t.verify().expect("transcript followed");
}

#[test]
fn power_supply_refusals_and_bad_channels() {
    let (mut p, t) = psu(vec![
        w("INST:NSEL 1"),
        w("VOLT 40"),
        w("SYST:ERR?"),
        r("-222,\"Data out of range\""),
    ]);
    let e = p.configure(1, 40.0, 0.1).expect_err("refused");
    assert_eq!(
        e.kind,
        DeviceErrorKind::Refused("error -222, \"Data out of range\"".into())
    );
    assert_eq!(e.command, "VOLT 40");
    let e: DeviceError = p.set_output(3, true).expect_err("no channel 3");
    assert!(e.to_string().contains("outputs 1 to 2"), "{e}");
    assert!(p.configure(1, -1.0, 0.1).is_err());
    t.verify().expect("transcript followed");
}

#[test]
fn power_supply_retries_a_lost_measurement() {
    let (mut p, t) = psu(vec![
        w("INST:NSEL 1"),
        w("MEAS:VOLT?"),
        Step::Silence,
        w("MEAS:VOLT?"),
        r("5.0"),
        w("MEAS:CURR?"),
        r("x"),
        w("MEAS:CURR?"),
        r("0.2"),
    ]);
    let m = p.measure(1).expect("after retries");
    assert_eq!((m.volts, m.amps), (5.0, 0.2));
    t.verify().expect("transcript followed");
}

fn frame(m: &Message) -> Vec<u8> {
    let mut out = Vec::new();
    m.encode(&mut out).expect("fits");
    out
}

fn counts(seq: u16) -> Message {
    Message::ReciprocalCounts {
        seq,
        status: 0,
        inputs: vec![
            ReciprocalCount {
                periods: 75,
                span: 250_000
            };
            12
        ],
    }
}

#[test]
fn counter_module_every_command_and_stream_frames_are_kept() {
    let status = StatusReply {
        firmware_id: 0x0203,
        relay_mask: 0x3F,
        rx_crc_errors: 0,
        rx_tail_errors: 0,
        overruns: 0,
    };
    let t = Transcript::new(vec![
        Step::Write(frame(&Message::StatusRequest)),
        Step::Reply(frame(&Message::Status(status))),
        Step::Write(frame(&Message::SetPower { mask: 0x3F })),
        Step::Reply(frame(&Message::Ack {
            cmd: 0x10,
            result: 0,
        })),
        Step::Write(frame(&Message::StartStreaming {
            mode: StreamMode::Reciprocal,
        })),
        // Counts may overtake the ack: they are queued, not lost.
        Step::Reply(
            [
                frame(&counts(0)),
                frame(&Message::Ack {
                    cmd: 0x11,
                    result: 0,
                }),
            ]
            .concat(),
        ),
        Step::Reply([frame(&counts(1)), frame(&counts(2))].concat()),
        Step::Write(frame(&Message::StopStreaming)),
        Step::Reply(frame(&Message::Ack {
            cmd: 0x12,
            result: 0,
        })),
    ]);
    let mut fmu = FmuDriver::new(t.clone(), "fmu1", POLICY);
    assert_eq!(fmu.status().expect("status"), status);
    fmu.set_power(0x3F).expect("power");
    fmu.start(StreamMode::Reciprocal).expect("start");
    let deadline = Instant::now() + Duration::from_millis(50);
    let mut got = fmu.receive(deadline).expect("first");
    got.extend(fmu.receive(deadline).expect("more"));
    assert_eq!(got, vec![counts(0), counts(1), counts(2)]);
    fmu.stop().expect("stop");
    assert_eq!(fmu.link_stats().decoder.frames, 7);
    t.verify().expect("transcript followed");
}

#[test]
fn counter_module_retries_a_lost_ack_and_reports_refusals() {
    let set = frame(&Message::SetPower { mask: 1 });
    let t = Transcript::new(vec![
        Step::Write(set.clone()),
        Step::Silence,
        Step::Write(set.clone()),
        Step::Reply(frame(&Message::Ack {
            cmd: 0x10,
            result: 0,
        })),
        Step::Write(set),
        Step::Reply(frame(&Message::Ack {
            cmd: 0x10,
            result: 4,
        })),
    ]);
    let mut fmu = FmuDriver::new(t.clone(), "fmu1", POLICY);
    fmu.set_power(1).expect("second attempt");
    let e = fmu.set_power(1).expect_err("refused");
    assert_eq!(
        e.kind,
        DeviceErrorKind::Refused("the module answered error code 4".into())
    );
    t.verify().expect("transcript followed");
}

#[test]
fn counter_module_silence_is_a_timeout_and_corrupt_frames_are_counted() {
    let stop = frame(&Message::StopStreaming);
    let mut corrupt = frame(&counts(5));
    corrupt[6] ^= 0x40;
    let t = Transcript::new(vec![
        Step::Reply(corrupt),
        Step::Write(stop.clone()),
        Step::Silence,
        Step::Write(stop.clone()),
        Step::Silence,
        Step::Write(stop),
        Step::Silence,
    ]);
    let mut fmu = FmuDriver::new(t.clone(), "fmu1", POLICY);
    assert!(
        fmu.receive(Instant::now() + Duration::from_millis(5))
            .expect("nothing valid")
            .is_empty()
    );
    assert_eq!(fmu.link_stats().decoder.bad_crc, 1);
    let e = fmu.stop().expect_err("silent");
    assert!(
        matches!(e.kind, DeviceErrorKind::Timeout { attempts: 3, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("counter module 'fmu1'"), "{e}");
    t.verify().expect("transcript followed");
}
