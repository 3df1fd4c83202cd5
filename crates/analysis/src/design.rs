//! Experiment design: the levels, the readings taken again on the way down
//! and the dwell that reach a target K2 uncertainty in the least centrifuge
//! time, predicted from a model of the station learned from its own runs
//! (method.md §3.3 for the constraints, §5 for the error sources).
//!
//! **The station's model** ([`StationModel`], learned by
//! [`StationModel::learn`] from the readings of past runs):
//! * each instrument's noise, in µg: flicker σ_f and random walk q
//!   [µg²/s] from the Allan deviation of its one-second values at rest
//!   ([`allan_deviation`], fitted as `σ_A²(τ) = σ_w²/τ + σ_f² + q·τ/3` by
//!   [`fit_allan`]), and white σ_w at the levels, the scatter of the
//!   dwells' one-second values (it grows with the acceleration; the fit's
//!   σ_w at rest is kept beside it); without values at rest, q from the
//!   pairs below;
//! * the level floor σ_h [µg]: what the readings of one level on the way up
//!   and on the way down differ by beyond that noise (a level's hysteresis,
//!   the table's repeatability — the reduction's pure error holds it too),
//!   from `E[d²] = 2·σ_w²/n + 2·(σ_f² + σ_h²) + q·Δt`, a least-squares line
//!   in their time apart Δt;
//! * the table's settle time per level step, `s0 + s1·|Δg|` [s], from the
//!   time between one reading's start and the next one's less the dwell;
//! * the between-level scatter τ of K2's half-difference series (the model
//!   inadequacy of [`crate::inadequacy`], the anomalies that differ between
//!   the mountings), `τ² = max(0, (RSS − Σ(1 − h)·v)/Σ(1 − h))`, per
//!   instrument; the model keeps the median.
//!
//! A station with no history uses [`StationModel::default`], the typical
//! virtual bench's (its 24-seed median), and says so.
//!
//! **The prediction** of a plan ([`predict`]): K2 is the quadratic
//! coefficient of the half-difference series ½(z_P − z_N) over the levels
//! (crate::inadequacy), so with G_ℓ its sensitivity to level ℓ's mean
//!
//! ```text
//! var(K2) = Σ_ℓ G_ℓ²·(τ² + v_ℓ),   v_ℓ = ¼·σ_r²·(1/m_ℓ,P + 1/m_ℓ,N)
//! σ_r² = σ_w²/n + σ_f² + σ_h² + q·T/6   (one reading; T the pass's time: a
//!                                        random walk's variance about its mean over T)
//! U95 = t₀.₉₇₅(ν)·√var(K2),   ν = L − p (the model inadequacy's, as in the budget)
//! ```
//!
//! with m_ℓ the readings of level ℓ (2 where it is read again on the way
//! down) and n the dwell's one-second values, times the model's
//! calibration: the median ratio of achieved to predicted K2 U95 over the
//! runs it learned from (the budget's jackknife over levels reads a sparse
//! anomaly, one activity dip, differently from the random effect assumed
//! here; the ratio is learned, not assumed). The centrifuge time of a pass
//! is Σ over its visits of the settle time of the step and the dwell.
//!
//! **The search** ([`design`]): L from [`MIN_LEVELS`] to
//! [`MAX_DESIGN_LEVELS`] levels spread evenly from 0 to the range, D of
//! them read again on the way down (every one where the plan measures
//! hysteresis; otherwise at least [`MIN_DOWN_LEVELS`], for the pure error),
//! and a dwell from [`DWELL_CHOICES_S`]; the one of least predicted time
//! whose predicted U95 meets the target. A target no candidate meets is
//! refused with the smallest U95 the search can reach.

use crate::lsq;
use crate::points::Mount;
use crate::statistics::student_t_975;
use crate::{AnalysisError, UG_PER_G};
pub use allan::{AllanFit, allan_deviation, fit_allan};
use serde::{Deserialize, Serialize};
pub use spread::{MIN_SPREAD_INSTRUMENTS, RUN_RANGE_PROBABILITY, run_median_range};

/// Fewest levels from 0 to the range (method.md §3.3).
pub const MIN_LEVELS: usize = 6;
/// Most levels the search tries.
pub const MAX_DESIGN_LEVELS: usize = 40;
/// Fewest levels read again on the way down: the pure error needs replicates.
pub const MIN_DOWN_LEVELS: usize = 2;
/// The dwells the search tries [one-second values].
pub const DWELL_CHOICES_S: [u32; 6] = [2, 3, 5, 10, 20, 30];
/// The model's order (cubic, method.md (2)): its parameter count.
const PARAMETERS: usize = 4;

/// The noise of one instrument's one-second values [µg].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NoiseModel {
    /// White noise at the levels: the scatter of the dwells' one-second
    /// values (the Allan deviation at 1 s of a white noise) [µg].
    pub white_ug: f64,
    /// White noise at rest, from the Allan fit [µg].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub white_at_rest_ug: Option<f64>,
    /// Flicker: the Allan deviation's floor [µg].
    pub flicker_ug: f64,
    /// Random walk: variance growth [µg²/s].
    pub random_walk_ug2_per_s: f64,
    /// What a level's readings up and down differ by beyond the noise
    /// (hysteresis, the table's repeatability) [µg].
    #[serde(default)]
    pub level_floor_ug: f64,
    /// Instrument-runs whose values at rest gave the Allan fit (0: none).
    #[serde(default)]
    pub at_rest_series: usize,
}

/// The station's model (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StationModel {
    /// The instruments' noise (medians over instruments).
    pub noise: NoiseModel,
    /// Settle time of a level step at no change of level [s].
    pub settle_s: f64,
    /// Settle time per g of level change [s/g].
    pub settle_s_per_g: f64,
    /// Between-level scatter τ of K2's half-difference series [µg] (median).
    pub between_level_ug: f64,
    /// The instruments' τ [µg] at 0, 10, … 100 % of their distribution
    /// (learned from at least [`MIN_SPREAD_INSTRUMENTS`] instrument-runs;
    /// none for the defaults): what a run's median K2 U95 may come out at
    /// ([`run_median_range`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub between_level_deciles_ug: Option<[f64; 11]>,
    /// Achieved over predicted K2 U95, the median over the runs learned
    /// from (each run's plan predicted again on this model): the budget
    /// reads a sparse anomaly through its jackknife over levels, not as the
    /// random effect the prediction assumes (1: no history).
    #[serde(default = "one")]
    pub calibration: f64,
    /// Runs learned from (0: the defaults).
    pub runs: usize,
    /// Instrument-runs learned from.
    pub instruments: usize,
}

impl Default for StationModel {
    /// A station with no history: the typical virtual bench's medians
    /// (`spinbench plan design` on 24 typical demo runs).
    fn default() -> Self {
        StationModel {
            noise: NoiseModel {
                white_ug: 80.0,
                white_at_rest_ug: None,
                flicker_ug: 0.0,
                random_walk_ug2_per_s: 0.0,
                level_floor_ug: 250.0,
                at_rest_series: 0,
            },
            settle_s: 12.0,
            settle_s_per_g: 0.0,
            between_level_ug: 600.0,
            between_level_deciles_ug: None,
            calibration: 1.0,
            runs: 0,
            instruments: 0,
        }
    }
}

/// One reading of a past run, as the model learns from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// The mounting.
    pub mount: Mount,
    /// |g_nominal| [g].
    pub g: f64,
    /// Taken on the way down.
    pub down: bool,
    /// The output over the mounting fit's k1 (signed), in g.
    pub output_g: f64,
    /// Standard deviation of its one-second values [µg].
    pub std_ug: f64,
    /// Its one-second values.
    pub n: u32,
    /// Time of its first and last one-second value [s].
    pub time_s: [f64; 2],
}

/// A plan as the prediction sees it: the levels up, those read again on
/// the way down, the dwell and the mountings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// The levels, ascending from 0 [g].
    pub levels_g: Vec<f64>,
    /// The levels read again on the way down [g] (a subset, not the top).
    pub down_levels_g: Vec<f64>,
    /// One-second values per reading.
    pub dwell_s: u32,
    /// Mountings (passes).
    pub passes: usize,
}

impl Candidate {
    /// The published plan: `levels` up and down, 10-s dwell.
    pub fn published(levels_g: &[f64], passes: usize) -> Candidate {
        Candidate {
            levels_g: levels_g.to_vec(),
            down_levels_g: levels_g[..levels_g.len().saturating_sub(1)].to_vec(),
            dwell_s: 10,
            passes,
        }
    }

    /// The order in which a pass visits the levels: up, then the down levels descending.
    pub fn sequence(&self) -> Vec<f64> {
        let mut down = self.down_levels_g.clone();
        down.sort_by(|a, b| b.total_cmp(a));
        self.levels_g.iter().copied().chain(down).collect()
    }
}

/// A plan's predicted K2 uncertainty and centrifuge time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Prediction {
    /// Predicted K2 U95 of the median instrument [µg/g²].
    pub k2_u95_ug_per_g2: f64,
    /// Predicted centrifuge time of the level steps, every pass [s].
    pub centrifuge_time_s: f64,
}

/// Predict a plan's K2 U95 and centrifuge time with `model` (module docs).
pub fn predict(model: &StationModel, plan: &Candidate) -> Result<Prediction, AnalysisError> {
    let terms = K2Terms::of(model, plan)?;
    Ok(Prediction {
        k2_u95_ug_per_g2: terms.u95(model.between_level_ug),
        centrifuge_time_s: terms.pass_time_s * plan.passes as f64,
    })
}

/// A plan's K2 variance as a function of the between-level τ (module
/// docs): `var(K2) = τ²·Σ G_ℓ² + Σ G_ℓ²·v_ℓ`.
struct K2Terms {
    /// Σ G_ℓ² [1/g⁴].
    sensitivity2: f64,
    /// Σ G_ℓ²·v_ℓ [µg²/g⁴].
    readings_var: f64,
    /// t₀.₉₇₅(L − p) times the model's calibration.
    factor: f64,
    /// Centrifuge time of one pass [s].
    pass_time_s: f64,
}

impl K2Terms {
    fn of(model: &StationModel, plan: &Candidate) -> Result<K2Terms, AnalysisError> {
        let levels = &plan.levels_g;
        if levels.len() < PARAMETERS + 1 || plan.dwell_s == 0 {
            return Err(AnalysisError::InvalidInput(format!(
                "a plan of {} levels and a {} s dwell cannot be predicted: at least {} levels and 1 s",
                levels.len(),
                plan.dwell_s,
                PARAMETERS + 1
            )));
        }
        let sequence = plan.sequence();
        let mut time_s = 0.0;
        for (i, g) in sequence.iter().enumerate() {
            let settle = if i == 0 {
                0.0
            } else {
                model.settle_s + model.settle_s_per_g * (g - sequence[i - 1]).abs()
            };
            time_s += settle + f64::from(plan.dwell_s);
        }
        let noise = &model.noise;
        let reading_var = noise.white_ug.powi(2) / f64::from(plan.dwell_s)
            + noise.flicker_ug.powi(2)
            + noise.level_floor_ug.powi(2)
            + noise.random_walk_ug2_per_s * time_s / 6.0;
        let design = lsq::polynomial_design(levels, PARAMETERS - 1);
        let op = lsq::solution_operator(&design, "plan design")?;
        let (mut sensitivity2, mut readings_var) = (0.0, 0.0);
        for (l, g) in levels.iter().enumerate() {
            let m = if plan.down_levels_g.contains(g) {
                2.0
            } else {
                1.0
            };
            // The series is in µg against g: its quadratic coefficient is K2 in µg/g².
            let g2 = op[(2, l)].powi(2);
            sensitivity2 += g2;
            readings_var += g2 * 0.25 * reading_var * (2.0 / m);
        }
        let t = student_t_975(levels.len() - PARAMETERS).unwrap_or(1.96);
        let calibration = if model.calibration.is_finite() && model.calibration > 0.0 {
            model.calibration
        } else {
            1.0
        };
        Ok(K2Terms {
            sensitivity2,
            readings_var,
            factor: calibration * t,
            pass_time_s: time_s,
        })
    }

    /// K2 U95 of an instrument whose between-level scatter is `tau_ug` [µg/g²].
    fn u95(&self, tau_ug: f64) -> f64 {
        self.factor * (tau_ug.powi(2) * self.sensitivity2 + self.readings_var).sqrt()
    }
}

/// A designed plan with its prediction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Design {
    /// The plan.
    pub plan: Candidate,
    /// Its prediction.
    pub prediction: Prediction,
}

/// A target the search cannot reach.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "a K2 U95 of {target:.3} µg/g² cannot be reached on this station: the smallest predicted is {best_u95:.3} µg/g² ({best_levels} levels, {best_dwell_s} s dwell, {best_time_s:.0} s); ask for at least that"
)]
pub struct Unreachable {
    /// The target [µg/g²].
    pub target: f64,
    /// The smallest U95 the search reached [µg/g²].
    pub best_u95: f64,
    /// Its levels.
    pub best_levels: usize,
    /// Its dwell [s].
    pub best_dwell_s: u32,
    /// Its time [s].
    pub best_time_s: f64,
}

/// `n` levels spread evenly from 0 to `range_g`, to 0.01 g.
pub fn even_levels(range_g: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (range_g * i as f64 / (n - 1).max(1) as f64 * 100.0).round() / 100.0)
        .collect()
}

/// `d` of `levels` (not the top) spread evenly, 0 g among them.
fn spread_down(levels: &[f64], d: usize) -> Vec<f64> {
    let below = &levels[..levels.len() - 1];
    if d >= below.len() {
        return below.to_vec();
    }
    let mut out: Vec<f64> = (0..d)
        .map(|j| {
            below[((below.len() - 1) as f64 * j as f64 / (d - 1).max(1) as f64).round() as usize]
        })
        .collect();
    out.dedup();
    out
}

/// The plan of least predicted time whose predicted K2 U95 is at most
/// `target_u95`, over `passes` mountings to `range_g`; every level read
/// again on the way down when `hysteresis` is asked for (module docs).
pub fn design(
    model: &StationModel,
    target_u95: f64,
    range_g: f64,
    passes: usize,
    hysteresis: bool,
) -> Result<Result<Design, Unreachable>, AnalysisError> {
    if !(target_u95.is_finite() && target_u95 > 0.0 && range_g.is_finite() && range_g > 0.0) {
        return Err(AnalysisError::InvalidInput(format!(
            "a design needs a positive target ({target_u95}) and range ({range_g})"
        )));
    }
    let mut best: Option<Design> = None;
    let mut smallest: Option<Design> = None;
    for n in MIN_LEVELS..=MAX_DESIGN_LEVELS {
        let levels = even_levels(range_g, n);
        let downs: Vec<usize> = if hysteresis {
            vec![n - 1]
        } else {
            let mut d: Vec<usize> = [2, 3, 4, 6, 8, 12, n - 1]
                .into_iter()
                .filter(|d| (MIN_DOWN_LEVELS..n).contains(d))
                .collect();
            d.dedup();
            d
        };
        for d in downs {
            for dwell_s in DWELL_CHOICES_S {
                let plan = Candidate {
                    levels_g: levels.clone(),
                    down_levels_g: spread_down(&levels, d),
                    dwell_s,
                    passes,
                };
                let prediction = predict(model, &plan)?;
                let candidate = Design { plan, prediction };
                let u = prediction.k2_u95_ug_per_g2;
                if smallest
                    .as_ref()
                    .is_none_or(|s| u < s.prediction.k2_u95_ug_per_g2)
                {
                    smallest = Some(candidate.clone());
                }
                if u <= target_u95
                    && best.as_ref().is_none_or(|b| {
                        let (t, bt) =
                            (prediction.centrifuge_time_s, b.prediction.centrifuge_time_s);
                        t < bt || (t == bt && u < b.prediction.k2_u95_ug_per_g2)
                    })
                {
                    best = Some(candidate);
                }
            }
        }
    }
    Ok(match (best, smallest) {
        (Some(b), _) => Ok(b),
        (None, Some(s)) => Err(Unreachable {
            target: target_u95,
            best_u95: s.prediction.k2_u95_ug_per_g2,
            best_levels: s.plan.levels_g.len(),
            best_dwell_s: s.plan.dwell_s,
            best_time_s: s.prediction.centrifuge_time_s,
        }),
        (None, None) => {
            return Err(AnalysisError::InvalidInput(
                "no plan could be predicted".into(),
            ));
        }
    })
}

impl StationModel {
    /// Learn the model from past runs: per run, per instrument, its
    /// readings, and the instruments' one-second values at rest [µg], one
    /// series per instrument-run (module docs). `None` when nothing could
    /// be learned.
    pub fn learn(runs: &[Vec<Vec<Reading>>], at_rest_ug: &[Vec<f64>]) -> Option<StationModel> {
        let mut whites = Vec::new();
        let mut pairs: Vec<(f64, f64)> = Vec::new(); // (Δt, d² − 2σ_w²/n)
        let mut steps: Vec<(f64, f64)> = Vec::new(); // (|Δg|, settle)
        let mut taus = Vec::new();
        let mut instruments = 0;
        for run in runs {
            for (i, unit) in run.iter().enumerate() {
                if unit.is_empty() {
                    continue;
                }
                instruments += 1;
                let w2: Vec<f64> = unit
                    .iter()
                    .filter(|r| r.std_ug.is_finite() && r.n >= 2)
                    .map(|r| r.std_ug.powi(2))
                    .collect();
                if !w2.is_empty() {
                    whites.push((w2.iter().sum::<f64>() / w2.len() as f64).sqrt());
                }
                for mount in [Mount::P, Mount::N] {
                    let mut of: Vec<&Reading> = unit.iter().filter(|r| r.mount == mount).collect();
                    of.sort_by(|a, b| a.time_s[0].total_cmp(&b.time_s[0]));
                    // The table's time is the same for every instrument: its steps once per run.
                    if i == 0 {
                        for w in of.windows(2) {
                            let settle = w[1].time_s[0] - w[0].time_s[0] - f64::from(w[0].n);
                            if (0.0..3_600.0).contains(&settle) {
                                steps.push(((w[1].g - w[0].g).abs(), settle));
                            }
                        }
                    }
                    for up in of.iter().filter(|r| !r.down) {
                        if let Some(down) = of.iter().find(|r| r.down && r.g == up.g) {
                            let d_ug = (up.output_g - down.output_g) * UG_PER_G;
                            let white = (up.std_ug.powi(2) / f64::from(up.n.max(1))
                                + down.std_ug.powi(2) / f64::from(down.n.max(1)))
                            .max(0.0);
                            let dt = (down.time_s[0] - up.time_s[0]).abs();
                            pairs.push((dt, d_ug * d_ug - white));
                        }
                    }
                }
                if let Some(tau) = between_level_ug(unit) {
                    taus.push(tau);
                }
            }
        }
        if instruments == 0 {
            return None;
        }
        let defaults = StationModel::default();
        // The Allan fits of the series at rest: the medians of their terms.
        let fits: Vec<AllanFit> = at_rest_ug
            .iter()
            .filter_map(|series| fit_allan(&allan_deviation(series)))
            .collect();
        let term = |f: fn(&AllanFit) -> f64| {
            let mut v: Vec<f64> = fits.iter().map(f).collect();
            median(&mut v)
        };
        let allan = (!fits.is_empty()).then(|| {
            (
                term(|f| f.white_ug).unwrap_or(0.0),
                term(|f| f.flicker_ug).unwrap_or(0.0),
                term(|f| f.random_walk_ug2_per_s).unwrap_or(0.0),
            )
        });
        // The pairs' floor beyond the noise, and their random walk.
        let (pair_floor2, pair_walk) = line(&pairs).map_or(
            (
                defaults.noise.level_floor_ug.powi(2),
                defaults.noise.random_walk_ug2_per_s,
            ),
            |(a, b)| (a.max(0.0) / 2.0, b.max(0.0)),
        );
        let (settle_s, settle_s_per_g) = line(&steps)
            .map_or((defaults.settle_s, defaults.settle_s_per_g), |(a, b)| {
                (a.max(0.0), b.max(0.0))
            });
        Some(StationModel {
            noise: match allan {
                // White noise as the levels see it (it grows with the
                // acceleration: the dwells' scatter), else at rest; flicker
                // and random walk need the long series at rest.
                Some((white_at_rest_ug, flicker_ug, random_walk_ug2_per_s)) => NoiseModel {
                    white_ug: median(&mut whites).unwrap_or(white_at_rest_ug),
                    white_at_rest_ug: Some(white_at_rest_ug),
                    flicker_ug,
                    random_walk_ug2_per_s,
                    level_floor_ug: (pair_floor2 - flicker_ug.powi(2)).max(0.0).sqrt(),
                    at_rest_series: fits.len(),
                },
                None => NoiseModel {
                    white_ug: median(&mut whites).unwrap_or(defaults.noise.white_ug),
                    white_at_rest_ug: None,
                    flicker_ug: 0.0,
                    random_walk_ug2_per_s: pair_walk,
                    level_floor_ug: pair_floor2.sqrt(),
                    at_rest_series: 0,
                },
            },
            settle_s,
            settle_s_per_g,
            between_level_deciles_ug: spread::deciles(&taus),
            between_level_ug: median(&mut taus).unwrap_or(defaults.between_level_ug),
            calibration: 1.0,
            runs: runs.len(),
            instruments,
        })
    }
}

fn one() -> f64 {
    1.0
}

/// The median of the finite values; `None` without one.
pub fn median(v: &mut Vec<f64>) -> Option<f64> {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// Least-squares line y = a + b·x; `None` with fewer than 3 points or no spread in x.
fn line(xy: &[(f64, f64)]) -> Option<(f64, f64)> {
    let xy: Vec<&(f64, f64)> = xy
        .iter()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    if xy.len() < 3 {
        return None;
    }
    let n = xy.len() as f64;
    let mx = xy.iter().map(|p| p.0).sum::<f64>() / n;
    let my = xy.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = xy.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if sxx <= 0.0 {
        return Some((my, 0.0));
    }
    let b = xy.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / sxx;
    Some((my - b * mx, b))
}

/// τ of one instrument's half-difference series (module docs) [µg];
/// `None` without both mountings over enough shared levels.
fn between_level_ug(unit: &[Reading]) -> Option<f64> {
    let mean = |mount: Mount, g: f64| {
        let of: Vec<f64> = unit
            .iter()
            .filter(|r| r.mount == mount && r.g == g)
            .map(|r| r.output_g)
            .collect();
        (!of.is_empty()).then(|| (of.iter().sum::<f64>() / of.len() as f64, of.len()))
    };
    let mut gs: Vec<f64> = unit.iter().map(|r| r.g).collect();
    gs.sort_by(f64::total_cmp);
    gs.dedup();
    // The pure error of one reading, pooled over both mountings [g²].
    let (mut ss, mut dof) = (0.0, 0usize);
    for mount in [Mount::P, Mount::N] {
        for &g in &gs {
            let of: Vec<f64> = unit
                .iter()
                .filter(|r| r.mount == mount && r.g == g)
                .map(|r| r.output_g)
                .collect();
            if of.len() >= 2 {
                let m = of.iter().sum::<f64>() / of.len() as f64;
                ss += of.iter().map(|x| (x - m).powi(2)).sum::<f64>();
                dof += of.len() - 1;
            }
        }
    }
    let sigma2 = if dof > 0 { ss / dof as f64 } else { 0.0 };
    let mut series = Vec::new();
    for &g in &gs {
        if let (Some((p, mp)), Some((n, mn))) = (mean(Mount::P, g), mean(Mount::N, g)) {
            let v = 0.25 * sigma2 * (1.0 / mp as f64 + 1.0 / mn as f64);
            series.push((g, 0.5 * (p - n), v));
        }
    }
    if series.len() < PARAMETERS + 2 {
        return None;
    }
    let x: Vec<f64> = series.iter().map(|s| s.0).collect();
    let y: Vec<f64> = series.iter().map(|s| s.1).collect();
    let design = lsq::polynomial_design(&x, PARAMETERS - 1);
    let fit = lsq::solve(&design, &y, "design").ok()?;
    let op = lsq::solution_operator(&design, "design").ok()?;
    let (mut expected, mut t) = (0.0, 0.0);
    for (i, s) in series.iter().enumerate() {
        let h: f64 = (0..PARAMETERS).map(|j| design[(i, j)] * op[(j, i)]).sum();
        expected += (1.0 - h) * s.2;
        t += 1.0 - h;
    }
    let tau2 = ((fit.stats.rss - expected) / t).max(0.0);
    Some(tau2.sqrt() * UG_PER_G)
}

mod allan;
mod spread;
#[cfg(test)]
mod tests;
