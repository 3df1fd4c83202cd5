//! Acceptance: the 95 % intervals the station reports are honest. Over
//! 2,000 noisy trials (fixed seed) the interval for k2 must cover the true
//! value in 93–97 % of trials (binomial σ at 2,000 trials is 0.49 %, so the
//! band is ±4σ around 95 %).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use spinbench_analysis::model::{Convention, fit_ieee1293, fit_mounting, ieee1293_output};
use spinbench_analysis::points::{published_levels, up_down};
use spinbench_analysis::{ModelOrder, Mount, Point};

const TRIALS: usize = 2_000;

fn noisy_pass(mount: Mount, k: [f64; 4], noise_ug: f64, rng: &mut ChaCha8Rng) -> Vec<Point> {
    let noise = Normal::new(0.0, noise_ug * 1e-6 * k[1]).expect("normal");
    up_down(&published_levels(70.0))
        .into_iter()
        .map(|g| {
            let applied = g * 1.0004;
            Point {
                mount,
                g_nominal: g,
                g_applied: applied,
                output: ieee1293_output(k, mount.input_sign() * applied) + noise.sample(rng),
                direction: None,
            }
        })
        .collect()
}

fn covers(ci: Option<[f64; 2]>, truth: f64) -> bool {
    let [lo, hi] = ci.expect("interval");
    lo <= truth && truth <= hi
}

#[test]
fn k2_intervals_cover_the_truth_95_percent_of_the_time() {
    let k = [0.0125, 101.25, 12.0e-6, 0.05e-6];
    let mut rng = ChaCha8Rng::seed_from_u64(1293);
    let (mut k2_p, mut k2_n, mut k2_full, mut k1_p, mut k0_p, mut k3_p) = (0, 0, 0, 0, 0, 0);
    for _ in 0..TRIALS {
        let p = noisy_pass(Mount::P, k, 2.0, &mut rng);
        let n = noisy_pass(Mount::N, k, 2.0, &mut rng);
        let fp = fit_mounting(&p, Mount::P, ModelOrder::Cubic, "P")
            .expect("P")
            .fit;
        let fn_ = fit_mounting(&n, Mount::N, ModelOrder::Cubic, "N")
            .expect("N")
            .fit;
        let both: Vec<Point> = p.iter().chain(&n).copied().collect();
        let ff =
            fit_ieee1293(&both, ModelOrder::Cubic, Convention::SignedInput, "full").expect("full");
        k2_p += usize::from(covers(fp.ci95.k2_ug_per_g2, k[2] * 1e6));
        k2_n += usize::from(covers(fn_.ci95.k2_ug_per_g2, -k[2] * 1e6));
        k2_full += usize::from(covers(ff.ci95.k2_ug_per_g2, k[2] * 1e6));
        k1_p += usize::from(covers(fp.ci95.k1, k[1]));
        k0_p += usize::from(covers(fp.ci95.k0_g, k[0]));
        k3_p += usize::from(covers(fp.ci95.k3_ug_per_g3, k[3] * 1e6));
    }
    let rate = |hits: usize| hits as f64 / TRIALS as f64;
    println!(
        "coverage over {TRIALS} trials: k2 P {:.4}, k2 N {:.4}, k2 full range {:.4}, k0 P {:.4}, k1 P {:.4}, k3 P {:.4}",
        rate(k2_p),
        rate(k2_n),
        rate(k2_full),
        rate(k0_p),
        rate(k1_p),
        rate(k3_p)
    );
    for (name, hits) in [("k2 P", k2_p), ("k2 N", k2_n), ("k2 full range", k2_full)] {
        let r = rate(hits);
        assert!((0.93..=0.97).contains(&r), "{name}: coverage {r}");
    }
    for (name, hits) in [("k0 P", k0_p), ("k1 P", k1_p), ("k3 P", k3_p)] {
        let r = rate(hits);
        assert!((0.93..=0.97).contains(&r), "{name}: coverage {r}");
    }
}
