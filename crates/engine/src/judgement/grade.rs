//! Grading: an instrument's points reduced and each figure held against
//! the plan's limit under its decision rule, into an outcome with coded
//! reasons (k2 with its GUM U95, guarded by default).

use crate::plan::{DecisionRule, Measurand, Verdict};
use crate::record::{Outcome, Reason, ReasonCode};
use spinbench_analysis::table_signature::TableSignature;
use spinbench_analysis::unit::{AnalysisOptions, UnitPoints};
use spinbench_analysis::{Mount, Point};

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
    table: Option<&TableSignature>,
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
    // The same reduction without some of its levels: what a flagged level
    // that K2's U95 does not carry would change (`Without`).
    let without = |levels: &[(Mount, f64)]| {
        let input = UnitPoints {
            unit: serial.to_string(),
            run: None,
            points: input
                .points
                .iter()
                .filter(|p| !levels.contains(&(p.mount, p.g_nominal.abs())))
                .copied()
                .collect(),
        };
        spinbench_analysis::unit::analyze_unit_with(&input, options, table).ok()
    };
    match spinbench_analysis::unit::analyze_unit_with(&input, options, table) {
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
            grade_k2(&a, limits, &without, &mut outcome, &mut reasons);
            for (name, value, limit, unit, [over, near]) in checks {
                let (Some(v), Some(l)) = (value, limit) else {
                    continue;
                };
                // These figures carry no uncertainty yet and are judged by their value.
                let (rule, u) = (DecisionRule::Simple, None::<f64>);
                let judged = Judged {
                    name: name.to_string(),
                    shown: shown_value(rule, v, u),
                    reach: reach(rule, v, u),
                    unit,
                    limit: l,
                    rule,
                    codes: [over, near],
                    variant: None,
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
            reasons.extend(a.notes.iter().map(|n| note_reason(&a, n)));
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

/// Hold the k2 measurand the limits name (`decide_on`) against its limit
/// under the limits' decision rule: the instrument's K2 with its U95
/// ([`grade_instrument_k2`]), or k2_max ([`grade_k2_max`]).
fn grade_k2(
    a: &spinbench_analysis::UnitAnalysis,
    limits: &crate::plan::Limits,
    without: Without,
    outcome: &mut Outcome,
    reasons: &mut Vec<Reason>,
) {
    match limits.decide_on {
        Measurand::K2 => grade_instrument_k2(a, limits, without, outcome, reasons),
        Measurand::K2Max => grade_k2_max(a, limits, without, outcome, reasons),
    }
}

/// Levels of a mounting, as (mounting, |g|).
type Levels = Vec<(Mount, f64)>;

/// The instrument's reduction again without the given levels (mounting,
/// |g|), `None` when it cannot be made.
type Without<'a> = &'a dyn Fn(&[(Mount, f64)]) -> Option<spinbench_analysis::UnitAnalysis>;

/// A note of the reduction as a reason. The anomaly rule's note (what it
/// left out of a mounting and what the refit found next) carries its
/// parts as arguments, from the record's structured exclusions and
/// diagnostics, so that every language can word it.
fn note_reason(a: &spinbench_analysis::UnitAnalysis, note: &str) -> Reason {
    let reason = Reason::new(ReasonCode::AnalysisNote, note);
    if !note.contains("left out by the anomaly rule, the refit finds") {
        return reason;
    }
    let Some(mount) = [Mount::P, Mount::N]
        .into_iter()
        .find(|m| note.starts_with(&format!("mounting {m}:")))
    else {
        return reason;
    };
    let left: Vec<String> = a
        .rule_exclusions
        .iter()
        .filter(|e| e.mount == mount)
        .map(|e| format!("{} g", e.g))
        .collect();
    let next: Vec<String> = a
        .fits
        .get(&mount)
        .and_then(|f| f.diagnostics.as_ref())
        .map(|d| {
            d.outlier_levels
                .iter()
                .map(spinbench_analysis::inadequacy::OutlierLevel::shown)
                .collect()
        })
        .unwrap_or_default();
    reason
        .with("mount", mount)
        .with("left", left.join(", "))
        .with("next", next.join(", "))
        .with("variant", "anomaly_refit")
}

fn flagged_levels(f: &spinbench_analysis::MountingFit) -> Vec<f64> {
    f.diagnostics
        .as_ref()
        .map(|d| d.outlier_levels.iter().map(|o| o.g).collect())
        .unwrap_or_default()
}

/// Whether an uncertainty's budget carries a misfit source (model
/// inadequacy or the fit's scatter).
fn carries_misfit(u: &spinbench_analysis::uncertainty::Uncertainty) -> bool {
    use spinbench_analysis::uncertainty::Source;
    u.budget
        .iter()
        .any(|c| matches!(c.source, Source::ModelInadequacy | Source::FitScatter))
}

/// Hold the instrument's own K2 = (k2_P − k2_N)/2 (method.md (15)) with its
/// GUM U95 against the limit. Without both mountings there is no K2:
/// inconclusive, said so. A level flagged off the curve in one mounting
/// only (the instrument's, which does not cancel from K2) while K2's U95
/// carries no misfit does not stand as a pass on that U alone: K2 is
/// reduced again without it, and the pass stands only when that K2 with
/// its own U95 passes too — the verdict does not depend on whether the
/// level is a dip (left out) or a true point (kept); the outcome is the
/// worse of the two, the reach the larger (docs/method.md §6). A level
/// flagged in both mountings at the same g is the table's and cancels
/// from K2.
fn grade_instrument_k2(
    a: &spinbench_analysis::UnitAnalysis,
    limits: &crate::plan::Limits,
    without: Without,
    outcome: &mut Outcome,
    reasons: &mut Vec<Reason>,
) {
    let rule = limits.decision_rule;
    let l = limits.k2_max_ug_per_g2;
    let Some(joint) = a.joint.as_ref() else {
        if a.fits.values().any(|f| f.fit.k2_ug_per_g2.is_some()) {
            reasons.push(
                Reason::new(
                    ReasonCode::K2Inconclusive,
                    format!(
                        "K2 needs both mountings (P and N) and this instrument has {}: not decided against the limit {l} µg/g²; measure the other mounting, or judge k2_max (decide_on = \"k2_max\")",
                        a.fits.keys().map(|m| m.to_string()).collect::<Vec<_>>().join(", ")
                    ),
                )
                .with("limit", l)
                .with("variant", "one_mounting"),
            );
            if *outcome != Outcome::Fail {
                *outcome = Outcome::Inconclusive;
            }
        }
        return;
    };
    let v = joint.k2_even_ug_per_g2;
    let u = joint.k2_even_u95;
    let unhandled = unhandled_own_levels(a);
    let shown_levels: Vec<String> = unhandled_shown(&unhandled);
    let judged = |v: f64, u: Option<f64>| Judged {
        name: "|K2| (both mountings)".to_string(),
        shown: shown_value(rule, v.abs(), u),
        reach: reach(rule, v, u),
        unit: "µg/g²",
        limit: l,
        rule,
        codes: [ReasonCode::K2OverLimit, ReasonCode::K2NearLimit],
        variant: Some("instrument"),
    };
    let verdict = rule.decide(v, u, l, limits.marginal_fraction);
    let accepted = matches!(verdict, Verdict::Pass | Verdict::Marginal);
    if unhandled.is_empty() || !accepted {
        record_verdict(
            verdict,
            &judged(v, u),
            limits.marginal_fraction,
            outcome,
            reasons,
        );
        return;
    }
    // The same verdict with the level left out. A reduction without it may
    // find the next level off the curve (a dip's wing, once its centre is
    // out): that one is left out too, at most `MAX_SET_ASIDE_ROUNDS` times,
    // and the pass stands only when every reduction of the chain passes.
    let mut left_out = unhandled.clone();
    let mut widest: Option<(Verdict, Judged)> = None;
    for _ in 0..MAX_SET_ASIDE_ROUNDS {
        let Some(b) = without(&left_out) else { break };
        let Some((v_out, u_out)) = b
            .joint
            .as_ref()
            .map(|j| (j.k2_even_ug_per_g2, j.k2_even_u95))
        else {
            break;
        };
        let verdict_out = rule.decide(v_out, u_out, l, limits.marginal_fraction);
        if !matches!(verdict_out, Verdict::Pass | Verdict::Marginal) {
            break;
        }
        let this = judged(v_out, u_out);
        let marginal = verdict_out == Verdict::Marginal
            || widest
                .as_ref()
                .is_some_and(|(w, _)| *w == Verdict::Marginal);
        let verdict_so_far = if marginal {
            Verdict::Marginal
        } else {
            Verdict::Pass
        };
        widest = match widest {
            Some((_, w)) if w.reach >= this.reach => Some((verdict_so_far, w)),
            _ => Some((verdict_so_far, this)),
        };
        let next: Vec<(Mount, f64)> = unhandled_own_levels(&b)
            .into_iter()
            .filter(|g| !left_out.contains(g))
            .collect();
        if next.is_empty() {
            let shown = unhandled_shown(&left_out);
            if let Some(out) = widest {
                graded_on_both(
                    [(verdict, judged(v, u)), out],
                    &shown,
                    limits,
                    outcome,
                    reasons,
                );
            }
            return;
        }
        left_out.extend(next);
    }
    misfit_not_in_u(&judged(v, u), &shown_levels, outcome, reasons);
}

/// The most reductions a pass is held on, each without one more level
/// found off the curve by the one before (a dip's centre, then its wings).
pub const MAX_SET_ASIDE_ROUNDS: usize = 3;

/// A pass that stands with and without the levels off the curve: said in
/// a note (with the value without them), graded the worse of the two
/// verdicts on the larger reach. `both`: (verdict, judged) with the
/// levels, then without.
fn graded_on_both(
    both: [(Verdict, Judged); 2],
    levels: &[String],
    limits: &crate::plan::Limits,
    outcome: &mut Outcome,
    reasons: &mut Vec<Reason>,
) {
    let [(verdict, kept), (verdict_out, left_out)] = both;
    reasons.push(
        Reason::new(
            ReasonCode::AnalysisNote,
            format!(
                "a level off the curve ({}) is not in the U95 of {}; without it that is {} µg/g², the same verdict, so the instrument is graded on the larger reach",
                levels.join("; "),
                kept.name,
                left_out.shown
            ),
        )
        .with("levels", levels.join("; "))
        .with("value", &left_out.shown)
        .with("variant", "verdict_unchanged"),
    );
    let worse = if verdict == Verdict::Marginal || verdict_out == Verdict::Marginal {
        Verdict::Marginal
    } else {
        Verdict::Pass
    };
    let wider = if left_out.reach > kept.reach {
        left_out
    } else {
        kept
    };
    record_verdict(worse, &wider, limits.marginal_fraction, outcome, reasons);
}

/// The levels flagged off the curve in one mounting only (the
/// instrument's own, which do not cancel from K2) while K2's U95 carries
/// no misfit source, as (mounting, |g|); empty when K2's budget carries
/// the misfit.
fn unhandled_own_levels(a: &spinbench_analysis::UnitAnalysis) -> Vec<(Mount, f64)> {
    let misfit_in_u = a
        .joint
        .as_ref()
        .and_then(|j| j.uncertainty.as_ref())
        .is_some_and(|j| carries_misfit(&j.k2_even_ug_per_g2));
    if misfit_in_u {
        return Vec::new();
    }
    let flagged: Vec<(Mount, Vec<f64>)> = a
        .fits
        .iter()
        .map(|(m, f)| (*m, flagged_levels(f)))
        .collect();
    let in_both = |g: f64| flagged.iter().all(|(_, gs)| gs.contains(&g));
    flagged
        .iter()
        .flat_map(|(m, gs)| gs.iter().filter(|g| !in_both(**g)).map(|g| (*m, *g)))
        .collect()
}

/// "P: [40.0] g" per mounting, as the reasons name such levels.
fn unhandled_shown(levels: &[(Mount, f64)]) -> Vec<String> {
    [Mount::P, Mount::N]
        .into_iter()
        .filter_map(|m| {
            let gs: Vec<f64> = levels.iter().filter(|l| l.0 == m).map(|l| l.1).collect();
            (!gs.is_empty()).then(|| format!("{m}: {gs:?} g"))
        })
        .collect()
}

/// A pass that cannot stand: a level off the curve is not in the U95.
fn misfit_not_in_u(
    judged: &Judged,
    unhandled: &[String],
    outcome: &mut Outcome,
    reasons: &mut Vec<Reason>,
) {
    let Judged {
        name,
        shown,
        unit,
        limit,
        ..
    } = judged;
    reasons.push(
        Reason::new(
            ReasonCode::K2Inconclusive,
            format!(
                "{name} {shown} {unit}: a level off the curve ({}) is not in its U95, so the result cannot be graded a pass; retest it",
                unhandled.join("; ")
            ),
        )
        .with("value", shown)
        .with("unit", *unit)
        .with("limit", *limit)
        .with("levels", unhandled.join("; "))
        .with("variant", "misfit"),
    );
    if *outcome != Outcome::Fail {
        *outcome = Outcome::Inconclusive;
    }
}

/// Hold k2_max, the larger |k2| of the mountings, against its limit under
/// the limits' decision rule: each mounting's k2 with its own GUM U95 (the
/// limit is on the maximum, so under the guarded rule every mounting must
/// pass with its U and any one failing with its U fails;
/// [`DecisionRule::decide_all`]). A mounting whose fit has a level flagged
/// off the curve while its U95 carries no misfit (no model-inadequacy or
/// fit-scatter source) does not stand as a pass on that U alone: as for
/// K2, the reduction is made again without those levels and the pass
/// stands only when it passes there too (the worse outcome, the larger
/// reach).
fn grade_k2_max(
    a: &spinbench_analysis::UnitAnalysis,
    limits: &crate::plan::Limits,
    without: Without,
    outcome: &mut Outcome,
    reasons: &mut Vec<Reason>,
) {
    let Some((verdict, judged, unhandled)) = k2_max_judged(a, limits) else {
        return;
    };
    let accepted = |v: Verdict| matches!(v, Verdict::Pass | Verdict::Marginal);
    if unhandled.is_empty() || !accepted(verdict) {
        record_verdict(verdict, &judged, limits.marginal_fraction, outcome, reasons);
        return;
    }
    let shown = unhandled_shown(&unhandled);
    let again = without(&unhandled)
        .as_ref()
        .and_then(|b| k2_max_judged(b, limits))
        .filter(|(v, _, left)| left.is_empty() && accepted(*v));
    let Some((verdict_out, left_out, _)) = again else {
        misfit_not_in_u(&judged, &shown, outcome, reasons);
        return;
    };
    graded_on_both(
        [(verdict, judged), (verdict_out, left_out)],
        &shown,
        limits,
        outcome,
        reasons,
    );
}

/// k2_max's verdict, the mounting that decided it as judged, and the
/// levels flagged in a mounting whose k2 U95 carries no misfit (mounting,
/// |g|); `None` without a k2.
fn k2_max_judged(
    a: &spinbench_analysis::UnitAnalysis,
    limits: &crate::plan::Limits,
) -> Option<(Verdict, Judged, Levels)> {
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
        if !budget.is_some_and(carries_misfit) {
            unhandled.extend(flagged_levels(f).into_iter().map(|g| (*mount, g)));
        }
        values.push((k2, u));
        mounts.push(*mount);
    }
    if values.is_empty() {
        return None;
    }
    let (verdict, decided_by) = rule.decide_all(&values, l, limits.marginal_fraction);
    let i = decided_by.unwrap_or(0);
    let (v, u) = values[i];
    let mount = mounts[i];
    let judged = Judged {
        name: format!("k2_max: |k2| (mounting {mount})"),
        shown: shown_value(rule, v.abs(), u),
        reach: reach(rule, v, u),
        unit: "µg/g²",
        limit: l,
        rule,
        codes: [ReasonCode::K2OverLimit, ReasonCode::K2NearLimit],
        variant: None,
    };
    Some((verdict, judged, unhandled))
}

/// A figure held against its limit: what the reasons say of it.
struct Judged {
    /// The figure's name ("|k2| (mounting P)", "nonlinearity").
    name: String,
    /// Its value as shown, with ± U95 under the guarded rule.
    shown: String,
    /// How far it reaches towards the limit: |value| + U95 under the
    /// guarded rule, |value| by value alone (a marginal reason says it).
    reach: f64,
    /// Its unit.
    unit: &'static str,
    /// The limit.
    limit: f64,
    /// The rule it was judged by.
    rule: DecisionRule,
    /// Its reason codes: over the limit, near it.
    codes: [ReasonCode; 2],
    /// The catalogue's variant of its reasons (`reason.<code>.<variant>`),
    /// when the figure is not the catalogue's plain one.
    variant: Option<&'static str>,
}

/// |v| + U under the guarded rule with a U, else |v|.
fn reach(rule: DecisionRule, v: f64, u: Option<f64>) -> f64 {
    match (rule, u) {
        (DecisionRule::Guarded, Some(u)) => v.abs() + u,
        _ => v.abs(),
    }
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
        reach,
        unit,
        limit: l,
        rule,
        codes: [over, near],
        variant,
    } = judged;
    let with_variant = |r: Reason| match variant {
        Some(v) => r.with("variant", *v),
        None => r,
    };
    let guarded = if *rule == DecisionRule::Guarded {
        " (guarded rule)"
    } else {
        ""
    };
    match verdict {
        Verdict::Fail => {
            reasons.push(with_variant(
                Reason::new(
                    *over,
                    format!("{name} {shown} {unit} above the limit {l} {unit}{guarded}"),
                )
                .with("value", shown)
                .with("unit", *unit)
                .with("limit", *l)
                .with("rule", rule.name()),
            ));
            *outcome = Outcome::Fail;
        }
        Verdict::Inconclusive => {
            reasons.push(with_variant(
                Reason::new(
                    ReasonCode::K2Inconclusive,
                    format!("{name} {shown} {unit} straddles the limit {l} {unit}: inconclusive under the guarded rule, retest advised"),
                )
                .with("value", shown)
                .with("unit", *unit)
                .with("limit", *l),
            ));
            if *outcome != Outcome::Fail {
                *outcome = Outcome::Inconclusive;
            }
        }
        Verdict::Marginal => {
            let band = format!("{:.0}", (1.0 - marginal_fraction) * 100.0);
            reasons.push(with_variant(
                Reason::new(
                    *near,
                    format!(
                        "{name} {shown} {unit} reaches {reach:.3} {unit}, within {band} % of the limit {l} {unit}{guarded}"
                    ),
                )
                .with("value", shown)
                .with("reach", format!("{reach:.3}"))
                .with("unit", *unit)
                .with("limit", *l)
                .with("band", band)
                .with("rule", rule.name()),
            ));
            if *outcome == Outcome::Pass {
                *outcome = Outcome::Marginal;
            }
        }
        Verdict::Pass => {}
    }
}

#[cfg(test)]
#[path = "grade_tests.rs"]
mod tests;
