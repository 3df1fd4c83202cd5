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

use crate::AnalysisError;
use crate::model::{Coefficients, ModelOrder, student_t_975};
use crate::points::Point;
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
}

impl TypeBInputs {
    /// Check every field: finite, not negative, within its named bound; the
    /// error names the key.
    pub fn validate(&self) -> Result<(), String> {
        let checks: [(&str, f64, f64); 17] = [
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
                return Err(format!("{key} = {value} is not a number from 0 to {bound}"));
            }
        }
        if self.rate_resolution_deg_s > 0.0 && self.arm_radius_m <= 0.0 {
            return Err(
                "rate_resolution_deg_s needs arm_radius_m (the radius that turns the rate into acceleration)"
                    .into(),
            );
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
        )
    }

    /// Type A (statistical) or B.
    pub fn is_type_a(self) -> bool {
        matches!(
            self,
            Source::Repeatability | Source::ModelInadequacy | Source::FitScatter
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

/// One source's effect on k0 [g], k1, k2 [µg/g²], k3 [µg/g³] of one mounting:
/// signed for a source the mountings share, an RSS over points otherwise.
#[derive(Debug, Clone, PartialEq)]
pub struct Effect {
    /// The source.
    pub source: Source,
    /// Its standard-uncertainty contribution to each coefficient.
    pub delta: [f64; 4],
    /// Its degrees of freedom; `None` = infinite (Type B).
    pub dof: Option<f64>,
}

/// Every source's effect on one mounting's coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct MountingBudget {
    /// Which coefficients the model has (k0, k1, k2, k3).
    pub present: [bool; 4],
    /// The effects, in source order.
    pub effects: Vec<Effect>,
}

impl MountingBudget {
    /// The combined uncertainty of each coefficient.
    pub fn uncertainties(&self) -> Coefficients<Option<Uncertainty>> {
        let of = |j: usize| {
            self.present[j].then(|| {
                combine(
                    self.effects
                        .iter()
                        .map(|e| (e.source, e.delta[j], e.dof))
                        .collect(),
                )
            })
        };
        Coefficients {
            k0_g: of(0),
            k1: of(1),
            k2_ug_per_g2: of(2),
            k3_ug_per_g3: of(3),
        }
    }
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

/// The coefficients k0 [g], k1, k2 [µg/g²], k3 [µg/g³] of the per-mounting fit
/// of `points` (magnitude convention), 0 where the order has none.
fn coefficients(
    points: &[Point],
    order: ModelOrder,
    what: &str,
) -> Result<[f64; 4], AnalysisError> {
    let fit =
        crate::model::fit_ieee1293(points, order, crate::model::Convention::PerMounting, what)?;
    Ok([
        fit.k0_g,
        fit.k1,
        fit.k2_ug_per_g2.unwrap_or(0.0),
        fit.k3_ug_per_g3.unwrap_or(0.0),
    ])
}

/// Central difference of the coefficients under a family of moved inputs.
fn sensitivity(
    points: &[Point],
    order: ModelOrder,
    step: f64,
    moved: impl Fn(&Point, f64) -> Point,
    what: &str,
) -> Result<[f64; 4], AnalysisError> {
    let at = |h: f64| {
        let ps: Vec<Point> = points.iter().map(|p| moved(p, h)).collect();
        coefficients(&ps, order, what)
    };
    let (plus, minus) = (at(step)?, at(-step)?);
    Ok(std::array::from_fn(|j| (plus[j] - minus[j]) / (2.0 * step)))
}

/// Level of the lack-of-fit F test above which the misfit is a significant
/// effect that the budget carries (model inadequacy).
pub const LACK_OF_FIT_ALPHA: f64 = 0.05;

/// Whether `v`'s lack of fit is significant at [`LACK_OF_FIT_ALPHA`].
fn lack_of_fit_significant(v: &crate::inadequacy::LevelVariance) -> Result<bool, AnalysisError> {
    use statrs::distribution::{ContinuousCDF, FisherSnedecor};
    if v.sigma2.is_nan() || v.sigma2 <= 0.0 {
        return Ok(v.ms_lof > 0.0);
    }
    let dist = FisherSnedecor::new(v.dof_lof as f64, v.dof_pe as f64)
        .map_err(|e| AnalysisError::InvalidInput(format!("lack-of-fit distribution: {e}")))?;
    Ok(dist.sf(v.ms_lof / v.sigma2) < LACK_OF_FIT_ALPHA)
}

/// The coefficients with each level of `levels` left out in turn.
pub fn leave_each_level_out(
    points: &[Point],
    levels: &[crate::inadequacy::Level],
    order: ModelOrder,
    what: &str,
) -> Result<Vec<[f64; 4]>, AnalysisError> {
    levels
        .iter()
        .map(|l| {
            let kept: Vec<Point> = points
                .iter()
                .enumerate()
                .filter(|(i, _)| !l.members.contains(i))
                .map(|(_, p)| *p)
                .collect();
            coefficients(&kept, order, what)
        })
        .collect()
}

/// The budget of one mounting's fit of `points` with `inputs`.
pub fn mounting_budget(
    points: &[Point],
    order: ModelOrder,
    inputs: &TypeBInputs,
    what: &str,
) -> Result<MountingBudget, AnalysisError> {
    let fit =
        crate::model::fit_ieee1293(points, order, crate::model::Convention::PerMounting, what)?;
    let p = order.coefficients();
    let present: [bool; 4] = std::array::from_fn(|j| j < p);
    let mut effects = Vec::new();

    // Type A: the pure error and the between-level variance through the
    // fit's sensitivities (crate::inadequacy); with no replicated level the
    // residual scatter, which holds both.
    let residuals: Vec<f64> = fit.residuals.iter().map(|r| r.residual).collect();
    let x: Vec<f64> = points.iter().map(Point::g_magnitude).collect();
    let degree = usize::from(order.degree());
    let levels = crate::inadequacy::levels(points);
    let design = crate::lsq::polynomial_design(&x, degree);
    let variance = crate::inadequacy::LevelVariance::estimate(&levels, &residuals, &design, what)?;
    let se = [
        fit.std_error.k0_g,
        fit.std_error.k1,
        fit.std_error.k2_ug_per_g2,
        fit.std_error.k3_ug_per_g3,
    ];
    match variance {
        Some(v) => {
            let g = crate::inadequacy::coefficient_sensitivities(
                &x,
                fit.polynomial_coefficients(),
                degree,
                what,
            )?;
            let repeatability = crate::inadequacy::repeatability(&g, v.sigma2);
            effects.push(Effect {
                source: Source::Repeatability,
                delta: repeatability,
                dof: Some(v.dof_pe as f64),
            });
            if lack_of_fit_significant(&v)? {
                let without = leave_each_level_out(points, &levels, order, what)?;
                let leverage = crate::inadequacy::level_leverage(&levels, &design, what)?;
                let full = coefficients(points, order, what)?;
                let jk = crate::inadequacy::jackknife_variance(full, &without, &leverage);
                let inadequacy: [f64; 4] = std::array::from_fn(|j| {
                    crate::inadequacy::inadequacy_beyond(jk[j], repeatability[j])
                });
                if inadequacy.iter().any(|u| *u > 0.0) {
                    effects.push(Effect {
                        source: Source::ModelInadequacy,
                        delta: inadequacy,
                        dof: Some(v.dof_lof as f64),
                    });
                }
            }
        }
        None if fit.dof > 0 => {
            let (ss_pe, dof_pe) = crate::inadequacy::pure_error(&levels, &residuals);
            // Replicates but no spare level: the pure error alone; else the residual scatter.
            let rss: f64 = residuals.iter().map(|r| r * r).sum();
            let (source, scale, dof) = if dof_pe > 0 && rss > 0.0 {
                let ratio = (ss_pe / dof_pe as f64) / (rss / fit.dof as f64);
                (Source::Repeatability, ratio.sqrt(), dof_pe)
            } else {
                (Source::FitScatter, 1.0, fit.dof)
            };
            effects.push(Effect {
                source,
                delta: std::array::from_fn(|j| se[j].unwrap_or(0.0) * scale),
                dof: Some(dof as f64),
            });
        }
        None => {}
    }

    let scaled = |p: &Point, h: f64| Point {
        g_applied: p.g_applied * (1.0 + h),
        ..*p
    };
    let mount = points.first().map_or(crate::points::Mount::P, |p| p.mount);
    let radius_reading_ppm = match mount {
        crate::points::Mount::P => inputs.radius_reading_ppm_p,
        crate::points::Mount::N => inputs.radius_reading_ppm_n,
    };
    let need_scale = inputs.radius_ppm > 0.0
        || radius_reading_ppm > 0.0
        || inputs.cross_axis_ug_per_g > 0.0
        || inputs.rate_accuracy_ppm > 0.0
        || inputs.g_local_ppm > 0.0;
    if need_scale {
        let d = sensitivity(points, order, 1e-6, scaled, what)?;
        let mut push = |source: Source, u_rel: f64| {
            if u_rel != 0.0 {
                effects.push(Effect {
                    source,
                    delta: d.map(|x| x * u_rel),
                    dof: None,
                });
            }
        };
        push(Source::Radius, inputs.radius_ppm * 1e-6);
        push(Source::RadiusReading, radius_reading_ppm * 1e-6);
        // Gravity across the axis reads as +c in P's radius and −c in N's
        // (rectangular); both mountings share the instrument's c.
        push(
            Source::CrossAxis,
            mount.input_sign() * inputs.cross_axis_ug_per_g * 1e-6 / 3f64.sqrt(),
        );
        // a ∝ ω²: twice the rate's relative error (rectangular).
        push(
            Source::RateAccuracy,
            2.0 * inputs.rate_accuracy_ppm * 1e-6 / 3f64.sqrt(),
        );
        // a ∝ 1/g_local.
        push(Source::GLocal, -inputs.g_local_ppm * 1e-6);
    }
    if inputs.timebase_ppm > 0.0 {
        let d = sensitivity(
            points,
            order,
            1e-6,
            |p, h| Point {
                output: p.output * (1.0 + h),
                ..*p
            },
            what,
        )?;
        let u_rel = inputs.timebase_ppm * 1e-6 / 3f64.sqrt();
        effects.push(Effect {
            source: Source::Timebase,
            delta: d.map(|x| x * u_rel),
            dof: None,
        });
    }
    if inputs.arm_stretch_u_ug_per_g2 > 0.0 {
        // c in µg/g²: a → a + c·1e-6·a².
        let d = sensitivity(
            points,
            order,
            1.0,
            |p, h| Point {
                g_applied: p.g_applied + h * 1e-6 * p.g_applied * p.g_applied,
                ..*p
            },
            what,
        )?;
        effects.push(Effect {
            source: Source::ArmStretch,
            delta: d.map(|x| x * inputs.arm_stretch_u_ug_per_g2),
            dof: None,
        });
    }

    // The windage heating ΔT(a), rising with ω³ ∝ a^1.5; its effect's sign
    // is unknown (rectangular), the same in both passes.
    let rise = |a: f64| inputs.temperature_rise_c_at_100g * (a / 100.0).powf(1.5);
    if inputs.temperature_rise_c_at_100g > 0.0 && inputs.k0_tempco_ug_per_c > 0.0 {
        let k1 = fit.k1;
        let d = sensitivity(
            points,
            order,
            1.0,
            |p, h| Point {
                // h µg/°C of bias moves the output by k1·h·1e-6·ΔT in the instrument's
                // own sense (k1 of mounting N is the instrument's k1 negated).
                output: p.output + k1 * p.mount.input_sign() * h * 1e-6 * rise(p.g_magnitude()),
                ..*p
            },
            what,
        )?;
        let u = inputs.k0_tempco_ug_per_c / 3f64.sqrt();
        effects.push(Effect {
            source: Source::TemperatureBias,
            delta: d.map(|x| x * u),
            dof: None,
        });
    }
    let scale_tempco = inputs.k1_tempco_ppm_per_c + inputs.arm_expansion_ppm_per_c;
    if inputs.temperature_rise_c_at_100g > 0.0 && scale_tempco > 0.0 {
        let d = sensitivity(
            points,
            order,
            1.0,
            |p, h| Point {
                g_applied: p.g_applied * (1.0 + h * 1e-6 * rise(p.g_magnitude())),
                ..*p
            },
            what,
        )?;
        let u = scale_tempco / 3f64.sqrt();
        effects.push(Effect {
            source: Source::TemperatureScale,
            delta: d.map(|x| x * u),
            dof: None,
        });
    }

    // The read-back's resolution: each point's own error, independent of the others.
    if inputs.rate_resolution_deg_s > 0.0 {
        let c = fit.polynomial_coefficients();
        let y_scale = points
            .iter()
            .fold(0.0_f64, |m, p| m.max(p.output.abs()))
            .max(1.0);
        let mut res2 = [0.0; 4];
        // δa = 2·δω·√(a·R/g), δω rectangular over one step, averaged over the read-backs.
        let u_w = inputs.rate_resolution_deg_s.to_radians()
            / 12f64.sqrt()
            / inputs.readings_per_point.max(1.0).sqrt();
        for i in 0..points.len() {
            // The fit is linear in the outputs: this difference is exact.
            let step = 1e-6 * y_scale;
            let at = |h: f64| {
                let mut ps = points.to_vec();
                ps[i].output += h;
                coefficients(&ps, order, what)
            };
            let (plus, minus) = (at(step)?, at(-step)?);
            let a = points[i].g_magnitude();
            let u_a = 2.0 * u_w * (a * inputs.arm_radius_m / inputs.g_local()).sqrt();
            let slope = c[1] + a * (2.0 * c[2] + 3.0 * c[3] * a);
            for j in 0..4 {
                res2[j] += ((plus[j] - minus[j]) / (2.0 * step) * slope * u_a).powi(2);
            }
        }
        effects.push(Effect {
            source: Source::RateResolution,
            delta: res2.map(f64::sqrt),
            dof: None,
        });
    }
    Ok(MountingBudget { present, effects })
}

/// The model inadequacy of K2 and of the odd part with the two mountings
/// paired level by level (each level left out of both together, so the
/// misfit both share, the table's, cancels in K2 as it does in K2 itself;
/// [`crate::inadequacy`]); it replaces the mountings' own model-inadequacy
/// sources in [`joint_uncertainty`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PairedInadequacy {
    /// Of K2 [µg/g²] and its dof; `None`: the half-difference fits.
    pub even: Option<(f64, f64)>,
    /// Of the odd part [µg/g²] and its dof; `None`: the half-sum fits.
    pub odd: Option<(f64, f64)>,
}

/// K2 = (k2_P − k2_N)/2 and the odd part (k2_P + k2_N)/2, method.md (15):
/// a source both mountings share adds with its sign, each mounting's own
/// sources in quadrature. The model inadequacy is `paired`'s when the
/// mountings could be paired level by level (else each mounting's own, in
/// quadrature: an upper bound, since their shared part would cancel).
/// `None` unless both budgets have k2.
pub fn joint_uncertainty(
    p: &MountingBudget,
    n: &MountingBudget,
    paired: Option<PairedInadequacy>,
) -> Option<(Uncertainty, Uncertainty)> {
    if !(p.present[2] && n.present[2]) {
        return None;
    }
    let (mut even, mut odd) = (Vec::new(), Vec::new());
    let skip = |s: Source| paired.is_some() && s == Source::ModelInadequacy;
    for e in p.effects.iter().filter(|e| !skip(e.source)) {
        let shared = e.source.shared_by_mountings();
        let other = n.effects.iter().find(|o| o.source == e.source);
        match (shared, other) {
            (true, Some(o)) => {
                even.push((e.source, 0.5 * (e.delta[2] - o.delta[2]), e.dof));
                odd.push((e.source, 0.5 * (e.delta[2] + o.delta[2]), e.dof));
            }
            _ => {
                even.push((e.source, 0.5 * e.delta[2], e.dof));
                odd.push((e.source, 0.5 * e.delta[2], e.dof));
            }
        }
    }
    for o in n.effects.iter().filter(|e| !skip(e.source)) {
        let shared_and_done =
            o.source.shared_by_mountings() && p.effects.iter().any(|e| e.source == o.source);
        if !shared_and_done {
            even.push((o.source, 0.5 * o.delta[2], o.dof));
            odd.push((o.source, 0.5 * o.delta[2], o.dof));
        }
    }
    if let Some(paired) = paired {
        if let Some((u, dof)) = paired.even {
            even.push((Source::ModelInadequacy, u, Some(dof)));
        }
        if let Some((u, dof)) = paired.odd {
            odd.push((Source::ModelInadequacy, u, Some(dof)));
        }
    }
    Some((combine(even), combine(odd)))
}

/// The anomaly rule's source: `with` and `without` are a mounting's
/// coefficients (k0 [g], k1, k2 [µg/g²], k3 [µg/g³]) with every level and
/// with the flagged levels left out. The reported value is `without`; the
/// rule's choice is bounded by the change it made, a rectangular
/// distribution of that half-width (u = |Δ|/√3), so a value the other
/// defensible reduction gives is never outside the budget.
pub fn anomaly_rule_effect(with: [f64; 4], without: [f64; 4]) -> Effect {
    Effect {
        source: Source::AnomalyRule,
        delta: std::array::from_fn(|j| (with[j] - without[j]).abs() / 3f64.sqrt()),
        dof: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dof_that_is_whole_up_to_rounding_gets_its_whole_coverage_factor() {
        let t14 = student_t_975(14).expect("t");
        assert_eq!(coverage_factor_95(Some(13.999_999_999_999_998)), t14);
        assert_eq!(coverage_factor_95(Some(14.0)), t14);
        // Fractional: rounded down, conservative.
        assert_eq!(coverage_factor_95(Some(14.5)), t14);
        assert_eq!(
            coverage_factor_95(Some(13.9)),
            student_t_975(13).expect("t")
        );
        assert_eq!(coverage_factor_95(None), 1.959_964);
        let single = combine(vec![(Source::Repeatability, 1.0, Some(14.0 - 2e-15))]);
        assert_eq!(single.u95, t14);
    }
}
