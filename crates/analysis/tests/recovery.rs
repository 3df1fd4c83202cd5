//! Acceptance: noise-free synthetic points from known k0..k3 come back to
//! 1e-9 relative, in both mountings, for orders 1–3, with levels up to 100 g
//! and each instrument at its own radius (g_applied ≠ g_nominal).

use spinbench_analysis::model::{Convention, fit_ieee1293, ieee1293_output};
use spinbench_analysis::points::{published_levels, up_down};
use spinbench_analysis::{AnalysisOptions, ModelOrder, Mount, Point, UnitPoints, analyze_dataset};

const TOLERANCE: f64 = 1e-9;

fn relative(got: f64, want: f64) -> f64 {
    ((got - want) / want).abs()
}

/// Points of one mounting, noise-free, with the radius off by `radius_ratio`.
fn pass(mount: Mount, k: [f64; 4], max_g: f64, radius_ratio: f64) -> Vec<Point> {
    up_down(&published_levels(max_g))
        .into_iter()
        .map(|g| {
            let applied = g * radius_ratio;
            Point {
                mount,
                g_nominal: g,
                g_applied: applied,
                output: ieee1293_output(k, mount.input_sign() * applied),
                direction: None,
            }
        })
        .collect()
}

/// True coefficients for each order (higher terms zero below the order).
fn truths(order: ModelOrder) -> Vec<[f64; 4]> {
    let base = [
        [0.0125, 101.25, 12.0e-6, 0.05e-6],
        [-0.83, 42.0, -28.0e-6, -0.11e-6],
        [0.31, 168.0, 1.5e-6, 0.013e-6],
    ];
    base.iter()
        .map(|k| match order {
            ModelOrder::Linear => [k[0], k[1], 0.0, 0.0],
            ModelOrder::Quadratic => [k[0], k[1], k[2], 0.0],
            ModelOrder::Cubic => *k,
        })
        .collect()
}

#[test]
fn per_mounting_fits_recover_the_truth_to_1e_9() {
    for order in [ModelOrder::Linear, ModelOrder::Quadratic, ModelOrder::Cubic] {
        for k in truths(order) {
            for max_g in [30.0, 70.0, 100.0] {
                let mut points = pass(Mount::P, k, max_g, 1.000_512);
                points.extend(pass(Mount::N, k, max_g, 0.999_725));
                let units = [UnitPoints {
                    unit: "SN".into(),
                    run: None,
                    points,
                }];
                let analysis = analyze_dataset(
                    &units,
                    AnalysisOptions {
                        order,
                        ..Default::default()
                    },
                );
                assert!(analysis.failed.is_empty(), "{:?}", analysis.failed);
                let unit = &analysis.units[0];
                for (mount, fit) in &unit.fits {
                    let s = mount.input_sign();
                    let f = &fit.fit;
                    let ctx = format!("order {order:?} k {k:?} max {max_g} g mount {mount}");
                    // Per-mounting convention (method.md §3.4): N flips k0, k1 and k2.
                    assert!(
                        relative(f.k0_g, s * k[0]) < TOLERANCE,
                        "k0 {ctx}: {}",
                        f.k0_g
                    );
                    assert!(relative(f.k1, s * k[1]) < TOLERANCE, "k1 {ctx}: {}", f.k1);
                    if order >= ModelOrder::Quadratic {
                        let k2 = f.k2_ug_per_g2.expect("k2 fitted");
                        assert!(relative(k2, s * k[2] * 1e6) < TOLERANCE, "k2 {ctx}: {k2}");
                    } else {
                        assert!(f.k2_ug_per_g2.is_none());
                    }
                    if order == ModelOrder::Cubic {
                        let k3 = f.k3_ug_per_g3.expect("k3 fitted");
                        assert!(relative(k3, k[3] * 1e6) < TOLERANCE, "k3 {ctx}: {k3}");
                    } else {
                        assert!(f.k3_ug_per_g3.is_none());
                    }
                }
                if order >= ModelOrder::Quadratic {
                    let k2_max = unit.k2_max_ug_per_g2.expect("k2_max");
                    assert!(relative(k2_max, k[2].abs() * 1e6) < TOLERANCE);
                }
            }
        }
    }
}

#[test]
fn full_range_signed_fit_recovers_one_set_of_coefficients() {
    for k in truths(ModelOrder::Cubic) {
        let mut points = pass(Mount::P, k, 100.0, 1.0004);
        points.extend(pass(Mount::N, k, 100.0, 0.9993));
        let f = fit_ieee1293(
            &points,
            ModelOrder::Cubic,
            Convention::SignedInput,
            "full range",
        )
        .expect("fit");
        assert!(relative(f.k0_g, k[0]) < TOLERANCE, "{}", f.k0_g);
        assert!(relative(f.k1, k[1]) < TOLERANCE, "{}", f.k1);
        assert!(relative(f.k2_ug_per_g2.expect("k2"), k[2] * 1e6) < TOLERANCE);
        assert!(relative(f.k3_ug_per_g3.expect("k3"), k[3] * 1e6) < TOLERANCE);
        // Both mountings' points are in it.
        assert_eq!(f.points, points.len());
        assert_eq!(f.levels, 2 * published_levels(100.0).len() - 1);
    }
}

#[test]
fn scale_factor_model_and_figures_agree_with_the_truth() {
    let k = [0.0125, 101.25, 12.0e-6, 0.05e-6];
    let mut points = pass(Mount::P, k, 70.0, 1.0);
    points.extend(pass(Mount::N, k, 70.0, 1.0));
    let units = [UnitPoints {
        unit: "SN".into(),
        run: None,
        points,
    }];
    let a = analyze_dataset(&units, AnalysisOptions::default());
    assert!(a.failed.is_empty(), "{:?}", a.failed);
    let u = &a.units[0];
    let sf = u.scale_factor.as_ref().expect("scale-factor model");
    // (10)–(11) on the model (2): KA = k1, KB/KA = k2, KC/KA = k3.
    assert!(relative(sf.ka, k[1]) < TOLERANCE);
    assert!(relative(sf.kb_over_ka_ug_per_g2, 12.0) < 1e-7);
    assert!(relative(sf.kc_over_ka_ug_per_g3, 0.05) < 1e-6);
    // Same scale factor both ways, so no asymmetry; no hysteresis in clean data.
    assert!(u.figures.asymmetry_ppm.expect("asymmetry").abs() < 1e-6);
    assert!(u.figures.hysteresis_ug.expect("hysteresis").abs() < 1e-6);
    // The best-line deviation is dominated by k2·a²: of order k2·FS²/2 ~ 0.03 g at 70 g.
    let nl = u.figures.nonlinearity.expect("nonlinearity");
    assert!(
        nl.max_deviation_ug > 1e4 && nl.max_deviation_ug < 1e5,
        "{nl:?}"
    );
    assert!(u.notes.is_empty(), "{:?}", u.notes);
}

#[test]
fn repeatability_compares_runs_of_the_same_serial() {
    let k = [0.0125, 101.25, 12.0e-6, 0.05e-6];
    let k_drifted = [0.0125 + 3e-6, 101.25 * (1.0 + 5e-6), 12.0e-6, 0.05e-6];
    let run = |label: &str, k| UnitPoints {
        unit: "SN7".into(),
        run: Some(label.into()),
        points: pass(Mount::P, k, 70.0, 1.0),
    };
    let a = analyze_dataset(
        &[run("1", k), run("2", k_drifted)],
        AnalysisOptions::default(),
    );
    assert!(a.failed.is_empty(), "{:?}", a.failed);
    for u in &a.units {
        let rep = u.figures.repeatability.as_ref().expect("repeatability");
        assert_eq!(rep.runs, 2);
        assert!((rep.scale_factor_ppm - 5.0).abs() < 1e-3, "{rep:?}");
        assert!((rep.bias_ug - 3.0).abs() < 1e-3, "{rep:?}");
    }
}
