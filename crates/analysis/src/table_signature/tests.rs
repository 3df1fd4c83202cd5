use super::*;
use crate::model::ieee1293_output;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// A run of `n` instruments (both mountings, the published levels up and
/// down), each with its own K2 and bias, white noise `noise_ug`, on a table
/// with `table` lines (gain per instrument from 0.8 to 1.2), and
/// instrument `dip.0` with a dip of `dip.2` µg at level `dip.1` in P.
/// A line of the table's error in |a|: (centre [g], half-width [g], height [µg]).
type Line = (f64, f64, f64);

fn line_at(lines: &[Line], a: f64) -> f64 {
    lines
        .iter()
        .map(|(c, w, h)| h / (1.0 + ((a - c) / w).powi(2)))
        .sum()
}

pub(super) fn run(
    seed: u64,
    n: usize,
    table: &[Line],
    noise_ug: f64,
    dip: Option<(usize, f64, f64)>,
) -> Vec<UnitPoints> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, noise_ug * 1e-6).expect("normal");
    let levels = crate::points::published_levels(70.0);
    (0..n)
        .map(|i| {
            let k2 = -20.0 + 40.0 * (i as f64 + 0.5) / n as f64;
            let k = [0.01 * i as f64, 80.0 + i as f64, k2 * 1e-6, 0.2e-6];
            let gain = 0.8 + 0.4 * i as f64 / (n.max(2) - 1) as f64;
            let mut points = Vec::new();
            for mount in [Mount::P, Mount::N] {
                let sign = mount.input_sign();
                for &g in levels.iter().chain(levels.iter().rev()) {
                    let table_ug = gain * line_at(table, g);
                    let dip_ug = match dip {
                        Some((who, at, size)) if who == i && mount == Mount::P && at == g => size,
                        _ => 0.0,
                    };
                    let a = g + (table_ug + dip_ug) * 1e-6 + noise.sample(&mut rng);
                    points.push(Point {
                        mount,
                        g_nominal: g,
                        g_applied: g,
                        output: ieee1293_output(k, sign * a),
                        direction: None,
                    });
                }
            }
            UnitPoints {
                unit: format!("T{i:02}"),
                run: None,
                points,
            }
        })
        .collect()
}

fn typical_table() -> Vec<Line> {
    vec![(40.0, 0.6, 16_000.0), (52.0, 14.0, -3_500.0)]
}

/// The per-mounting k2 of `points` of one mounting [µg/g²].
fn k2_of(points: &[Point]) -> f64 {
    crate::uncertainty::coefficients_of(points, ModelOrder::Cubic, "t").expect("fit")[2]
}

#[test]
fn the_table_is_learned_from_the_instruments_and_its_effect_on_each_mountings_k2_removed() {
    // A table whose two features' effects on k2 add (the typical table's nearly cancel).
    let table = vec![(45.0, 0.6, 16_000.0), (20.0, 8.0, -3_500.0)];
    let units = run(3, 12, &table, 10.0, Some((4, 25.0, -8_000.0)));
    // The same run on the table without its resonance: the broad error's
    // unseen part is not the signature's to correct (module docs).
    let clean = run(3, 12, &table[1..], 10.0, Some((4, 25.0, -8_000.0)));
    let sig = estimate(&units, ModelOrder::Cubic).expect("a signature");
    assert!(!sig.correction.spikes.is_empty(), "{}", sig.describe());
    assert_eq!(sig.instruments, 12);
    // The resonance is found where it is.
    assert!(
        sig.correction
            .spikes
            .iter()
            .any(|sp| sp.g == 45.0 && sp.height_ug > 10_000.0),
        "{}",
        sig.describe()
    );
    // The instrument's dip is the instrument's, not the table's.
    assert!(
        sig.instrument_levels
            .contains(&("T04".to_string(), Mount::P, 25.0)),
        "{:?}",
        sig.instrument_levels
    );
    // Each mounting's k2 after the correction is the resonance-free one
    // within a fraction of what the resonance did to it.
    let (mut before, mut after) = (0.0_f64, 0.0_f64);
    for (u, c) in units.iter().zip(&clean) {
        for mount in [Mount::P, Mount::N] {
            let pick = |ps: &[Point]| {
                ps.iter()
                    .filter(|p| p.mount == mount)
                    .copied()
                    .collect::<Vec<_>>()
            };
            let truth = k2_of(&pick(&c.points));
            let raw = k2_of(&pick(&u.points));
            let fixed = k2_of(&pick(&sig.correct(&u.unit, &u.points)));
            before = before.max((raw - truth).abs());
            after = after.max((fixed - truth).abs());
        }
    }
    assert!(before > 3.0, "the resonance moved k2 by {before}");
    assert!(
        after < 0.3 * before,
        "k2 error {before} → {after} µg/g²: {}",
        sig.describe()
    );
}

#[test]
fn a_clean_table_gives_no_lines_in_most_runs() {
    let mut found = 0;
    let runs: usize = 40;
    for seed in 0..runs {
        let units = run(seed as u64, 10, &[], 10.0, None);
        let sig = estimate(&units, ModelOrder::Cubic).expect("a signature");
        found += usize::from(!sig.correction.spikes.is_empty());
    }
    assert!(
        found * 20 <= runs,
        "a line found on a clean table in {found}/{runs} runs"
    );
}

#[test]
fn too_few_instruments_learn_nothing() {
    let units = run(1, MIN_INSTRUMENTS - 1, &typical_table(), 10.0, None);
    assert!(estimate(&units, ModelOrder::Cubic).is_none());
}

#[test]
fn past_runs_on_the_same_table_sharpen_the_correction() {
    // Four instruments learn the table's resonance alone; with three past
    // runs' signatures pooled, the correction rests on them too and its
    // jackknife over this run's instruments shrinks.
    let table = vec![(45.0, 0.6, 16_000.0)];
    let alone = estimate(&run(21, 4, &table, 10.0, None), ModelOrder::Cubic).expect("a signature");
    let past: Vec<TableSignature> = (0..3)
        .map(|s| estimate(&run(30 + s, 12, &table, 10.0, None), ModelOrder::Cubic).expect("past"))
        .collect();
    let prior = Prior::of(&past).expect("a prior");
    assert_eq!(prior.runs, 3);
    assert_eq!(prior.instruments, 36);
    let units = run(21, 4, &table, 10.0, None);
    let pooled = estimate_with(&units, ModelOrder::Cubic, Some(&prior)).expect("a signature");
    assert_eq!(pooled.runs, 4);
    // The run's own measurement stays its own (what the next prior pools;
    // only the couplings it is divided by follow the pooled correction).
    for (p, a) in pooled.levels.iter().zip(&alone.levels) {
        assert_eq!(p.g, a.g);
        assert!(
            (p.residual_ug - a.residual_ug).abs() <= 0.01 * a.residual_ug.abs() + 1.0,
            "{p:?} {a:?}"
        );
    }
    let spike = |s: &TableSignature| {
        s.correction
            .spikes
            .iter()
            .find(|sp| sp.g == 45.0)
            .map(|sp| sp.height_ug)
            .expect("the resonance")
    };
    let spread = |s: &TableSignature| {
        let h: Vec<f64> = s
            .replicates
            .iter()
            .filter_map(|(_, c)| {
                c.spikes
                    .iter()
                    .find(|sp| sp.g == 45.0)
                    .map(|sp| sp.height_ug)
            })
            .collect();
        let mean = h.iter().sum::<f64>() / h.len() as f64;
        (h.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / h.len() as f64).sqrt()
    };
    assert!(
        (spike(&pooled) - 16_000.0).abs() < 0.05 * 16_000.0,
        "{}",
        pooled.describe()
    );
    assert!(
        spread(&pooled) < spread(&alone),
        "jackknife spread {} pooled, {} alone",
        spread(&pooled),
        spread(&alone)
    );
}
