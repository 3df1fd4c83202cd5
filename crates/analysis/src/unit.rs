//! The complete reduction of one instrument (one "unit", OpenHTF's unit
//! under test) and of a batch of them.
//!
//! The per-mounting fits are the primary result: if one cannot be made, the
//! unit's analysis fails with the reason. The secondary results (full-range
//! fit, scale-factor model, figures, model comparison) are computed where the
//! data allow and otherwise left out with a note that says why.

use crate::compare::{ModelComparison, compare_models};
use crate::figures::{self, Hysteresis, Nonlinearity};
use crate::model::{Convention, Ieee1293Fit, ModelOrder, MountingFit, fit_ieee1293, fit_mounting};
pub use crate::points::UnitPoints;
use crate::points::{Mount, Point, infer_directions};
use crate::scale_factor::{ScaleFactorModel, scale_factor_model};
use crate::{AnalysisError, UG_PER_G};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Choices that shape a reduction.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AnalysisOptions {
    /// Order of the model (2) fitted per mounting and over the full range.
    pub order: ModelOrder,
    /// The Type B inputs of the GUM budget (all zero: Type A only).
    pub type_b: crate::uncertainty::TypeBInputs,
    /// What happens to a level the diagnostics find off the curve.
    pub anomalies: AnomalyRule,
}

/// What the reduction does with a level found off the curve
/// ([`crate::inadequacy::outlier_levels`]); a plan's `anomalies` key.
///
/// `flag`: every level stays in the fit, the level is named in the
/// diagnostics, and the misfit it makes is in the budget as model
/// inadequacy (a level random effect), so the U95 covers it without
/// anything being left out. `exclude` leaves each flagged level out
/// automatically, says so in the record and the report (level, rule,
/// reason), and carries the change that made to every coefficient in the
/// budget as the anomaly-rule source: a smaller U where the anomaly was a
/// single level, never one that hides the choice. `own` (the shipped
/// plans') lets the data choose between the two, level by level: a level flagged
/// in one mounting only is the instrument's own dip (an activity dip
/// rides with the instrument; the table's error is at the same g in both
/// mountings) and is left out as `exclude` does; a level flagged at the
/// same g in both mountings is the table's, cancels from K2, and is kept
/// as `flag` does (docs/method.md §6, levels off the curve).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AnomalyRule {
    /// Keep every level; the misfit is in the budget (the default: a
    /// plan stored without the key was reduced so).
    #[default]
    Flag,
    /// Leave flagged levels out, the effect of doing so in the budget.
    Exclude,
    /// Leave out the levels flagged in one mounting only (the
    /// instrument's own), keep those flagged in both (the table's).
    Own,
}

impl AnomalyRule {
    /// Its name in plans and reports: `flag`, `exclude` or `own`.
    pub fn name(self) -> &'static str {
        match self {
            AnomalyRule::Flag => "flag",
            AnomalyRule::Exclude => "exclude",
            AnomalyRule::Own => "own",
        }
    }
}

impl std::str::FromStr for AnomalyRule {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text.trim() {
            "flag" => Ok(AnomalyRule::Flag),
            "exclude" => Ok(AnomalyRule::Exclude),
            "own" => Ok(AnomalyRule::Own),
            other => Err(format!(
                "anomalies = '{other}': write \"own\", \"flag\" or \"exclude\""
            )),
        }
    }
}

/// The full-range IEEE 1293 fit over signed input (method.md §3.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FullRangeFit {
    /// The mountings whose points were used.
    pub mounts: Vec<Mount>,
    /// The fit against signed input.
    #[serde(flatten)]
    pub fit: Ieee1293Fit,
    /// The same range fitted with the odd-quadratic term Koq·a·|a| too
    /// (method.md (12)): K2 and Koq (plus arm stretch) apart.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub with_koq: Option<crate::joint::FullRangeKoq>,
}

/// Repeatability of one unit across several runs (method.md §3.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Repeatability {
    /// Number of runs compared.
    pub runs: usize,
    /// Largest spread of k1 over mean, over the mountings [ppm].
    pub scale_factor_ppm: f64,
    /// Largest spread of k0 over the mountings [µg].
    pub bias_ug: f64,
}

/// Scale-factor figures of merit of one unit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Figures {
    /// Scale-factor asymmetry between P (+a) and N (−a) [ppm]; needs both mountings.
    pub asymmetry_ppm: Option<f64>,
    /// Nonlinearity from the best straight line over full scale [ppm FS].
    pub nonlinearity_ppm_fs: Option<f64>,
    /// Details of the nonlinearity.
    pub nonlinearity: Option<Nonlinearity>,
    /// Largest ascending − descending difference [µg].
    pub hysteresis_ug: Option<f64>,
    /// Where the hysteresis occurs.
    pub hysteresis: Option<Hysteresis>,
    /// Scale-factor repeatability across runs of this unit [ppm].
    pub repeatability_ppm: Option<f64>,
    /// Details of the repeatability.
    pub repeatability: Option<Repeatability>,
}

/// Everything the reduction says about one unit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnitAnalysis {
    /// Serial number.
    pub unit: String,
    /// Run label, when the input had several runs.
    pub run: Option<String>,
    /// Per-mounting fits (method.md §3.4), keyed `P` and/or `N`.
    pub fits: BTreeMap<Mount, MountingFit>,
    /// The larger |k2| of the mountings [µg/g²]; `None` for order 1.
    pub k2_max_ug_per_g2: Option<f64>,
    /// The mounting k2_max comes from.
    pub k2_max_mount: Option<Mount>,
    /// Both mountings together: K2 (even) and the odd part, with U95.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<crate::joint::JointK2>,
    /// Full-range fit over signed input.
    pub full_range: Option<FullRangeFit>,
    /// Scale-factor nonlinearity model (10)–(11).
    pub scale_factor: Option<ScaleFactorModel>,
    /// Figures of merit.
    pub figures: Figures,
    /// Model families compared per mounting.
    pub model_comparison: BTreeMap<Mount, ModelComparison>,
    /// Why any secondary result is missing.
    pub notes: Vec<String>,
    /// Levels the anomaly rule left out (`anomalies = "exclude"`), with the
    /// rule and the reason; their effect is in the budget.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rule_exclusions: Vec<crate::exclusion::LevelExclusion>,
}

/// Reduce one unit's points.
pub fn analyze_unit(
    input: &UnitPoints,
    options: AnalysisOptions,
) -> Result<UnitAnalysis, AnalysisError> {
    analyze_unit_with(input, options, None)
}

/// Reduce one unit's points with the centrifuge's signature learned from
/// its run's instruments ([`crate::table_signature`]): each point's applied
/// acceleration corrected by it, the correction's uncertainty in the
/// budget (the table-signature source), and the stated table-disturbance
/// bound cut to what the signature could have missed. `None`: as
/// [`analyze_unit`].
pub fn analyze_unit_with(
    input: &UnitPoints,
    options: AnalysisOptions,
    table: Option<&crate::table_signature::TableSignature>,
) -> Result<UnitAnalysis, AnalysisError> {
    let corrected;
    let input = match table {
        Some(t) => {
            corrected = UnitPoints {
                points: t.correct(&input.unit, &input.points),
                ..input.clone()
            };
            &corrected
        }
        None => input,
    };
    let label = input.label();
    if input.points.is_empty() {
        return Err(AnalysisError::InvalidInput(format!(
            "{label} has no points"
        )));
    }
    let mut notes = Vec::new();
    let mut by_mount: BTreeMap<Mount, Vec<Point>> = BTreeMap::new();
    for p in &input.points {
        by_mount.entry(p.mount).or_default().push(*p);
    }
    for points in by_mount.values_mut() {
        infer_directions(points);
    }

    let mut fits = BTreeMap::new();
    let mut budgets = BTreeMap::new();
    let mut rule_exclusions = Vec::new();
    let mut unfit: Vec<(Mount, AnalysisError)> = Vec::new();
    // Every mounting fitted first: which levels each flags decides, under
    // `own`, which are the instrument's and which the table's.
    let mut first_fits = BTreeMap::new();
    for (&mount, points) in by_mount.iter() {
        let what = format!("{label} mounting {mount}");
        // A mounting that cannot be fitted leaves the other's fit standing.
        match fit_mounting(points, mount, options.order, &what) {
            Ok(fit) => {
                first_fits.insert(mount, fit);
            }
            Err(e) => unfit.push((mount, e)),
        }
    }
    let flagged_in = |m: Mount| -> Vec<f64> {
        first_fits
            .get(&m)
            .and_then(|f: &MountingFit| f.diagnostics.as_ref())
            .map(|d| d.outlier_levels.iter().map(|o| o.g).collect())
            .unwrap_or_default()
    };
    let flagged: BTreeMap<Mount, Vec<f64>> = [Mount::P, Mount::N]
        .into_iter()
        .map(|m| (m, flagged_in(m)))
        .collect();
    let both_fitted = first_fits.contains_key(&Mount::P) && first_fits.contains_key(&Mount::N);
    for (&mount, points) in by_mount.iter_mut() {
        let what = format!("{label} mounting {mount}");
        let Some(mut fit) = first_fits.remove(&mount) else {
            continue;
        };
        let mut anomaly_effect = None;
        // The levels the rule leaves out of this mounting.
        let other_mount = match mount {
            Mount::P => Mount::N,
            Mount::N => Mount::P,
        };
        let other = flagged.get(&other_mount).cloned().unwrap_or_default();
        let leave_out = |g: f64| match options.anomalies {
            AnomalyRule::Flag => false,
            AnomalyRule::Exclude => true,
            // Without the other mounting nothing tells the two apart: kept.
            AnomalyRule::Own => both_fitted && !other.contains(&g),
        };
        if options.anomalies != AnomalyRule::Flag {
            match exclude_flagged(
                points,
                &fit,
                options.order,
                &input.unit,
                &what,
                &leave_out,
                options.anomalies,
            )? {
                Excluded::Nothing => {}
                Excluded::Levels {
                    kept,
                    refit,
                    removed,
                    effect,
                } => {
                    // The rule leaves out once (a stated stop): what the
                    // refit's narrower yardstick finds next is shown as such,
                    // kept, its misfit in the budget's model inadequacy.
                    let left: Vec<String> = removed.iter().map(|e| format!("{} g", e.g)).collect();
                    let next: Vec<String> = refit
                        .diagnostics
                        .as_ref()
                        .map(|d| {
                            d.outlier_levels
                                .iter()
                                .map(crate::inadequacy::OutlierLevel::shown)
                                .collect()
                        })
                        .unwrap_or_default();
                    if !next.is_empty() {
                        notes.push(format!(
                            "mounting {mount}: with {} left out by the anomaly rule, the refit finds {} off the curve; the rule leaves out once, so these are kept and their misfit is in the budget's model inadequacy",
                            left.join(", "),
                            next.join(", ")
                        ));
                    }
                    *points = kept;
                    fit = *refit;
                    rule_exclusions.extend(removed);
                    anomaly_effect = Some(effect);
                }
                Excluded::TooFew(why) => notes.push(why),
            }
        }
        let signature_effect = match table {
            Some(t) => t.correction_effect(&input.unit, points, options.order, &what)?,
            None => None,
        };
        match crate::uncertainty::mounting_budget_of(
            points,
            options.order,
            &options.type_b,
            table.is_some(),
            &what,
        ) {
            Ok(mut budget) => {
                budget.effects.extend(anomaly_effect);
                budget.effects.extend(signature_effect);
                fit.uncertainty = Some(budget.uncertainties());
                budgets.insert(mount, budget);
            }
            Err(e) => notes.push(format!("mounting {mount} uncertainty budget left out: {e}")),
        }
        fits.insert(mount, fit);
    }
    if fits.is_empty() {
        // Nothing to report: the first mounting's reason is the unit's.
        if let Some((_, e)) = unfit.into_iter().next() {
            return Err(e);
        }
    } else {
        for (mount, e) in &unfit {
            notes.push(format!(
                "mounting {mount} not reduced ({e}); the other mounting's results stand, K2 of both mountings needs it"
            ));
        }
        // The fits that follow use only the mountings that could be fitted.
        by_mount.retain(|m, _| fits.contains_key(m));
    }
    let all: Vec<Point> = by_mount.values().flatten().copied().collect();

    let k2_max = fits
        .values()
        .filter_map(|f| f.fit.k2_ug_per_g2.map(|k2| (f.mount, k2)))
        .fold(None, |best: Option<(Mount, f64)>, (m, k2)| match best {
            Some((_, b)) if b.abs() >= k2.abs() => best,
            _ => Some((m, k2)),
        });

    let mut note = |e: AnalysisError, what: &str| notes.push(format!("{what} left out: {e}"));
    let full_range = match fit_ieee1293(
        &all,
        options.order,
        Convention::SignedInput,
        &format!("{label} full range"),
    ) {
        Ok(fit) => Some(FullRangeFit {
            mounts: by_mount.keys().copied().collect(),
            fit,
            with_koq: crate::joint::full_range_koq(&all, &format!("{label} full range with Koq")),
        }),
        Err(e) => {
            note(e, "full-range fit");
            None
        }
    };
    let scale_factor = scale_factor_model(&all, &label)
        .map_err(|e| note(e, "scale-factor model"))
        .ok();
    let nonlinearity = figures::nonlinearity(&all, &label)
        .map_err(|e| note(e, "nonlinearity"))
        .ok();
    let k1_of = |m: Mount| fits.get(&m).map(|f| f.fit.k1);
    let asymmetry_ppm = match (k1_of(Mount::P), k1_of(Mount::N)) {
        (Some(p), Some(n)) => figures::asymmetry_ppm(p, n),
        _ => None,
    };
    // The local slope of each mounting's fit (method.md (2) differentiated).
    let slope_of = |m: Mount, a: f64| {
        fits.get(&m).map(|f| {
            let c = f.fit.polynomial_coefficients();
            c[1] + a * (2.0 * c[2] + 3.0 * c[3] * a)
        })
    };
    let hysteresis = figures::hysteresis(&all, slope_of);

    let mut model_comparison = BTreeMap::new();
    for (&mount, points) in &by_mount {
        let x: Vec<f64> = points.iter().map(Point::g_magnitude).collect();
        let y: Vec<f64> = points.iter().map(|p| p.output).collect();
        let k1_abs = k1_of(mount).map_or(1.0, f64::abs);
        match compare_models(&x, &y, k1_abs, &format!("{label} mounting {mount}")) {
            Ok(c) => {
                model_comparison.insert(mount, c);
            }
            Err(e) => note(e, "model comparison"),
        }
    }

    let joint = match (fits.get(&Mount::P), fits.get(&Mount::N)) {
        (Some(p), Some(n)) => crate::joint::joint_k2(
            p,
            n,
            budgets.get(&Mount::P).zip(budgets.get(&Mount::N)),
            paired_inadequacy(&by_mount, &fits, &budgets, options.order, &label),
        ),
        _ => None,
    };
    Ok(UnitAnalysis {
        unit: input.unit.clone(),
        run: input.run.clone(),
        fits,
        k2_max_ug_per_g2: k2_max.map(|(_, k2)| k2.abs()),
        k2_max_mount: k2_max.map(|(m, _)| m),
        joint,
        full_range,
        scale_factor,
        figures: Figures {
            asymmetry_ppm,
            nonlinearity_ppm_fs: nonlinearity.map(|n| n.ppm_fs),
            nonlinearity,
            hysteresis_ug: hysteresis.map(|h| h.ug),
            hysteresis,
            repeatability_ppm: None,
            repeatability: None,
        },
        model_comparison,
        notes,
        rule_exclusions,
    })
}

/// What the anomaly rule did to one mounting.
enum Excluded {
    /// No level was flagged.
    Nothing,
    /// Flagged levels left out: the points kept, their fit, the exclusions
    /// and the budget's anomaly-rule source.
    Levels {
        kept: Vec<Point>,
        refit: Box<MountingFit>,
        removed: Vec<crate::exclusion::LevelExclusion>,
        effect: crate::uncertainty::Effect,
    },
    /// Levels were flagged but too few would be left: kept, with why.
    TooFew(String),
}

/// Leave the levels `fit`'s diagnostics flagged and `leave_out` picks out
/// of `points` (the rule `rule` chose them), when enough levels remain for
/// the model with a residual and a spare level.
fn exclude_flagged(
    points: &[Point],
    fit: &MountingFit,
    order: ModelOrder,
    unit: &str,
    what: &str,
    leave_out: &dyn Fn(f64) -> bool,
    rule: AnomalyRule,
) -> Result<Excluded, AnalysisError> {
    let flagged: Vec<&crate::inadequacy::OutlierLevel> = fit
        .diagnostics
        .as_ref()
        .map(|d| d.outlier_levels.iter().filter(|o| leave_out(o.g)).collect())
        .unwrap_or_default();
    if flagged.is_empty() {
        return Ok(Excluded::Nothing);
    }
    let mount = fit.mount;
    let kept: Vec<Point> = points
        .iter()
        .filter(|p| !flagged.iter().any(|o| o.g == p.g_nominal.abs()))
        .copied()
        .collect();
    let left = crate::inadequacy::levels(&kept).len();
    if left < order.coefficients() + 2 {
        return Ok(Excluded::TooFew(format!(
            "mounting {mount}: {} level(s) flagged off the curve were kept (leaving them out would leave {left} levels, fewer than the model needs with a spare); the budget's model inadequacy covers them",
            flagged.len()
        )));
    }
    let refit = fit_mounting(&kept, mount, order, what)?;
    let coefficients = |f: &MountingFit| {
        [
            f.fit.k0_g,
            f.fit.k1,
            f.fit.k2_ug_per_g2.unwrap_or(0.0),
            f.fit.k3_ug_per_g3.unwrap_or(0.0),
        ]
    };
    let effect = crate::uncertainty::anomaly_rule_effect(coefficients(fit), coefficients(&refit));
    let removed = flagged
        .iter()
        .map(|o| crate::exclusion::LevelExclusion {
            unit: Some(unit.to_string()),
            mount,
            g: o.g,
            reason: format!(
                "off the curve through the other levels by {:+.0} µg (t = {:.1}, p = {:.1e}, Bonferroni over the levels)",
                o.residual_ug, o.t, o.p
            ),
            by: match rule {
                AnomalyRule::Own => {
                    "the anomaly rule (anomalies = \"own\": flagged in this mounting only, the instrument's own)"
                        .into()
                }
                _ => format!("the anomaly rule (anomalies = \"{}\")", rule.name()),
            },
            points_removed: points
                .iter()
                .filter(|p| p.g_nominal.abs() == o.g)
                .count(),
        })
        .collect();
    Ok(Excluded::Levels {
        kept,
        refit: Box::new(refit),
        removed,
        effect,
    })
}

/// The repeatability of one instrument over several runs (the one
/// definition `analyze`, `spinbench unit` and the batch report use): per
/// mounting, the spread of |k1| over the runs relative to its mean [ppm]
/// and the spread of k0 [µg]; the larger of the two mountings. `None`
/// with fewer than two runs of a mounting.
pub fn repeatability_of(runs: &[&UnitAnalysis]) -> Option<Repeatability> {
    let mut sf_ppm: Option<f64> = None;
    let mut bias_ug: Option<f64> = None;
    for mount in [Mount::P, Mount::N] {
        let fits: Vec<&Ieee1293Fit> = runs
            .iter()
            .filter_map(|u| u.fits.get(&mount).map(|f| &f.fit))
            .collect();
        let k1: Vec<f64> = fits.iter().map(|f| f.k1.abs()).collect();
        if let Some(r) = figures::repeatability_ppm(&k1) {
            sf_ppm = Some(sf_ppm.map_or(r, |m| m.max(r)));
        }
        let k0: Vec<f64> = fits.iter().map(|f| f.k0_g).collect();
        if k0.len() >= 2 {
            let spread = k0.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - k0.iter().copied().fold(f64::INFINITY, f64::min);
            let ug = spread * UG_PER_G;
            bias_ug = Some(bias_ug.map_or(ug, |m| m.max(ug)));
        }
    }
    Some(Repeatability {
        runs: runs.len(),
        scale_factor_ppm: sf_ppm?,
        bias_ug: bias_ug?,
    })
}

/// The reduction of a batch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetAnalysis {
    /// Model order used.
    pub order: ModelOrder,
    /// One entry per unit (and run) that could be reduced, in input order.
    pub units: Vec<UnitAnalysis>,
    /// Each unit that could not be reduced, with why (the others are not held back by it).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub failed: Vec<UnitFailure>,
    /// Levels an engineer excluded, with the reason and who (applied before the fits).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub exclusions: Vec<crate::exclusion::LevelExclusion>,
    /// The centrifuge's signature learned from each run's instruments (a
    /// run of at least [`crate::table_signature::MIN_INSTRUMENTS`]), which
    /// corrected its units' points as the station does.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub table_signatures: Vec<RunSignature>,
}

/// The centrifuge's signature of one run of a dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSignature {
    /// The run label (`None`: the file's units have none).
    pub run: Option<String>,
    /// The signature.
    pub signature: crate::table_signature::TableSignature,
}

/// A unit of a batch that could not be reduced.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnitFailure {
    /// Serial number.
    pub unit: String,
    /// Run label, when the file has one.
    pub run: Option<String>,
    /// Why.
    pub error: String,
}

/// Reduce every unit that can be reduced; each one that cannot is listed in
/// [`DatasetAnalysis::failed`] with its error, and holds back no other.
/// Units that share a serial number across several runs also get the
/// repeatability of their scale factor and bias.
pub fn analyze_dataset(inputs: &[UnitPoints], options: AnalysisOptions) -> DatasetAnalysis {
    let mut units = Vec::with_capacity(inputs.len());
    let mut failed = Vec::new();
    // The centrifuge's signature of each run (the units that share a run
    // label), learned from its instruments as the station does in a run.
    let mut by_run: BTreeMap<Option<String>, Vec<UnitPoints>> = BTreeMap::new();
    for input in inputs {
        by_run
            .entry(input.run.clone())
            .or_default()
            .push(input.clone());
    }
    let signatures: BTreeMap<Option<String>, crate::table_signature::TableSignature> = by_run
        .into_iter()
        .filter_map(|(run, group)| {
            crate::table_signature::estimate(&group, options.order).map(|t| (run, t))
        })
        .collect();
    for input in inputs {
        match analyze_unit_with(input, options, signatures.get(&input.run)) {
            Ok(u) => units.push(u),
            Err(e) => failed.push(UnitFailure {
                unit: input.unit.clone(),
                run: input.run.clone(),
                error: e.to_string(),
            }),
        }
    }

    let mut by_serial: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for (i, u) in units.iter().enumerate() {
        by_serial.entry(u.unit.clone()).or_default().push(i);
    }
    for indices in by_serial.values().filter(|ix| ix.len() >= 2) {
        let runs: Vec<&UnitAnalysis> = indices.iter().map(|&i| &units[i]).collect();
        if let Some(rep) = repeatability_of(&runs) {
            for &i in indices {
                units[i].figures.repeatability_ppm = Some(rep.scale_factor_ppm);
                units[i].figures.repeatability = Some(rep.clone());
            }
        }
    }
    DatasetAnalysis {
        order: options.order,
        units,
        failed,
        exclusions: Vec::new(),
        table_signatures: signatures
            .into_iter()
            .map(|(run, signature)| RunSignature { run, signature })
            .collect(),
    }
}

mod paired;
use paired::paired_inadequacy;

#[cfg(test)]
mod tests;
