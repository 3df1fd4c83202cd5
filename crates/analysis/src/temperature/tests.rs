use super::*;

fn at(t: f64, k0_ug: f64, k1: f64, k2: f64) -> AtTemperature {
    AtTemperature {
        setpoint_c: t - 4.0,
        temperature_c: t,
        temperature_spread_c: 0.0,
        points: 60,
        k0_g: [k0_ug * 1e-6, 2e-6],
        k1_hz_per_g: [k1, 1e-3],
        k2_ug_per_g2: Some([k2, 0.2]),
    }
}

#[test]
fn straight_lines_give_their_slopes_and_intervals_at_their_weights() {
    // 20 µg/°C, 30 ppm/°C of 100 Hz/g, 0.05 µg/g²/°C about 25 °C.
    let figs: Vec<AtTemperature> = [-20.0, 25.0, 60.0]
        .iter()
        .map(|&t| {
            let d = t - 25.0;
            at(
                t,
                500.0 + 20.0 * d,
                100.0 * (1.0 + 30e-6 * d),
                10.0 + 0.05 * d,
            )
        })
        .collect();
    let c = temperature_coefficients(&figs).expect("fit");
    assert!((c.k0_ug_per_c - 20.0).abs() < 1e-6, "{}", c.k0_ug_per_c);
    assert!((c.k1_ppm_per_c - 30.0).abs() < 0.01, "{}", c.k1_ppm_per_c);
    assert!((c.k2_ug_per_g2_per_c.unwrap_or(0.0) - 0.05).abs() < 1e-9);
    // u = 1 / √(Σ w (T − T̄)²) on a perfect line; U95 = t(1)·u alone.
    let stt: f64 = [-20.0f64, 25.0, 60.0]
        .iter()
        .map(|t| (t - 65.0 / 3.0).powi(2))
        .sum();
    let want = 0.2 / stt.sqrt();
    assert!((c.u.k2.unwrap_or(0.0) - want).abs() < 1e-12);
    let t1 = crate::statistics::student_t_975(1).expect("t(1)");
    assert!((c.k2_ug_per_g2_per_c_u95.unwrap_or(0.0) - t1 * want).abs() < 1e-12);
}

/// Points at `temperature`: a table error that repeats level by level
/// (the same at every temperature) and independent noise `noise_hz`.
fn points_at(rng: &mut rand_chacha::ChaCha8Rng, k0_hz: f64, noise_hz: f64) -> Vec<Point> {
    use crate::points::Direction;
    use rand_distr::{Distribution, Normal};
    let noise = Normal::new(0.0, noise_hz).expect("normal");
    let mut out = Vec::new();
    for mount in [Mount::P, Mount::N] {
        for (direction, levels) in [
            (Direction::Up, [0.0, 1.0, 5.0, 10.0, 20.0, 30.0, 40.0]),
            (Direction::Down, [40.0, 30.0, 20.0, 10.0, 5.0, 1.0, 0.0]),
        ] {
            for g in levels {
                let a = mount.input_sign() * g;
                // A repeated misfit 50 times the noise (the table's errors at this level).
                let repeated = 50.0 * noise_hz * (0.37 * g).sin();
                out.push(Point {
                    mount,
                    g_nominal: g,
                    g_applied: g,
                    output: k0_hz + 100.0 * a + 1e-3 * a * a + repeated + noise.sample(rng),
                    direction: Some(direction),
                });
            }
        }
    }
    out
}

#[test]
fn paired_differences_see_only_what_differs_between_temperatures() {
    use rand::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(15);
    let noise_hz = 1e-3;
    let mut ratios = Vec::new();
    for _ in 0..200 {
        let reference = points_at(&mut rng, 5.0, noise_hz);
        let other = points_at(&mut rng, 5.3, noise_hz);
        let u = paired_uncertainty(&reference, &other, 100.0).expect("paired");
        // Δk0's uncertainty, as the noise alone gives it (a cubic
        // through 28 differences of variance 2σ²): ≈ σ/√14 … σ.
        assert!(u.k0_g * 100.0 < noise_hz, "{} g", u.k0_g);
        assert!(u.k2_ug_per_g2.is_some(), "both mountings paired");
        ratios.push(u.k0_g * 100.0 / noise_hz);
    }
    // Stable over draws, and blind to the repeated misfit 50× the noise.
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    assert!((0.15..0.7).contains(&mean), "{mean}");
    // Without k1 the outputs cannot be put in g.
    let p = points_at(&mut rng, 5.0, noise_hz);
    assert!(paired_uncertainty(&p, &p, 0.0).is_none());
    // Levels that do not pair (another plan) give nothing.
    let mut moved = points_at(&mut rng, 5.0, noise_hz);
    moved.iter_mut().for_each(|p| p.g_nominal += 0.5);
    assert!(paired_uncertainty(&p, &moved, 100.0).is_none());
}

#[test]
fn each_temperature_carries_the_whole_of_its_differences_uncertainty() {
    // Not a share 1/√2 of it. What the pairs see moves
    // with the temperature (a dip reached elsewhere as the resonators
    // warm), so the errors on either side of the reference add in the
    // slope: with the share the coefficients' U95 held the truth for
    // 78–85 % of the typical bench's instruments over 12 seeds; with
    // the whole, 94–98 % (scripts/coverage 12 typical --temperatures=-20,25,60).
    use rand::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
    let reference = points_at(&mut rng, 5.0, 1e-3);
    let other = points_at(&mut rng, 5.4, 1e-3);
    let u = paired_uncertainty(&reference, &other, 100.0).expect("paired");
    let whole = cubic_errors(&pairs(&reference, &other, 100.0, None)).expect("cubic");
    assert!(
        (u.k0_g - whole[0] / 100.0).abs() <= 1e-12 * whole[0].abs(),
        "{u:?} {whole:?}"
    );
    assert!(
        (u.k1_hz_per_g - whole[1]).abs() <= 1e-12 * whole[1].abs(),
        "{u:?} {whole:?}"
    );
    let per_mount = |m| cubic_errors(&pairs(&reference, &other, 100.0, Some(m))).expect("cubic");
    let k2 = 0.5 * per_mount(Mount::P)[2].hypot(per_mount(Mount::N)[2]) / 100.0 * 1e6;
    assert!((u.k2_ug_per_g2.expect("K2") - k2).abs() <= 1e-9 * k2);
}

#[test]
fn the_batch_judges_the_lines_scatter() {
    let line = |t: f64, bend: f64| at(t, 500.0 + 20.0 * (t - 25.0) + bend, 100.0, 10.0);
    let straight: Vec<AtTemperature> = [-20.0, 25.0, 60.0].iter().map(|&t| line(t, 0.0)).collect();
    let c = temperature_coefficients(&straight).expect("fit");
    // On a straight line B = 0: U95 = t(1)·u for one instrument alone.
    assert!((c.k0_ug_per_c_u95 - 12.706 * c.u.k0).abs() < 1e-2 * c.u.k0);
    // At two temperatures nothing judges the line: 1.96·u.
    let two = temperature_coefficients(&straight[..2]).expect("fit");
    assert!((two.k0_ug_per_c_u95 - 1.96 * two.u.k0).abs() < 1e-12);
    // Scatter 3 times the uᵢ in every instrument: B ≈ 3 over 10 lines, t(10).
    let bent: Vec<AtTemperature> = [-20.0, 25.0, 60.0]
        .iter()
        .zip([0.0, 12.0, 0.0])
        .map(|(&t, b)| line(t, b))
        .collect();
    let one = temperature_coefficients(&bent).expect("fit");
    let mut batch = vec![one; 10];
    pool(&mut batch);
    let b = batch[0].batch.expect("judged");
    assert_eq!(b.dof[0], 10);
    assert_eq!(b.instruments, 10);
    let birge = (one.chi2.k0).sqrt();
    assert!((b.birge_ratio.k0 - birge).abs() < 1e-9 && birge > 1.0);
    let t10 = 2.228;
    assert!((batch[0].k0_ug_per_c_u95 / (birge * one.u.k0) - t10).abs() < 1e-3);
    // Alone, its one degree of freedom takes t(1) = 12.7.
    assert!((one.k0_ug_per_c_u95 / (birge * one.u.k0) - 12.706).abs() < 1e-2);
    // Pooling again changes nothing.
    let again = batch.clone();
    pool(&mut batch);
    assert_eq!(again, batch);
}

#[test]
fn the_same_scatter_in_every_instrument_covers_the_small_u_ones_too() {
    // Every instrument's k1 line is bent by the same
    // amount (what the pairs cannot see does not shrink with u), but
    // one instrument has ten times smaller uᵢ. The additive τ²
    // covers the error of the small-u ones; the Birge ratio did not.
    let bent = |u_k1: f64| -> TemperatureCoefficients {
        let figs: Vec<AtTemperature> = [(-20.0, 0.0), (25.0, 0.0), (60.0, 4e-4)]
            .iter()
            .map(|&(t, bend)| AtTemperature {
                k1_hz_per_g: [100.0 + bend, u_k1],
                ..at(t, 500.0, 100.0, 10.0)
            })
            .collect();
        temperature_coefficients(&figs).expect("fit")
    };
    let mut batch: Vec<_> = (0..12)
        .map(|i| bent(if i == 0 { 1e-5 } else { 1e-4 }))
        .collect();
    pool(&mut batch);
    // The true coefficient is 0; each line's slope error is the bend's.
    for c in &batch {
        assert!(
            c.k1_ppm_per_c.abs() < c.k1_ppm_per_c_u95,
            "|{}| ≥ U95 {} (u {})",
            c.k1_ppm_per_c,
            c.k1_ppm_per_c_u95,
            c.u.k1
        );
    }
    let b = batch[0].batch.expect("judged");
    assert!(b.between_u.k1 > 0.0 && b.between_u.k0 == 0.0);
    // Without a stated β, the whole arm's bound adds a rectangular term
    // to k1's alone.
    let before = batch.clone();
    with_arm_expansion(&mut batch, None, 0.45);
    let t12 = 2.179;
    let grown = batch[0].k1_ppm_per_c_u95.powi(2) - before[0].k1_ppm_per_c_u95.powi(2);
    assert!(
        (grown / (t12 * t12) - 0.45f64.powi(2) / 3.0).abs() < 1e-3,
        "{grown}"
    );
    assert_eq!(batch[0].k0_ug_per_c_u95, before[0].k0_ug_per_c_u95);
    assert_eq!(batch[0].k1_ppm_per_c, before[0].k1_ppm_per_c);
    // A stated β corrects k1's coefficient, once however often applied,
    // with a term of 20 % of it.
    with_arm_expansion(&mut batch, Some(0.45), 12.0);
    with_arm_expansion(&mut batch, Some(0.45), 12.0);
    assert!((before[0].k1_ppm_per_c - batch[0].k1_ppm_per_c - 0.45).abs() < 1e-12);
    let grown = batch[0].k1_ppm_per_c_u95.powi(2) - before[0].k1_ppm_per_c_u95.powi(2);
    assert!(
        (grown / (t12 * t12) - 0.09f64.powi(2) / 3.0).abs() < 1e-4,
        "{grown}"
    );
    // Pooling again keeps the bound.
    let again = batch.clone();
    pool(&mut batch);
    assert_eq!(again, batch);
}

#[test]
fn a_dip_at_one_level_moves_the_paired_slope_and_its_uncertainty_says_so() {
    // Paired differences with an activity dip at one
    // level (both directions) and a little noise: the dip moves the
    // fitted slope; the returned uncertainty covers that move, where
    // the residuals' standard error alone did not.
    let levels = [-70.0, -50.0, -30.0, -10.0, 0.0, 10.0, 30.0, 50.0, 70.0];
    let noise = [1.0, -1.0, 0.5, -0.5, 0.2, -0.2, 0.8, -0.8, 0.3];
    let make = |dip: f64| -> Vec<(f64, f64)> {
        levels
            .iter()
            .zip(noise)
            .flat_map(|(&x, n)| {
                let y = if x == 30.0 { dip } else { 0.0 };
                [(x, y + n * 1e-3), (x, y - n * 1e-3)]
            })
            .collect()
    };
    let slope = |pairs: &[(f64, f64)]| {
        let x: Vec<f64> = pairs.iter().map(|p| p.0).collect();
        let y: Vec<f64> = pairs.iter().map(|p| p.1).collect();
        solve(&polynomial_design(&x, 3), &y, "test")
            .expect("fit")
            .coefficients[1]
    };
    let dipped = make(0.5);
    let moved = (slope(&dipped) - slope(&make(0.0))).abs();
    let u = cubic_errors(&dipped).expect("errors")[1];
    let x: Vec<f64> = dipped.iter().map(|p| p.0).collect();
    let y: Vec<f64> = dipped.iter().map(|p| p.1).collect();
    let se_dipped = solve(&polynomial_design(&x, 3), &y, "test")
        .expect("fit")
        .covariance
        .expect("cov")[(1, 1)]
        .sqrt();
    // At a coverage factor of 2 the interval holds the move; the
    // standard error's did not.
    assert!(
        2.0 * u >= moved,
        "u {u}: 2u < the dip's move of the slope {moved}"
    );
    assert!(
        2.0 * se_dipped < moved,
        "se {se_dipped} already covered {moved}"
    );
    // Clean data: about the standard error (the jackknife does not
    // blow it up).
    let clean = make(0.0);
    let x: Vec<f64> = clean.iter().map(|p| p.0).collect();
    let y: Vec<f64> = clean.iter().map(|p| p.1).collect();
    let fit = solve(&polynomial_design(&x, 3), &y, "test").expect("fit");
    let se = fit.covariance.expect("cov")[(1, 1)].sqrt();
    let u_clean = cubic_errors(&clean).expect("errors")[1];
    assert!(u_clean >= se && u_clean < 3.0 * se, "{u_clean} vs se {se}");
}

#[test]
fn a_bend_the_line_does_not_hold_widens_the_interval_and_one_temperature_is_refused() {
    let mut figs: Vec<AtTemperature> = [-20.0, 25.0, 60.0]
        .iter()
        .map(|&t| at(t, 500.0, 100.0, 10.0))
        .collect();
    let straight = temperature_coefficients(&figs).expect("fit");
    figs[1].k2_ug_per_g2 = Some([12.0, 0.2]);
    let bent = temperature_coefficients(&figs).expect("fit");
    assert!(
        bent.k2_ug_per_g2_per_c_u95.unwrap_or(0.0)
            > 5.0 * straight.k2_ug_per_g2_per_c_u95.unwrap_or(1.0)
    );
    assert!(temperature_coefficients(&figs[..1]).is_err());
}
