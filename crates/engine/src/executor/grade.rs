//! Grading: an instrument's points reduced and each figure held against
//! the plan's limit under its decision rule, into an outcome with coded
//! reasons (k2 with its GUM U95, guarded by default).

use super::*;
use crate::plan::{DecisionRule, Verdict};

/// One graded instrument: its reduction, k2_max, outcome and reasons.
#[derive(Debug, Clone)]
pub struct Graded {
    /// The reduction, when it could be made.
    pub analysis: Option<spinbench_analysis::UnitAnalysis>,
    /// The larger |k2| of the mountings [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// The worst verdict of its figures.
    pub outcome: Outcome,
    /// Why, when not a plain pass.
    pub reasons: Vec<Reason>,
}

/// Reduce the points of an instrument that completed its part of the plan
/// and hold each figure against its limit, under the limits' decision rule
/// (k2 with its GUM U95; the other figures by their value).
pub fn grade(
    serial: &str,
    points: Vec<Point>,
    options: AnalysisOptions,
    limits: &crate::plan::Limits,
) -> Graded {
    let mut reasons = Vec::new();
    let mut analysis = None;
    let mut k2_max = None;
    let mut outcome = Outcome::Fail;
    let input = UnitPoints {
        unit: serial.to_string(),
        run: None,
        points,
    };
    match analyze_unit(&input, options) {
        Ok(a) => {
            k2_max = a.k2_max_ug_per_g2;
            // Each figure against its limit; the outcome is the worst.
            let f = &a.figures;
            let checks = [
                (
                    "nonlinearity",
                    f.nonlinearity_ppm_fs,
                    limits.nonlinearity_max_ppm_fs,
                    "ppm FS",
                    [
                        ReasonCode::NonlinearityOverLimit,
                        ReasonCode::NonlinearityNearLimit,
                    ],
                ),
                (
                    "|asymmetry|",
                    f.asymmetry_ppm.map(f64::abs),
                    limits.asymmetry_max_ppm,
                    "ppm",
                    [
                        ReasonCode::AsymmetryOverLimit,
                        ReasonCode::AsymmetryNearLimit,
                    ],
                ),
                (
                    "|hysteresis|",
                    f.hysteresis_ug.map(f64::abs),
                    limits.hysteresis_max_ug,
                    "µg",
                    [
                        ReasonCode::HysteresisOverLimit,
                        ReasonCode::HysteresisNearLimit,
                    ],
                ),
            ];
            outcome = Outcome::Pass;
            grade_k2(&a, limits, &mut outcome, &mut reasons);
            for (name, value, limit, unit, [over, near]) in checks {
                let (Some(v), Some(l)) = (value, limit) else {
                    continue;
                };
                // These figures carry no uncertainty yet and are judged by their value.
                let (rule, u) = (DecisionRule::Simple, None::<f64>);
                let judged = Judged {
                    name: name.to_string(),
                    shown: shown_value(rule, v, u),
                    unit,
                    limit: l,
                    rule,
                    codes: [over, near],
                };
                let verdict = rule.decide(v, u, l, limits.marginal_fraction);
                record_verdict(
                    verdict,
                    &judged,
                    limits.marginal_fraction,
                    &mut outcome,
                    &mut reasons,
                );
            }
            if k2_max.is_none() {
                reasons.push(Reason::new(ReasonCode::NoK2, "the model order has no k2"));
            }
            reasons.extend(
                a.notes
                    .iter()
                    .map(|n| Reason::new(ReasonCode::AnalysisNote, n.clone())),
            );
            analysis = Some(a);
        }
        Err(e) => reasons.push(
            Reason::new(ReasonCode::CannotReduce, format!("cannot reduce: {e}")).with("detail", e),
        ),
    }
    Graded {
        analysis,
        k2_max_ug_per_g2: k2_max,
        outcome,
        reasons,
    }
}

/// Hold k2_max, the larger |k2| of the mountings, against its limit under
/// the limits' decision rule: each mounting's k2 with its own GUM U95 (the
/// limit is on the maximum, so under the guarded rule every mounting must
/// pass with its U and any one failing with its U fails;
/// [`DecisionRule::decide_all`]). A mounting whose fit has a level flagged
/// off the curve while its U95 carries no misfit (no model-inadequacy or
/// fit-scatter source) is never a pass on that U: inconclusive, said so.
fn grade_k2(
    a: &spinbench_analysis::UnitAnalysis,
    limits: &crate::plan::Limits,
    outcome: &mut Outcome,
    reasons: &mut Vec<Reason>,
) {
    use spinbench_analysis::uncertainty::Source;
    let rule = limits.decision_rule;
    let l = limits.k2_max_ug_per_g2;
    let mut values = Vec::new();
    let mut mounts = Vec::new();
    let mut unhandled = Vec::new();
    for (mount, f) in &a.fits {
        let Some(k2) = f.fit.k2_ug_per_g2 else {
            continue;
        };
        let budget = f.uncertainty.as_ref().and_then(|u| u.k2_ug_per_g2.as_ref());
        // Its GUM budget (Type A and the station's Type B), else its interval half-width.
        let u = budget
            .map(|u| u.u95)
            .or_else(|| f.fit.ci95.k2_ug_per_g2.map(|[lo, hi]| 0.5 * (hi - lo)));
        let flagged = f
            .diagnostics
            .as_ref()
            .map(|d| d.outlier_levels.iter().map(|o| o.g).collect::<Vec<f64>>())
            .unwrap_or_default();
        let misfit_in_u = budget.is_some_and(|u| {
            u.budget
                .iter()
                .any(|c| matches!(c.source, Source::ModelInadequacy | Source::FitScatter))
        });
        if !flagged.is_empty() && !misfit_in_u {
            unhandled.push(format!("{mount}: {flagged:?} g"));
        }
        values.push((k2, u));
        mounts.push(*mount);
    }
    if values.is_empty() {
        return;
    }
    let (verdict, decided_by) = rule.decide_all(&values, l, limits.marginal_fraction);
    let i = decided_by.unwrap_or(0);
    let (v, u) = values[i];
    let mount = mounts[i];
    let judged = Judged {
        name: format!("|k2| (mounting {mount})"),
        shown: shown_value(rule, v.abs(), u),
        unit: "µg/g²",
        limit: l,
        rule,
        codes: [ReasonCode::K2OverLimit, ReasonCode::K2NearLimit],
    };
    if !unhandled.is_empty() && matches!(verdict, Verdict::Pass | Verdict::Marginal) {
        let Judged {
            name, shown, unit, ..
        } = &judged;
        reasons.push(
            Reason::new(
                ReasonCode::K2Inconclusive,
                format!(
                    "{name} {shown} {unit}: a level off the curve ({}) is not in its U95, so the result cannot be graded a pass; retest, or reduce with anomalies = \"exclude\"",
                    unhandled.join("; ")
                ),
            )
            .with("value", shown)
            .with("unit", *unit)
            .with("limit", l),
        );
        *outcome = Outcome::Inconclusive;
        return;
    }
    record_verdict(verdict, &judged, limits.marginal_fraction, outcome, reasons);
}

/// A figure held against its limit: what the reasons say of it.
struct Judged {
    /// The figure's name ("|k2| (mounting P)", "nonlinearity").
    name: String,
    /// Its value as shown, with ± U95 under the guarded rule.
    shown: String,
    /// Its unit.
    unit: &'static str,
    /// The limit.
    limit: f64,
    /// The rule it was judged by.
    rule: DecisionRule,
    /// Its reason codes: over the limit, near it.
    codes: [ReasonCode; 2],
}

/// "v ± U" under the guarded rule with a U, else "v".
fn shown_value(rule: DecisionRule, v: f64, u: Option<f64>) -> String {
    match (rule, u) {
        (DecisionRule::Guarded, Some(u)) => format!("{v:.3} ± {u:.3}"),
        _ => format!("{v:.3}"),
    }
}

/// The reason a verdict gives, and the outcome it makes (the worst so far).
fn record_verdict(
    verdict: Verdict,
    judged: &Judged,
    marginal_fraction: f64,
    outcome: &mut Outcome,
    reasons: &mut Vec<Reason>,
) {
    let Judged {
        name,
        shown,
        unit,
        limit: l,
        rule,
        codes: [over, near],
    } = judged;
    let guarded = if *rule == DecisionRule::Guarded {
        " (guarded rule)"
    } else {
        ""
    };
    match verdict {
        Verdict::Fail => {
            reasons.push(
                Reason::new(
                    *over,
                    format!("{name} {shown} {unit} above the limit {l} {unit}{guarded}"),
                )
                .with("value", shown)
                .with("unit", *unit)
                .with("limit", *l)
                .with("rule", rule.name()),
            );
            *outcome = Outcome::Fail;
        }
        Verdict::Inconclusive => {
            reasons.push(
                Reason::new(
                    ReasonCode::K2Inconclusive,
                    format!("{name} {shown} {unit} straddles the limit {l} {unit}: inconclusive under the guarded rule, retest advised"),
                )
                .with("value", shown)
                .with("unit", *unit)
                .with("limit", *l),
            );
            if *outcome != Outcome::Fail {
                *outcome = Outcome::Inconclusive;
            }
        }
        Verdict::Marginal => {
            let band = format!("{:.0}", (1.0 - marginal_fraction) * 100.0);
            reasons.push(
                Reason::new(
                    *near,
                    format!(
                        "{name} {shown} {unit} within {band} % of the limit {l} {unit}{guarded}"
                    ),
                )
                .with("value", shown)
                .with("unit", *unit)
                .with("limit", *l)
                .with("band", band)
                .with("rule", rule.name()),
            );
            if *outcome == Outcome::Pass {
                *outcome = Outcome::Marginal;
            }
        }
        Verdict::Pass => {}
    }
}
