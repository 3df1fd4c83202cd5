//! Transcript tests of both chamber drivers (expected writes, scripted
//! replies): every operation, a lost reply retried, a garbled reply, a
//! Modbus exception as a final refusal, a setpoint out of range never sent.

use spinbench_devices::chamber::{Chamber, LineChamber, ModbusChamber};
use spinbench_devices::{DeviceErrorKind, IoPolicy, Step, Transcript};
use spinbench_wire::chamber::{LineChamberDialect, ModbusFraming, RegisterMap};

const POLICY: IoPolicy = IoPolicy {
    timeout_ms: 50,
    retries: 2,
};

fn crc(frame: &[u8]) -> Vec<u8> {
    let mut out = frame.to_vec();
    let c = crc::Crc::<u16>::new(&crc::CRC_16_MODBUS).checksum(frame);
    out.extend_from_slice(&c.to_le_bytes());
    out
}

fn map() -> RegisterMap {
    toml::from_str("setpoint = 100\nprocess_value = 101\nrun = 102\nalarms = 103\npurge = 104\n")
        .expect("map")
}

fn rtu(steps: Vec<Step>) -> (ModbusChamber<Transcript>, Transcript) {
    let t = Transcript::new(steps);
    (
        ModbusChamber::new(t.clone(), map(), ModbusFraming::Rtu, "climate", POLICY),
        t,
    )
}

#[test]
fn modbus_rtu_every_operation() {
    let write = |reg: u8, hi: u8, lo: u8| crc(&[1, 6, 0, reg, hi, lo]);
    let read = |reg: u8| crc(&[1, 3, 0, reg, 0, 1]);
    let (mut c, t) = rtu(vec![
        // setpoint −40.0 °C = −400 = 0xFE70; a write is echoed.
        Step::Write(write(100, 0xFE, 0x70)),
        Step::Reply(write(100, 0xFE, 0x70)),
        Step::Write(read(100)),
        Step::Reply(crc(&[1, 3, 2, 0xFE, 0x70])),
        // the air at 23.5 °C, in two pieces.
        Step::Write(read(101)),
        Step::Reply(crc(&[1, 3, 2, 0x00, 0xEB])[..3].to_vec()),
        Step::Reply(crc(&[1, 3, 2, 0x00, 0xEB])[3..].to_vec()),
        Step::Write(write(102, 0, 1)),
        Step::Reply(write(102, 0, 1)),
        Step::Write(read(103)),
        Step::Reply(crc(&[1, 3, 2, 0x00, 0x04])),
        Step::Write(write(104, 0, 1)),
        Step::Reply(write(104, 0, 1)),
        Step::Write(write(102, 0, 0)),
        Step::Reply(write(102, 0, 0)),
    ]);
    c.set_setpoint_c(-40.0).expect("setpoint");
    assert_eq!(c.setpoint_c().expect("setpoint back"), -40.0);
    assert_eq!(c.temperature_c().expect("air"), 23.5);
    c.set_running(true).expect("run");
    assert_eq!(c.alarms().expect("alarms"), 4);
    c.set_purge(true).expect("purge");
    c.set_running(false).expect("stop");
    t.verify().expect("transcript followed");
}

#[test]
fn modbus_a_lost_reply_is_retried_a_bad_crc_is_garbled_and_an_exception_is_final() {
    let read = crc(&[1, 3, 0, 101, 0, 1]);
    let mut bad = crc(&[1, 3, 2, 0x00, 0xEB]);
    bad[4] ^= 0xFF;
    let (mut c, t) = rtu(vec![
        Step::Write(read.clone()),
        Step::Silence,
        Step::Write(read.clone()),
        Step::Reply(crc(&[1, 3, 2, 0x00, 0xEB])),
        Step::Write(read.clone()),
        Step::Reply(bad.clone()),
        Step::Write(read.clone()),
        Step::Reply(bad.clone()),
        Step::Write(read.clone()),
        Step::Reply(bad),
        Step::Write(crc(&[1, 6, 0, 102, 0, 1])),
        Step::Reply(crc(&[1, 0x86, 0x04])),
    ]);
    assert_eq!(c.temperature_c().expect("retried"), 23.5);
    let e = c.temperature_c().expect_err("three bad CRCs");
    assert!(
        matches!(e.kind, DeviceErrorKind::Garbled { attempts: 3, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("climate"), "{e}");
    let e = c.set_running(true).expect_err("exception");
    assert_eq!(
        e.kind,
        DeviceErrorKind::Refused(
            "Modbus exception 4 (server device failure: the controller failed while doing it)"
                .into()
        ),
        "{e}"
    );
    let e = c.set_setpoint_c(f64::NAN).expect_err("never sent");
    assert!(matches!(e.kind, DeviceErrorKind::Rejected(_)));
    t.verify().expect("transcript followed");
}

#[test]
fn modbus_tcp_frames_carry_the_mbap_header() {
    // transaction 1, protocol 0, length 6, unit 1, function 3, register 101, 1 word.
    let t = Transcript::new(vec![
        Step::Write(vec![0, 1, 0, 0, 0, 6, 1, 3, 0, 101, 0, 1]),
        Step::Reply(vec![0, 1, 0, 0, 0, 5, 1, 3, 2, 0xFF, 0x38]),
    ]);
    let mut c = ModbusChamber::new(t.clone(), map(), ModbusFraming::Tcp, "climate", POLICY);
    assert_eq!(c.temperature_c().expect("air"), -20.0);
    t.verify().expect("transcript followed");
}

#[test]
fn line_dialect_every_operation_and_a_refusal() {
    let dialect: LineChamberDialect = toml::from_str(
        "line_ending = \"\\n\"\nset_setpoint = \"SETP {value}\"\nread_setpoint = \"SETP?\"\nread_temperature = \"TEMP?\"\nrun = \"RUN\"\nstop = \"STOP\"\nread_alarms = \"ALRM?\"\npurge_on = \"PURGE 1\"\npurge_off = \"PURGE 0\"\nack = \"OK\"\n",
    )
    .expect("dialect");
    let w = |s: &str| Step::write(&format!("{s}\n"));
    let r = |s: &str| Step::reply(&format!("{s}\n"));
    let t = Transcript::new(vec![
        w("SETP 70.00"),
        r("OK"),
        w("SETP?"),
        r("70.0"),
        w("TEMP?"),
        r("T=+24.87 C"),
        w("RUN"),
        r("OK"),
        w("ALRM?"),
        r("0"),
        w("PURGE 1"),
        r("OK"),
        w("PURGE 0"),
        r("ERR 12 valve fault"),
    ]);
    let mut c = LineChamber::new(t.clone(), dialect, "climate", POLICY);
    c.set_setpoint_c(70.0).expect("setpoint");
    assert_eq!(c.setpoint_c().expect("back"), 70.0);
    assert_eq!(c.temperature_c().expect("air"), 24.87);
    c.set_running(true).expect("run");
    assert_eq!(c.alarms().expect("alarms"), 0);
    c.set_purge(true).expect("purge");
    let e = c.set_purge(false).expect_err("refused");
    assert!(matches!(e.kind, DeviceErrorKind::Refused(_)), "{e}");
    assert!(
        c.set_setpoint_c(500.0).is_err(),
        "beyond the setpoint range, never sent"
    );
    t.verify().expect("transcript followed");
}

/// A chamber config whose purge is on a relay module, both on scripted
/// transcripts: the controller's port sees the setpoint, the relay's the
/// purge (a Modbus coil, function 5, or a line command).
#[test]
fn a_purge_relay_takes_the_purge_and_the_controller_the_rest() {
    use spinbench_devices::chamber::PurgeOnRelay;
    let write = |reg: u8, hi: u8, lo: u8| crc(&[1, 6, 0, reg, hi, lo]);
    // The controller: no purge register in its map.
    let no_purge: RegisterMap =
        toml::from_str("setpoint = 100\nprocess_value = 101\nrun = 102\n").expect("map");
    let controller = Transcript::new(vec![
        Step::Write(write(100, 0x00, 0x32)),
        Step::Reply(write(100, 0x00, 0x32)),
    ]);
    // A relay board at unit 2, the valve on coil 3: on = 0xFF00, off = 0x0000.
    let relay_map: RegisterMap =
        toml::from_str("unit_id = 2\nsetpoint = 0\nprocess_value = 0\nrun = 0\npurge_coil = 3\n")
            .expect("relay map");
    let relay = Transcript::new(vec![
        Step::Write(crc(&[2, 5, 0, 3, 0xFF, 0x00])),
        Step::Reply(crc(&[2, 5, 0, 3, 0xFF, 0x00])),
        Step::Write(crc(&[2, 5, 0, 3, 0x00, 0x00])),
        Step::Reply(crc(&[2, 5, 0, 3, 0x00, 0x00])),
    ]);
    let mut chamber = PurgeOnRelay::new(
        Box::new(ModbusChamber::new(
            controller.clone(),
            no_purge.clone(),
            ModbusFraming::Rtu,
            "climate",
            POLICY,
        )),
        Box::new(ModbusChamber::new(
            relay.clone(),
            relay_map,
            ModbusFraming::Rtu,
            "purge relay",
            POLICY,
        )),
    );
    chamber
        .set_setpoint_c(5.0)
        .expect("setpoint to the controller");
    chamber.set_purge(true).expect("purge on at the relay");
    chamber.set_purge(false).expect("purge off at the relay");
    controller
        .verify()
        .expect("every step of the controller's transcript");
    relay
        .verify()
        .expect("every step of the relay's transcript");

    // A line relay module that acknowledges.
    let line = Transcript::new(vec![
        Step::Write(b"RELAY 1 ON\r\n".to_vec()),
        Step::Reply(b"OK\r\n".to_vec()),
    ]);
    let mut line_relay = LineChamber::new(
        line.clone(),
        LineChamberDialect::relay("RELAY 1 ON", "RELAY 1 OFF", Some("OK".into()), "\r\n"),
        "purge relay",
        POLICY,
    );
    line_relay.set_purge(true).expect("relay on");
    line.verify().expect("every step of the line's transcript");
    let e = line_relay
        .set_setpoint_c(5.0)
        .expect_err("a relay module has no setpoint");
    assert!(e.to_string().contains("purge relay"), "{e}");

    // The controller without a purge output refuses a purge, naming it.
    let mut bare = ModbusChamber::new(
        Transcript::new(vec![]),
        no_purge,
        ModbusFraming::Rtu,
        "climate",
        POLICY,
    );
    let e = bare.set_purge(true).expect_err("no purge output");
    assert!(e.to_string().contains("purge"), "{e}");
}

#[test]
fn a_purge_on_both_the_controller_and_a_relay_is_refused_naming_the_key() {
    use spinbench_devices::chamber::ChamberConfig;
    let section = |protocol: &str| -> ChamberConfig {
        toml::from_str(&format!(
            "name = \"climate\"\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\nprotocol = {protocol}\n[purge_relay]\nname = \"valve\"\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\nprotocol = {{ kind = \"modbus-tcp\", coil = 2 }}\n"
        ))
        .expect("section")
    };
    let both =
        section("{ kind = \"modbus-tcp\", setpoint = 1, process_value = 2, run = 3, purge = 4 }");
    let e = both.validate().expect_err("two purge outputs");
    assert_eq!(e.key, "chamber.purge_relay", "{e}");
    let relay_only = section("{ kind = \"modbus-tcp\", setpoint = 1, process_value = 2, run = 3 }");
    relay_only.validate().expect("the valve on the relay only");
    // A register map naming a register and a coil for it.
    let map: RegisterMap =
        toml::from_str("setpoint = 1\nprocess_value = 2\nrun = 3\npurge = 4\npurge_coil = 5\n")
            .expect("map");
    assert_eq!(
        map.validate().expect_err("both"),
        spinbench_wire::chamber::MapError::TwoPurgeOutputs
    );
}

#[test]
fn modbus_busy_is_asked_again_and_a_wrong_address_is_named() {
    let read = crc(&[1, 3, 0, 101, 0, 1]);
    let (mut c, t) = rtu(vec![
        // 06 (busy) and 05 (acknowledge): asked again, with back-off.
        Step::Write(read.clone()),
        Step::Reply(crc(&[1, 0x83, 0x06])),
        Step::Write(read.clone()),
        Step::Reply(crc(&[1, 0x83, 0x05])),
        Step::Write(read.clone()),
        Step::Reply(crc(&[1, 3, 2, 0x00, 0xEB])),
        // 02: a wrong register address, final, and said so.
        Step::Write(read.clone()),
        Step::Reply(crc(&[1, 0x83, 0x02])),
    ]);
    let started = std::time::Instant::now();
    assert_eq!(c.busy_replies(), 0);
    assert_eq!(c.temperature_c().expect("asked again"), 23.5);
    assert_eq!(c.busy_replies(), 2, "each busy reply counted");
    assert!(started.elapsed() >= std::time::Duration::from_millis(300));
    let e = c.temperature_c().expect_err("wrong address");
    assert!(e.to_string().contains("wrong register address"), "{e}");
    t.verify().expect("transcript followed");
}

#[test]
fn modbus_a_controller_rebooting_is_waited_for_within_the_outage_budget() {
    let read = crc(&[1, 3, 0, 101, 0, 1]);
    // Refused twice (one exchange's retries), then back after a pause.
    let (mut c, t) = rtu(vec![
        Step::Disconnect,
        Step::RefuseReopen,
        Step::RefuseReopen,
        Step::Reopen,
        Step::Write(read.clone()),
        Step::Reply(crc(&[1, 3, 2, 0x00, 0xEB])),
    ]);
    assert_eq!(c.temperature_c().expect("rode the outage"), 23.5);
    t.verify().expect("transcript followed");
    // Away beyond the budget (0.25 s: one pause of 0.1 s, not a second of
    // 0.2 s): the command fails, saying how long and what to configure.
    let t = Transcript::new(vec![
        Step::Disconnect,
        Step::RefuseReopen,
        Step::RefuseReopen,
        Step::RefuseReopen,
        Step::RefuseReopen,
    ]);
    let mut c = ModbusChamber::new(t.clone(), map(), ModbusFraming::Rtu, "climate", POLICY)
        .with_outage_budget(std::time::Duration::from_millis(250));
    let e = c.temperature_c().expect_err("away too long");
    assert!(
        e.to_string().contains("outage budget") && e.to_string().contains("chamber.outage_s"),
        "{e}"
    );
    t.verify().expect("transcript followed");
}

#[test]
fn modbus_silence_within_the_outage_budget_is_ridden_and_beyond_it_is_a_timeout() {
    let read = crc(&[1, 3, 0, 101, 0, 1]);
    // Every try of one exchange unanswered (a link dropping bytes), then
    // an answer after the back-off: ridden, as a refused connection is.
    let mut steps = Vec::new();
    for _ in 0..3 {
        steps.push(Step::Write(read.clone()));
        steps.push(Step::Silence);
    }
    steps.push(Step::Write(read.clone()));
    steps.push(Step::Reply(crc(&[1, 3, 2, 0x00, 0xEB])));
    let (mut c, t) = rtu(steps);
    let started = std::time::Instant::now();
    assert_eq!(c.temperature_c().expect("rode the silence"), 23.5);
    assert!(
        started.elapsed() >= std::time::Duration::from_millis(90),
        "one back-off pause"
    );
    t.verify().expect("transcript followed");
    // Silent beyond the budget: the command fails, saying so.
    let mut steps = Vec::new();
    for _ in 0..6 {
        steps.push(Step::Write(read.clone()));
        steps.push(Step::Silence);
    }
    let t = Transcript::new(steps);
    let mut c = ModbusChamber::new(t.clone(), map(), ModbusFraming::Rtu, "climate", POLICY)
        .with_outage_budget(std::time::Duration::from_millis(250));
    let e = c.temperature_c().expect_err("silent too long");
    // Still a timeout (the safe state asks a timed-out device nothing
    // more), counting every try across the back-off.
    assert!(
        matches!(e.kind, DeviceErrorKind::Timeout { attempts, .. } if attempts >= 6),
        "{e}"
    );
    assert!(e.to_string().contains("climate"), "{e}");
    t.verify().expect("transcript followed");
}
