//! Each error source of precision centrifuge testing (IEEE Std 836,
//! method.md §5) seen in the station's own data at its true size: the
//! modules' bytes decoded by the station's decoder into one-second values,
//! the rate read back through the controller's command line, the
//! temperature frames.
//!
//! Most checks run the same bench twice, with and without the source: a
//! source draws nothing from the random streams, so the noise is the same
//! in both and their difference is the source alone.

mod support;

use spinbench_sim::config::Disturbance;
use spinbench_sim::world::EARTH_RATE_RAD_S;
use spinbench_sim::{Mounting, SimConfig, World};
use spinbench_wire::fmu::StreamMode;
use support::{Capture, power_up, quiet, settle, spin};

const G: f64 = spinbench_analysis::STANDARD_GRAVITY_M_S2;

/// What the station has of a stretch of time.
struct Seen {
    /// Per slot: dF of each complete one-second window [Hz].
    df_hz: Vec<Vec<f64>>,
    /// Per slot: f1 + f2 of each window [Hz].
    sum_hz: Vec<Vec<f64>>,
    /// The controller's rate, read once a second [deg/s].
    rates_deg_s: Vec<f64>,
    /// Per slot: the temperature frames [°C].
    temps_c: Vec<Vec<f64>>,
}

impl Seen {
    fn mean_df(&self, slot: usize) -> f64 {
        mean(&self.df_hz[slot])
    }

    fn mean_rate_rad_s(&self) -> f64 {
        mean(&self.rates_deg_s).to_radians()
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// A quiet bench with `change` applied, powered, streaming, every instrument as `mounting`.
fn bench(mounting: Mounting, change: impl FnOnce(&mut SimConfig)) -> World {
    let mut c = quiet();
    change(&mut c);
    c.validate().expect("a valid bench");
    let mut w = World::new(c);
    power_up(&mut w, StreamMode::Reciprocal);
    w.set_all_mountings(mounting);
    w
}

/// Watch `seconds` as the station does: windows, temperatures, a rate query a second.
fn watch(world: &mut World, seconds: usize) -> Seen {
    let mut capture = Capture::new(StreamMode::Reciprocal);
    let mut rates = Vec::new();
    for _ in 0..seconds {
        capture.run(world, 0, 1.0);
        let reply = world
            .handle_centrifuge_line(":READ:RATE? 1")
            .expect("the controller answers");
        rates.push(reply.trim().parse::<f64>().expect("a rate"));
    }
    let slots = world.instrument_count();
    let complete: Vec<_> = capture.windows.iter().filter(|w| w.is_complete()).collect();
    let per_slot = |f: &dyn Fn(&spinbench_wire::fmu::InstrumentValue) -> Option<f64>| {
        (0..slots)
            .map(|s| {
                complete
                    .iter()
                    .filter_map(|w| f(&w.instruments[s]))
                    .collect()
            })
            .collect::<Vec<Vec<f64>>>()
    };
    Seen {
        df_hz: per_slot(&|v| v.df_hz),
        sum_hz: per_slot(&|v| v.f1_hz.zip(v.f2_hz).map(|(a, b)| a + b)),
        rates_deg_s: rates,
        temps_c: (0..slots)
            .map(|s| capture.temps_c.iter().map(|t| t[s]).collect())
            .collect(),
    }
}

/// The table's rate for `g` at the drawing radius [deg/s] (method.md (4)).
fn rate_for(world: &World, g: f64) -> f64 {
    (g * G / world.config().centrifuge.arm_radius_m)
        .sqrt()
        .to_degrees()
}

/// Spin to `g`, let it settle, watch.
fn at_level(world: &mut World, g: f64, seconds: usize) -> Seen {
    let rate = rate_for(world, g);
    spin(world, rate);
    settle(world, 40.0);
    watch(world, seconds)
}

/// Per slot: (with − without) of the mean dF, as acceleration in the
/// per-mounting convention (divided by the output's slope sign·k1) [µg].
fn shift_ug(with: &Seen, without: &Seen, world: &World, sign: f64) -> Vec<f64> {
    let truth = world.truth();
    (0..world.instrument_count())
        .map(|s| {
            let k1 = truth.instruments[s].vba.k1_hz_per_g;
            (with.mean_df(s) - without.mean_df(s)) / (sign * k1) * 1e6
        })
        .collect()
}

fn assert_close(what: &str, got: f64, want: f64, relative: f64, absolute: f64) {
    assert!(
        (got - want).abs() <= relative * want.abs() + absolute,
        "{what}: measured {got:.3}, true {want:.3}"
    );
}

/// In both mountings at `g`: each instrument's shift with `change` (per
/// mounting, per-mounting convention) over a², with its truth.
fn shift_over_a2_per_mounting(
    change: impl Fn(&mut SimConfig),
    g: f64,
) -> Vec<(Mounting, usize, f64, spinbench_sim::world::InstrumentTruth)> {
    let mut out = Vec::new();
    for (mounting, sign) in [(Mounting::ArmP, 1.0), (Mounting::ArmN, -1.0)] {
        let mut with = bench(mounting, &change);
        let mut without = bench(mounting, |_| {});
        let seen = at_level(&mut with, g, 5);
        let base = at_level(&mut without, g, 5);
        let truth = with.truth();
        let w = seen.mean_rate_rad_s();
        for (s, shift) in shift_ug(&seen, &base, &with, sign).into_iter().enumerate() {
            let t = truth.instruments[s].clone();
            let r = match mounting {
                Mounting::ArmP => t.position.radius_p_m,
                _ => t.position.radius_n_m,
            };
            let a = w * w * r / G;
            out.push((mounting, s, shift / (a * a), t));
        }
    }
    out
}

#[test]
fn arm_stretch_is_the_part_of_k2_common_to_mountings_p_and_n() {
    // c = 10 µg/g² at the drawing radius: k_s = c·R0²/g.
    let stretch = |c: &mut SimConfig| c.centrifuge.arm_stretch_m_per_rad2_s2 = 10e-6 * 0.64 / G;
    for (mounting, s, per_a2, t) in shift_over_a2_per_mounting(stretch, 60.0) {
        // The same in both mountings: + c·a² on the magnitude (method.md (15)).
        assert_close(
            &format!("slot {s} {mounting:?}: arm stretch / a² [µg/g²]"),
            per_a2,
            t.per_mounting_k2.arm_stretch_ug_per_g2,
            0.01,
            0.0,
        );
    }
}

#[test]
fn koq_enters_both_mountings_alike_while_k2_changes_sign() {
    let koq = |c: &mut SimConfig| c.instruments.koq_max_ug_per_g2 = 20.0;
    for (mounting, s, per_a2, t) in shift_over_a2_per_mounting(koq, 50.0) {
        assert_close(
            &format!("slot {s} {mounting:?}: Koq·a·|a| / a² [µg/g²]"),
            per_a2,
            t.vba.koq_ug_per_g2,
            0.02,
            0.05,
        );
        let pm = &t.per_mounting_k2;
        assert_close(
            "k2_P − k2_N = 2·K2",
            pm.p_ug_per_g2 - pm.n_ug_per_g2,
            2.0 * t.instrument_k2_ug_per_g2,
            1e-9,
            1e-9,
        );
        assert_close(
            "(k2_P + k2_N)/2 = Koq",
            0.5 * (pm.p_ug_per_g2 + pm.n_ug_per_g2),
            t.vba.koq_ug_per_g2,
            1e-9,
            1e-9,
        );
    }
}

#[test]
fn the_arm_expands_with_its_windage_heating() {
    let heat = |c: &mut SimConfig| {
        c.centrifuge.windage_c_at_100g = 5.0;
        c.centrifuge.windage_tau_s = 3.0;
    };
    let mut with = bench(Mounting::ArmP, |c| {
        heat(c);
        c.centrifuge.arm_expansion_ppm_per_c = 200.0;
    });
    let mut without = bench(Mounting::ArmP, heat);
    let seen = at_level(&mut with, 80.0, 5);
    let base = at_level(&mut without, 80.0, 5);
    let heating_c = with.windage_c();
    // Windage rises with the cube of the rate: 5 °C·(80/100)^1.5 once settled.
    assert_close(
        "windage heating [°C]",
        heating_c,
        5.0 * 0.8_f64.powf(1.5),
        0.02,
        0.0,
    );
    let w = seen.mean_rate_rad_s();
    for (s, shift) in shift_ug(&seen, &base, &with, 1.0).into_iter().enumerate() {
        // R0·α·ΔT more radius: ω²·R0·α·ΔT/g more acceleration.
        let want = w * w * 0.8 * 200e-6 * heating_c / G * 1e6;
        assert_close(&format!("slot {s}: expansion [µg]"), shift, want, 0.02, 1.0);
    }
}

#[test]
fn earth_rate_adds_to_one_spin_direction_and_subtracts_from_the_other() {
    let latitude = |c: &mut SimConfig| c.latitude_deg = 45.0;
    for direction in [1.0, -1.0] {
        let mut with = bench(Mounting::ArmP, latitude);
        let mut without = bench(Mounting::ArmP, |_| {});
        let g = 20.0;
        let rate = direction * rate_for(&with, g);
        for w in [&mut with, &mut without] {
            spin(w, rate);
            settle(w, 40.0);
        }
        let seen = watch(&mut with, 10);
        let base = watch(&mut without, 10);
        let omega = seen.mean_rate_rad_s();
        assert_eq!(
            omega.signum(),
            direction,
            "the table turns the way commanded"
        );
        let earth = EARTH_RATE_RAD_S * 45f64.to_radians().sin();
        assert_eq!(with.truth().centrifuge.earth_rate_vertical_rad_s, earth);
        let truth = with.truth();
        for (s, shift) in shift_ug(&seen, &base, &with, 1.0).into_iter().enumerate() {
            let a = omega * omega * truth.instruments[s].position.radius_p_m / G;
            // (ω + Ω)² − ω² = 2ωΩ + Ω²: + with the Earth, − against it (method.md §5).
            let want = a * (2.0 * earth / omega + (earth / omega).powi(2)) * 1e6;
            assert_close(
                &format!("slot {s}, direction {direction}: Earth rate [µg]"),
                shift,
                want,
                0.03,
                0.5,
            );
            assert_eq!(shift.signum(), direction);
        }
    }
}

#[test]
fn a_tilted_axis_moves_each_second_but_not_the_mean_over_revolutions() {
    let tilt_urad = 2000.0;
    let mut with = bench(Mounting::ArmP, |c| c.centrifuge.tilt_urad = tilt_urad);
    let mut without = bench(Mounting::ArmP, |_| {});
    let seen = at_level(&mut with, 10.0, 40);
    let base = at_level(&mut without, 10.0, 40);
    let truth = with.truth();
    let omega = seen.mean_rate_rad_s();
    // A·cos(ωt) averaged over one second: amplitude A·|2·sin(ω/2)|/ω, RMS that/√2.
    let per_second = tilt_urad * (2.0 * (omega / 2.0).sin()).abs() / omega / 2f64.sqrt();
    for s in 0..with.instrument_count() {
        let k1 = truth.instruments[s].vba.k1_hz_per_g;
        let diffs: Vec<f64> = seen.df_hz[s]
            .iter()
            .zip(&base.df_hz[s])
            .map(|(a, b)| (a - b) / k1 * 1e6)
            .collect();
        let m = mean(&diffs);
        let spread = rms(&diffs.iter().map(|d| d - m).collect::<Vec<_>>());
        assert_close(
            &format!("slot {s}: once-per-revolution RMS of 1-s values [µg]"),
            spread,
            per_second,
            0.2,
            0.0,
        );
        // Over 40 s the first-order part nearly cancels: well under 2 % of A.
        assert!(m.abs() < 0.02 * tilt_urad, "slot {s}: mean shift {m:.1} µg");
    }
}

#[test]
fn gravity_across_the_axis_shifts_every_reading_by_the_cross_axis_sensitivity() {
    let mut world = bench(Mounting::ArmP, |c| {
        c.instruments.cross_axis_max_ug_per_g = 300.0;
        c.instruments.self_heating_c = 0.0;
    });
    let seen = at_level(&mut world, 1.0, 20);
    let truth = world.truth();
    let w = seen.mean_rate_rad_s();
    let mut largest = 0.0_f64;
    for s in 0..world.instrument_count() {
        let t = &truth.instruments[s];
        let a = w * w * t.position.radius_p_m / G;
        let v = &t.vba;
        let model = v.k0_g + a + v.k2_ug_per_g2 * 1e-6 * a * a + v.k3_ug_per_g3 * 1e-6 * a.powi(3);
        let cross_ug = (seen.mean_df(s) / v.k1_hz_per_g - model) * 1e6;
        assert_close(
            &format!("slot {s}: 1 g across the axis [µg]"),
            cross_ug,
            v.cross_axis_ug_per_g,
            0.0,
            3.0,
        );
        largest = largest.max(v.cross_axis_ug_per_g.abs());
    }
    assert!(
        largest > 50.0,
        "the population's cross-axis terms are too small to test"
    );
}

#[test]
fn the_rate_read_back_has_its_scale_error_resolution_and_gate() {
    let rate = 300.0;
    // Scale error alone: every reading off by exactly the scale.
    let mut scaled = bench(Mounting::ArmP, |c| c.centrifuge.readback_scale_ppm = 100.0);
    spin(&mut scaled, rate);
    settle(&mut scaled, 40.0);
    let seen = watch(&mut scaled, 5);
    let true_deg_s = scaled.table.rate_rad_s.to_degrees();
    assert_close(
        "read-back scale [ppm]",
        (mean(&seen.rates_deg_s) / true_deg_s - 1.0) * 1e6,
        100.0,
        0.0,
        0.01,
    );
    // Resolution alone: multiples of it, within half of it.
    let mut coarse = bench(Mounting::ArmP, |c| {
        c.centrifuge.readback_resolution_deg_s = 0.25;
    });
    spin(&mut coarse, rate + 0.1);
    settle(&mut coarse, 40.0);
    let seen = watch(&mut coarse, 3);
    let true_deg_s = coarse.table.rate_rad_s.to_degrees();
    for r in &seen.rates_deg_s {
        assert!(((r / 0.25).round() * 0.25 - r).abs() < 1e-6, "{r}");
        assert!(
            (r - true_deg_s).abs() <= 0.125 + 1e-6,
            "{r} vs {true_deg_s}"
        );
    }
    // The gate: a short gate shows the once-per-revolution ripple, a whole-second one averages it.
    let scatter = |gate_s: f64| {
        let mut w = bench(Mounting::ArmP, |c| {
            c.centrifuge.ripple_ppm = 2000.0;
            c.centrifuge.readback_gate_s = gate_s;
        });
        spin(&mut w, 333.0);
        settle(&mut w, 40.0);
        let seen = watch(&mut w, 30);
        let m = mean(&seen.rates_deg_s);
        rms(&seen
            .rates_deg_s
            .iter()
            .map(|r| r / m - 1.0)
            .collect::<Vec<_>>())
            * 1e6
    };
    let (short, long) = (scatter(0.05), scatter(1.0));
    assert!(
        short > 3.0 * long && short > 500.0,
        "gate 0.05 s: {short:.0} ppm, gate 1 s: {long:.0} ppm"
    );
}

#[test]
fn the_table_rate_wanders_and_the_instruments_feel_what_the_controller_reads() {
    let mut world = bench(Mounting::ArmP, |c| c.centrifuge.wander_ppm = 30.0);
    let seen = at_level(&mut world, 30.0, 600);
    let m = mean(&seen.rates_deg_s);
    let wander_ppm: Vec<f64> = seen
        .rates_deg_s
        .iter()
        .map(|r| (r / m - 1.0) * 1e6)
        .collect();
    assert_close("rate wander RMS [ppm]", rms(&wander_ppm), 30.0, 0.6, 0.0);
    // dF moves with ω²: its relative change is twice the rate's, second by second.
    let df = &seen.df_hz[0];
    let df_mean = mean(df);
    let n = df.len().min(wander_ppm.len());
    let rel: Vec<f64> = df[..n].iter().map(|d| (d / df_mean - 1.0) * 1e6).collect();
    let slope = rel.iter().zip(&wander_ppm).map(|(y, x)| x * y).sum::<f64>()
        / wander_ppm[..n].iter().map(|x| x * x).sum::<f64>();
    assert_close(
        "dF against the read-back rate [ppm/ppm]",
        slope,
        2.0,
        0.05,
        0.0,
    );
}

#[test]
fn a_structural_resonance_shifts_one_level_up_and_down_alike() {
    let resonance = |c: &mut SimConfig| {
        c.centrifuge.disturbances = vec![Disturbance {
            at_g: 30.0,
            width_g: 0.5,
            amplitude_ug: 5000.0,
        }];
        c.instruments.disturbance_gain = [0.5, 1.5];
    };
    let mut with = bench(Mounting::ArmP, resonance);
    let mut without = bench(Mounting::ArmP, |_| {});
    let truth = with.truth();
    let gains: Vec<f64> = truth
        .instruments
        .iter()
        .map(|t| t.vba.disturbance_gain)
        .collect();
    // Up to 30 g, on to 40 g, back down to 30 g; and 35 g beside it.
    for (g, near) in [(30.0, true), (40.0, false), (30.0, true), (35.0, false)] {
        let seen = at_level(&mut with, g, 5);
        let base = at_level(&mut without, g, 5);
        let nominal = {
            let w = seen.mean_rate_rad_s();
            w * w * 0.8 / G
        };
        let shape = 1.0 / (1.0 + ((nominal - 30.0) / 0.5).powi(2));
        for (s, shift) in shift_ug(&seen, &base, &with, 1.0).into_iter().enumerate() {
            assert_close(
                &format!("slot {s} at {g} g: disturbance [µg]"),
                shift,
                5000.0 * gains[s] * shape,
                0.01,
                1.0,
            );
            if near {
                assert!(shift > 2000.0, "slot {s}: {shift}");
            } else {
                assert!(shift.abs() < 250.0, "slot {s} at {g} g: {shift}");
            }
        }
    }
}

#[test]
fn scale_factor_asymmetry_parts_k1_plus_from_k1_minus() {
    for (mounting, sign) in [(Mounting::ArmP, 1.0), (Mounting::ArmN, -1.0)] {
        let mut with = bench(mounting, |c| c.instruments.asymmetry_max_ppm = 500.0);
        let mut without = bench(mounting, |_| {});
        let seen = at_level(&mut with, 50.0, 5);
        let base = at_level(&mut without, 50.0, 5);
        let truth = with.truth();
        let w = seen.mean_rate_rad_s();
        for (s, shift) in shift_ug(&seen, &base, &with, sign).into_iter().enumerate() {
            let t = &truth.instruments[s];
            let a = w * w * t.position.radius_p_m / G;
            // K1± = K1·(1 ± asymmetry/2): the positive input of mounting P
            // reads asymmetry/2 high, the negative input of N as much low.
            let want = sign * 0.5 * t.vba.asymmetry_ppm * a;
            assert_close(
                &format!("slot {s} {mounting:?}: asymmetry [µg]"),
                shift,
                want,
                0.02,
                1.0,
            );
        }
    }
}

#[test]
fn self_heating_windage_and_the_resonator_sum_follow_the_temperature() {
    let mut world = bench(Mounting::ArmP, |c| {
        c.instruments.resonator_sum_ppm_per_c = -30.0;
        c.instruments.self_heating_c = 4.0;
        c.instruments.warmup_tau_s = 60.0;
        c.centrifuge.windage_c_at_100g = 6.0;
        c.centrifuge.windage_tau_s = 60.0;
    });
    let ambient = world.config().ambient_c;
    let early = watch(&mut world, 5);
    settle(&mut world, 600.0);
    let late = watch(&mut world, 5);
    for s in 0..world.instrument_count() {
        let t0 = mean(&early.temps_c[s]);
        let t1 = mean(&late.temps_c[s]);
        // Self-heating: ambient + 4 °C once warm.
        assert_close(
            &format!("slot {s}: warm [°C]"),
            t1,
            ambient + 4.0,
            0.0,
            0.05,
        );
        // f1 + f2 tracks the temperature: −30 ppm/°C of the common frequency.
        let ppm_per_c = (mean(&late.sum_hz[s]) / mean(&early.sum_hz[s]) - 1.0) * 1e6 / (t1 - t0);
        assert_close(
            &format!("slot {s}: f1 + f2 [ppm/°C]"),
            ppm_per_c,
            -30.0,
            0.03,
            0.0,
        );
    }
    // Windage: 6 °C at 100 g once settled.
    let spinning = at_level(&mut world, 100.0, 1);
    settle(&mut world, 600.0);
    let hot = watch(&mut world, 5);
    let w = spinning.mean_rate_rad_s();
    let at_100g = (w * w * 0.8 / G / 100.0).powf(1.5);
    for s in 0..world.instrument_count() {
        assert_close(
            &format!("slot {s}: windage [°C]"),
            mean(&hot.temps_c[s]) - (ambient + 4.0),
            6.0 * at_100g,
            0.02,
            0.02,
        );
    }
}

#[test]
fn bias_and_scale_factor_move_with_their_temperature_coefficients() {
    let heat = |c: &mut SimConfig| {
        c.centrifuge.windage_c_at_100g = 8.0;
        c.centrifuge.windage_tau_s = 60.0;
        c.instruments.self_heating_c = 0.0;
    };
    let mut with = bench(Mounting::ArmP, |c| {
        heat(c);
        c.instruments.temp_coeff_ug_per_c = 50.0;
        c.instruments.k1_temp_coeff_ppm_per_c = 100.0;
    });
    let mut without = bench(Mounting::ArmP, |c| {
        heat(c);
        c.instruments.temp_coeff_ug_per_c = 0.0;
    });
    let rate = rate_for(&with, 70.0);
    spin(&mut with, rate);
    spin(&mut without, rate);
    settle(&mut with, 600.0);
    settle(&mut without, 600.0);
    let seen = watch(&mut with, 5);
    let base = watch(&mut without, 5);
    let truth = with.truth();
    let ambient = with.config().ambient_c;
    let w = seen.mean_rate_rad_s();
    for s in 0..with.instrument_count() {
        let v = &truth.instruments[s].vba;
        // The temperature the station was sent, above the warm temperature at rest.
        let dt = mean(&seen.temps_c[s]) - ambient;
        assert!(dt > 2.0, "slot {s}: only {dt} °C of windage");
        let a = w * w * truth.instruments[s].position.radius_p_m / G;
        let got = (seen.mean_df(s) - base.mean_df(s)) / v.k1_hz_per_g * 1e6;
        // k1·(1 + c1·ΔT)·(… + c0·ΔT) − k1·(…): c0·ΔT plus c1·ΔT times the input.
        let want = v.temp_coeff_ug_per_c * dt + v.k1_temp_coeff_ppm_per_c * dt * (a + v.k0_g);
        assert_close(&format!("slot {s}: temperature [µg]"), got, want, 0.02, 3.0);
    }
}

/// Allan deviation of one-second values at cluster length `m` seconds.
fn allan(values: &[f64], m: usize) -> f64 {
    let means: Vec<f64> = values.chunks_exact(m).map(mean).collect();
    let d: Vec<f64> = means.windows(2).map(|w| w[1] - w[0]).collect();
    (d.iter().map(|x| x * x).sum::<f64>() / (2.0 * d.len() as f64)).sqrt()
}

/// Per slot, one-second values at rest (input axis up) as acceleration [µg].
fn at_rest_ug(change: impl FnOnce(&mut SimConfig), seconds: usize) -> Vec<Vec<f64>> {
    let mut world = bench(Mounting::TumbleUp, |c| {
        c.instruments.noise_ug = 1.0;
        c.instruments.self_heating_c = 0.0;
        change(c);
    });
    let seen = watch(&mut world, seconds);
    let truth = world.truth();
    seen.df_hz
        .iter()
        .enumerate()
        .map(|(s, v)| {
            let k1 = truth.instruments[s].vba.k1_hz_per_g;
            v.iter().map(|d| d / k1 * 1e6).collect()
        })
        .collect()
}

#[test]
fn bias_random_walk_grows_with_the_root_of_time() {
    // 600 µg/√h = 10 µg/√s: Allan deviation B·√(τ/3).
    let values = at_rest_ug(|c| c.instruments.bias_walk_ug_per_sqrt_h = 600.0, 2400);
    let (mut at30, mut at120) = (Vec::new(), Vec::new());
    for v in &values {
        at30.push(allan(v, 30));
        at120.push(allan(v, 120));
    }
    assert_close(
        "Allan deviation at 30 s [µg]",
        rms(&at30),
        10.0 * 10f64.sqrt(),
        0.3,
        0.0,
    );
    assert_close(
        "Allan deviation at 120 s [µg]",
        rms(&at120),
        10.0 * 40f64.sqrt(),
        0.35,
        0.0,
    );
}

#[test]
fn low_frequency_noise_is_flat_in_allan_deviation() {
    let flicker = at_rest_ug(|c| c.instruments.flicker_ug = 50.0, 2400);
    let white = at_rest_ug(|c| c.instruments.noise_ug = 50.0, 2400);
    let ratio = |values: &[Vec<f64>]| {
        let short: Vec<f64> = values.iter().map(|v| allan(v, 10)).collect();
        let long: Vec<f64> = values.iter().map(|v| allan(v, 100)).collect();
        (rms(&long) / rms(&short), rms(&short))
    };
    let (flat, size) = ratio(&flicker);
    let (falling, _) = ratio(&white);
    // White noise falls as τ^−½ (ratio ≈ 0.32); 1/f noise stays about level.
    assert!(
        (0.6..=1.7).contains(&flat),
        "1/f noise: σ(100 s)/σ(10 s) = {flat:.2}"
    );
    assert!(
        falling < 0.45,
        "white noise: σ(100 s)/σ(10 s) = {falling:.2}"
    );
    assert!(
        (5.0..=50.0).contains(&size),
        "1/f noise at 10 s: {size:.1} µg of 50 µg RMS"
    );
}
