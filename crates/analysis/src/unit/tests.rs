use super::*;
use crate::model::ieee1293_output;
use crate::points::infer_directions;

/// Perfect data with a large k2; the descent runs 10 ppm faster (20 ppm more g).
fn faster_descent(mount: Mount) -> UnitPoints {
    let k = [0.01, 100.0, 300e-6, 0.5e-6];
    let levels = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0];
    let up = levels.iter().map(|&g| (g, 1.0));
    let down = levels.iter().rev().skip(1).map(|&g| (g, 1.000_02));
    let sign = mount.input_sign();
    let mut points: Vec<Point> = up
        .chain(down)
        .map(|(g, scale)| Point {
            mount,
            g_nominal: g,
            g_applied: sign * g * scale,
            output: ieee1293_output(k, sign * g * scale),
            direction: None,
        })
        .collect();
    infer_directions(&mut points);
    UnitPoints {
        unit: "H".into(),
        run: None,
        points,
    }
}

#[test]
fn a_faster_descent_on_perfect_data_is_no_hysteresis() {
    for mount in [Mount::P, Mount::N] {
        let a = analyze_unit(&faster_descent(mount), AnalysisOptions::default()).expect("reduced");
        let h = a.figures.hysteresis_ug.expect("hysteresis");
        // With k1 alone this read 2·k2·a·Δa ≈ −59 µg at 70 g.
        assert!(h.abs() < 0.1, "{mount}: {h} µg");
    }
}

#[test]
fn one_unit_that_cannot_be_reduced_holds_back_no_other() {
    let good = faster_descent(Mount::P);
    let bad = UnitPoints {
        unit: "ONE-LEVEL".into(),
        run: None,
        points: good.points[..1].to_vec(),
    };
    let d = analyze_dataset(&[bad, good], AnalysisOptions::default());
    assert_eq!(d.units.len(), 1);
    assert_eq!(d.units[0].unit, "H");
    assert_eq!(d.failed.len(), 1);
    assert_eq!(d.failed[0].unit, "ONE-LEVEL");
    assert!(d.failed[0].error.contains("level"), "{}", d.failed[0].error);
}

#[test]
fn a_mounting_that_cannot_be_fitted_leaves_the_other_standing() {
    let mut input = faster_descent(Mount::P);
    let n = faster_descent(Mount::N);
    // Two N readings: too few levels for a cubic.
    input.points.extend(n.points.iter().take(2).copied());
    let a = analyze_unit(&input, AnalysisOptions::default()).expect("P still reduced");
    assert!(a.fits.contains_key(&Mount::P) && !a.fits.contains_key(&Mount::N));
    assert!(
        a.notes.iter().any(|n| n.contains("mounting N not reduced")),
        "{:?}",
        a.notes
    );
}

#[test]
fn the_budget_and_the_diagnostics_share_one_pure_error() {
    let mut input = faster_descent(Mount::P);
    for (i, p) in input.points.iter_mut().enumerate() {
        p.output += 1e-3 * ((i * 7919) % 13) as f64;
    }
    let a = analyze_unit(&input, AnalysisOptions::default()).expect("reduced");
    let fit = &a.fits[&Mount::P];
    let dof_pe = fit
        .diagnostics
        .as_ref()
        .and_then(|d| d.lack_of_fit.as_ref())
        .map(|l| l.dof[1]);
    let budget = fit
        .uncertainty
        .as_ref()
        .and_then(|u| u.k2_ug_per_g2.as_ref())
        .expect("budget");
    let repeat = budget
        .budget
        .iter()
        .find(|c| c.source == crate::uncertainty::Source::Repeatability)
        .expect("repeatability");
    assert!(repeat.u > 0.0);
    // No drift term: the dof is the replicates' own (levels with two readings).
    assert_eq!(dof_pe, Some(7));
    assert_eq!(budget.dof_eff.map(|d| d.round() as usize), Some(7));
}

/// Both mountings of one instrument through the published levels, up and
/// down, the descent's applied acceleration `descent_ppm` higher (the
/// rate is read, not set exactly), white noise `noise_ug`, and
/// `dip_ug` at `dip_g` in mounting P only (the instrument's own anomaly).
fn both_mountings(
    seed: u64,
    descent_ppm: f64,
    noise_ug: f64,
    dip_g: f64,
    dip_ug: f64,
) -> UnitPoints {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, noise_ug * 1e-6).expect("normal");
    let k = [0.02, 100.0, 12e-6, 0.3e-6];
    let levels = crate::points::published_levels(70.0);
    let mut points = Vec::new();
    for mount in [Mount::P, Mount::N] {
        let sign = mount.input_sign();
        let up = levels.iter().map(|&g| (g, 1.0));
        let down = levels.iter().rev().map(|&g| (g, 1.0 + descent_ppm * 1e-6));
        for (g, scale) in up.chain(down) {
            let a = g * scale;
            let dip = if mount == Mount::P && g == dip_g {
                dip_ug * 1e-6
            } else {
                0.0
            };
            points.push(Point {
                mount,
                g_nominal: g,
                g_applied: a,
                output: ieee1293_output(k, sign * (a + dip + noise.sample(&mut rng))),
                direction: None,
            });
        }
    }
    UnitPoints {
        unit: "PAIRED".into(),
        run: None,
        points,
    }
}

#[test]
fn k2s_misfit_test_takes_the_pure_error_of_the_residuals_not_of_the_outputs() {
    use crate::uncertainty::Source;
    // The descent 30 ppm higher parts the up and down outputs of 70 g by
    // 2,100 µg; their residuals agree to the noise. An instrument's own
    // 2,000 µg dip at 30 g in P must reach K2's budget as model inadequacy.
    let (mut carried, trials) = (0usize, 20u64);
    for seed in 0..trials {
        let a = analyze_unit(
            &both_mountings(seed, 30.0, 10.0, 30.0, 2_000.0),
            AnalysisOptions::default(),
        )
        .expect("reduced");
        let joint = a.joint.expect("both mountings");
        let budget = joint.uncertainty.expect("budgets");
        carried += usize::from(
            budget
                .k2_even_ug_per_g2
                .budget
                .iter()
                .any(|c| c.source == Source::ModelInadequacy),
        );
    }
    assert!(
        carried as u64 >= trials - 1,
        "K2's inadequacy carried in {carried}/{trials}"
    );
}

/// Both mountings of one instrument (k2 10 µg/g², k3 0.05 µg/g³) at 0–70 g
/// in 5 g steps, up and down, with a repeatable scatter of about 150 µg,
/// and `extra_p` (µg) added to mounting P's input at each |g|.
fn both_mountings_with(extra_p: impl Fn(f64) -> f64) -> UnitPoints {
    let k = [0.01, 100.0, 10e-6, 0.05e-6];
    let levels: Vec<f64> = (0..=14).map(|i| 5.0 * f64::from(i)).collect();
    let mut points = Vec::new();
    let mut i = 0u64;
    for mount in [Mount::P, Mount::N] {
        let sign = mount.input_sign();
        let up = levels.iter().copied();
        let down = levels.iter().rev().skip(1).copied();
        for g in up.chain(down) {
            i += 1;
            // A fixed pseudo-random scatter, uniform in ±260 µg (150 µg RMS).
            let scatter_g = 260e-6 * (((i * 7919 + 13) % 101) as f64 / 50.0 - 1.0);
            let extra_g = if mount == Mount::P {
                extra_p(g) * 1e-6
            } else {
                0.0
            };
            let a = sign * g;
            points.push(Point {
                mount,
                g_nominal: g,
                g_applied: a,
                output: ieee1293_output(k, a + sign * extra_g) + k[1] * scatter_g,
                direction: None,
            });
        }
    }
    infer_directions(&mut points);
    UnitPoints {
        unit: "R".into(),
        run: None,
        points,
    }
}

#[test]
fn a_ramp_the_cubic_absorbs_in_one_mounting_is_in_k2_s_uncertainty() {
    // From nothing at 20 g to 8,000 µg at 70 g, in P only: the cubic
    // absorbs most of it, and only the two mountings' cubic coefficients,
    // which are the instrument's one K3, tell that it did.
    let ramp = |g: f64| 8000.0 * ((g - 20.0) / 50.0).max(0.0);
    let options = AnalysisOptions {
        anomalies: AnomalyRule::Own,
        ..AnalysisOptions::default()
    };
    let a = analyze_unit(&both_mountings_with(ramp), options).expect("reduced");
    let joint = a.joint.as_ref().expect("K2");
    let u95 = joint.k2_even_u95.expect("U95");
    let error = (joint.k2_even_ug_per_g2 - 10.0).abs();
    assert!(
        error > 1.0,
        "the ramp moves K2 ({error} µg/g²), or this tests nothing"
    );
    assert!(
        error <= u95,
        "K2 {} ± {u95} against 10",
        joint.k2_even_ug_per_g2
    );
    // Without the ramp the interval stays narrow.
    let clean = analyze_unit(&both_mountings_with(|_| 0.0), options).expect("reduced");
    let clean_u95 = clean
        .joint
        .as_ref()
        .and_then(|j| j.k2_even_u95)
        .expect("U95");
    assert!(
        clean_u95 < 0.5 * u95,
        "clean {clean_u95} against ramp {u95}"
    );
}
