//! Judging: every instrument's points fitted and its figures held against
//! the plan's limits, into its record and outcome.

use super::*;
use crate::plan::{DecisionRule, Verdict};
use spinbench_analysis::exclusion::LevelExclusion;

impl Executor<'_> {
    /// How `slot`'s points are reduced: the plan's order and the station's
    /// Type B inputs with the slot's radius.
    pub(super) fn analysis_options(&self, slot: usize) -> AnalysisOptions {
        AnalysisOptions {
            order: self.plan.order,
            type_b: spinbench_analysis::uncertainty::TypeBInputs {
                // Each point averages its dwell's one-second read-backs.
                // (the fewest an adaptive dwell takes).
                readings_per_point: f64::from(match self.plan.plan.dwell.sem_target_ug {
                    Some(_) => self.plan.plan.dwell.min_seconds.max(1),
                    None => self.plan.plan.dwell.seconds.max(1),
                }),
                ..self.station.type_b(slot)
            },
        }
    }

    /// The steps of the plan that measure `slot` (tumble, radius, levels
    /// of the passes it takes part in) and were not all done.
    pub(super) fn steps_left(&self, slot: usize) -> usize {
        self.plan
            .steps
            .iter()
            .enumerate()
            .filter(|(_, step)| match step {
                Step::Tumble { .. } => true,
                Step::Radius { pass } | Step::Level { pass, .. } => self
                    .plan
                    .passes
                    .get(*pass)
                    .and_then(|p| p.get(slot))
                    .is_some_and(Option::is_some),
                _ => false,
            })
            .filter(|(index, _)| !self.completed.contains(index))
            .count()
    }

    /// Fit every instrument and give each its record and outcome. An
    /// instrument whose part of the plan was not completed (`run_complete`
    /// false, and steps of its left) is [`Outcome::Incomplete`]: its points
    /// are fitted and kept, but never graded pass or fail.
    pub(super) fn records(&self, run_complete: bool, run_reason: Option<&str>) -> Vec<UnitRecord> {
        let limits = self.plan.plan.limits;
        let mut out = Vec::new();
        for (slot, u) in self.units.iter().enumerate() {
            let Some(serial) = self.plan.serials[slot].clone() else {
                continue;
            };
            let mut reasons = Vec::new();
            let mut analysis = None;
            // The plan's exclusions for this instrument, applied to its points.
            let (points, exclusions) = self.excluded(&serial, &u.points);
            let mut k2_max = None;
            let mut outcome = Outcome::Fail;
            let left = if run_complete || u.failed.is_some() {
                0
            } else {
                self.steps_left(slot)
            };
            if left > 0 {
                outcome = Outcome::Incomplete;
                reasons.push(Reason::new(ReasonCode::Incomplete, format!(
                    "incomplete: the run ended with {left} of this instrument's measuring steps not done ({})",
                    run_reason.unwrap_or("no reason recorded")
                )));
                if !u.points.is_empty()
                    && let Ok(a) = analyze_unit(
                        &UnitPoints {
                            unit: serial.clone(),
                            run: None,
                            points: points.clone(),
                        },
                        self.analysis_options(slot),
                    )
                {
                    k2_max = a.k2_max_ug_per_g2;
                    analysis = Some(a);
                }
            } else if let Some(f) = &u.failed {
                reasons.push(f.clone());
            } else if u.points.is_empty() {
                reasons.push(Reason::new(ReasonCode::NoPoints, "no points were taken"));
            } else {
                let input = UnitPoints {
                    unit: serial.clone(),
                    run: None,
                    points: points.clone(),
                };
                match analyze_unit(&input, self.analysis_options(slot)) {
                    Ok(a) => {
                        k2_max = a.k2_max_ug_per_g2;
                        // Each figure against its limit; the outcome is the worst.
                        let f = &a.figures;
                        let checks = [
                            (
                                "|k2|",
                                k2_max,
                                Some(limits.k2_max_ug_per_g2),
                                "µg/g²",
                                [ReasonCode::K2OverLimit, ReasonCode::K2NearLimit],
                            ),
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
                        // k2's U95: its mounting's GUM budget (Type A and the
                        // station's Type B inputs), else its interval half-width.
                        let k2_u95 = a.k2_max_mount.and_then(|m| a.fits.get(&m)).and_then(|f| {
                            f.uncertainty
                                .as_ref()
                                .and_then(|u| u.k2_ug_per_g2.as_ref())
                                .map(|u| u.u95)
                                .or_else(|| f.fit.ci95.k2_ug_per_g2.map(|[lo, hi]| 0.5 * (hi - lo)))
                        });
                        let rule = limits.decision_rule;
                        for (name, value, limit, unit, [over, near]) in checks {
                            let (Some(v), Some(l)) = (value, limit) else {
                                continue;
                            };
                            // k2 carries its U95; the other figures carry no
                            // uncertainty yet and are judged by their value.
                            let (rule, u) = if over == ReasonCode::K2OverLimit {
                                (rule, k2_u95)
                            } else {
                                (DecisionRule::Simple, None)
                            };
                            let shown = match (rule, u) {
                                (DecisionRule::Guarded, Some(u)) => format!("{v:.3} ± {u:.3}"),
                                _ => format!("{v:.3}"),
                            };
                            let guarded = if rule == DecisionRule::Guarded {
                                " (guarded rule)"
                            } else {
                                ""
                            };
                            match rule.decide(v, u, l, limits.marginal_fraction) {
                                Verdict::Fail => {
                                    reasons.push(Reason::new(
                                        over,
                                        format!("{name} {shown} {unit} above the limit {l} {unit}{guarded}"),
                                    ));
                                    outcome = Outcome::Fail;
                                }
                                Verdict::Inconclusive => {
                                    reasons.push(Reason::new(
                                        ReasonCode::K2Inconclusive,
                                        format!("{name} {shown} {unit} straddles the limit {l} {unit}: inconclusive under the guarded rule, retest advised"),
                                    ));
                                    if outcome != Outcome::Fail {
                                        outcome = Outcome::Inconclusive;
                                    }
                                }
                                Verdict::Marginal => {
                                    reasons.push(Reason::new(
                                        near,
                                        format!(
                                            "{name} {shown} {unit} within {:.0} % of the limit {l} {unit}{guarded}",
                                            (1.0 - limits.marginal_fraction) * 100.0
                                        ),
                                    ));
                                    if outcome == Outcome::Pass {
                                        outcome = Outcome::Marginal;
                                    }
                                }
                                Verdict::Pass => {}
                            }
                        }
                        if k2_max.is_none() {
                            reasons
                                .push(Reason::new(ReasonCode::NoK2, "the model order has no k2"));
                        }
                        reasons.extend(
                            a.notes
                                .iter()
                                .map(|n| Reason::new(ReasonCode::AnalysisNote, n.clone())),
                        );
                        analysis = Some(a);
                    }
                    Err(e) => reasons.push(Reason::new(
                        ReasonCode::CannotReduce,
                        format!("cannot reduce: {e}"),
                    )),
                }
            }
            out.push(UnitRecord {
                slot,
                serial,
                tumble: u.cal.map(|c| [c.bias_output, c.scale_factor]),
                drawing_radius_m: self.station.drawing_radius_m(slot),
                radius_m: u.radius.clone(),
                points: u.points.clone(),
                analysis,
                k2_max_ug_per_g2: k2_max,
                outcome,
                reasons,
                decision_rule: Some(limits.decision_rule),
                exclusions,
            });
        }
        out
    }
}

impl Executor<'_> {
    /// A unit's points with the plan's exclusions for it left out, and the
    /// exclusions that removed something (by: the plan's operator).
    fn excluded(
        &self,
        serial: &str,
        records: &[PointRecord],
    ) -> (
        Vec<Point>,
        Vec<spinbench_analysis::exclusion::LevelExclusion>,
    ) {
        let plan = &self.plan.plan;
        let mut units = [UnitPoints {
            unit: serial.to_string(),
            run: None,
            points: point_list(records),
        }];
        let by = if plan.operator.is_empty() {
            "the plan".to_string()
        } else {
            plan.operator.clone()
        };
        let mut exclusions: Vec<LevelExclusion> = plan
            .exclusions
            .iter()
            .filter(|e| e.serial.as_deref().is_none_or(|s| s == serial))
            .map(|e| LevelExclusion {
                unit: Some(serial.to_string()),
                mount: e.mount,
                g: e.g,
                reason: e.reason.clone(),
                by: by.clone(),
                points_removed: 0,
            })
            .collect();
        spinbench_analysis::exclusion::apply(&mut units, &mut exclusions);
        // One that removed nothing from this instrument is not its record's.
        exclusions.retain(|e| e.points_removed > 0);
        let [unit] = units;
        (unit.points, exclusions)
    }
}

/// The analysis' points of a unit's records.
fn point_list(records: &[PointRecord]) -> Vec<Point> {
    records
        .iter()
        .map(|p| Point {
            mount: p.mount,
            g_nominal: p.g_nominal,
            g_applied: p.g_applied,
            output: p.output_hz,
            direction: Some(p.direction),
        })
        .collect()
}
