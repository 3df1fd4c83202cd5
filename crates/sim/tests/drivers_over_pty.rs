//! The production drivers of the hardware layer against the virtual bench
//! over real pseudo-terminals (and TCP), exactly as the station will run.

use serde::Deserialize;
use spinbench_devices::config::{CentrifugeConfig, FmuConfig, PowerSupplyConfig};
use spinbench_devices::{
    Centrifuge, CounterModule, DialectCentrifuge, FmuDriver, IoPolicy, PowerSupply,
    ScpiPowerSupply, SerialSettings, SerialTransport,
};
use spinbench_sim::config::SimDialect;
use spinbench_sim::serve::{Endpoint, RunningBench, ServeOptions};
use spinbench_sim::{Mounting, SimConfig};
use spinbench_wire::centrifuge::AcutrolDialect;
use spinbench_wire::fmu::{StreamMode, WindowAccumulator, WindowConfig, WindowValue};
use std::time::{Duration, Instant};

const POLICY: IoPolicy = IoPolicy {
    timeout_ms: 2000,
    retries: 2,
};

fn quiet(speed: f64) -> SimConfig {
    let mut c = SimConfig {
        modules: 1,
        speed,
        ..SimConfig::default()
    };
    c.instruments.warmup_ug = 0.0;
    c.instruments.temp_coeff_ug_per_c = 0.0;
    c.instruments.bias_walk_ug_per_sqrt_h = 0.0;
    c.centrifuge.ripple_ppm = 0.0;
    c.centrifuge.wander_ppm = 0.0;
    c
}

fn serial(endpoint: &Endpoint, baud: u32) -> SerialTransport {
    let Endpoint::Pty(path) = endpoint else {
        panic!("expected a pty endpoint, got {endpoint:?}")
    };
    SerialTransport::open(SerialSettings::new(path.clone(), baud)).expect("open the bench's pty")
}

/// Collect `n` one-second windows from a streaming module.
fn windows(fmu: &mut dyn CounterModule, n: usize) -> Vec<WindowValue> {
    let mut acc = WindowAccumulator::new(WindowConfig::default());
    let mut out = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(60);
    while out.len() < n {
        assert!(
            Instant::now() < deadline,
            "no data from the bench in 60 s ({} windows)",
            out.len()
        );
        for m in fmu
            .receive(Instant::now() + Duration::from_millis(500))
            .expect("receive")
        {
            out.extend(acc.push(&m));
        }
    }
    out
}

#[test]
fn production_drivers_run_the_bench_over_real_ptys() {
    let bench = RunningBench::start(quiet(0.0), ServeOptions::default()).expect("bench");
    let e = bench.endpoints().clone();

    let mut rails = ScpiPowerSupply::new(serial(&e.rails, 115_200), "rails", 2, POLICY);
    assert!(rails.identify().expect("idn").contains("SIM-PSU-15V"));
    for ch in [1, 2] {
        rails.configure(ch, 15.0, 0.5).expect("configure");
        rails.set_output(ch, true).expect("on");
    }

    let mut fmu = FmuDriver::new(serial(&e.modules[0], 921_600), "fmu1", POLICY);
    fmu.set_power(0x3F).expect("relays");
    assert_eq!(fmu.status().expect("status").relay_mask, 0x3F);
    let amps = rails.measure(1).expect("measure").amps;
    assert!(
        (amps - 6.0 * 0.04).abs() < 1e-6,
        "current follows the relays: {amps}"
    );

    let mut table = DialectCentrifuge::new(
        serial(&e.centrifuge, 9600),
        AcutrolDialect::default(),
        "sim",
        POLICY,
        2400.0,
    );
    assert!(table.identify().expect("idn").contains("SPINBENCH-SIM"));
    bench.with_world(|w| w.set_all_mountings(Mounting::ArmP));
    let (g, r0) =
        bench.with_world(|w| (w.config().g_local_m_s2, w.config().centrifuge.arm_radius_m));
    let w = spinbench_analysis::centrifuge::rate_for_acceleration_rad_s(10.0, r0, g).expect("rate");
    table.arm().expect("arm");
    assert!(table.read_interlocks().expect("interlocks"));
    table.set_rate(w.to_degrees()).expect("rate");

    fmu.start(StreamMode::Reciprocal).expect("start");
    // 20 s of simulated time to spin up and settle, then 10 one-second values.
    let got = windows(&mut fmu, 30);
    let rate = table.read_rate().expect("rate");
    assert!(
        (rate - w.to_degrees()).abs() < 1e-3 * w.to_degrees(),
        "settled at {rate} deg/s"
    );
    let truth = bench.with_world(|w| w.truth());
    for slot in 0..6 {
        let t = &truth.instruments[slot];
        let a = w * w * t.position.radius_p_m / g;
        let k = [
            t.vba.k0_g,
            t.vba.k1_hz_per_g,
            t.vba.k2_ug_per_g2 * 1e-6,
            t.vba.k3_ug_per_g3 * 1e-6,
        ];
        let expected = spinbench_analysis::model::ieee1293_output(k, a)
            + t.vba.k1_hz_per_g * t.vba.cross_axis_ug_per_g * 1e-6;
        let last: Vec<f64> = got[20..]
            .iter()
            .filter_map(|w| w.instruments[slot].df_hz)
            .collect();
        assert_eq!(last.len(), 10);
        let mean = last.iter().sum::<f64>() / 10.0;
        let tol = 6.0 * t.vba.noise_ug * 1e-6 * t.vba.k1_hz_per_g / 10f64.sqrt();
        assert!(
            (mean - expected).abs() < tol,
            "slot {slot}: {mean} vs {expected} ± {tol}"
        );
    }
    assert!(
        got.iter().all(|w| w.is_complete()),
        "no tick lost over the pty"
    );
    let link = fmu.link_stats();
    assert_eq!((link.decoder.bad_crc, link.decoder.bytes_skipped), (0, 0));

    table.stop().expect("stop");
    table.disarm().expect("disarm");
    fmu.stop().expect("stop streaming");
    bench.shutdown();
}

#[derive(Deserialize)]
struct Devices {
    centrifuge: CentrifugeConfig,
    fmu: Vec<FmuConfig>,
    power_supply: Vec<PowerSupplyConfig>,
}

#[test]
fn the_printed_station_config_connects_including_the_mnemonic_dialect_over_tcp() {
    let mut config = quiet(0.0);
    config.centrifuge.dialect = SimDialect::Mnemonic;
    let bench = RunningBench::start(
        config,
        ServeOptions {
            line_devices_on_tcp: true,
        },
    )
    .expect("bench");
    let text = bench.station_config_toml();
    let devices: Devices = toml::from_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let mut table = devices.centrifuge.connect().expect("centrifuge");
    assert!(table.identify().expect("id").contains("MNEMONIC"));
    table.arm().expect("arm");
    table.set_rate(360.0).expect("60 rpm");
    assert!(table.set_rate(1e5).is_err(), "above the limit");
    let mut logic = devices.power_supply[1].connect().expect("logic supply");
    assert!((logic.measure(1).expect("measure").volts - 5.0).abs() < 1e-9);
    let mut fmu = devices.fmu[0].connect(0).expect("fmu");
    fmu.set_power(0x01).expect("relay");
    // Let simulated time pass through the control socket's clock.
    std::thread::sleep(Duration::from_millis(300));
    let rate = table.read_rate().expect("rate");
    assert!(rate > 0.0, "the table is spinning up: {rate}");
    table.stop().expect("stop");
    bench.shutdown();
}

#[test]
fn the_bench_shuts_down_even_when_the_station_stopped_reading() {
    let bench = RunningBench::start(quiet(0.0), ServeOptions::default()).expect("bench");
    let mut fmu = FmuDriver::new(
        serial(&bench.endpoints().modules[0], 921_600),
        "fmu1",
        POLICY,
    );
    fmu.set_power(0x3F).expect("relays");
    fmu.start(StreamMode::Reciprocal).expect("start");
    // Stop reading while the module streams: the pty fills up.
    std::thread::sleep(Duration::from_millis(500));
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        bench.shutdown();
        let _ = tx.send(());
    });
    assert!(
        rx.recv_timeout(Duration::from_secs(10)).is_ok(),
        "the bench did not shut down"
    );
    drop(fmu);
}

#[derive(Deserialize)]
struct ChamberOnly {
    chamber: spinbench_devices::chamber::ChamberConfig,
}

fn chamber_bench(chamber: spinbench_sim::chamber::ChamberSimConfig) -> RunningBench {
    let config = SimConfig {
        // 200× real time: the air's minutes pass in a second.
        chamber: Some(chamber),
        ..quiet(200.0)
    };
    RunningBench::start(config, ServeOptions::default()).expect("bench")
}

#[test]
fn the_modbus_chamber_driver_runs_the_benchs_chamber_over_a_real_pty() {
    let bench = chamber_bench(Default::default());
    let text = bench.station_config_toml();
    let config: ChamberOnly = toml::from_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let mut chamber = config.chamber.connect().expect("chamber");
    let start = chamber.temperature_c().expect("air");
    assert!((start - 23.0).abs() < 0.2, "the room: {start}");
    chamber.set_setpoint_c(40.0).expect("setpoint");
    assert_eq!(chamber.setpoint_c().expect("setpoint back"), 40.0);
    chamber.set_running(true).expect("run");
    chamber.set_purge(true).expect("purge");
    // 1.5 s of wall time: 300 s of the bench, the air at 3 °C/min.
    std::thread::sleep(Duration::from_millis(1500));
    let warm = chamber.temperature_c().expect("air");
    assert!(warm > start + 5.0, "heating: {start} → {warm} °C");
    assert_eq!(chamber.alarms().expect("alarms"), 0);
    let (purge, running, setpoint) = bench.with_world(|w| {
        let c = w.chamber().expect("a chamber");
        (c.purge, c.running, c.setpoint_c)
    });
    assert!(purge && running && setpoint == 40.0);
    bench.shutdown();
}

#[test]
fn a_silent_chamber_is_a_timeout_naming_it_and_a_runaway_sets_its_alarm() {
    use spinbench_sim::chamber::{ChamberFault, ChamberSimConfig};
    let silent = chamber_bench(ChamberSimConfig {
        fault: ChamberFault::Silent,
        ..Default::default()
    });
    let text = silent.station_config_toml();
    let config: ChamberOnly = toml::from_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let mut chamber = config.chamber.connect().expect("chamber");
    let e = chamber.temperature_c().expect_err("silent");
    assert!(
        matches!(e.kind, spinbench_devices::DeviceErrorKind::Timeout { .. }),
        "{e}"
    );
    assert!(e.to_string().contains("sim-chamber"), "{e}");
    silent.shutdown();

    let runaway = chamber_bench(ChamberSimConfig {
        fault: ChamberFault::Runaway,
        ..Default::default()
    });
    let text = runaway.station_config_toml();
    let config: ChamberOnly = toml::from_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let mut chamber = config.chamber.connect().expect("chamber");
    chamber.set_setpoint_c(23.0).expect("setpoint");
    std::thread::sleep(Duration::from_millis(1500));
    assert_ne!(
        chamber.alarms().expect("alarms"),
        0,
        "over-temperature alarm"
    );
    runaway.shutdown();
}

#[test]
fn a_purge_valve_on_a_relay_module_is_switched_through_its_own_port() {
    use spinbench_sim::chamber::ChamberSimConfig;
    let bench = chamber_bench(ChamberSimConfig {
        purge_on_relay: true,
        ..Default::default()
    });
    let text = bench.station_config_toml();
    assert!(text.contains("[chamber.purge_relay]"), "{text}");
    let config: ChamberOnly = toml::from_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let mut chamber = config.chamber.connect().expect("chamber with its relay");
    let purge = |b: &RunningBench| b.with_world(|w| w.chamber().map(|c| c.purge));
    chamber.set_purge(true).expect("purge on through the relay");
    assert_eq!(purge(&bench), Some(true));
    // The controller still answers for the rest.
    chamber.set_setpoint_c(-10.0).expect("setpoint");
    assert_eq!(chamber.setpoint_c().expect("setpoint back"), -10.0);
    chamber.set_purge(false).expect("purge off");
    assert_eq!(purge(&bench), Some(false));
    bench.shutdown();
}
