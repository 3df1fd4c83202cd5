//! The budgets: a mounting's coefficients with every Type A and Type B
//! source and its sensitivity (model inadequacy by the leverage-adjusted
//! jackknife over levels when the lack of fit is significant), the joint
//! K2's, and the anomaly rule's effect.

use super::{
    AnalysisError, Coefficients, ModelOrder, Point, Source, TypeBInputs, Uncertainty, combine,
};

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

/// The coefficients k0 [g], k1, k2 [µg/g²], k3 [µg/g³] of the per-mounting fit
/// of `points` (magnitude convention), 0 where the order has none.
pub fn coefficients(
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
pub(super) fn sensitivity(
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
pub(super) fn lack_of_fit_significant(
    v: &crate::inadequacy::LevelVariance,
) -> Result<bool, AnalysisError> {
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

/// Each level's mean of `values` (residuals), in level order.
pub fn level_means(levels: &[crate::inadequacy::Level], values: &[f64]) -> Vec<f64> {
    levels
        .iter()
        .map(|l| l.members.iter().map(|&i| values[i]).sum::<f64>() / l.members.len().max(1) as f64)
        .collect()
}

/// The coefficients with each block of `block` adjacent levels (sliding)
/// left out in turn.
pub fn leave_blocks_out(
    points: &[Point],
    levels: &[crate::inadequacy::Level],
    order: ModelOrder,
    block: usize,
    what: &str,
) -> Result<Vec<[f64; 4]>, AnalysisError> {
    levels
        .windows(block.max(1))
        .map(|w| {
            let kept: Vec<Point> = points
                .iter()
                .enumerate()
                .filter(|(i, _)| !w.iter().any(|l| l.members.contains(i)))
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
    mounting_budget_of(points, order, inputs, false, what)
}

/// The budget of one mounting's fit of `points` with `inputs`, the points
/// corrected by the table's learned signature when `table_corrected`
/// (docs/method.md §6). The model inadequacy is what the levels' jackknife
/// finds beyond the repeatability and, on points the signature has not
/// corrected, beyond the table disturbance's Type B term: there the
/// jackknife sees the table's bump among the levels' scatter, and it is
/// counted once. On corrected points the level-by-level part the jackknife
/// could see is gone (the signature took it out), so what it finds is the
/// instrument's own misfit, all of it model inadequacy, beside the stated
/// Type B term for the table's part no population of instruments can tell
/// from their curvature.
pub fn mounting_budget_of(
    points: &[Point],
    order: ModelOrder,
    inputs: &TypeBInputs,
    table_corrected: bool,
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
    // The table's disturbance (a Type B source below) moves the levels'
    // readings too: the jackknife sees it among the levels' scatter, so the
    // model inadequacy is what it finds beyond the repeatability and this.
    let table = if inputs.table_disturbance_ug > 0.0 {
        Some(table_disturbance_effect(points, order, inputs, what)?)
    } else {
        None
    };
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
                let mut jk = crate::inadequacy::jackknife_variance(full, &without, &leverage);
                // A misfit spread over neighbouring levels: blocks of them too.
                if crate::inadequacy::neighbours_correlated(&level_means(&levels, &residuals)) {
                    let b = crate::inadequacy::NEIGHBOUR_BLOCK;
                    let blocks = leave_blocks_out(points, &levels, order, b, what)?;
                    let jb = crate::inadequacy::block_jackknife(full, &blocks, &leverage, b);
                    jk = std::array::from_fn(|j| jk[j].max(jb[j]));
                }
                let inadequacy: [f64; 4] = std::array::from_fn(|j| {
                    let known = if table_corrected {
                        0.0
                    } else {
                        table.map_or(0.0, |t| t[j])
                    };
                    crate::inadequacy::inadequacy_beyond(jk[j], repeatability[j].hypot(known))
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

    if let Some(delta) = table {
        effects.push(Effect {
            source: Source::TableDisturbance,
            delta,
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

/// The table-disturbance source's standard uncertainty of each coefficient
/// ([`TypeBInputs::table_disturbance_ug`]): the bound's bump (a Lorentzian
/// of height `table_disturbance_ug` in |a|, the disturbance model of the
/// virtual bench and of a resonance's response) centred at every 1 g from
/// the smallest to the largest level, with half-widths w, 1.5·w and 2·w;
/// per coefficient the bump that moves it most, with its sign (both
/// mountings at the same levels meet the same bump, so the sign lets it
/// cancel from K2), over √3 (rectangular). The coefficients' sensitivity to
/// each point's applied acceleration is found once; a bump's effect is then
/// their sum weighted by its heights (first order, as every Type B term).
fn table_disturbance_effect(
    points: &[Point],
    order: ModelOrder,
    inputs: &TypeBInputs,
    what: &str,
) -> Result<[f64; 4], AnalysisError> {
    let width = if inputs.table_disturbance_width_g > 0.0 {
        inputs.table_disturbance_width_g
    } else {
        super::DEFAULT_TABLE_DISTURBANCE_WIDTH_G
    };
    let (lo, hi) = points.iter().fold((f64::INFINITY, 0.0_f64), |(lo, hi), p| {
        (lo.min(p.g_magnitude()), hi.max(p.g_magnitude()))
    });
    if !(lo.is_finite() && hi > lo) {
        return Ok([0.0; 4]);
    }
    // ∂coefficient/∂|a_i| per µg, each point's |a| moved alone.
    let step_ug = 100.0;
    let mut per_point = Vec::with_capacity(points.len());
    for i in 0..points.len() {
        let at = |h: f64| {
            let mut ps = points.to_vec();
            let sign = if ps[i].g_applied < 0.0 { -1.0 } else { 1.0 };
            ps[i].g_applied += sign * h * 1e-6;
            coefficients(&ps, order, what)
        };
        let (plus, minus) = (at(step_ug)?, at(-step_ug)?);
        per_point.push(std::array::from_fn::<f64, 4, _>(|j| {
            (plus[j] - minus[j]) / (2.0 * step_ug)
        }));
    }
    // At most a thousand centres (a level is at most MAX_LEVEL_G).
    let centres = (hi - lo).ceil().min(1_000.0) as usize;
    let mut worst = [0.0_f64; 4];
    for k in 0..=centres {
        let centre = lo + k as f64;
        for w in [width, 1.5 * width, 2.0 * width] {
            let mut d = [0.0; 4];
            for (p, s) in points.iter().zip(&per_point) {
                let x = (p.g_magnitude() - centre) / w;
                let height = inputs.table_disturbance_ug / (1.0 + x * x);
                for j in 0..4 {
                    d[j] += s[j] * height;
                }
            }
            for j in 0..4 {
                if d[j].abs() > worst[j].abs() {
                    worst[j] = d[j];
                }
            }
        }
    }
    Ok(worst.map(|x| x / 3f64.sqrt()))
}
