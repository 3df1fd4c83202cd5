use super::*;
use crate::model::ieee1293_output;
use crate::points::Mount;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const LEVELS: [f64; 16] = [
    0.0, 1.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0, 55.0, 60.0, 65.0, 70.0,
];

/// Up and down through the published levels, white noise `noise_ug`,
/// `shift_ug` added to both readings of level `at_g`.
fn pass(mount: Mount, seed: u64, noise_ug: f64, at_g: f64, shift_ug: f64) -> Vec<Point> {
    let k = [0.02, 100.0, 12e-6, 0.3e-6];
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, noise_ug * 1e-6 * 100.0).expect("normal");
    LEVELS
        .iter()
        .chain(LEVELS.iter().rev())
        .map(|&g| {
            let a = mount.input_sign() * g;
            let shift = if g == at_g {
                shift_ug * 1e-6 * 100.0
            } else {
                0.0
            };
            Point {
                mount,
                g_nominal: g,
                g_applied: g,
                output: ieee1293_output(k, a) + shift + noise.sample(&mut rng),
                direction: None,
            }
        })
        .collect()
}

#[test]
fn clean_data_raise_few_false_alarms_and_a_single_dip_is_found() {
    let (mut false_alarms, mut found, runs) = (0, 0, 400);
    for seed in 0..runs {
        let clean = pass(Mount::P, seed, 10.0, -1.0, 0.0);
        false_alarms += usize::from(!outlier_levels(&clean, 3, 100.0, "clean").is_empty());
        // A dip of 15,000 µg over 100 µg of noise at one level.
        let at = LEVELS[2 + (seed as usize % 14)];
        let dipped = pass(Mount::P, seed, 100.0, at, 15_000.0);
        let flagged = outlier_levels(&dipped, 3, 100.0, "dip");
        found += usize::from(flagged.first().is_some_and(|o| o.g == at));
    }
    let rate = false_alarms as f64 / runs as f64;
    assert!(rate <= 0.05, "false alarms {rate}");
    assert!(found as f64 / runs as f64 >= 0.95, "found {found}/{runs}");
}

#[test]
fn a_second_anomaly_is_found_once_the_first_is_set_aside() {
    // A 20,000 µg level inflates the yardstick; a 1,500 µg one beside
    // it, 150 times the noise, must still be found.
    let (mut both, runs) = (0u64, 100u64);
    for seed in 0..runs {
        let mut points = pass(Mount::P, seed, 10.0, 60.0, 20_000.0);
        for p in points.iter_mut().filter(|p| p.g_nominal == 25.0) {
            p.output += 1_500.0 * 1e-6 * 100.0;
        }
        let flagged: Vec<f64> = outlier_levels(&points, 3, 100.0, "two")
            .iter()
            .map(|o| o.g)
            .collect();
        both += u64::from(flagged.contains(&60.0) && flagged.contains(&25.0));
    }
    assert!(both * 10 >= runs * 9, "both found in {both}/{runs}");
}

#[test]
fn the_between_level_variance_is_estimated_without_bias() {
    // Level effects of 300 µg RMS over 10 µg of noise: τ̂ near 300.
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let effect = Normal::new(0.0, 300e-6 * 100.0).expect("normal");
    let mut tau2 = Vec::new();
    for seed in 0..200 {
        let mut pts = pass(Mount::P, seed, 10.0, -1.0, 0.0);
        let shifts: Vec<f64> = LEVELS.iter().map(|_| effect.sample(&mut rng)).collect();
        for p in &mut pts {
            let i = LEVELS
                .iter()
                .position(|g| *g == p.g_nominal)
                .expect("level");
            p.output += shifts[i];
        }
        let x: Vec<f64> = pts.iter().map(Point::g_magnitude).collect();
        let y: Vec<f64> = pts.iter().map(|p| p.output).collect();
        let design = lsq::polynomial_design(&x, 3);
        let fit = lsq::solve(&design, &y, "t").expect("fit");
        let v = LevelVariance::estimate(&levels(&pts), &fit.residuals, &design, "t")
            .expect("estimate")
            .expect("replicated");
        tau2.push(v.tau2);
    }
    let mean_tau_ug = (tau2.iter().sum::<f64>() / tau2.len() as f64).sqrt() / 100.0 * 1e6;
    assert!((mean_tau_ug - 300.0).abs() < 30.0, "τ̂ {mean_tau_ug} µg");
}

/// Each reading of the levels up and down at its level's `misfit(g)`
/// minus the cubic's least-squares part of it (the residual a fit leaves),
/// with the true effect of `misfit` on k2 (the part the cubic absorbs).
fn residual_of(misfit: impl Fn(f64) -> f64) -> (Vec<f64>, Vec<f64>, f64) {
    let x: Vec<f64> = LEVELS
        .iter()
        .chain(LEVELS.iter().rev().skip(1))
        .copied()
        .collect();
    let d: Vec<f64> = x.iter().map(|g| misfit(*g)).collect();
    let design = lsq::polynomial_design(&x, 3);
    let op = lsq::solution_operator(&design, "test").expect("operator");
    let dv = nalgebra::DVector::from_column_slice(&d);
    let coef = &op * &dv;
    let r = &dv - &design * &coef;
    (x, r.iter().copied().collect(), coef[2])
}

/// What the 16 levels' residuals `r` at `x` show, none set aside, over
/// a pure error of 1e-10.
fn read_all(x: &[f64], r: &[f64]) -> Option<SmoothMisfit> {
    let readings = Readings {
        x,
        misfit: r,
        set_aside: &vec![false; x.len()],
        read_degree: 3,
    };
    smooth_misfit(&readings, 1e-10, 16, 3, 2, "test")
}

#[test]
fn a_broad_bumps_absorbed_part_is_read_from_what_it_leaves() {
    // A 2,000 µg bump of σ 8 g at 40 g: the cubic absorbs most of it and
    // leaves no trace of that part; the shape links the two.
    let (x, r, truth) = residual_of(|g| 2e-3 * (-0.5 * ((g - 40.0) / 8.0).powi(2)).exp());
    let s = read_all(&x, &r).expect("read as broad");
    assert!(
        (s.effect - truth).abs() < 0.15 * truth.abs(),
        "effect {} truth {truth}",
        s.effect
    );
    // A step of 1,000 µg from 33 g on.
    let (x, r, truth) = residual_of(|g| if g > 33.0 { 1e-3 } else { 0.0 });
    let s = read_all(&x, &r).expect("read as a step");
    assert!(
        (s.effect - truth).abs() < 0.15 * truth.abs(),
        "effect {} truth {truth}",
        s.effect
    );
}

#[test]
fn a_ramp_from_a_level_on_is_read_as_a_hinge() {
    // 0 up to 30 g, then rising to 5,000 µg at the top: the cubic absorbs
    // most of it; a bump or a step would read a part of it only.
    let top = *LEVELS.last().expect("levels");
    let (x, r, truth) = residual_of(|g| {
        if g > 30.0 {
            5e-3 * (g - 30.0) / (top - 30.0)
        } else {
            0.0
        }
    });
    let s = read_all(&x, &r).expect("read as a hinge");
    assert!(
        (s.effect - truth).abs() < 0.15 * truth.abs(),
        "effect {} truth {truth}",
        s.effect
    );
}

#[test]
fn a_dip_at_one_level_is_left_to_the_jackknife() {
    let (x, r, _) = residual_of(|g| if g == 40.0 { 5e-3 } else { 0.0 });
    assert_eq!(read_all(&x, &r), None);
    // No misfit, nothing read.
    assert_eq!(
        smooth_misfit(
            &Readings {
                x: &x,
                misfit: &vec![0.0; x.len()],
                set_aside: &vec![false; x.len()],
                read_degree: 3,
            },
            1e-10,
            16,
            3,
            2,
            "test"
        ),
        None
    );
}

#[test]
fn a_broad_bump_is_read_past_a_dip_once_the_dips_level_is_set_aside() {
    let bump = |g: f64| 2e-3 * (-0.5 * ((g - 45.0) / 8.0).powi(2)).exp();
    let (_, _, truth) = residual_of(bump);
    let (x, r, _) = residual_of(|g| bump(g) + if g == 20.0 { 8e-3 } else { 0.0 });
    let aside: Vec<bool> = x.iter().map(|g| *g == 20.0).collect();
    let s = smooth_misfit(
        &Readings {
            x: &x,
            misfit: &r,
            set_aside: &aside,
            read_degree: 3,
        },
        1e-10,
        15,
        3,
        2,
        "test",
    )
    .expect("read");
    assert!(
        (s.effect - truth).abs() < 0.2 * truth.abs(),
        "effect {} truth {truth}",
        s.effect
    );
    // Read with the dip among the levels, no one shape explains most of it.
    assert_eq!(read_all(&x, &r), None);
}

#[test]
fn a_plan_of_few_levels_reads_no_shape() {
    // 7 levels and a cubic: 3 residual directions, too few to tell a shape.
    let x: Vec<f64> = [0.0, 1.0, 2.0, 4.0, 6.0, 8.0, 10.0].repeat(2);
    let bump: Vec<f64> = x
        .iter()
        .map(|g| 1e-3 * (-0.5 * ((g - 5.0) / 1.2).powi(2)).exp())
        .collect();
    let design = lsq::polynomial_design(&x, 3);
    let op = lsq::solution_operator(&design, "test").expect("operator");
    let b = nalgebra::DVector::from_column_slice(&bump);
    let r = &b - &design * (&op * &b);
    let r: Vec<f64> = r.iter().copied().collect();
    let readings = Readings {
        x: &x,
        misfit: &r,
        set_aside: &vec![false; x.len()],
        read_degree: 3,
    };
    assert_eq!(smooth_misfit(&readings, 1e-10, 7, 3, 2, "test"), None);
}
