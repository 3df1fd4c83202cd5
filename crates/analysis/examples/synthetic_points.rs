//! Write a synthetic points file (CSV on stdout) with known truth, the one
//! shipped as `examples/points.csv`:
//!
//! ```text
//! cargo run -p spinbench-analysis --example synthetic_points > examples/points.csv
//! ```
//!
//! Three units, mountings P and N, the published level table (0, 1, 5, then
//! every 5 g to 70 g, up and back down), each instrument at its own true
//! radius (so g_applied differs from g_nominal), white output noise of 2 µg
//! per averaged point. Unit SN2603 is tested twice (runs 1 and 2). The truth
//! goes to stderr.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use spinbench_analysis::model::ieee1293_output;
use spinbench_analysis::points::{published_levels, up_down};

struct Truth {
    unit: &'static str,
    k: [f64; 4],
    radius_offset_mm: [f64; 2],
}

fn main() {
    let units = [
        Truth {
            unit: "SN2601",
            k: [0.0125, 101.25, 12.0e-6, 0.05e-6],
            radius_offset_mm: [0.41, -0.22],
        },
        Truth {
            unit: "SN2602",
            k: [-0.0083, 87.6, -6.5e-6, -0.02e-6],
            radius_offset_mm: [-0.35, 0.18],
        },
        Truth {
            unit: "SN2603",
            k: [0.0210, 120.4, 24.0e-6, 0.0],
            radius_offset_mm: [0.08, 0.52],
        },
    ];
    let r0_m = 0.8;
    let noise_ug = 2.0;
    let levels = up_down(&published_levels(70.0));

    let mut rng = ChaCha8Rng::seed_from_u64(2601);
    let unit_noise = Normal::new(0.0, noise_ug * 1e-6).expect("valid normal");
    println!("unit,mount,g_nominal,g_applied,output,run");
    for t in &units {
        let runs: &[&str] = if t.unit == "SN2603" {
            &["1", "2"]
        } else {
            &[""]
        };
        for run in runs {
            for (m, (mount, sign)) in [("P", 1.0), ("N", -1.0)].into_iter().enumerate() {
                let radius_m = r0_m + t.radius_offset_mm[m] * 1e-3;
                for &g in &levels {
                    let g_applied = g * radius_m / r0_m;
                    let a = sign * g_applied;
                    let output = ieee1293_output(t.k, a) + t.k[1] * unit_noise.sample(&mut rng);
                    println!("{},{mount},{g},{g_applied:.6},{output:.6},{run}", t.unit);
                }
            }
        }
        eprintln!(
            "{}: k0 {} g, k1 {} Hz/g, k2 {} µg/g², k3 {} µg/g³, radius offsets P {} mm, N {} mm",
            t.unit,
            t.k[0],
            t.k[1],
            t.k[2] * 1e6,
            t.k[3] * 1e6,
            t.radius_offset_mm[0],
            t.radius_offset_mm[1]
        );
    }
}
