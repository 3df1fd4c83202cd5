//! K2's U95 against anomalies of several shapes added to an instrument
//! whose true K2 is known ("build for the physics, not for one
//! shape"). Each shape is drawn at random in size, place and width over
//! many synthetic instruments, in one mounting unless said, over white
//! scatter of 20–150 µg; the truth is the instrument's K2 without it.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Uniform};
use spinbench_analysis::model::ieee1293_output;
use spinbench_analysis::points::{infer_directions, published_levels, up_down};
use spinbench_analysis::unit::analyze_unit;
use spinbench_analysis::{AnalysisOptions, Mount, Point, UnitPoints};

const K: [f64; 4] = [0.01, 46.5, 12e-6, 0.05e-6];

/// What an anomaly adds [µg of acceleration] to a reading of mounting
/// `mount` at level `g`, the `index`-th reading of the run, on the way up
/// or not.
type Anomaly = dyn Fn(Mount, f64, usize, bool) -> f64;

fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    Uniform::new(lo, hi).expect("uniform").sample(rng)
}

/// Both mountings, 0–70 g up and down, of an instrument with `k2` and a
/// common part of 4 µg/g², scatter `noise_ug`, plus `anomaly`.
fn instrument(rng: &mut ChaCha8Rng, k2: f64, noise_ug: f64, anomaly: &Anomaly) -> Vec<Point> {
    let noise = Normal::new(0.0, noise_ug * 1e-6).expect("normal");
    let mut out = Vec::new();
    let mut index = 0usize;
    for mount in [Mount::P, Mount::N] {
        let sign = mount.input_sign();
        let sequence = up_down(&published_levels(70.0));
        let mut up = true;
        let mut pass: Vec<Point> = sequence
            .into_iter()
            .map(|g| {
                let a = sign * g * (1.0 + 4e-6 * g);
                let extra = anomaly(mount, g, index, up);
                if g >= 70.0 {
                    up = false;
                }
                index += 1;
                Point {
                    mount,
                    g_nominal: g,
                    g_applied: g,
                    output: ieee1293_output([K[0], K[1], k2 * 1e-6, K[3]], a)
                        + K[1] * (noise.sample(rng) + sign * extra * 1e-6),
                    direction: None,
                }
            })
            .collect();
        infer_directions(&mut pass);
        out.extend(pass);
    }
    out
}

/// The share of `trials` instruments whose K2 lies within its U95 with the
/// anomaly `shape` names.
fn coverage(shape: &str, trials: usize) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(36);
    let mut inside = 0usize;
    for t in 0..trials {
        let k2 = uniform(&mut rng, -30.0, 30.0);
        let noise = uniform(&mut rng, 20.0, 150.0);
        let sign = if t % 2 == 0 { 1.0 } else { -1.0 };
        let size = sign * uniform(&mut rng, 2_000.0, 15_000.0);
        let broad_size = size / 5.0;
        let (centre, other) = (uniform(&mut rng, 10.0, 65.0), uniform(&mut rng, 10.0, 65.0));
        let half_width = uniform(&mut rng, 1.0, 3.0);
        let sigma = uniform(&mut rng, 5.0, 12.0);
        let one = if t % 3 == 0 { Mount::N } else { Mount::P };
        let dip = move |g: f64, at: f64| (-((g - at) / 0.4).powi(2)).exp();
        let anomaly: Box<Anomaly> = match shape {
            "none" => Box::new(|_, _, _, _| 0.0),
            // A resonator mode crossing at one level.
            "dip" => Box::new(move |m, g, _, _| if m == one { size * dip(g, centre) } else { 0.0 }),
            // A resonance with Lorentzian wings over neighbouring levels.
            "wings" => Box::new(move |m, g, _, _| {
                if m == one {
                    size / (1.0 + ((g - centre) / half_width).powi(2))
                } else {
                    0.0
                }
            }),
            // A broad bump of the response, 400–3,000 µg, σ 5–12 g.
            "broad bump" => Box::new(move |m, g, _, _| {
                if m == one {
                    broad_size * (-0.5 * ((g - centre) / sigma).powi(2)).exp()
                } else {
                    0.0
                }
            }),
            // A mode hop: 400–3,000 µg from one level on.
            "step" => Box::new(move |m, g, _, _| {
                if m == one && g > centre {
                    broad_size
                } else {
                    0.0
                }
            }),
            // A dip in each mounting, at different levels.
            "two dips" => Box::new(move |m, g, _, _| match m {
                Mount::P => size * dip(g, centre),
                Mount::N => 0.6 * size * dip(g, other),
            }),
            // A broad bump in one mounting and a mode crossing in the
            // other (the typical bench's instruments have their dips).
            "bump and dip" => Box::new(move |m, g, _, _| {
                if m == one {
                    broad_size * (-0.5 * ((g - centre) / sigma).powi(2)).exp()
                } else {
                    size * dip(g, other)
                }
            }),
            // The bias drifting through the run.
            "drift" => Box::new(move |_, _, i, _| broad_size * 0.3 * i as f64 / 62.0),
            // The way down off the way up, growing with g.
            "hysteresis" => {
                Box::new(move |_, g, _, up| if up { 0.0 } else { broad_size * 0.3 * g / 70.0 })
            }
            other => panic!("no shape {other}"),
        };
        let points = instrument(&mut rng, k2, noise, &*anomaly);
        let analysis = analyze_unit(
            &UnitPoints {
                unit: shape.into(),
                run: None,
                points,
            },
            AnalysisOptions::default(),
        )
        .expect("reduced");
        let joint = analysis.joint.expect("K2");
        let u95 = joint.k2_even_u95.expect("U95");
        inside += usize::from((joint.k2_even_ug_per_g2 - k2).abs() <= u95);
    }
    inside as f64 / trials as f64
}

#[test]
fn k2s_interval_holds_anomalies_of_every_shape() {
    let trials = 400;
    let mut report = Vec::new();
    // Without the smooth-misfit term (inadequacy/smooth.rs) a broad bump
    // was held in 66 % and a step in 50 %.
    for shape in [
        "dip",
        "wings",
        "broad bump",
        "step",
        "two dips",
        "bump and dip",
        "drift",
        "hysteresis",
    ] {
        let c = coverage(shape, trials);
        println!("K2 within U95 with a {shape}: {c:.3} of {trials}");
        report.push((shape, c));
    }
    let shown: Vec<String> = report
        .iter()
        .map(|(shape, c)| format!("{shape} {c:.3}"))
        .collect();
    for (shape, c) in &report {
        assert!(
            *c >= 0.90,
            "K2 coverage with a {shape} under 90 %: {}",
            shown.join(", ")
        );
    }
}

#[test]
fn on_clean_instruments_the_shapes_add_no_width() {
    // No anomaly: the interval is the repeatability's, near its nominal 95 %
    // (150 trials: ±3.5 % is three binomial standard deviations).
    let c = coverage("none", 150);
    println!("K2 within U95 with no anomaly: {c:.3}");
    assert!((0.915..=0.99).contains(&c), "coverage {c}");
}
