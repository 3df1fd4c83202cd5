//! The linearised GUM budget ([`spinbench_analysis::uncertainty`]) against a
//! Monte Carlo propagation of the same input distributions (JCGM 101): every
//! Type B input drawn from its distribution, the station's points made from
//! the perturbed truth, refitted as the station would, many times over.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Uniform};
use spinbench_analysis::model::{Convention, fit_ieee1293, ieee1293_output};
use spinbench_analysis::uncertainty::{TypeBInputs, joint_uncertainty, mounting_budget};
use spinbench_analysis::{ModelOrder, Mount, Point};

const K: [f64; 4] = [0.002, 120.0, 20e-6, 0.5e-6];

fn inputs() -> TypeBInputs {
    TypeBInputs {
        radius_ppm: 30.0,
        radius_reading_ppm_p: 8.0,
        radius_reading_ppm_n: 12.0,
        cross_axis_ug_per_g: 50.0,
        rate_accuracy_ppm: 10.0,
        rate_resolution_deg_s: 0.002,
        readings_per_point: 1.0,
        arm_radius_m: 0.8,
        g_local_m_s2: 9.8,
        g_local_ppm: 5.0,
        timebase_ppm: 2.0,
        arm_stretch_u_ug_per_g2: 0.5,
        temperature_rise_c_at_100g: 1.5,
        k0_tempco_ug_per_c: 20.0,
        k1_tempco_ppm_per_c: 15.0,
        arm_expansion_ppm_per_c: 12.0,
        chamber_radius_expansion_ppm_per_c: None,
        table_disturbance_ug: 0.0,
        table_disturbance_width_g: 0.0,
    }
}

/// The published levels, up then down.
fn levels() -> Vec<f64> {
    let mut up = vec![0.0, 1.0];
    up.extend((1..=14).map(|i| 5.0 * f64::from(i)));
    let down: Vec<f64> = up.iter().rev().skip(1).copied().collect();
    up.into_iter().chain(down).collect()
}

/// One draw of every Type B error: (shared by both mountings, per mounting).
struct Draw {
    rate: f64,
    g: f64,
    timebase: f64,
    stretch: f64,
    k0_tc: f64,
    scale_tc: f64,
    /// Gravity across the axis: +c in P's radius, −c in N's.
    cross_axis: f64,
    radius: [f64; 2],
    resolution: Vec<[f64; 2]>,
}

fn draw(rng: &mut ChaCha8Rng, b: &TypeBInputs, points: usize) -> Draw {
    let normal = |rng: &mut ChaCha8Rng, u: f64| Normal::new(0.0, u).map_or(0.0, |n| n.sample(rng));
    let rect = |rng: &mut ChaCha8Rng, half: f64| {
        Uniform::new_inclusive(-half, half).map_or(0.0, |u| u.sample(rng))
    };
    Draw {
        rate: rect(rng, b.rate_accuracy_ppm * 1e-6),
        g: normal(rng, b.g_local_ppm * 1e-6),
        timebase: rect(rng, b.timebase_ppm * 1e-6),
        stretch: normal(rng, b.arm_stretch_u_ug_per_g2) * 1e-6,
        k0_tc: rect(rng, b.k0_tempco_ug_per_c) * 1e-6,
        scale_tc: rect(rng, b.k1_tempco_ppm_per_c + b.arm_expansion_ppm_per_c) * 1e-6,
        cross_axis: rect(rng, b.cross_axis_ug_per_g * 1e-6),
        radius: [
            normal(rng, b.radius_ppm * 1e-6) + normal(rng, b.radius_reading_ppm_p * 1e-6),
            normal(rng, b.radius_ppm * 1e-6) + normal(rng, b.radius_reading_ppm_n * 1e-6),
        ],
        resolution: (0..points)
            .map(|_| {
                let q = b.rate_resolution_deg_s.to_radians() / 2.0;
                [rect(rng, q), rect(rng, q)]
            })
            .collect(),
    }
}

/// The points the station records in `mount` when the inputs are off by `d`
/// (`None`: the nominal, error-free points).
fn points(mount: Mount, b: &TypeBInputs, d: Option<&Draw>) -> Vec<Point> {
    let m = usize::from(mount == Mount::N);
    levels()
        .iter()
        .enumerate()
        .map(|(i, &g)| {
            // The true applied acceleration and the station's value of it.
            let mut a_station = g;
            let mut output_scale = 1.0;
            let mut bias = 0.0;
            if let Some(d) = d {
                let rise = b.temperature_rise_c_at_100g * (g / 100.0).powf(1.5);
                let dw = d.resolution[i][m];
                let w = (g * b.g_local_m_s2 / b.arm_radius_m).sqrt();
                a_station = g
                    * (1.0 + d.radius[m])
                    * (1.0 + mount.input_sign() * d.cross_axis)
                    * (1.0 + 2.0 * d.rate)
                    * (1.0 - d.g)
                    * (1.0 + d.scale_tc * rise)
                    + d.stretch * g * g
                    + 2.0 * dw * w * b.arm_radius_m / b.g_local_m_s2;
                output_scale = 1.0 + d.timebase;
                bias = d.k0_tc * rise;
            }
            let sign = mount.input_sign();
            Point {
                mount,
                g_nominal: g,
                g_applied: a_station.abs(),
                output: ieee1293_output(K, sign * g) * output_scale + K[1] * bias,
                direction: None,
            }
        })
        .collect()
}

fn coefficients(points: &[Point]) -> [f64; 4] {
    let f = fit_ieee1293(points, ModelOrder::Cubic, Convention::PerMounting, "mc").expect("fit");
    [
        f.k0_g,
        f.k1,
        f.k2_ug_per_g2.expect("k2"),
        f.k3_ug_per_g3.expect("k3"),
    ]
}

fn std_dev(v: &[f64]) -> f64 {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

/// Half-width of the shortest... the symmetric 95 % interval about the mean.
fn half_width_95(v: &[f64]) -> f64 {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let mut dev: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    dev.sort_by(f64::total_cmp);
    dev[(0.95 * dev.len() as f64) as usize]
}

#[test]
fn the_linearised_budget_agrees_with_a_monte_carlo_propagation() {
    let b = inputs();
    let budget_p =
        mounting_budget(&points(Mount::P, &b, None), ModelOrder::Cubic, &b, "P").expect("budget P");
    let budget_n =
        mounting_budget(&points(Mount::N, &b, None), ModelOrder::Cubic, &b, "N").expect("budget N");
    let lin = budget_p.uncertainties();
    let (even, odd) = joint_uncertainty(&budget_p, &budget_n, None).expect("joint");

    let mut rng = ChaCha8Rng::seed_from_u64(101);
    let trials = 20_000;
    let n = levels().len();
    let (mut coef, mut k2_even, mut k2_odd) = (vec![Vec::new(); 4], Vec::new(), Vec::new());
    for _ in 0..trials {
        let d = draw(&mut rng, &b, n);
        let p = coefficients(&points(Mount::P, &b, Some(&d)));
        let q = coefficients(&points(Mount::N, &b, Some(&d)));
        for j in 0..4 {
            coef[j].push(p[j]);
        }
        k2_even.push(0.5 * (p[2] - q[2]));
        k2_odd.push(0.5 * (p[2] + q[2]));
    }
    let linear = [
        lin.k0_g.expect("k0").u,
        lin.k1.expect("k1").u,
        lin.k2_ug_per_g2.as_ref().expect("k2").u,
        lin.k3_ug_per_g3.as_ref().expect("k3").u,
    ];
    for (j, name) in ["k0", "k1", "k2", "k3"].iter().enumerate() {
        let mc = std_dev(&coef[j]);
        let ratio = mc / linear[j];
        println!(
            "{name}: u linear {:.4e}, Monte Carlo {mc:.4e}, ratio {ratio:.4}",
            linear[j]
        );
        // 20,000 draws: the Monte Carlo standard deviation is good to about 0.5 %.
        assert!((ratio - 1.0).abs() < 0.03, "{name}: ratio {ratio}");
    }
    let k2 = lin.k2_ug_per_g2.expect("k2");
    let mc95 = half_width_95(&coef[2]);
    println!(
        "k2 U95: linear {:.4}, Monte Carlo 95 % half-width {mc95:.4}",
        k2.u95
    );
    assert!((mc95 / k2.u95 - 1.0).abs() < 0.06, "{mc95} vs {}", k2.u95);
    for (name, lin, mc) in [("K2", &even, &k2_even), ("odd", &odd, &k2_odd)] {
        let ratio = std_dev(mc) / lin.u;
        println!(
            "{name}: u linear {:.4e}, Monte Carlo {:.4e}, ratio {ratio:.4}",
            lin.u,
            std_dev(mc)
        );
        assert!((ratio - 1.0).abs() < 0.03, "{name}: ratio {ratio}");
    }
    // Every source is in the budget, and the largest is named first.
    let sources = k2.budget.iter().filter(|c| !c.source.is_type_a()).count();
    assert_eq!(sources, 10, "{:?}", k2.budget);
    assert!(k2.budget.windows(2).all(|w| w[0].u >= w[1].u));
}

#[test]
fn type_b_inputs_are_refused_out_of_bounds_by_name() {
    for (text_key, bad) in [
        (
            "radius_ppm",
            TypeBInputs {
                radius_ppm: -1.0,
                ..TypeBInputs::default()
            },
        ),
        (
            "timebase_ppm",
            TypeBInputs {
                timebase_ppm: f64::NAN,
                ..TypeBInputs::default()
            },
        ),
        (
            "rate_resolution_deg_s",
            TypeBInputs {
                rate_resolution_deg_s: 0.001,
                ..TypeBInputs::default()
            },
        ),
    ] {
        let e = bad.validate().expect_err("refused");
        assert!(e.to_string().contains(text_key), "{e}");
    }
    assert_eq!(inputs().validate(), Ok(()));
}

#[test]
fn a_broad_table_disturbance_is_in_each_mountings_k2_and_cancels_from_k2() {
    // A Lorentzian bump of the table's acceleration in |a| (3,000 µg at
    // 45 g, 10 g wide), the same in both mountings: each mounting's k2
    // moves, K2 does not; the bound's source covers the move and is absent
    // from K2's budget.
    use spinbench_analysis::uncertainty::Source;
    let bump = |g: f64| 3_000e-6 / (1.0 + ((g - 45.0) / 10.0).powi(2));
    let with_bump = |mount: Mount| -> Vec<Point> {
        points(mount, &inputs(), None)
            .into_iter()
            .map(|p| {
                let sign = mount.input_sign();
                let a = p.g_nominal + bump(p.g_nominal);
                Point {
                    output: ieee1293_output(K, sign * a),
                    ..p
                }
            })
            .collect()
    };
    let b = TypeBInputs {
        table_disturbance_ug: 3_000.0,
        table_disturbance_width_g: 8.0,
        ..TypeBInputs::default()
    };
    let (p, n) = (with_bump(Mount::P), with_bump(Mount::N));
    let (bp, bn) = (
        mounting_budget(&p, ModelOrder::Cubic, &b, "P").expect("P"),
        mounting_budget(&n, ModelOrder::Cubic, &b, "N").expect("N"),
    );
    let k2 = |pts: &[Point]| coefficients(pts)[2];
    let clean = coefficients(&points(Mount::P, &inputs(), None))[2];
    let moved = k2(&p) - clean;
    let table = bp
        .effects
        .iter()
        .find(|e| e.source == Source::TableDisturbance)
        .expect("the table's source")
        .delta[2];
    assert!(moved.abs() > 0.5, "the bump moves k2 by {moved}");
    assert!(
        moved.abs() <= table.abs() * 3f64.sqrt(),
        "k2 moved {moved}, the bound's half-width is {}",
        table.abs() * 3f64.sqrt()
    );
    let (even, odd) = joint_uncertainty(&bp, &bn, None).expect("joint");
    let share = |u: &spinbench_analysis::uncertainty::Uncertainty| {
        u.budget
            .iter()
            .find(|c| c.source == Source::TableDisturbance)
            .map_or(0.0, |c| c.u)
    };
    assert!(
        share(&even) < 0.01 * table.abs(),
        "K2: {} of {table}",
        share(&even)
    );
    assert!(share(&odd) > 0.5 * table.abs(), "odd part: {}", share(&odd));
    // K2 itself hardly moves (second order).
    let k2_even = 0.5 * (k2(&p) - k2(&n));
    let clean_even = 0.5 * (clean - coefficients(&points(Mount::N, &inputs(), None))[2]);
    assert!(
        (k2_even - clean_even).abs() < 0.01 * moved.abs(),
        "{k2_even} vs {clean_even}, a mounting moved {moved}"
    );
}

/// Mounting P's points of the reference instrument with `feature(g)` [g]
/// added to each level's acceleration and white noise (seed `seed`).
fn points_with(seed: u64, feature: impl Fn(f64) -> f64) -> Vec<Point> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 30e-6 * K[1]).expect("normal");
    points(Mount::P, &inputs(), None)
        .into_iter()
        .map(|q| Point {
            output: ieee1293_output(K, q.g_nominal + feature(q.g_nominal)) + noise.sample(&mut rng),
            ..q
        })
        .collect()
}

/// A budget's standard uncertainty of k2 from `source` (0 when absent).
fn k2_part(
    b: &spinbench_analysis::uncertainty::MountingBudget,
    source: spinbench_analysis::uncertainty::Source,
) -> f64 {
    b.effects
        .iter()
        .find(|e| e.source == source)
        .map_or(0.0, |e| e.delta[2])
}

#[test]
fn a_table_disturbance_the_jackknife_sees_is_not_counted_twice() {
    // The table's bump moves the levels' readings, so the jackknife over
    // levels sees it among their scatter; with the bump's own Type B source
    // in the budget the model inadequacy is only what the jackknife finds
    // beyond the repeatability and that source (u_MI² = max(0, u_JK² −
    // u_rep² − u_table²)), never both in full.
    use spinbench_analysis::uncertainty::Source;
    let p = points_with(25, |g| 3_000e-6 / (1.0 + ((g - 45.0) / 3.0).powi(2)));
    let with = TypeBInputs {
        table_disturbance_ug: 3_000.0,
        table_disturbance_width_g: 3.0,
        ..TypeBInputs::default()
    };
    let part = k2_part;
    let alone = mounting_budget(&p, ModelOrder::Cubic, &TypeBInputs::default(), "P").expect("P");
    let both = mounting_budget(&p, ModelOrder::Cubic, &with, "P").expect("P");
    let (inadequacy_alone, table) = (
        part(&alone, Source::ModelInadequacy),
        part(&both, Source::TableDisturbance),
    );
    assert!(inadequacy_alone > 0.0, "the jackknife sees the bump");
    assert!(table.abs() > 0.0, "the table's source is in the budget");
    let expected = (inadequacy_alone.powi(2) - table.powi(2)).max(0.0).sqrt();
    let got = part(&both, Source::ModelInadequacy);
    assert!(
        (got - expected).abs() <= 1e-9 * inadequacy_alone,
        "model inadequacy {got} with the table's source {table}, {expected} expected (alone {inadequacy_alone})"
    );
    assert!(got < inadequacy_alone, "{got} vs {inadequacy_alone}");
}

#[test]
fn on_points_the_signature_corrected_the_instruments_own_misfit_is_kept_whole() {
    // Once the table's learned signature has taken its level-by-level part
    // out of the points, the jackknife over levels no longer sees the table:
    // what it finds is the instrument's own misfit (here an activity dip at
    // one level), and all of it is model inadequacy beside the stated Type B
    // term. Cut by that term it would leave the dip's effect on k2 out of
    // the interval (the per-mounting misses on the typical bench).
    use spinbench_analysis::uncertainty::{Source, mounting_budget_of};
    let mut rng = ChaCha8Rng::seed_from_u64(26);
    let noise = Normal::new(0.0, 30e-6 * K[1]).expect("normal");
    let dip = |g: f64| {
        if (g - 50.0).abs() < 0.5 {
            -4_000e-6
        } else {
            0.0
        }
    };
    let p: Vec<Point> = points(Mount::P, &inputs(), None)
        .into_iter()
        .map(|q| Point {
            output: ieee1293_output(K, q.g_nominal + dip(q.g_nominal)) + noise.sample(&mut rng),
            ..q
        })
        .collect();
    let with = TypeBInputs {
        table_disturbance_ug: 3_000.0,
        table_disturbance_width_g: 8.0,
        ..TypeBInputs::default()
    };
    let part = k2_part;
    let alone = mounting_budget(&p, ModelOrder::Cubic, &TypeBInputs::default(), "P").expect("P");
    let uncorrected = mounting_budget_of(&p, ModelOrder::Cubic, &with, false, "P").expect("P");
    let corrected = mounting_budget_of(&p, ModelOrder::Cubic, &with, true, "P").expect("P");
    let dip_alone = part(&alone, Source::ModelInadequacy);
    assert!(dip_alone > 0.0, "the jackknife sees the dip");
    assert!(
        part(&corrected, Source::TableDisturbance).abs() > 0.0,
        "the stated Type B term stays"
    );
    assert!(
        (part(&corrected, Source::ModelInadequacy) - dip_alone).abs() <= 1e-9 * dip_alone,
        "corrected points: the dip's misfit {} kept whole ({dip_alone} alone)",
        part(&corrected, Source::ModelInadequacy)
    );
    assert!(
        part(&uncorrected, Source::ModelInadequacy) < dip_alone,
        "uncorrected points: the table's term is taken from what the jackknife sees"
    );
}
