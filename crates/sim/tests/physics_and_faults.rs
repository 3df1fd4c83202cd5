//! The virtual bench, driven only through the bytes and lines the station
//! sends, and judged only by the bytes it sends back: the physics, the
//! determinism, and every fault kind's effect on the wire.

mod support;

use spinbench_sim::config::SlotRef;
use spinbench_sim::world::TICK_S;
use spinbench_sim::{Mounting, SimConfig, SupplyId, World};
use spinbench_wire::fmu::{Message, StreamMode, WindowValue};
use support::{Capture, power_up, quiet, settle, spin};

#[test]
fn the_rate_reaches_the_command_within_its_settling_time() {
    let mut world = World::new(quiet());
    let rate = 600.0;
    spin(&mut world, rate);
    let cfg = world.config().centrifuge.clone();
    // Ramp at the acceleration limit, then a second-order settle (4/ζωn to 2 %).
    let ramp_s = rate / cfg.max_accel_deg_s2;
    let settle_s = 4.0 / (cfg.loop_damping * std::f64::consts::TAU * cfg.loop_natural_hz);
    let mut peak = 0.0_f64;
    let mut last_outside = 0.0;
    for _ in 0..((ramp_s + 3.0 * settle_s) / TICK_S) as usize {
        world.step();
        let r = world.table.measured_rate_rad_s().to_degrees();
        peak = peak.max(r);
        if ((r - rate) / rate).abs() > 0.02 {
            last_outside = world.now_s();
        }
    }
    assert!(
        last_outside <= ramp_s + settle_s,
        "settled at {last_outside} s, allowed {} s",
        ramp_s + settle_s
    );
    let overshoot = (peak - rate) / rate;
    assert!(overshoot > 0.0 && overshoot < 0.2, "overshoot {overshoot}");
    // And the controller reports it.
    let reply = world
        .handle_centrifuge_line(":READ:RATE? 1")
        .expect("reply");
    assert!(
        (reply.parse::<f64>().expect("number") - rate).abs() < 1e-3 * rate,
        "{reply}"
    );
}

#[test]
fn one_second_outputs_in_mounting_p_follow_the_model_at_the_true_radius() {
    let mut world = World::new(quiet());
    world.set_all_mountings(Mounting::ArmP);
    power_up(&mut world, StreamMode::Reciprocal);
    let g = world.config().g_local_m_s2;
    let r0 = world.config().centrifuge.arm_radius_m;
    // The rate for 30 g at the drawing radius (method.md (4)).
    let w = spinbench_analysis::centrifuge::rate_for_acceleration_rad_s(30.0, r0, g).expect("rate");
    spin(&mut world, w.to_degrees());
    settle(&mut world, 20.0);
    let mut cap = Capture::new(StreamMode::Reciprocal);
    cap.run(&mut world, 0, 11.0);
    let truth = world.truth();
    let complete: Vec<&WindowValue> = cap.windows.iter().filter(|w| w.is_complete()).collect();
    assert!(complete.len() >= 9, "{} windows", complete.len());
    for (slot, t) in truth.instruments.iter().enumerate().take(6) {
        let a = w * w * t.position.radius_p_m / g;
        let k = [
            t.vba.k0_g,
            t.vba.k1_hz_per_g,
            t.vba.k2_ug_per_g2 * 1e-6,
            t.vba.k3_ug_per_g3 * 1e-6,
        ];
        let expected = spinbench_analysis::model::ieee1293_output(k, a)
            + t.vba.k1_hz_per_g * t.vba.cross_axis_ug_per_g * 1e-6;
        let values: Vec<f64> = complete
            .iter()
            .filter_map(|w| w.instruments[slot].df_hz)
            .collect();
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let noise_hz = t.vba.noise_ug * 1e-6 * t.vba.k1_hz_per_g;
        let tolerance = 5.0 * noise_hz / (values.len() as f64).sqrt();
        assert!(
            (mean - expected).abs() < tolerance,
            "slot {slot}: mean {mean} expected {expected} ± {tolerance}"
        );
        // The radius matters: the drawing radius would be off by far more than the noise.
        let at_r0 = spinbench_analysis::model::ieee1293_output(k, 30.0)
            + t.vba.k1_hz_per_g * t.vba.cross_axis_ug_per_g * 1e-6;
        if (t.position.radius_p_m - r0).abs() > 0.1e-3 {
            assert!(
                (mean - at_r0).abs() > tolerance,
                "slot {slot} cannot tell its radius from R0"
            );
        }
    }
}

#[test]
fn gated_and_reciprocal_resolution_differ_as_predicted() {
    let mut config = quiet();
    config.instruments.noise_ug = 0.0;
    for (mode, check) in [(StreamMode::Gated, 0), (StreamMode::Reciprocal, 1)] {
        let mut world = World::new(config.clone());
        world.set_all_mountings(Mounting::TumbleUp);
        power_up(&mut world, mode);
        let mut cap = Capture::new(mode);
        cap.run(&mut world, 0, 6.0);
        let truth = world.truth();
        let t = truth.instruments[0].vba;
        let (f1_true, _) =
            spinbench_sim::vba::Vba::new(t).resonators(&spinbench_sim::vba::Inputs {
                a_g: 1.0,
                ..Default::default()
            });
        for w in cap.windows.iter().filter(|w| w.is_complete()).skip(1) {
            let f1 = w.instruments[0].f1_hz.expect("f1");
            let err = (f1 - f1_true).abs();
            if check == 0 {
                // Gated: whole counts in 1 s, 1 Hz resolution (1/(f·T) ≈ 3e-5).
                assert_eq!(f1.fract(), 0.0);
                assert!(err <= 1.0, "gated error {err}");
            } else {
                // Reciprocal: one 10 ns reference tick in 1 s, ≈ 1e-8 relative.
                assert!(err / f1_true < 3e-8, "reciprocal error {err} Hz");
            }
        }
    }
}

fn byte_stream(config: SimConfig) -> Vec<u8> {
    let mut world = World::new(config);
    world.set_all_mountings(Mounting::ArmP);
    power_up(&mut world, StreamMode::Reciprocal);
    spin(&mut world, 300.0);
    let mut bytes = Vec::new();
    for _ in 0..2000 {
        for m in world.step() {
            bytes.extend(m);
        }
    }
    bytes
}

#[test]
fn the_same_seed_gives_the_same_byte_stream() {
    let mut c = SimConfig::default();
    c.faults.bit_error_rate = 1e-4;
    let a = byte_stream(c.clone());
    let b = byte_stream(c.clone());
    assert!(a.len() > 100_000);
    assert_eq!(a, b);
    c.seed = 2;
    assert_ne!(a, byte_stream(c));
}

fn faulty(f: impl FnOnce(&mut SimConfig)) -> (World, Capture) {
    let mut c = quiet();
    f(&mut c);
    let mut world = World::new(c);
    world.set_all_mountings(Mounting::TumbleUp);
    power_up(&mut world, StreamMode::Reciprocal);
    (world, Capture::new(StreamMode::Reciprocal))
}

#[test]
fn fault_bit_errors_are_seen_as_bad_crc() {
    let (mut world, mut cap) = faulty(|c| c.faults.bit_error_rate = 1e-4);
    cap.run(&mut world, 0, 5.0);
    let s = cap.stats();
    assert!(s.bad_crc > 0, "{s:?}");
    assert!(s.frames > 1500, "most frames survive: {s:?}");
    assert!(cap.acc.stats().lost_ticks > 0);
}

#[test]
fn fault_dropped_bytes_are_skipped_and_lose_ticks() {
    let (mut world, mut cap) = faulty(|c| c.faults.byte_drop_rate = 1e-4);
    cap.run(&mut world, 0, 5.0);
    assert!(cap.stats().bytes_skipped > 0);
    assert!(cap.acc.stats().lost_ticks > 0);
}

#[test]
fn fault_dropped_frames_are_sequence_gaps_with_clean_crc() {
    let (mut world, mut cap) = faulty(|c| c.faults.frame_drop_rate = 0.01);
    cap.run(&mut world, 0, 5.0);
    assert_eq!(cap.stats().bad_crc, 0);
    let w = cap.acc.stats();
    assert!(w.gaps > 0 && w.incomplete_windows > 0, "{w:?}");
}

#[test]
fn fault_a_module_goes_silent() {
    let (mut world, mut cap) = faulty(|c| c.faults.module_silent = Some((0, 2.0)));
    cap.run(&mut world, 0, 2.0);
    let before = cap.bytes.len();
    assert!(before > 0);
    cap.run(&mut world, 0, 2.0);
    assert!(
        cap.bytes.len() - before < 200,
        "at most the frames of the switching tick"
    );
    assert!(
        world
            .handle_module_message(0, Ok(Message::StatusRequest))
            .is_empty(),
        "no answer either"
    );
}

#[test]
fn fault_dead_and_noisy_instruments() {
    let (mut world, mut cap) = faulty(|c| {
        c.faults.dead_instruments = vec![SlotRef { module: 0, slot: 1 }];
        c.faults.noisy_instruments = vec![SlotRef { module: 0, slot: 2 }];
    });
    cap.run(&mut world, 0, 8.0);
    let windows: Vec<&WindowValue> = cap.windows.iter().skip(1).collect();
    assert!(
        windows.iter().all(|w| w.instruments[1].df_hz.is_none()),
        "a dead instrument outputs nothing"
    );
    let spread = |slot: usize| {
        let v: Vec<f64> = windows
            .iter()
            .filter_map(|w| w.instruments[slot].df_hz)
            .collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
    };
    assert!(
        spread(2) > 50.0 * spread(0),
        "noisy {} vs normal {}",
        spread(2),
        spread(0)
    );
}

#[test]
fn fault_centrifuge_comms_go_silent() {
    let (mut world, _) = faulty(|c| c.faults.centrifuge_silent_at_s = Some(1.0));
    assert!(world.handle_centrifuge_line("*IDN?").is_some());
    settle(&mut world, 1.5);
    assert_eq!(world.handle_centrifuge_line("*IDN?"), None);
}

#[test]
fn fault_an_interlock_opens_mid_run() {
    let (mut world, _) = faulty(|c| c.faults.interlock_open_at_s = Some(30.0));
    spin(&mut world, 360.0);
    settle(&mut world, 25.0);
    assert_eq!(world.handle_centrifuge_line(":INT?").as_deref(), Some("1"));
    settle(&mut world, 30.0);
    assert_eq!(world.handle_centrifuge_line(":INT?").as_deref(), Some("0"));
    let rate: f64 = world
        .handle_centrifuge_line(":READ:RATE? 1")
        .expect("rate")
        .parse()
        .expect("number");
    assert!(rate.abs() < 1.0, "the table stopped: {rate}");
    // Latched: closing needs a reset.
    world.handle_centrifuge_line(":INT:CLOS 1");
    assert_eq!(world.handle_centrifuge_line(":INT?").as_deref(), Some("0"));
    world.handle_centrifuge_line(":INT:RES 1");
    world.handle_centrifuge_line(":INT:CLOS 1");
    assert_eq!(world.handle_centrifuge_line(":INT?").as_deref(), Some("1"));
}

#[test]
fn fault_an_interlock_timed_by_spin_waits_for_the_table_to_turn() {
    let (mut world, _) = faulty(|c| c.faults.interlock_open_after_spin_s = Some(20.0));
    // At rest for longer than the fault's time: nothing opens.
    settle(&mut world, 60.0);
    spin(&mut world, 360.0);
    settle(&mut world, 10.0);
    assert_eq!(world.handle_centrifuge_line(":INT?").as_deref(), Some("1"));
    settle(&mut world, 20.0);
    assert_eq!(world.handle_centrifuge_line(":INT?").as_deref(), Some("0"));
}

#[test]
fn fault_the_supply_trips_on_over_current() {
    let (mut world, mut cap) = faulty(|c| c.faults.supply_trip_at_s = Some(2.0));
    cap.run(&mut world, 0, 4.0);
    assert_eq!(
        world
            .handle_supply_line(SupplyId::Rails, "SYST:ERR?")
            .as_deref(),
        Some("-300,\"Over-current protection tripped\"")
    );
    assert_eq!(
        world
            .handle_supply_line(SupplyId::Rails, "MEAS:CURR?")
            .as_deref(),
        Some("0.00000")
    );
    // On the counter-module wire: the instruments stopped.
    let last = cap.windows.last().expect("windows");
    assert!(
        last.instruments.iter().all(|i| i.df_hz.is_none()),
        "{last:?}"
    );
    // A real over-current trips too: a limit below the load.
    let (mut world, _) = faulty(|_| {});
    world.handle_supply_line(SupplyId::Rails, "INST:NSEL 1");
    world.handle_supply_line(SupplyId::Rails, "CURR 0.1");
    settle(&mut world, 0.01);
    assert_eq!(
        world
            .handle_supply_line(SupplyId::Rails, "OUTP?")
            .as_deref(),
        Some("0")
    );
}

#[test]
fn supply_current_follows_the_relay_mask() {
    let (mut world, _) = faulty(|_| {});
    let current = |w: &mut World| -> f64 {
        w.handle_supply_line(SupplyId::Rails, "INST:NSEL 1");
        w.handle_supply_line(SupplyId::Rails, "MEAS:CURR?")
            .expect("reply")
            .parse()
            .expect("number")
    };
    assert!((current(&mut world) - 6.0 * 0.04).abs() < 1e-9);
    world.handle_module_message(0, Ok(Message::SetPower { mask: 0b0000_0011 }));
    assert!((current(&mut world) - 2.0 * 0.04).abs() < 1e-9);
}
