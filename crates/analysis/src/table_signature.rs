//! The centrifuge's own signature, learned from the instruments it tests
//! (docs/method.md §6, "Every instrument on the arm sees the same table").
//!
//! A disturbance of the table (a structural resonance, a broad bump of the
//! arm's motion) moves the applied acceleration at a given speed by the
//! same amount for every instrument on the arm, in both mountings, in every
//! run on that centrifuge, scaled by the instrument's coupling to it (its
//! place on the arm, within about ±20 %). An instrument's own anomaly (an
//! activity dip) sits at one level of one instrument. So the population of
//! a run's instruments measures the table:
//!
//! 1. each mounting of each instrument is fitted with the model's
//!    polynomial, leaving out the levels found off the curve in that
//!    mounting alone (the instrument's own anomalies), and its level-mean
//!    residuals are expressed as acceleration, e_{j,ℓ} [µg];
//! 2. the signature at each level is the median over the mountings of
//!    e_{j,ℓ}/gᵢ, with its standard error from the median absolute
//!    deviation (robust: an instrument's anomaly at a level moves one of
//!    many values);
//! 3. the signature is split into the table's sharp resonances, each a
//!    spike at one level (a resonance narrower than the levels' spacing
//!    is met at one speed), and its broad error: the spikes are fitted
//!    through the polynomial's projection beside a smooth broad part (the
//!    powers of the level above the model's degree, projected likewise),
//!    each added only while significant against the signature's standard
//!    errors at the family-wise level [`SIGNATURE_ALPHA`] over the levels
//!    (at most [`MAX_SPIKES`]); what the spikes leave is the signature's
//!    remainder, level by level;
//! 4. steps 1–3 are repeated with the instrument-side levels found off
//!    the curve once the table is taken out (one anomaly no longer hides
//!    another).
//!
//! Each point's applied acceleration is then corrected by its
//! instrument's coupling to the table (its place on the arm, within about
//! ±20 %) times the spike and the remainder at its level. The coupling is
//! read at the largest spike in each mounting: the table couples into both
//! mountings alike, so when the two disagree one of them has an anomaly of
//! the instrument's own at that level (the typical bench puts activity dips
//! there), and the mounting nearer the median coupling gives it. An
//! instrument's remaining difference is its own misfit, which the outlier
//! test judges and its budget's model inadequacy carries.
//!
//! **What the data identify.** Only the part of the table's error that the
//! model's polynomial does not absorb is seen in the residuals; the rest
//! cannot be told from the instruments' own curvature. A spike is seen
//! whole (a single level is no polynomial), so its whole effect, the
//! coefficients' share of it too, is identified and corrected. A broad
//! error is seen only in part: its seen part (the remainder) is taken out
//! of the readings, which cleans the residuals that the misfit tests and
//! the jackknife judge and changes no coefficient; its unseen part stays in
//! the station's stated table-disturbance bound, a Type B term
//! ([`crate::uncertainty::TypeBInputs::table_disturbance_ug`]). (Fitting
//! broad Lorentzian lines and carrying their unseen part over was tried on
//! the typical bench: lines of very different heights explain one seen
//! part equally well, and the correction moved every mounting's k2 by
//! several µg/g² the wrong way.)
//!
//! The correction's own uncertainty is the jackknife over the instruments
//! (each left out in turn, the signature estimated again), the budget's
//! table-signature source; both mountings share it, so it cancels from K2.

use crate::model::ModelOrder;
use crate::points::{Mount, Point};
use crate::unit::UnitPoints;
use crate::{AnalysisError, UG_PER_G};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

mod change;
mod fit;
mod prior;
pub use change::{CHANGE_RELATIVE, CHANGE_Z, SignatureChange, change_of, disagreement};
use fit::{fit_spikes, level_residuals, median_se, residual_projector, slope_of};
pub use prior::Prior;

/// Family-wise false-alarm rate of adding a line to the signature (over
/// the candidate lines, Bonferroni).
pub const SIGNATURE_ALPHA: f64 = 0.01;
/// At most this many spikes explain a signature.
pub const MAX_SPIKES: usize = 4;
/// Fewer instruments than this cannot tell the table from an instrument.
pub const MIN_INSTRUMENTS: usize = 4;
/// Two mountings' couplings to the table agree within this (else one of
/// them has an anomaly of its own at the spike's level).
pub const COUPLING_AGREEMENT: f64 = 0.05;
/// A level off the curve in more than this share of the mountings is the
/// table's, not an instrument's.
pub const MAX_OWN_SHARE: f64 = 0.2;
/// The wide bumps that model the broad error beside the spikes.
const BROAD_BUMPS: usize = 4;
/// No spike below this level [g]: a table at a crawl has no resonance of
/// note, and the lowest levels (0, 1 g) sit too close to tell a spike from
/// the broad error.
pub const MIN_SPIKE_G: f64 = 3.0;
/// A spike's height is at most this [µg].
const MAX_HEIGHT_UG: f64 = crate::uncertainty::MAX_TABLE_DISTURBANCE_UG;
/// The signature's standard error never counts below this [µg].
const SE_FLOOR_UG: f64 = 0.5;
/// The detection limit is this many standard errors of the signature.
pub const DETECTION_Z: f64 = 3.0;

/// A sharp resonance of the table, met at one level.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spike {
    /// The level [g].
    pub g: f64,
    /// Its error of the applied acceleration there [µg] (positive: the arm
    /// gives more acceleration than ω²R).
    pub height_ug: f64,
}

/// What corrects the applied acceleration: the spikes, whole, and the
/// seen remainder of the broad error, level by level.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Correction {
    /// The spikes.
    pub spikes: Vec<Spike>,
    /// (level [g], remainder [µg]) of the levels the signature measured.
    pub remainder: Vec<(f64, f64)>,
}

impl Correction {
    /// Its value at a level [µg] (0 at a level the signature did not measure).
    pub fn at_level(&self, g: f64) -> f64 {
        self.spikes
            .iter()
            .filter(|s| s.g == g)
            .map(|s| s.height_ug)
            .sum::<f64>()
            + self
                .remainder
                .iter()
                .find(|(l, _)| *l == g)
                .map_or(0.0, |(_, r)| *r)
    }

    /// Its value at a point [µg].
    pub fn at(&self, p: &Point) -> f64 {
        self.at_level(p.g_nominal.abs())
    }

    /// Whether it corrects nothing.
    pub fn is_empty(&self) -> bool {
        self.spikes.is_empty() && self.remainder.iter().all(|(_, r)| *r == 0.0)
    }
}

/// The signature at one level.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SignatureLevel {
    /// The level [g].
    pub g: f64,
    /// The median residual of the mountings there, as acceleration [µg].
    pub residual_ug: f64,
    /// Its standard error [µg].
    pub se_ug: f64,
    /// The spike there, whole [µg] (0: none).
    pub spike_ug: f64,
    /// What the spikes leave of the signature there: the seen part of the
    /// table's broad error, corrected at this level [µg].
    pub remainder_ug: f64,
    /// The mountings that measured it.
    pub mountings: usize,
}

/// The table's signature learned from a run's instruments.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TableSignature {
    /// What corrects the points: its spikes (none: no sharp resonance was
    /// found) and the seen remainder level by level.
    pub correction: Correction,
    /// Each instrument's coupling to the table (1: the median instrument's).
    #[serde(default)]
    pub gains: BTreeMap<String, f64>,
    /// The signature level by level.
    pub levels: Vec<SignatureLevel>,
    /// The instruments and mountings it rests on.
    pub instruments: usize,
    /// The mountings it rests on.
    pub mountings: usize,
    /// The runs it rests on.
    pub runs: usize,
    /// The smallest spike's seen part it finds [µg]
    /// ([`DETECTION_Z`] × the signature's median standard error).
    pub detection_ug: f64,
    /// The correction with each instrument left out in turn (the jackknife of
    /// the correction's uncertainty), by the instrument left out.
    pub replicates: Vec<(String, Correction)>,
    /// The instrument-side levels found off the curve once the table was
    /// taken out: (serial, mounting, level [g]).
    pub instrument_levels: Vec<(String, Mount, f64)>,
    /// The table changed since the earlier runs it was to be pooled with:
    /// where, and that this signature rests on its own run alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub change: Option<SignatureChange>,
}

/// One mounting of one instrument.
struct Series {
    unit: String,
    points: Vec<Point>,
    /// Levels of this mounting alone left out of its fit [g].
    own: Vec<f64>,
}

impl Series {
    /// 0 for mounting P, 1 for N.
    fn side(&self) -> usize {
        usize::from(self.points.first().is_some_and(|p| p.mount != Mount::P))
    }
}

/// The signature of `series` (each mounting's residuals over its
/// instrument's coupling `gains`): the level set, the
/// median residual and its standard error per level, and the mountings
/// per level. Levels measured by fewer than half the mountings are left out.
/// The table couples into both mountings alike: at a level where the two
/// mountings' medians differ by more than [`CHANGE_Z`] standard errors,
/// one mounting carries a feature of the instruments' own, and the
/// mounting nearer zero gives the table's part there. The mountings of
/// side `set_aside` (0 P, 1 N), whose whole batch shares a feature of its
/// own, are left out.
fn signature_of(
    residuals: &[(usize, Vec<(f64, f64)>)],
    series: &[Series],
    gains: &BTreeMap<String, f64>,
    set_aside: Option<usize>,
) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<usize>) {
    let residuals: Vec<&(usize, Vec<(f64, f64)>)> = residuals
        .iter()
        .filter(|(j, _)| Some(series[*j].side()) != set_aside)
        .collect();
    // Per level, the values of mountings P and N.
    let mut at: BTreeMap<u64, [Vec<f64>; 2]> = BTreeMap::new();
    for (j, r) in &residuals {
        let s = &series[*j];
        let gain = gains.get(&s.unit).copied().unwrap_or(1.0);
        for &(g, e) in r {
            if !s.own.contains(&g) {
                at.entry(g.to_bits()).or_default()[s.side()].push(e / gain);
            }
        }
    }
    let need = residuals.len().div_ceil(2).max(MIN_INSTRUMENTS);
    let (mut levels, mut s, mut se, mut count) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut ordered: Vec<(f64, [Vec<f64>; 2])> = at
        .into_iter()
        .map(|(g, v)| (f64::from_bits(g), v))
        .collect();
    ordered.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (g, [mut p, mut n_side]) in ordered {
        let mut v: Vec<f64> = p.iter().chain(&n_side).copied().collect();
        if v.len() < need {
            continue;
        }
        let n = v.len();
        let both = median_se(&mut v);
        let one_mounting = match (median_se(&mut p), median_se(&mut n_side)) {
            (Some((mp, ep)), Some((mn, en)))
                if p.len() >= MIN_INSTRUMENTS && n_side.len() >= MIN_INSTRUMENTS =>
            {
                let scale = CHANGE_RELATIVE * mp.abs().max(mn.abs());
                let z = (mp - mn).abs()
                    / (ep.max(SE_FLOOR_UG).powi(2) + en.max(SE_FLOOR_UG).powi(2) + scale.powi(2))
                        .sqrt();
                (z > CHANGE_Z).then_some(if mp.abs() <= mn.abs() {
                    (mp, ep)
                } else {
                    (mn, en)
                })
            }
            _ => None,
        };
        if let Some((m, e)) = one_mounting.or(both) {
            levels.push(g);
            s.push(m);
            se.push(e.max(SE_FLOOR_UG));
            count.push(n);
        }
    }
    (levels, s, se, count)
}

/// Each instrument's coupling to the table, read at the largest spike in
/// each of its mountings (module docs): the mountings' mean when they
/// agree within [`COUPLING_AGREEMENT`], else the one nearer 1; within
/// 0.5–2; 1 without a spike.
fn gains_of(
    residuals: &[(usize, Vec<(f64, f64)>)],
    series: &[Series],
    correction: &Correction,
    levels: &[f64],
    s: &[f64],
) -> BTreeMap<String, f64> {
    let mut out: BTreeMap<String, f64> = BTreeMap::new();
    let largest = correction
        .spikes
        .iter()
        .max_by(|a, b| a.height_ug.abs().total_cmp(&b.height_ug.abs()));
    let Some(spike) = largest else {
        return out;
    };
    let Some(at) = levels.iter().position(|g| *g == spike.g) else {
        return out;
    };
    if s[at].abs() <= f64::EPSILON {
        return out;
    }
    let mut ratios: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for (j, r) in residuals {
        if let Some(&(_, e)) = r.iter().find(|(g, _)| *g == spike.g) {
            ratios
                .entry(series[*j].unit.clone())
                .or_default()
                .push(e / s[at]);
        }
    }
    for (unit, r) in ratios {
        let gain = match r.as_slice() {
            [a, b] if (a - b).abs() <= COUPLING_AGREEMENT => 0.5 * (a + b),
            [a, b] => {
                if (a - 1.0).abs() <= (b - 1.0).abs() {
                    *a
                } else {
                    *b
                }
            }
            [a] => *a,
            _ => 1.0,
        };
        out.insert(
            unit,
            if gain.is_finite() {
                gain.clamp(0.5, 2.0)
            } else {
                1.0
            },
        );
    }
    out
}

/// The correction the signature `s` at `levels` makes: its spikes and
/// what they leave, level by level.
fn correction_of(
    levels: &[f64],
    s: &[f64],
    se: &[f64],
    m: &DMatrix<f64>,
    degree: usize,
) -> Correction {
    let spikes = fit_spikes(levels, s, se, m, degree);
    let raw = DMatrix::from_fn(levels.len(), 1, |i, _| {
        spikes
            .iter()
            .filter(|sp| sp.g == levels[i])
            .map(|sp| sp.height_ug)
            .sum::<f64>()
    });
    // The median of residuals need not lie in the residual space: the
    // remainder is projected again, so that it changes no coefficient.
    let rest = DMatrix::from_fn(levels.len(), 1, |i, _| s[i] - raw[i]);
    let remainder = m * rest;
    Correction {
        remainder: levels
            .iter()
            .enumerate()
            .map(|(i, &g)| (g, remainder[i]))
            .collect(),
        spikes,
    }
}

/// Estimate the table's signature from a run's instruments (module docs).
/// `None` with fewer than [`MIN_INSTRUMENTS`] instruments, or too few
/// shared levels for the model with spare levels.
pub fn estimate(units: &[UnitPoints], order: ModelOrder) -> Option<TableSignature> {
    estimate_with(units, order, None)
}

/// [`estimate`], the run's signature pooled with what past runs on the
/// same centrifuge measured (`prior`) before the correction is made; the
/// signature's `levels` stay the run's own measurement (what the next
/// run's prior pools), its correction rests on both. When the run's own
/// signature disagrees with the prior ([`disagreement`]) the table has
/// changed: the run learns alone and its signature's `change` says where.
pub fn estimate_with(
    units: &[UnitPoints],
    order: ModelOrder,
    prior: Option<&Prior>,
) -> Option<TableSignature> {
    let pooled = estimate_once(units, order, prior)?;
    let Some(prior) = prior else {
        return Some(pooled);
    };
    if disagreement(&prior.levels, &pooled.levels).is_empty() {
        return Some(pooled);
    }
    let Some(mut alone) = estimate_once(units, order, None) else {
        return Some(pooled);
    };
    let Some(change) = change_of(&disagreement(&prior.levels, &alone.levels), prior.runs) else {
        return Some(pooled);
    };
    alone.change = Some(change);
    alone.runs = 1;
    Some(alone)
}

/// One estimate of the signature, pooled with `prior` when given.
fn estimate_once(
    units: &[UnitPoints],
    order: ModelOrder,
    prior: Option<&Prior>,
) -> Option<TableSignature> {
    let degree = usize::from(order.degree());
    let mut series: Vec<Series> = Vec::new();
    for u in units {
        let mut by_mount: BTreeMap<Mount, Vec<Point>> = BTreeMap::new();
        for p in &u.points {
            by_mount.entry(p.mount).or_default().push(*p);
        }
        for (_, points) in by_mount {
            if crate::inadequacy::levels(&points).len() >= degree + 4 {
                series.push(Series {
                    unit: u.unit.clone(),
                    points,
                    own: Vec::new(),
                });
            }
        }
    }
    let instruments: std::collections::BTreeSet<&str> =
        series.iter().map(|s| s.unit.as_str()).collect();
    if instruments.len() < MIN_INSTRUMENTS {
        return None;
    }
    let instruments = instruments.len();
    let mut correction = Correction::default();
    let mut gains: BTreeMap<String, f64> = BTreeMap::new();
    let mut result = None;
    // Three rounds: the table from the mountings, then each mounting's own
    // levels off the curve with the table taken out, then the table again.
    // A side whose mountings share a level off the curve of their own.
    let mut set_aside: Option<usize> = None;
    for _round in 0..3 {
        let residuals: Vec<(usize, Vec<(f64, f64)>)> = series
            .iter()
            .enumerate()
            .filter_map(|(j, s)| level_residuals(&s.points, degree, &s.own).map(|r| (j, r)))
            .collect();
        let (levels, s, se, count) = signature_of(&residuals, &series, &gains, set_aside);
        if levels.len() < degree + 4 {
            return None;
        }
        let m = residual_projector(&levels, degree)?;
        let (pooled, pooled_se) = match prior {
            Some(p) => p.pool(&levels, &s, &se),
            None => (s.clone(), se.clone()),
        };
        correction = correction_of(&levels, &pooled, &pooled_se, &m, degree);
        gains = gains_of(&residuals, &series, &correction, &levels, &pooled);
        // Each mounting's own levels off the curve once the table is out.
        for sr in &mut series {
            let gain = gains.get(&sr.unit).copied().unwrap_or(1.0);
            let corrected = correct_points(&sr.points, &correction, gain);
            let k1 = slope_of(&corrected, degree).unwrap_or(1.0).abs();
            sr.own = crate::inadequacy::outlier_levels(&corrected, degree, k1, "table signature")
                .iter()
                .map(|o| o.g)
                .collect();
        }
        // A level off the curve in many mountings of both sides at once is
        // the table's (what the correction does not yet explain), not an
        // instrument's; one flagged in many of one side only is a feature
        // the batch's instruments share in that mounting, theirs.
        let mut flagged_in: BTreeMap<u64, [usize; 2]> = BTreeMap::new();
        let mut on_side = [0_usize; 2];
        for sr in &series {
            on_side[sr.side()] += 1;
            for g in &sr.own {
                flagged_in.entry(g.to_bits()).or_default()[sr.side()] += 1;
            }
        }
        let shared = on_side.map(|n| (n as f64 * MAX_OWN_SHARE).max(1.0));
        // A level flagged in most of one side's mountings and few of the
        // other's: that side's batch shares a feature of its own, and the
        // table is learned from the other side alone (a mounting fitted
        // without a level sees the table's resonances through another
        // projection).
        set_aside = set_aside.or_else(|| {
            flagged_in.values().find_map(|n| {
                (0..2).find(|&side| {
                    n[side] as f64 > 0.5 * on_side[side] as f64
                        && n[1 - side] as f64 <= shared[1 - side]
                })
            })
        });
        for sr in &mut series {
            sr.own.retain(|g| {
                flagged_in
                    .get(&g.to_bits())
                    .is_some_and(|n| n[0] as f64 <= shared[0] || n[1] as f64 <= shared[1])
                    && !correction.spikes.iter().any(|sp| sp.g == *g)
            });
        }
        let median_se = {
            let mut v = se.clone();
            median_se(&mut v).map_or(SE_FLOOR_UG, |(m, _)| m)
        };
        result = Some((levels, s, se, count, m, median_se, residuals));
    }
    let (levels, s, se, count, m, median_se, residuals) = result?;
    // The jackknife over instruments: each left out, the correction again.
    let units_list: Vec<String> = series
        .iter()
        .map(|s| s.unit.clone())
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    let replicates = units_list
        .iter()
        .map(|left_out| {
            let kept: Vec<(usize, Vec<(f64, f64)>)> = residuals
                .iter()
                .filter(|(j, _)| &series[*j].unit != left_out)
                .cloned()
                .collect();
            let (lv, sv, sev, _) = signature_of(&kept, &series, &gains, set_aside);
            let (sv, sev) = match prior {
                Some(p) => p.pool(&lv, &sv, &sev),
                None => (sv, sev),
            };
            let replicate = if lv == levels {
                correction_of(&lv, &sv, &sev, &m, degree)
            } else {
                residual_projector(&lv, degree).map_or_else(Correction::default, |mm| {
                    correction_of(&lv, &sv, &sev, &mm, degree)
                })
            };
            (left_out.clone(), replicate)
        })
        .collect();
    let instrument_levels = series
        .iter()
        .flat_map(|s| {
            let mount = s.points.first().map_or(Mount::P, |p| p.mount);
            s.own.iter().map(move |g| (s.unit.clone(), mount, *g))
        })
        .collect();
    Some(TableSignature {
        levels: levels
            .iter()
            .enumerate()
            .map(|(i, &g)| SignatureLevel {
                g,
                residual_ug: s[i],
                se_ug: se[i],
                spike_ug: correction
                    .spikes
                    .iter()
                    .filter(|sp| sp.g == g)
                    .map(|sp| sp.height_ug)
                    .sum(),
                remainder_ug: correction.remainder.get(i).map_or(0.0, |r| r.1),
                mountings: count[i],
            })
            .collect(),
        correction,
        gains,
        instruments,
        mountings: series.len(),
        runs: 1 + prior.map_or(0, |p| p.runs),
        detection_ug: DETECTION_Z * median_se,
        replicates,
        instrument_levels,
        change: None,
    })
}

/// `points` with each applied acceleration corrected by `gain` times the
/// correction at it (its sign kept).
pub fn correct_points(points: &[Point], correction: &Correction, gain: f64) -> Vec<Point> {
    points
        .iter()
        .map(|p| {
            let shift = gain * correction.at(p) / UG_PER_G;
            let sign = if p.g_applied < 0.0 { -1.0 } else { 1.0 };
            Point {
                g_applied: p.g_applied + sign * shift,
                ..*p
            }
        })
        .collect()
}

impl TableSignature {
    /// The coupling of instrument `unit` (1 when it was not part of the estimate).
    pub fn gain(&self, unit: &str) -> f64 {
        self.gains.get(unit).copied().unwrap_or(1.0)
    }

    /// `points` of instrument `unit` with the table taken out of their
    /// applied acceleration.
    pub fn correct(&self, unit: &str, points: &[Point]) -> Vec<Point> {
        correct_points(points, &self.correction, self.gain(unit))
    }

    /// Whether it corrects nothing.
    pub fn is_empty(&self) -> bool {
        self.correction.is_empty()
    }

    /// The correction's standard uncertainty of each coefficient of one
    /// mounting's fit of `points` (already corrected; instrument `unit`):
    /// the jackknife over the instruments the signature rests on,
    /// (n − 1)/n · Σ (Δ₍₋ᵢ₎ − Δ̄)², with Δ₍₋ᵢ₎ the coefficients' change when
    /// the signature without instrument i corrects instead; its degrees of
    /// freedom n − 1.
    pub fn correction_effect(
        &self,
        unit: &str,
        points: &[Point],
        order: ModelOrder,
        what: &str,
    ) -> Result<Option<crate::uncertainty::Effect>, AnalysisError> {
        let n = self.replicates.len();
        if n < 2 || (self.is_empty() && self.replicates.iter().all(|(_, c)| c.is_empty())) {
            return Ok(None);
        }
        let gain = self.gain(unit);
        let full = crate::uncertainty::coefficients_of(points, order, what)?;
        let mut deltas = Vec::with_capacity(n);
        for (_, replicate) in &self.replicates {
            // The replicate's correction in place of the full one's.
            let swapped: Vec<Point> = points
                .iter()
                .map(|p| {
                    let shift = gain * (replicate.at(p) - self.correction.at(p)) / UG_PER_G;
                    let sign = if p.g_applied < 0.0 { -1.0 } else { 1.0 };
                    Point {
                        g_applied: p.g_applied + sign * shift,
                        ..*p
                    }
                })
                .collect();
            let c = crate::uncertainty::coefficients_of(&swapped, order, what)?;
            deltas.push(std::array::from_fn::<f64, 4, _>(|j| c[j] - full[j]));
        }
        let mean: [f64; 4] =
            std::array::from_fn(|j| deltas.iter().map(|d| d[j]).sum::<f64>() / n as f64);
        let factor = (n as f64 - 1.0) / n as f64;
        let delta: [f64; 4] = std::array::from_fn(|j| {
            (factor * deltas.iter().map(|d| (d[j] - mean[j]).powi(2)).sum::<f64>()).sqrt()
        });
        Ok(Some(crate::uncertainty::Effect {
            source: crate::uncertainty::Source::TableSignature,
            delta,
            dof: Some((n - 1) as f64),
        }))
    }

    /// One line for `analyze` and the reports.
    pub fn describe(&self) -> String {
        let largest = self
            .correction
            .remainder
            .iter()
            .fold(0.0_f64, |m, (_, r)| m.max(r.abs()));
        let lines = if self.correction.spikes.is_empty() {
            format!("no sharp resonance; the broad error's seen part up to {largest:.0} µg")
        } else {
            let sharp = self
                .correction
                .spikes
                .iter()
                .map(|sp| format!("{:+.0} µg at {} g", sp.height_ug, sp.g))
                .collect::<Vec<_>>()
                .join(", ");
            format!("resonance {sharp}; the broad error's seen part up to {largest:.0} µg")
        };
        let changed = self.change.as_ref().map_or(String::new(), |c| {
            format!(
                "; changed at {} since the {} earlier run(s), which are set aside",
                c.levels_shown(),
                c.earlier_runs
            )
        });
        format!(
            "the centrifuge's signature from {} instrument(s), {} mounting(s), {} run(s): {lines}; detection limit {:.0} µg{changed}",
            self.instruments, self.mountings, self.runs, self.detection_ug
        )
    }
}

#[cfg(test)]
mod tests;
