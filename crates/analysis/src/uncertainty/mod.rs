//! The GUM uncertainty of one mounting's coefficients (JCGM 100; method.md §6)
//! and of the two mountings' K2 and odd part (method.md (15)).
//!
//! Every source is propagated through its sensitivity coefficients, found
//! by refitting method.md (2) to the points with that source's input moved
//! (central differences; the fit is linear in the outputs and smooth in the
//! inputs, so this is the GUM's first-order propagation without hand-derived
//! derivatives that could drift from the fit):
//!
//! | source | model | distribution | shared |
//! |---|---|---|---|
//! | repeatability (Type A) | σ̂²·G·Gᵀ: the pure-error variance of replicated levels (up, down, repeated visits; [`crate::inadequacy::pure_error`]) through the fit | Student t, ν = pure-error dof | per mounting |
//! | model inadequacy (Type A) | the leverage-adjusted jackknife over levels beyond the repeatability, when the lack of fit is significant ([`crate::inadequacy`]) | Student t, ν = L − p | per mounting; for K2 and the odd part each level left out of both mountings together ([`PairedInadequacy`]) |
//! | fit scatter (Type A) | the fit's covariance with the residual variance, when no level is replicated (misfit and noise together) | Student t, ν = fit dof | per mounting |
//! | anomaly rule | a level left out by `anomalies = "exclude"`: the change its exclusion made to the coefficient ([`anomaly_rule_effect`]) | rectangular, half-width the change | per mounting |
//! | radius | a → a·(1 + δR/R), method.md (9) | normal, u = `radius_ppm` (the fixture, the drawing) | per mounting (R+ and R− measured apart) |
//! | radius reading | the same, from the noise of the tumble's and the radius step's readings | normal, u = `radius_reading_ppm_p`/`_n` (measured per instrument) | per mounting |
//! | cross axis | a → a·(1 ± c): gravity across the input axis in the 1 g radius reading, when no four-position tumble measured it | rectangular ± `cross_axis_ug_per_g`, sign + in P, − in N | common, with the mounting's sign |
//! | rate accuracy | a → a·(1 + 2·δω/ω), method.md (14) | rectangular ± `rate_accuracy_ppm` | common |
//! | rate resolution | δa_i = 2·δω·√(a_i·R/g) per point, averaged over its n read-backs | rectangular ± step/2, /√n | per point |
//! | g_local | a → a·(1 − δg/g), method.md (3) | normal, u = `g_local_ppm` | common |
//! | timebase | output → output·(1 + ε) | rectangular ± `timebase_ppm` | common |
//! | arm stretch | a → a + δc·a², method.md (13) | normal, u = `arm_stretch_u_ug_per_g2` | common |
//! | temperature (bias) | output error k1·k0'·ΔT(a) | rectangular ± `k0_tempco_ug_per_c` | common |
//! | temperature (scale) | a → a·(1 + (k1' + α_arm)·ΔT(a)) | rectangular ± the coefficients' sum | common |
//!
//! ΔT(a) = `temperature_rise_c_at_100g`·(a/100 g)^1.5 is the windage heating
//! of the instruments and the arm, which rises with ω³ (method.md §5); a
//! slow drift of the room cancels between the ascending and descending
//! readings of a level to first order and is not modelled.
//!
//! Combined: u_c² = Σ uᵢ²; effective degrees of freedom by Welch–Satterthwaite
//! ν_eff = u_c⁴ / Σ uᵢ⁴/νᵢ (Type B sources ν = ∞); U95 = t₀.₉₇₅(ν_eff)·u_c.
//!
//! **The measurand is the instrument's coefficient**, the value another
//! station would find for the same instrument, not "the method's
//! coefficient over this plan's levels on this centrifuge". A misfit that
//! repeats in every reading of a level (a level displaced up and down
//! alike: an activity dip of the instrument, a resonance of the table) is
//! therefore an error of the coefficient, and the budget carries it as its
//! own Type A source, model inadequacy, estimated from the lack of fit
//! (method.md §5; the GUM asks that every significant effect be corrected
//! or included). A level the diagnostics find off the curve can instead be
//! left out by the plan's stated rule (`anomalies = "exclude"`), whose
//! effect then enters as the anomaly-rule source. For K2 the part of the
//! misfit the two mountings share (the table's) cancels, as K2 itself does.

mod budget;
#[cfg(test)]
mod tests;

pub use budget::{
    Effect, LACK_OF_FIT_ALPHA, MountingBudget, PairedInadequacy, anomaly_rule_effect,
    coefficients as coefficients_of, joint_uncertainty, leave_each_level_out, mounting_budget,
    mounting_budget_of,
};

use crate::AnalysisError;
use crate::model::{Coefficients, ModelOrder};
use crate::points::Point;
use crate::statistics::student_t_975;
use serde::{Deserialize, Serialize};
use std::fmt;

/// The largest relative Type B input accepted [ppm] (10 %).
pub const MAX_TYPE_B_PPM: f64 = 1e5;
/// The largest arm-stretch uncertainty accepted [µg/g²].
pub const MAX_STRETCH_U_UG_PER_G2: f64 = 1e4;
/// The largest temperature span accepted [°C].
pub const MAX_TEMPERATURE_SPAN_C: f64 = 200.0;
/// The largest temperature coefficient accepted [µg/°C or ppm/°C].
pub const MAX_TEMPCO: f64 = 1e5;
/// The largest rate-read-back resolution accepted [°/s].
pub const MAX_RESOLUTION_DEG_S: f64 = 100.0;
/// The largest arm radius accepted [m].
pub const MAX_ARM_RADIUS_M: f64 = 20.0;

/// The Type B inputs of a reduction: the station config's `[uncertainty]`
/// section, or `analyze --type-b FILE` for legacy data. Every field
/// defaults to 0 (that source contributes nothing).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TypeBInputs {
    /// Standard uncertainty of each instrument's radius, relative [ppm]
    /// (the tumble's noise and the 1 g reading, method.md (5)–(8)).
    pub radius_ppm: f64,
    /// The radius's relative standard uncertainty from the noise of the
    /// readings that found it in mounting P [ppm] (the station measures it
    /// per instrument, [`crate::radius::RadiusCalibration::reading_u_ppm`]).
    pub radius_reading_ppm_p: f64,
    /// The same in mounting N [ppm].
    pub radius_reading_ppm_n: f64,
    /// Bound of the instruments' sensitivity to gravity across the input
    /// axis, ± half-width [µg/g], which shifts the 1 g radius reading; 0 when
    /// a four-position tumble measured it and the radius was corrected.
    pub cross_axis_ug_per_g: f64,
    /// The controller's rate read-back accuracy, ± half-width [ppm of rate].
    pub rate_accuracy_ppm: f64,
    /// The rate read-back's resolution (one step) [°/s].
    pub rate_resolution_deg_s: f64,
    /// The arm radius the resolution is turned into acceleration with [m]
    /// (needed only with `rate_resolution_deg_s`).
    pub arm_radius_m: f64,
    /// Rate read-backs averaged into each point (the point's one-second
    /// values; 0 or 1: one). The table's ripple dithers the read-back's
    /// quantisation, so its error averages as 1/√n.
    pub readings_per_point: f64,
    /// Local gravity [m/s²] for the same (default standard gravity).
    pub g_local_m_s2: f64,
    /// Standard uncertainty of g_local, relative [ppm].
    pub g_local_ppm: f64,
    /// The counters' timebase accuracy, ± half-width [ppm].
    pub timebase_ppm: f64,
    /// Standard uncertainty of the arm-stretch coefficient c [µg/g²]
    /// (method.md (13); the stretch itself is in the applied acceleration).
    pub arm_stretch_u_ug_per_g2: f64,
    /// The instruments' and the arm's temperature rise with speed at 100 g
    /// (windage heating; ∝ ω³ below and above) [°C].
    pub temperature_rise_c_at_100g: f64,
    /// Bound of the bias temperature coefficient [µg/°C].
    pub k0_tempco_ug_per_c: f64,
    /// Bound of the scale-factor temperature coefficient [ppm/°C].
    pub k1_tempco_ppm_per_c: f64,
    /// Bound of the arm's thermal expansion coefficient [ppm/°C] (method.md (13)).
    pub arm_expansion_ppm_per_c: f64,
    /// How much an instrument's radius grows per °C of the temperature
    /// chamber, relative [ppm/°C]: the length of the radius that sits in
    /// the chamber (the fixture) times its expansion coefficient, over the
    /// radius, from the station's drawing. The radius is found at the
    /// reference temperature only, so k1's temperature coefficient is
    /// corrected by it, with 20 % of it as a rectangular Type B term
    /// (analysis::temperature). Absent: no correction, and the whole arm's
    /// `arm_expansion_ppm_per_c` as the term's half width.
    pub chamber_radius_expansion_ppm_per_c: Option<f64>,
    /// Bound of the table's error of the applied acceleration that varies
    /// slowly with speed (a broad structural disturbance), ± [µg], from the
    /// centrifuge's characterization. The same in both mountings, so it
    /// cancels from K2 but not from a mounting's k2; no fit can tell it from
    /// the instrument's curvature, so only this bound covers it. Its effect
    /// on each coefficient is the largest over bumps of this height centred
    /// anywhere in the levels' range with half-widths from
    /// `table_disturbance_width_g` to twice that (rectangular).
    pub table_disturbance_ug: f64,
    /// The shortest half-width of that disturbance [g] (with
    /// `table_disturbance_ug`; 0: 8 g). Narrower features show as a level
    /// off the curve and are in the model inadequacy.
    pub table_disturbance_width_g: f64,
}

/// The largest table-disturbance bound accepted [µg].
pub const MAX_TABLE_DISTURBANCE_UG: f64 = 1e5;
/// The half-width assumed when a table-disturbance bound gives none [g].
pub const DEFAULT_TABLE_DISTURBANCE_WIDTH_G: f64 = 8.0;

/// A Type B input the budget cannot take; names the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InputError {
    /// Not a number from 0 to its bound.
    #[error("{key} = {value} is not a number from 0 to {bound}")]
    OutOfBound {
        /// The key.
        key: &'static str,
        /// The value given.
        value: f64,
        /// The highest allowed.
        bound: f64,
    },
    /// A rate resolution with no radius to turn it into acceleration.
    #[error(
        "rate_resolution_deg_s needs arm_radius_m (the radius that turns the rate into acceleration)"
    )]
    ResolutionWithoutRadius,
}

impl TypeBInputs {
    /// Check every field: finite, not negative, within its named bound; the
    /// error names the key.
    pub fn validate(&self) -> Result<(), InputError> {
        let checks: [(&str, f64, f64); 19] = [
            (
                "table_disturbance_ug",
                self.table_disturbance_ug,
                MAX_TABLE_DISTURBANCE_UG,
            ),
            (
                "table_disturbance_width_g",
                self.table_disturbance_width_g,
                1_000.0,
            ),
            ("readings_per_point", self.readings_per_point, 1e5),
            ("radius_ppm", self.radius_ppm, MAX_TYPE_B_PPM),
            (
                "radius_reading_ppm_p",
                self.radius_reading_ppm_p,
                MAX_TYPE_B_PPM,
            ),
            (
                "radius_reading_ppm_n",
                self.radius_reading_ppm_n,
                MAX_TYPE_B_PPM,
            ),
            (
                "cross_axis_ug_per_g",
                self.cross_axis_ug_per_g,
                MAX_TYPE_B_PPM,
            ),
            ("rate_accuracy_ppm", self.rate_accuracy_ppm, MAX_TYPE_B_PPM),
            (
                "rate_resolution_deg_s",
                self.rate_resolution_deg_s,
                MAX_RESOLUTION_DEG_S,
            ),
            ("arm_radius_m", self.arm_radius_m, MAX_ARM_RADIUS_M),
            ("g_local_m_s2", self.g_local_m_s2, 20.0),
            ("g_local_ppm", self.g_local_ppm, MAX_TYPE_B_PPM),
            ("timebase_ppm", self.timebase_ppm, MAX_TYPE_B_PPM),
            (
                "arm_stretch_u_ug_per_g2",
                self.arm_stretch_u_ug_per_g2,
                MAX_STRETCH_U_UG_PER_G2,
            ),
            (
                "temperature_rise_c_at_100g",
                self.temperature_rise_c_at_100g,
                MAX_TEMPERATURE_SPAN_C,
            ),
            (
                "arm_expansion_ppm_per_c",
                self.arm_expansion_ppm_per_c,
                MAX_TEMPCO,
            ),
            ("k0_tempco_ug_per_c", self.k0_tempco_ug_per_c, MAX_TEMPCO),
            ("k1_tempco_ppm_per_c", self.k1_tempco_ppm_per_c, MAX_TEMPCO),
            (
                "chamber_radius_expansion_ppm_per_c",
                self.chamber_radius_expansion_ppm_per_c.unwrap_or(0.0),
                MAX_TEMPCO,
            ),
        ];
        for (key, value, bound) in checks {
            if !value.is_finite() || value < 0.0 || value > bound {
                return Err(InputError::OutOfBound { key, value, bound });
            }
        }
        if self.rate_resolution_deg_s > 0.0 && self.arm_radius_m <= 0.0 {
            return Err(InputError::ResolutionWithoutRadius);
        }
        Ok(())
    }

    fn g_local(&self) -> f64 {
        if self.g_local_m_s2 > 0.0 {
            self.g_local_m_s2
        } else {
            crate::STANDARD_GRAVITY_M_S2
        }
    }
}

/// A source of uncertainty.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// Type A: the pure error of replicated levels.
    Repeatability,
    /// Type A: the between-level variance beyond the pure error (the model
    /// does not describe the levels; a level random effect).
    ModelInadequacy,
    /// The effect of leaving out the levels the anomaly rule flagged.
    AnomalyRule,
    /// Type A: the residual scatter, when no level is replicated.
    FitScatter,
    /// Each instrument's radius (the fixture's bound).
    Radius,
    /// Each instrument's radius, from its readings' noise.
    RadiusReading,
    /// Gravity across the input axis in the radius reading.
    CrossAxis,
    /// The rate read-back's accuracy.
    RateAccuracy,
    /// The rate read-back's resolution.
    RateResolution,
    /// Local gravity.
    GLocal,
    /// The counters' timebase.
    Timebase,
    /// The arm-stretch coefficient.
    ArmStretch,
    /// The temperature rise with speed, through the bias.
    TemperatureBias,
    /// The temperature rise with speed, through the scale factor and the arm.
    TemperatureScale,
    /// The table's slowly varying structural disturbance of the applied
    /// acceleration (both mountings alike: it cancels from K2).
    TableDisturbance,
    /// Type A: the correction by the centrifuge's signature learned from
    /// the instruments (the jackknife over them; both mountings alike).
    TableSignature,
}

impl Source {
    /// Whether both mountings share this source's error (so it is added
    /// with its sign between them) or each has its own.
    pub fn shared_by_mountings(self) -> bool {
        matches!(
            self,
            Source::RateAccuracy
                | Source::CrossAxis
                | Source::GLocal
                | Source::Timebase
                | Source::ArmStretch
                | Source::TemperatureBias
                | Source::TemperatureScale
                | Source::TableDisturbance
                | Source::TableSignature
        )
    }

    /// Type A (statistical) or B.
    pub fn is_type_a(self) -> bool {
        matches!(
            self,
            Source::Repeatability
                | Source::ModelInadequacy
                | Source::FitScatter
                | Source::TableSignature
        )
    }
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Source::Repeatability => "repeatability (A)",
            Source::ModelInadequacy => "model inadequacy (A)",
            Source::AnomalyRule => "anomaly rule",
            Source::FitScatter => "fit scatter (A)",
            Source::Radius => "radius",
            Source::RadiusReading => "radius reading",
            Source::CrossAxis => "cross axis",
            Source::RateAccuracy => "rate accuracy",
            Source::RateResolution => "rate resolution",
            Source::GLocal => "g_local",
            Source::Timebase => "timebase",
            Source::ArmStretch => "arm stretch",
            Source::TemperatureBias => "temperature (bias)",
            Source::TemperatureScale => "temperature (scale, arm)",
            Source::TableDisturbance => "table disturbance",
            Source::TableSignature => "table signature (A)",
        })
    }
}

/// One source's contribution |cᵢ|·u(xᵢ) to a coefficient's uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Contribution {
    /// The source.
    pub source: Source,
    /// Its contribution, in the coefficient's unit.
    pub u: f64,
}

/// A coefficient's GUM uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Uncertainty {
    /// Combined standard uncertainty, in the coefficient's unit.
    pub u: f64,
    /// Expanded uncertainty at 95 %: t₀.₉₇₅(ν_eff)·u.
    #[serde(rename = "U95")]
    pub u95: f64,
    /// Effective degrees of freedom (Welch–Satterthwaite); `None` = infinite.
    pub dof_eff: Option<f64>,
    /// Each source's contribution, largest first.
    pub budget: Vec<Contribution>,
}

impl fmt::Display for Uncertainty {
    /// "U95 2.10 (u 1.02, ν 14.2: repeatability (A) 0.98, radius 0.20, …)".
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let dof = self
            .dof_eff
            .map_or_else(|| "∞".to_string(), |d| format!("{d:.1}"));
        let parts: Vec<String> = self
            .budget
            .iter()
            .map(|c| format!("{} {}", c.source, sig(c.u)))
            .collect();
        write!(
            f,
            "U95 {} (u {}, ν {dof}: {})",
            sig(self.u95),
            sig(self.u),
            parts.join(", ")
        )
    }
}

/// Three significant figures, for budget lines.
pub fn sig(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let digits = (2 - v.abs().log10().floor() as i32).clamp(0, 12) as usize;
    format!("{v:.digits$}")
}

/// Combine components (source, contribution, dof) into one uncertainty;
/// components of one source are merged in the budget (RSS).
pub fn combine(components: Vec<(Source, f64, Option<f64>)>) -> Uncertainty {
    let u2: f64 = components.iter().map(|(_, d, _)| d * d).sum();
    let u = u2.sqrt();
    let ws: f64 = components
        .iter()
        .filter_map(|(_, d, dof)| dof.map(|n| d.powi(4) / n.max(1.0)))
        .sum();
    let dof_eff = (ws > 0.0).then(|| u2 * u2 / ws).filter(|d| d.is_finite());
    let k = coverage_factor_95(dof_eff);
    let mut budget: Vec<Contribution> = Vec::new();
    for (source, d, _) in components {
        match budget.iter_mut().find(|c| c.source == source) {
            Some(c) => c.u = c.u.hypot(d),
            None => budget.push(Contribution { source, u: d.abs() }),
        }
    }
    budget.sort_by(|a, b| b.u.total_cmp(&a.u));
    Uncertainty {
        u,
        u95: k * u,
        dof_eff,
        budget,
    }
}

/// The 95 % coverage factor t₀.₉₇₅(ν) for effective degrees of freedom ν
/// (`None`: infinite): ν rounded down to a whole number (conservative, as
/// the GUM allows), but only past a relative tolerance of 1e-9, so that a
/// ν that is 14 up to rounding (13.999999999999998) is 14 and the
/// coefficients of one fit get the same factor.
pub fn coverage_factor_95(dof_eff: Option<f64>) -> f64 {
    match dof_eff {
        Some(d) if d.is_finite() && d < 1e6 => {
            let whole = (d * (1.0 + 1e-9)).floor().max(1.0);
            student_t_975(whole as usize).unwrap_or(1.959_964)
        }
        _ => 1.959_964,
    }
}
