//! Temperature coefficients of an instrument: its bias
//! k0, scale factor k1 and K2 reduced at each chamber temperature, and a
//! straight line through each against the instrument's own temperature.
//!
//! ```text
//! y(T) = y₀ + c·(T − T̄),  weights wᵢ = 1/u(yᵢ)²,  T̄ = Σ wᵢTᵢ / Σ wᵢ
//! c = Σ wᵢ(Tᵢ − T̄)yᵢ / Σ wᵢ(Tᵢ − T̄)²,   u(c) = 1/√(Σ wᵢ(Tᵢ − T̄)²)
//! ```
//!
//! **Which uncertainty of yᵢ.** A temperature's k0, k1 and K2 carry errors
//! that are the same at every temperature: the table's rate and radius
//! errors repeat level by level, the budget's Type B inputs are shared.
//! They leave the slope, so the uᵢ here are only what differs between
//! temperatures, found from the points themselves ([`paired_uncertainty`]):
//! each level's output at a temperature less the same level's at the
//! reference temperature (corrected by k1 for the small difference of the
//! applied accelerations) is fitted with a cubic in the signed input;
//! its intercept, slope and (per mounting) square term have the standard
//! uncertainties of Δk0, Δk1 and ΔK2, and each temperature carries the
//! whole of its difference's (not a share 1/√2, as if the two temperatures'
//! errors were independent): what the pairs see moves with the temperature
//! (an activity dip is reached at another acceleration as the resonators
//! warm), so the errors of the temperatures on either side of the
//! reference have opposite signs and add in the slope instead of averaging
//! out. With the share 1/√2 the coefficients' U95 held the truth for
//! 77–80 % of the typical bench's instruments.
//! (The full fits' standard errors, which hold the repeated table errors,
//! overstated the slopes' by 50 times on the typical bench.)
//!
//! **What the pairs cannot see** — the bias's slow walk between the hours
//! of the passes, the instruments' temperature lag — shows as scatter of
//! the yᵢ about their line. One instrument's three temperatures give one
//! degree of freedom, too few to judge it, so the batch judges it
//! ([`pool`]), per coefficient, by an additive between-instrument term: what
//! the pairs cannot see is the same size in every instrument (the walk and
//! the lag do not shrink with an instrument's small u), so the slope of each
//! gains the same variance τ², estimated by moments over the run,
//! τ² = max(0, Σⱼ(χ²ⱼ − νⱼ)·uⱼ²) / Σν (for a line with equal uᵢ,
//! E[χ²] = ν·(1 + s²/u(yᵢ)²) and the slope's share of s² is u(c)²·s²/u(yᵢ)²),
//! and U95 = t(Σν)·√(u(c)² + τ²), Student's t at Σν degrees of freedom, the
//! judgement's own (a batch of twelve at three temperatures: t(12) = 2.18;
//! one instrument alone: t(1) = 12.7 — it cannot judge its line). With
//! Σν = 0 (two temperatures) U95 = 1.96·u: nothing judges the line. (A
//! multiplicative Birge ratio B = √(Σχ²/Σν), kept in the record beside τ,
//! widens a small u by the same ratio as a large one, and left the
//! small-u instruments' coefficients outside their U95.)
//!
//! **The arm.** The radius is found at the reference temperature only, so
//! the part of the radius in the chamber (the fixture), which grows with
//! the chamber's temperature, reads as a scale factor that grows with it by
//! β = L·α/R [ppm/°C]. A station that states β (`[uncertainty]
//! chamber_radius_expansion_ppm_per_c`, from its drawing) has k1's
//! coefficient corrected by −β, with a rectangular Type B term of half
//! width 20 % of β (L and α known to that); one that does not has no
//! correction and a rectangular term of half width `arm_expansion_ppm_per_c`,
//! as if the whole arm might follow the chamber ([`with_arm_expansion`]).
//!
//! The temperature's own spread over a temperature's points (the
//! instruments still settling while they are measured) enters as errors in
//! the variable: after a first fit, u(yᵢ)² gains (c·u(T̄ᵢ))², u(T̄ᵢ) the
//! standard error of that temperature's mean, and the line is fitted again.
//! A sensor's calibration offset, common to every temperature, leaves the
//! slope and is not propagated.

use crate::AnalysisError;
use crate::lsq::{polynomial_design, solve};
use crate::points::{Mount, Point};
use crate::statistics::student_t_975;
use serde::{Deserialize, Serialize};

/// One instrument's figures at one temperature, each with its standard uncertainty.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AtTemperature {
    /// The chamber's setpoint [°C].
    pub setpoint_c: f64,
    /// The instrument's mean temperature over its points there [°C].
    pub temperature_c: f64,
    /// The standard deviation of its points' temperatures there [°C].
    #[serde(default)]
    pub temperature_spread_c: f64,
    /// How many points were taken there (0 in records from before it was kept).
    #[serde(default)]
    pub points: usize,
    /// Bias [g] and the standard uncertainty of what differs from the other
    /// temperatures' (module docs).
    pub k0_g: [f64; 2],
    /// Scale factor [Hz/g] and its standard uncertainty, as for k0.
    pub k1_hz_per_g: [f64; 2],
    /// K2, the even second-order term [µg/g²], and its standard uncertainty,
    /// as for k0 (absent with one mounting).
    pub k2_ug_per_g2: Option<[f64; 2]>,
}

/// The standard uncertainties of one temperature's figures that differ
/// from another's (each temperature carries the whole difference's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairedUncertainty {
    /// Of k0 [g].
    pub k0_g: f64,
    /// Of k1 [Hz/g].
    pub k1_hz_per_g: f64,
    /// Of K2 [µg/g²] (absent unless both mountings were paired).
    pub k2_ug_per_g2: Option<f64>,
}

impl PairedUncertainty {
    /// The root mean square of several (the reference temperature's share,
    /// from its pairs with each other temperature).
    pub fn rms(of: &[PairedUncertainty]) -> Option<PairedUncertainty> {
        if of.is_empty() {
            return None;
        }
        let rms = |f: &dyn Fn(&PairedUncertainty) -> f64| {
            (of.iter().map(|p| f(p).powi(2)).sum::<f64>() / of.len() as f64).sqrt()
        };
        Some(PairedUncertainty {
            k0_g: rms(&|p| p.k0_g),
            k1_hz_per_g: rms(&|p| p.k1_hz_per_g),
            k2_ug_per_g2: of
                .iter()
                .all(|p| p.k2_ug_per_g2.is_some())
                .then(|| rms(&|p| p.k2_ug_per_g2.unwrap_or(0.0))),
        })
    }
}

/// Pair each level taken at `other` with the same level (mounting, nominal
/// g, direction, in order) at `reference`; `(signed input, output
/// difference corrected by k1 for the applied accelerations' difference)`.
fn pairs(reference: &[Point], other: &[Point], k1: f64, mount: Option<Mount>) -> Vec<(f64, f64)> {
    let mut used = vec![false; other.len()];
    let mut out = Vec::new();
    for r in reference
        .iter()
        .filter(|p| mount.is_none_or(|m| p.mount == m))
    {
        let found = other.iter().enumerate().position(|(i, o)| {
            !used[i]
                && o.mount == r.mount
                && o.g_nominal == r.g_nominal
                && o.direction == r.direction
        });
        if let Some(i) = found {
            used[i] = true;
            let o = &other[i];
            out.push((
                r.g_signed(),
                o.output - r.output - k1 * (o.g_signed() - r.g_signed()),
            ));
        }
    }
    out
}

/// Standard uncertainties of a cubic's first three coefficients through
/// `pairs`, if it has degrees of freedom left: the larger of the fit's
/// standard error and the delete-one-level jackknife's (Hinkley's
/// (L − p)/L·ΣΔ²). A structure the cubic does not hold — an activity dip
/// that moves with the temperature, at one level — is scatter to the
/// standard error but moves the coefficients; the jackknife sees how much.
fn cubic_errors(pairs: &[(f64, f64)]) -> Option<[f64; 3]> {
    const DEGREE: usize = 3;
    if pairs.len() < DEGREE + 3 {
        return None;
    }
    let fit_of = |pairs: &[&(f64, f64)]| {
        let x: Vec<f64> = pairs.iter().map(|p| p.0).collect();
        let y: Vec<f64> = pairs.iter().map(|p| p.1).collect();
        solve(
            &polynomial_design(&x, DEGREE),
            &y,
            "paired temperature differences",
        )
        .ok()
    };
    let all: Vec<&(f64, f64)> = pairs.iter().collect();
    let fit = fit_of(&all)?;
    let cov = fit.covariance.as_ref()?;
    let se = |i: usize| cov[(i, i)].max(0.0).sqrt();
    // The levels (signed input), each left out in turn.
    let mut levels: Vec<f64> = pairs.iter().map(|p| p.0).collect();
    levels.sort_by(f64::total_cmp);
    levels.dedup();
    let p = DEGREE + 1;
    let mut deltas = [0.0f64; 3];
    let mut used = 0usize;
    for level in &levels {
        let rest: Vec<&(f64, f64)> = pairs.iter().filter(|q| q.0 != *level).collect();
        if rest.len() < p + 1 {
            continue;
        }
        if let Some(without) = fit_of(&rest) {
            for (j, d) in deltas.iter_mut().enumerate() {
                *d += (without.coefficients[j] - fit.coefficients[j]).powi(2);
            }
            used += 1;
        }
    }
    let jackknife = |j: usize| {
        if used > p {
            ((used - p) as f64 / used as f64 * deltas[j]).sqrt()
        } else {
            0.0
        }
    };
    Some(std::array::from_fn(|j| se(j).max(jackknife(j))))
}

/// What differs between the figures at `other` and at `reference` (module
/// docs), the whole of the difference's for each temperature; `None` when
/// too few levels pair. `k1_hz_per_g` converts outputs to g.
pub fn paired_uncertainty(
    reference: &[Point],
    other: &[Point],
    k1_hz_per_g: f64,
) -> Option<PairedUncertainty> {
    if !(k1_hz_per_g.is_finite() && k1_hz_per_g != 0.0) {
        return None;
    }
    let k1 = k1_hz_per_g.abs();
    let all = cubic_errors(&pairs(reference, other, k1_hz_per_g, None))?;
    let per_mount = |m| cubic_errors(&pairs(reference, other, k1_hz_per_g, Some(m)));
    let k2 = match (per_mount(Mount::P), per_mount(Mount::N)) {
        // K2 = (k2_P + k2_N)/2 in µg/g².
        (Some(p), Some(n)) => Some(0.5 * p[2].hypot(n[2]) / k1 * 1e6),
        _ => None,
    };
    // Each temperature carries the difference's whole uncertainty (module docs).
    let share = 1.0;
    Some(PairedUncertainty {
        k0_g: all[0] / k1 * share,
        k1_hz_per_g: all[1] * share,
        k2_ug_per_g2: k2.map(|v| v * share),
    })
}

/// One value per coefficient (k0, k1 and, with two mountings, K2).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PerCoefficient {
    /// For k0.
    pub k0: f64,
    /// For k1.
    pub k1: f64,
    /// For K2.
    pub k2: Option<f64>,
}

/// The batch's judgement of the lines' scatter ([`pool`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BatchBirge {
    /// √(Σχ²/Σν) over the batch, per coefficient (for the record: the U95
    /// use `between_u`).
    pub birge_ratio: PerCoefficient,
    /// τ, the between-instrument standard uncertainty every slope gains
    /// (µg/°C, ppm/°C, µg/g²/°C; module docs).
    #[serde(default)]
    pub between_u: PerCoefficient,
    /// The half width of the arm's expansion term added to k1's
    /// coefficient [ppm/°C] (0 when none was given).
    #[serde(default)]
    pub arm_expansion_ppm_per_c: f64,
    /// The correction already applied to k1's coefficient for the radius's
    /// growth in the chamber [ppm/°C] (subtracted; module docs).
    #[serde(default)]
    pub arm_correction_ppm_per_c: f64,
    /// Σν, per coefficient.
    pub dof: [usize; 3],
    /// How many instruments.
    pub instruments: usize,
}

/// The temperature coefficients and their expanded uncertainties (95 %).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TemperatureCoefficients {
    /// Bias [µg/°C].
    pub k0_ug_per_c: f64,
    /// Its U95.
    #[serde(rename = "k0_ug_per_c_U95")]
    pub k0_ug_per_c_u95: f64,
    /// Scale factor, relative to its value at the mean temperature [ppm/°C].
    pub k1_ppm_per_c: f64,
    /// Its U95.
    #[serde(rename = "k1_ppm_per_c_U95")]
    pub k1_ppm_per_c_u95: f64,
    /// K2 [µg/g²/°C] (absent with one mounting).
    pub k2_ug_per_g2_per_c: Option<f64>,
    /// Its U95.
    #[serde(rename = "k2_ug_per_g2_per_c_U95")]
    pub k2_ug_per_g2_per_c_u95: Option<f64>,
    /// Temperatures used.
    pub temperatures: usize,
    /// Each slope's standard uncertainty from the uᵢ, before any widening
    /// (µg/°C, ppm/°C, µg/g²/°C).
    #[serde(default)]
    pub u: PerCoefficient,
    /// Each line's χ² about its figures (temperatures − 2 degrees of freedom).
    #[serde(default)]
    pub chi2: PerCoefficient,
    /// The scatter's judgement the U95 were widened by (module docs).
    #[serde(default)]
    pub batch: Option<BatchBirge>,
}

/// A weighted line's slope, its value at T̄, the slope's standard
/// uncertainty and the χ² of the figures about the line.
fn slope(t: &[f64], y: &[f64], u: &[f64]) -> Option<(f64, f64, f64, f64)> {
    if t.len() < 2 || u.iter().any(|&v| !(v.is_finite() && v > 0.0)) {
        return None;
    }
    let w: Vec<f64> = u.iter().map(|v| 1.0 / (v * v)).collect();
    let sw: f64 = w.iter().sum();
    let t_bar = w.iter().zip(t).map(|(w, t)| w * t).sum::<f64>() / sw;
    let y_bar = w.iter().zip(y).map(|(w, y)| w * y).sum::<f64>() / sw;
    let stt: f64 = w.iter().zip(t).map(|(w, t)| w * (t - t_bar).powi(2)).sum();
    if stt <= 0.0 {
        return None;
    }
    let c = w
        .iter()
        .zip(t)
        .zip(y)
        .map(|((w, t), y)| w * (t - t_bar) * y)
        .sum::<f64>()
        / stt;
    let chi2: f64 = w
        .iter()
        .zip(t)
        .zip(y)
        .map(|((w, t), y)| w * (y - y_bar - c * (t - t_bar)).powi(2))
        .sum();
    Some((c, y_bar, 1.0 / stt.sqrt(), chi2))
}

/// Fit the coefficients through the figures at two or more temperatures;
/// the U95 judge the lines' scatter by this instrument alone (as a batch
/// of one: [`pool`] judges it over the run's).
pub fn temperature_coefficients(
    at: &[AtTemperature],
) -> Result<TemperatureCoefficients, AnalysisError> {
    let t: Vec<f64> = at.iter().map(|a| a.temperature_c).collect();
    let need = || {
        AnalysisError::InvalidInput(format!(
            "temperature coefficients need figures at two or more distinct temperatures with their uncertainties; got {}",
            at.len()
        ))
    };
    let column = |f: &dyn Fn(&AtTemperature) -> [f64; 2]| -> (Vec<f64>, Vec<f64>) {
        at.iter().map(|a| (f(a)[0], f(a)[1])).unzip()
    };
    // The standard error of each temperature's mean (its whole spread for
    // records that did not keep how many points).
    let u_t: Vec<f64> = at
        .iter()
        .map(|a| a.temperature_spread_c.max(0.0) / (a.points.max(1) as f64).sqrt())
        .collect();
    // Errors in the variable: fit, widen each u(y) by the slope times u(T), fit again.
    let with_spread = |y: &[f64], u: &[f64]| -> Option<(f64, f64, f64, f64)> {
        let (c, ..) = slope(&t, y, u)?;
        let widened: Vec<f64> = u.iter().zip(&u_t).map(|(u, ut)| u.hypot(c * ut)).collect();
        slope(&t, y, &widened)
    };
    let (k0, u0) = column(&|a| a.k0_g);
    let (k1, u1) = column(&|a| a.k1_hz_per_g);
    let (c0, _, s0, chi0) = with_spread(&k0, &u0).ok_or_else(need)?;
    let (c1, k1_bar, s1, chi1) = with_spread(&k1, &u1).ok_or_else(need)?;
    let k2 = if at.iter().all(|a| a.k2_ug_per_g2.is_some()) {
        let (k2, u2): (Vec<f64>, Vec<f64>) = at
            .iter()
            .filter_map(|a| a.k2_ug_per_g2)
            .map(|v| (v[0], v[1]))
            .unzip();
        with_spread(&k2, &u2)
    } else {
        None
    };
    let ppm = 1e6 / k1_bar.abs();
    let mut c = TemperatureCoefficients {
        k0_ug_per_c: c0 * 1e6,
        k0_ug_per_c_u95: 0.0,
        k1_ppm_per_c: c1 * ppm,
        k1_ppm_per_c_u95: 0.0,
        k2_ug_per_g2_per_c: k2.map(|v| v.0),
        k2_ug_per_g2_per_c_u95: None,
        temperatures: at.len(),
        u: PerCoefficient {
            k0: s0 * 1e6,
            k1: s1 * ppm,
            k2: k2.map(|v| v.2),
        },
        chi2: PerCoefficient {
            k0: chi0,
            k1: chi1,
            k2: k2.map(|v| v.3),
        },
        batch: None,
    };
    pool(std::slice::from_mut(&mut c));
    Ok(c)
}

/// Judge the lines' scatter over a batch (module docs): per coefficient,
/// τ² = max(0, Σ(χ²ⱼ − νⱼ)·uⱼ²)/Σν; every U95 = t(Σν)·√(u² + τ²) (1.96·u
/// when Σν = 0: two temperatures cannot judge their line).
/// Depends only on each entry's `u` and `chi2`, so pooling again is safe;
/// it keeps an arm-expansion bound already applied.
pub fn pool(batch: &mut [TemperatureCoefficients]) {
    let dof_of = |c: &TemperatureCoefficients| c.temperatures.saturating_sub(2);
    // Over the entries that have the coefficient: (B, τ², t) with τ² the
    // moments estimate; (1, 0, 1.96) with nothing to judge by.
    let judge = |rows: &mut dyn Iterator<Item = (f64, f64, usize)>| -> (f64, f64, f64) {
        let (chi2, excess, dof) = rows.fold((0.0, 0.0, 0), |(c, e, n), (u, chi2, dof)| {
            (c + chi2, e + (chi2 - dof as f64) * u * u, n + dof)
        });
        if dof == 0 {
            return (1.0, 0.0, 1.96);
        }
        let birge = (chi2 / dof as f64).sqrt();
        let tau2 = (excess / dof as f64).max(0.0);
        (birge, tau2, student_t_975(dof).unwrap_or(12.71))
    };
    let (b0, tau0, t0) = judge(&mut batch.iter().map(|c| (c.u.k0, c.chi2.k0, dof_of(c))));
    let (b1, tau1, t1) = judge(&mut batch.iter().map(|c| (c.u.k1, c.chi2.k1, dof_of(c))));
    let k2_rows = |c: &TemperatureCoefficients| Some((c.u.k2?, c.chi2.k2?, dof_of(c)));
    let (b2, tau2, t2) = judge(&mut batch.iter().filter_map(k2_rows));
    let dof01 = batch.iter().map(dof_of).sum();
    let dof2 = batch.iter().filter_map(k2_rows).map(|r| r.2).sum();
    let instruments = batch.len();
    for c in batch.iter_mut() {
        let arm = c.batch.map_or(0.0, |b| b.arm_expansion_ppm_per_c);
        let correction = c.batch.map_or(0.0, |b| b.arm_correction_ppm_per_c);
        c.k0_ug_per_c_u95 = t0 * c.u.k0.hypot(tau0.sqrt());
        c.k1_ppm_per_c_u95 = t1 * (c.u.k1.powi(2) + tau1 + arm * arm / 3.0).sqrt();
        c.k2_ug_per_g2_per_c_u95 = c.u.k2.map(|u| t2 * u.hypot(tau2.sqrt()));
        c.batch = Some(BatchBirge {
            birge_ratio: PerCoefficient {
                k0: b0,
                k1: b1,
                k2: c.u.k2.map(|_| b2),
            },
            between_u: PerCoefficient {
                k0: tau0.sqrt(),
                k1: tau1.sqrt(),
                k2: c.u.k2.map(|_| tau2.sqrt()),
            },
            arm_expansion_ppm_per_c: arm,
            arm_correction_ppm_per_c: correction,
            dof: [dof01, dof01, dof2],
            instruments,
        });
    }
}

/// The chamber's effect on the radius (module docs): with the station's
/// `stated` β [ppm/°C], k1's coefficient corrected by −β and a rectangular
/// term of half width 0.2·β; without, no correction and a rectangular term
/// of half width `whole_arm_ppm_per_c`. Then the batch is judged again.
/// Applying it again replaces the earlier correction. A value that is not
/// finite and ≥ 0 counts as 0.
pub fn with_arm_expansion(
    batch: &mut [TemperatureCoefficients],
    stated: Option<f64>,
    whole_arm_ppm_per_c: f64,
) {
    let clean = |v: f64| if v.is_finite() && v > 0.0 { v } else { 0.0 };
    let (correction, half_width) = match stated {
        Some(beta) => (clean(beta), STATED_RADIUS_EXPANSION_REL * clean(beta)),
        None => (0.0, clean(whole_arm_ppm_per_c)),
    };
    for c in batch.iter_mut() {
        let mut b = c.batch.unwrap_or(BatchBirge {
            birge_ratio: PerCoefficient::default(),
            between_u: PerCoefficient::default(),
            arm_expansion_ppm_per_c: 0.0,
            arm_correction_ppm_per_c: 0.0,
            dof: [0; 3],
            instruments: 0,
        });
        c.k1_ppm_per_c -= correction - b.arm_correction_ppm_per_c;
        b.arm_correction_ppm_per_c = correction;
        b.arm_expansion_ppm_per_c = half_width;
        c.batch = Some(b);
    }
    pool(batch);
}

/// How well a stated β (the fixture's length in the chamber and its
/// expansion coefficient) is known: a rectangular half width of this share.
pub const STATED_RADIUS_EXPANSION_REL: f64 = 0.2;

#[cfg(test)]
mod tests;
