use super::*;
use crate::model::ieee1293_output;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// A run of `n` instruments (both mountings, the published levels up and
/// down), each with its own K2 and bias, white noise `noise_ug`, on a table
/// with `table` lines (gain per instrument from 0.8 to 1.2), and
/// instrument `dip.0` (every one: `usize::MAX`) with a dip of `dip.2` µg
/// at level `dip.1` in P.
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
                        Some((who, at, size))
                            if (who == i || who == usize::MAX) && mount == Mount::P && at == g =>
                        {
                            size
                        }
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

/// Six runs' signatures on `table`, newest first (each its own run's).
fn six_runs_on(table: &[Line]) -> Vec<TableSignature> {
    let mut past: Vec<TableSignature> = Vec::new();
    for s in 0..6 {
        let prior = Prior::of(&past);
        let sig = estimate_with(
            &run(60 + s, 12, table, 10.0, None),
            ModelOrder::Cubic,
            prior.as_ref(),
        )
        .expect("a signature");
        past.insert(0, sig);
    }
    past
}

fn spike_at(s: &TableSignature, g: f64) -> Option<f64> {
    s.correction
        .spikes
        .iter()
        .find(|sp| sp.g == g)
        .map(|sp| sp.height_ug)
}

#[test]
fn an_unchanged_table_pools_every_run_and_says_nothing() {
    let table = typical_table();
    let past = six_runs_on(&table);
    assert!(
        past.iter().all(|s| s.change.is_none()),
        "no false alarm among the six"
    );
    assert_eq!(past[0].runs, 6, "{}", past[0].describe());
    for seed in 0..12 {
        let prior = Prior::of(&past).expect("a prior");
        assert_eq!((prior.runs, prior.set_aside_runs), (6, 0));
        let sig = estimate_with(
            &run(100 + seed, 12, &table, 10.0, None),
            ModelOrder::Cubic,
            Some(&prior),
        )
        .expect("a signature");
        assert!(sig.change.is_none(), "seed {seed}: {}", sig.describe());
        assert_eq!(sig.runs, 7);
    }
}

#[test]
fn a_moved_resonance_is_said_and_the_run_learns_alone() {
    let old = typical_table();
    let past = six_runs_on(&old);
    let moved = vec![(55.0, 0.6, 16_000.0), (52.0, 14.0, -3_500.0)];
    let units = run(200, 12, &moved, 10.0, None);
    let prior = Prior::of(&past).expect("a prior");
    let sig = estimate_with(&units, ModelOrder::Cubic, Some(&prior)).expect("a signature");
    let change = sig.change.clone().expect("the change is said");
    assert!(
        change.levels_g.contains(&40.0) && change.levels_g.contains(&55.0),
        "{change:?}"
    );
    assert_eq!(change.earlier_runs, 6);
    assert_eq!(sig.runs, 1);
    assert!(
        sig.describe().contains("changed at 40 g, 55 g"),
        "{}",
        sig.describe()
    );
    // It corrects the new resonance, not the old one, as a new station would.
    assert!(spike_at(&sig, 40.0).is_none(), "{}", sig.describe());
    let new = spike_at(&sig, 55.0).expect("the new resonance");
    assert!(
        (new - 16_000.0).abs() < 0.1 * 16_000.0,
        "{}",
        sig.describe()
    );
    let fresh = estimate(&units, ModelOrder::Cubic).expect("a new station's");
    assert_eq!(sig.correction, fresh.correction);
    // Couplings are the instruments' own (0.8–1.2), not pinned at a clamp.
    assert!(
        sig.gains.values().all(|g| (0.7..=1.3).contains(g)),
        "{:?}",
        sig.gains
    );
    // The next run pools only the runs since the change.
    let mut newest = past.clone();
    newest.insert(0, sig);
    let prior = Prior::of(&newest).expect("a prior");
    assert_eq!((prior.runs, prior.set_aside_runs), (1, 6));
    let next = estimate_with(
        &run(201, 12, &moved, 10.0, None),
        ModelOrder::Cubic,
        Some(&prior),
    )
    .expect("a signature");
    assert!(next.change.is_none(), "{}", next.describe());
    assert_eq!(next.runs, 2);
}

#[test]
fn a_repaired_or_shrunk_resonance_is_a_change_too() {
    let past = six_runs_on(&typical_table());
    let prior = Prior::of(&past).expect("a prior");
    for (what, height) in [("repaired", 0.0), ("shrunk", 8_000.0)] {
        let table = vec![(40.0, 0.6, height), (52.0, 14.0, -3_500.0)];
        let sig = estimate_with(
            &run(300, 12, &table, 10.0, None),
            ModelOrder::Cubic,
            Some(&prior),
        )
        .expect("a signature");
        let change = sig
            .change
            .clone()
            .unwrap_or_else(|| panic!("{what}: {}", sig.describe()));
        assert!(change.levels_g.contains(&40.0), "{what}: {change:?}");
        let seen = spike_at(&sig, 40.0).unwrap_or(0.0);
        assert!(
            (seen - height).abs() < 1_000.0,
            "{what}: {}",
            sig.describe()
        );
    }
}

#[test]
fn two_sharp_resonances_are_both_found() {
    let table = vec![
        (40.0, 0.6, 16_000.0),
        (55.0, 0.6, -9_000.0),
        (52.0, 14.0, -3_500.0),
    ];
    let sig = estimate(&run(400, 12, &table, 10.0, None), ModelOrder::Cubic).expect("a signature");
    let a = spike_at(&sig, 40.0).unwrap_or_else(|| panic!("{}", sig.describe()));
    let b = spike_at(&sig, 55.0).expect("55 g");
    assert!(
        (a - 16_000.0).abs() < 800.0 && (b + 9_000.0).abs() < 800.0,
        "{}",
        sig.describe()
    );
}

#[test]
fn a_defect_the_whole_batch_shares_in_one_mounting_is_not_the_tables() {
    let table = typical_table();
    let units = run(500, 12, &table, 10.0, Some((usize::MAX, 30.0, 8_000.0)));
    let sig = estimate(&units, ModelOrder::Cubic).expect("a signature");
    let clean = estimate(&run(500, 12, &table, 10.0, None), ModelOrder::Cubic).expect("clean");
    assert!(spike_at(&sig, 30.0).is_none(), "{}", sig.describe());
    // At most 6 % of the 8,000 µg is taken for the table (half of it
    // when P and N were one population).
    for l in [25.0, 30.0, 35.0] {
        let (with, without) = (sig.correction.at_level(l), clean.correction.at_level(l));
        assert!(
            (with - without).abs() < 480.0,
            "{l} g: {with} against {without} without it"
        );
    }
    assert!(spike_at(&sig, 40.0).is_some(), "{}", sig.describe());
    // Mounting N, which has no defect, comes out as it does without it.
    let mut worst = 0.0_f64;
    for (u, c) in units.iter().zip(run(500, 12, &table, 10.0, None)) {
        let n_of = |p: &[Point]| -> Vec<Point> {
            p.iter().filter(|p| p.mount == Mount::N).copied().collect()
        };
        let with = k2_of(&sig.correct(&u.unit, &n_of(&u.points)));
        let without = k2_of(&clean.correct(&c.unit, &n_of(&c.points)));
        worst = worst.max((with - without).abs());
    }
    assert!(worst < 0.5, "mounting N's k2 moved by up to {worst} µg/g²");
}
