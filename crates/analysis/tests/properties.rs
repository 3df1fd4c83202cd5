//! Property tests of the fits: recovery on arbitrary level sets and
//! coefficients, invariances, and no panic on any finite input.

use proptest::prelude::*;
use spinbench_analysis::model::{fit_mounting, ieee1293_output};
use spinbench_analysis::{AnalysisOptions, ModelOrder, Mount, Point, UnitPoints, analyze_dataset};

fn mount() -> impl Strategy<Value = Mount> {
    prop_oneof![Just(Mount::P), Just(Mount::N)]
}

fn order() -> impl Strategy<Value = ModelOrder> {
    prop_oneof![
        Just(ModelOrder::Linear),
        Just(ModelOrder::Quadratic),
        Just(ModelOrder::Cubic)
    ]
}

/// Distinct levels in 0..=100 g: a sorted set of whole-g steps.
fn levels() -> impl Strategy<Value = Vec<f64>> {
    proptest::collection::btree_set(0u32..=100, 5..30)
        .prop_map(|s| s.into_iter().map(f64::from).collect())
}

fn points(mount: Mount, k: [f64; 4], levels: &[f64]) -> Vec<Point> {
    levels
        .iter()
        .map(|&g| Point {
            mount,
            g_nominal: g,
            g_applied: g,
            output: ieee1293_output(k, mount.input_sign() * g),
            direction: None,
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Noise-free data come back closely for any instrument-like coefficients
    /// and any set of at least five distinct levels up to 100 g.
    #[test]
    fn noise_free_recovery(
        mount in mount(),
        k0 in -2.0f64..2.0,
        k1 in 20.0f64..200.0,
        k2_ug in -50.0f64..50.0,
        k3_ug in -0.5f64..0.5,
        levels in levels(),
    ) {
        let k = [k0, k1, k2_ug * 1e-6, k3_ug * 1e-6];
        let f = fit_mounting(&points(mount, k, &levels), mount, ModelOrder::Cubic, "prop")
            .expect("fit").fit;
        let s = mount.input_sign();
        prop_assert!((f.k1 - s * k1).abs() < 1e-9 * k1);
        prop_assert!((f.k0_g - s * k0).abs() < 1e-9);
        // Absolute, in µg/gⁿ: well under any instrument's noise.
        prop_assert!((f.k2_ug_per_g2.expect("k2") - s * k2_ug).abs() < 1e-5);
        prop_assert!((f.k3_ug_per_g3.expect("k3") - k3_ug).abs() < 1e-6);
    }

    /// Scaling the output by λ scales k1 by λ and leaves k0, k2, k3 alone.
    #[test]
    fn output_scale_only_changes_k1(
        lambda in prop_oneof![0.001f64..0.999, 1.001f64..1000.0],
        noise in proptest::collection::vec(-1e-4f64..1e-4, 30),
        order in order(),
    ) {
        let k = [0.01, 100.0, 10e-6, 0.05e-6];
        let levels: Vec<f64> = (0..30).map(|i| f64::from(i) * 3.0).collect();
        let mut base = points(Mount::P, k, &levels);
        for (p, n) in base.iter_mut().zip(&noise) {
            p.output += n;
        }
        let scaled: Vec<Point> = base.iter().map(|p| Point { output: p.output * lambda, ..*p }).collect();
        let a = fit_mounting(&base, Mount::P, order, "a").expect("a").fit;
        let b = fit_mounting(&scaled, Mount::P, order, "b").expect("b").fit;
        prop_assert!(((b.k1 / a.k1) - lambda).abs() < 1e-9 * lambda);
        prop_assert!((b.k0_g - a.k0_g).abs() < 1e-9);
        if let (Some(x), Some(y)) = (a.k2_ug_per_g2, b.k2_ug_per_g2) {
            prop_assert!((x - y).abs() < 1e-6);
        }
        prop_assert!((a.residual_rms_ug - b.residual_rms_ug).abs() < 1e-6 * a.residual_rms_ug.max(1.0));
    }

    /// Any finite points: the analysis returns a result or an error, never panics,
    /// and a result's numbers are finite.
    #[test]
    fn arbitrary_finite_points_never_panic(
        raw in proptest::collection::vec((any::<bool>(), -200.0f64..200.0, -1e6f64..1e6), 0..40),
        order in order(),
    ) {
        let points: Vec<Point> = raw
            .iter()
            .map(|&(n, g, out)| Point {
                mount: if n { Mount::N } else { Mount::P },
                g_nominal: g.round(),
                g_applied: g,
                output: out,
                direction: None,
            })
            .collect();
        let units = [UnitPoints { unit: "X".into(), run: None, points }];
        let a = analyze_dataset(&units, AnalysisOptions { order, ..Default::default() });
        // Reduced or said why, never both, never neither.
        prop_assert_eq!(a.units.len() + a.failed.len(), 1);
        for unit in &a.units {
            for fit in unit.fits.values() {
                prop_assert!(fit.fit.k1.is_finite() && fit.fit.k0_g.is_finite());
            }
        }
    }
}
