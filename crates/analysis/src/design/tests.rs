use super::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn model() -> StationModel {
    StationModel {
        noise: NoiseModel {
            white_ug: 50.0,
            white_at_rest_ug: None,
            flicker_ug: 0.0,
            random_walk_ug2_per_s: 0.0,
            level_floor_ug: 0.0,
            at_rest_series: 0,
        },
        settle_s: 10.0,
        settle_s_per_g: 0.5,
        between_level_ug: 1_000.0,
        between_level_deciles_ug: None,
        calibration: 1.0,
        runs: 0,
        instruments: 0,
    }
}

#[test]
fn a_plans_time_is_its_visits_settles_and_dwells() {
    let m = StationModel {
        settle_s_per_g: 0.0,
        ..model()
    };
    let plan = Candidate {
        levels_g: even_levels(50.0, 6),
        down_levels_g: vec![0.0, 20.0],
        dwell_s: 10,
        passes: 2,
    };
    assert_eq!(
        plan.sequence(),
        vec![0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 20.0, 0.0]
    );
    let p = predict(&m, &plan).expect("predict");
    // 8 visits of 10 s, 7 settles of 10 s, two passes.
    assert!((p.centrifuge_time_s - 2.0 * 150.0).abs() < 1e-9, "{p:?}");
    // More levels: a smaller U95 for the same model.
    let more = Candidate {
        levels_g: even_levels(50.0, 20),
        ..plan.clone()
    };
    assert!(predict(&m, &more).expect("more").k2_u95_ug_per_g2 < p.k2_u95_ug_per_g2);
}

#[test]
fn the_prediction_is_the_spread_of_k2_under_the_model() {
    // Monte Carlo of the model itself: level effects τ per mounting's
    // half-difference and white noise per reading; the K2 of the
    // half-difference series' cubic spreads as the prediction says.
    let m = model();
    let plan = Candidate {
        levels_g: even_levels(70.0, 12),
        down_levels_g: vec![0.0, 30.0, 60.0],
        dwell_s: 5,
        passes: 2,
    };
    let p = predict(&m, &plan).expect("predict");
    let t = student_t_975(12 - 4).expect("t");
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let tau = Normal::new(0.0, m.between_level_ug).expect("normal");
    let white = Normal::new(0.0, m.noise.white_ug / 5f64.sqrt()).expect("normal");
    let design = lsq::polynomial_design(&plan.levels_g, 3);
    let mut k2 = Vec::new();
    for _ in 0..4000 {
        let y: Vec<f64> = plan
            .levels_g
            .iter()
            .map(|g| {
                let reads = if plan.down_levels_g.contains(g) { 2 } else { 1 };
                let mean = |rng: &mut ChaCha8Rng| {
                    (0..reads).map(|_| white.sample(rng)).sum::<f64>() / f64::from(reads)
                };
                // ½(z_P − z_N): each mounting's own noise, and the level effect.
                tau.sample(&mut rng) + 0.5 * (mean(&mut rng) - mean(&mut rng))
            })
            .collect();
        k2.push(lsq::solve(&design, &y, "mc").expect("fit").coefficients[2]);
    }
    let sd = (k2.iter().map(|k| k * k).sum::<f64>() / k2.len() as f64).sqrt();
    let predicted_sd = p.k2_u95_ug_per_g2 / t;
    assert!(
        (sd / predicted_sd - 1.0).abs() < 0.05,
        "Monte Carlo {sd}, predicted {predicted_sd}"
    );
}

#[test]
fn the_design_meets_its_target_in_less_time_than_the_published_plan() {
    let m = model();
    let published = Candidate::published(&crate::points::published_levels(70.0), 2);
    let reference = predict(&m, &published).expect("published");
    let d = design(&m, reference.k2_u95_ug_per_g2, 70.0, 2, false)
        .expect("design")
        .expect("reachable");
    assert!(d.prediction.k2_u95_ug_per_g2 <= reference.k2_u95_ug_per_g2);
    assert!(
        d.prediction.centrifuge_time_s < 0.7 * reference.centrifuge_time_s,
        "{d:?} vs {reference:?}"
    );
    assert!(d.plan.levels_g.len() >= MIN_LEVELS);
    assert!(d.plan.down_levels_g.len() >= MIN_DOWN_LEVELS);
    // Hysteresis asked for: every level below the top is read on the way down.
    let h = design(&m, reference.k2_u95_ug_per_g2, 70.0, 2, true)
        .expect("design")
        .expect("reachable");
    assert_eq!(h.plan.down_levels_g.len(), h.plan.levels_g.len() - 1);
    // A target below what any plan reaches is refused, saying what can be.
    let refused = design(&m, 0.01, 70.0, 2, false)
        .expect("design")
        .expect_err("unreachable");
    assert!(refused.best_u95 > 0.01);
    assert!(
        refused.to_string().contains("cannot be reached"),
        "{refused}"
    );
    assert!(design(&m, f64::NAN, 70.0, 2, false).is_err());
}

#[test]
fn the_model_is_learned_from_the_readings_of_past_runs() {
    // Synthetic runs: white 50 µg at n = 10, settle 10 s + 0.5 s/g, level
    // effects of 1,000 µg RMS in mounting P only (τ of the half-difference 500).
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let effect = Normal::new(0.0, 1_000e-6).expect("normal");
    let noise = Normal::new(0.0, 50e-6 / 10f64.sqrt()).expect("normal");
    let levels = crate::points::published_levels(70.0);
    let sequence = crate::points::up_down(&levels);
    let mut runs = Vec::new();
    for _ in 0..4 {
        let mut units = Vec::new();
        for _ in 0..12 {
            let shift: Vec<f64> = levels.iter().map(|_| effect.sample(&mut rng)).collect();
            let mut readings = Vec::new();
            let mut t = 0.0;
            for mount in [Mount::P, Mount::N] {
                let mut last: f64 = 0.0;
                let mut top = false;
                for &g in &sequence {
                    t += 10.0 + 0.5 * (g - last).abs();
                    last = g;
                    let i = levels.iter().position(|l| *l == g).expect("level");
                    let sign = if mount == Mount::P { 1.0 } else { -1.0 };
                    let own = if mount == Mount::P { shift[i] } else { 0.0 };
                    readings.push(Reading {
                        mount,
                        g,
                        down: top,
                        output_g: sign * g + 1e-5 * g * g + own + noise.sample(&mut rng),
                        std_ug: 50.0,
                        n: 10,
                        time_s: [t, t + 9.0],
                    });
                    t += 10.0;
                    top |= g == 70.0;
                }
            }
            units.push(readings);
        }
        runs.push(units);
    }
    let m = StationModel::learn(&runs, &[]).expect("learned");
    assert_eq!((m.runs, m.instruments), (4, 48));
    assert!((m.noise.white_ug - 50.0).abs() < 1.0, "{m:?}");
    assert!(
        (m.settle_s - 10.0).abs() < 1.0 && (m.settle_s_per_g - 0.5).abs() < 0.05,
        "{m:?}"
    );
    assert!((m.between_level_ug / 500.0 - 1.0).abs() < 0.25, "{m:?}");
    assert!(m.noise.level_floor_ug < 30.0, "{m:?}");
    assert!(StationModel::learn(&[], &[]).is_none());
}

#[test]
fn the_noise_at_rest_is_read_from_its_allan_deviation() {
    // White noise of 40 µg at 1 s plus a random walk of 4 µg²/s, 4,000 s
    // at rest: the fit gives both back; white noise alone gives no walk.
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let white = Normal::new(0.0, 40.0).expect("normal");
    let step = Normal::new(0.0, 2.0).expect("normal");
    let mut walk = 0.0;
    let series: Vec<f64> = (0..4000)
        .map(|_| {
            walk += step.sample(&mut rng);
            walk + white.sample(&mut rng)
        })
        .collect();
    let adev = allan_deviation(&series);
    assert_eq!(adev.first().map(|p| p.0), Some(1.0));
    assert_eq!(
        adev.last().map(|p| p.0),
        Some(512.0),
        "τ up to a quarter of the series"
    );
    let fit = fit_allan(&adev).expect("fit");
    assert!((fit.white_ug / 40.0 - 1.0).abs() < 0.15, "{fit:?}");
    assert!(
        (fit.random_walk_ug2_per_s / 4.0 - 1.0).abs() < 0.5,
        "{fit:?}"
    );
    let quiet: Vec<f64> = (0..4000).map(|_| white.sample(&mut rng)).collect();
    let fit = fit_allan(&allan_deviation(&quiet)).expect("fit");
    assert!((fit.white_ug / 40.0 - 1.0).abs() < 0.1, "{fit:?}");
    assert!(fit.random_walk_ug2_per_s < 0.05, "{fit:?}");
    // Too short, or not a number: nothing.
    assert!(fit_allan(&allan_deviation(&quiet[..8])).is_none());
    assert!(allan_deviation(&[1.0, f64::NAN, 2.0, 3.0]).is_empty());
    // The model takes its noise from the values at rest when it has them.
    let reading = Reading {
        mount: Mount::P,
        g: 0.0,
        down: false,
        output_g: 0.0,
        std_ug: 500.0,
        n: 10,
        time_s: [0.0, 9.0],
    };
    let m = StationModel::learn(&[vec![vec![reading]]], &[series]).expect("model");
    assert_eq!(m.noise.at_rest_series, 1);
    let at_rest = m.noise.white_at_rest_ug.expect("white at rest");
    assert!((at_rest / 40.0 - 1.0).abs() < 0.15, "{m:?}");
    // The levels' white noise is the dwells' scatter.
    assert_eq!(m.noise.white_ug, 500.0);
    assert!(m.noise.random_walk_ug2_per_s > 1.0, "{m:?}");
}
