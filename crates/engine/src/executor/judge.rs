//! Judging: every instrument's points fitted and its figures held against
//! the plan's limits, into its record and outcome.

use super::Executor;
use super::stability::mean_std;
use crate::event::{Event, Wording};
use crate::judgement::{
    analysis_options, grade, graded_points, plan_exclusions, table_signature, temperature_reasons,
    unmeasured,
};
use crate::plan::Step;
use crate::record::{Outcome, PointRecord, Reason, ReasonCode, UnitRecord};
use spinbench_analysis::Point;
use spinbench_analysis::unit::{AnalysisOptions, UnitPoints, analyze_unit};

impl Executor<'_> {
    /// How `slot`'s points are reduced ([`analysis_options`]).
    pub(super) fn analysis_options(&self, slot: usize) -> AnalysisOptions {
        let u = &self.units[slot];
        analysis_options(
            &self.plan,
            self.station,
            slot,
            &u.radius_reading_u_ppm,
            u.cross_axis.is_some(),
        )
    }

    /// The instrument's figures at each of the plan's temperatures (every
    /// mounting's points there reduced together: the full-range fit's k0 and
    /// k1, the joint K2) and the coefficients through them; a temperature
    /// whose points cannot be reduced is left out with a note.
    fn temperature_figures(
        &self,
        slot: usize,
        serial: &str,
        all: &[PointRecord],
        reasons: &mut Vec<Reason>,
    ) -> (
        Vec<spinbench_analysis::temperature::AtTemperature>,
        Option<spinbench_analysis::temperature::TemperatureCoefficients>,
    ) {
        use spinbench_analysis::temperature::{
            AtTemperature, PairedUncertainty, paired_uncertainty, temperature_coefficients,
        };
        let mut setpoints = self.plan.plan.temperatures_c.clone();
        setpoints.sort_by(f64::total_cmp);
        setpoints.dedup();
        // Each temperature's figures (their full fits' values) and points.
        let mut found: Vec<(AtTemperature, Vec<Point>)> = Vec::new();
        for setpoint_c in setpoints {
            let here: Vec<PointRecord> = all
                .iter()
                .filter(|p| p.setpoint_c == Some(setpoint_c))
                .cloned()
                .collect();
            let temperatures: Vec<f64> = here.iter().filter_map(|p| p.temperature_c).collect();
            if temperatures.is_empty() {
                continue;
            }
            let (temperature_c, temperature_spread_c) = mean_std(&temperatures);
            let (points, _) = plan_exclusions(&self.plan, serial, &here);
            let input = UnitPoints {
                unit: serial.to_string(),
                run: None,
                points: points.clone(),
            };
            let figures = analyze_unit(&input, self.analysis_options(slot))
                .ok()
                .and_then(|a| {
                    let full = a.full_range.as_ref()?;
                    let k2 = a.joint.as_ref().map(|j| [j.k2_even_ug_per_g2, f64::NAN]);
                    Some(AtTemperature {
                        setpoint_c,
                        temperature_c,
                        temperature_spread_c,
                        points: temperatures.len(),
                        k0_g: [full.fit.k0_g, f64::NAN],
                        k1_hz_per_g: [full.fit.k1, f64::NAN],
                        k2_ug_per_g2: k2,
                    })
                });
            match figures {
                Some(f) => found.push((f, points)),
                None => reasons.push(
                    Reason::new(
                        ReasonCode::AnalysisNote,
                        format!("its points at {setpoint_c} °C could not be reduced; that temperature is left out of the temperature coefficients"),
                    )
                    .with("variant", "temperature_not_reduced")
                    .with("setpoint", setpoint_c),
                ),
            }
        }
        // Their uncertainties: what differs from the reference temperature's
        // (analysis::temperature's docs), the reference's share the rms of its pairs'.
        let reference = crate::soak::reference_c(
            &self.plan.plan.temperatures_c,
            self.station.temperature.ambient_c,
        );
        let Some(r) = found
            .iter()
            .position(|(a, _)| Some(a.setpoint_c) == reference)
        else {
            return (found.into_iter().map(|(a, _)| a).collect(), None);
        };
        let k1 = found[r].0.k1_hz_per_g[0];
        let paired: Vec<Option<PairedUncertainty>> = found
            .iter()
            .enumerate()
            .map(|(i, (_, points))| {
                (i != r)
                    .then(|| paired_uncertainty(&found[r].1, points, k1))
                    .flatten()
            })
            .collect();
        let others: Vec<PairedUncertainty> = paired.iter().flatten().copied().collect();
        let reference_u = PairedUncertainty::rms(&others);
        let mut at = Vec::new();
        for (i, (mut a, _)) in found.into_iter().enumerate() {
            let Some(u) = (if i == r { reference_u } else { paired[i] }) else {
                reasons.push(
                    Reason::new(
                        ReasonCode::AnalysisNote,
                        format!("its levels at {} °C do not pair with those at the reference temperature; that temperature is left out of the temperature coefficients", a.setpoint_c),
                    )
                    .with("variant", "temperature_not_paired")
                    .with("setpoint", a.setpoint_c),
                );
                continue;
            };
            a.k0_g[1] = u.k0_g;
            a.k1_hz_per_g[1] = u.k1_hz_per_g;
            a.k2_ug_per_g2 = a.k2_ug_per_g2.zip(u.k2_ug_per_g2).map(|(v, u)| [v[0], u]);
            at.push(a);
        }
        let coefficients = (at.len() >= 2)
            .then(|| temperature_coefficients(&at).ok())
            .flatten();
        (at, coefficients)
    }

    /// The steps of the plan that measure `slot` (tumble, radius, levels
    /// of the passes it takes part in) and were not all done.
    pub(super) fn steps_left(&self, slot: usize) -> usize {
        self.plan
            .steps
            .iter()
            .enumerate()
            .filter(|(_, step)| match step {
                Step::Tumble { .. } | Step::CrossTumble { .. } => true,
                _ => step.measured_pass().is_some_and(|pass| {
                    self.plan
                        .passes
                        .get(pass)
                        .and_then(|p| p.get(slot))
                        .is_some_and(Option::is_some)
                }),
            })
            .filter(|(index, _)| !self.progress.completed.contains(index))
            .count()
    }

    /// Fit every instrument and give each its record and outcome. An
    /// instrument whose part of the plan was not completed (`run_complete`
    /// false, and steps of its left) is [`Outcome::Incomplete`]: its points
    /// are fitted and kept, but never graded pass or fail.
    pub(super) fn records(&self, run_complete: bool, run_reason: Option<&str>) -> Vec<UnitRecord> {
        let limits = self.plan.plan.limits;
        let mut out = Vec::new();
        // Each instrument's points as graded (the plan's exclusions applied).
        let graded: Vec<Option<(Vec<Point>, Vec<_>)>> = self
            .units
            .iter()
            .enumerate()
            .map(|(slot, u)| {
                let serial = self.plan.serials[slot].as_ref()?;
                Some(plan_exclusions(
                    &self.plan,
                    serial,
                    &graded_points(&self.plan, self.station, &u.points),
                ))
            })
            .collect();
        // The centrifuge's signature from every instrument that measured
        // (a dead one has no points), before any is graded.
        let table = table_signature(
            self.units
                .iter()
                .zip(&graded)
                .enumerate()
                .filter(|(_, (u, _))| u.failed.is_none())
                .filter_map(|(slot, (_, g))| {
                    let (points, _) = g.as_ref()?;
                    Some(UnitPoints {
                        unit: self.plan.serials[slot].clone()?,
                        run: None,
                        points: points.clone(),
                    })
                }),
            self.plan.order,
            self.plan.table_prior.as_ref(),
        );
        for (slot, (u, graded_points)) in self.units.iter().zip(graded).enumerate() {
            let (Some(serial), Some((points, exclusions))) =
                (self.plan.serials[slot].clone(), graded_points)
            else {
                continue;
            };
            let mut reasons = Vec::new();
            let mut analysis = None;
            let mut k2_max = None;
            let mut outcome = Outcome::Fail;
            let left = if run_complete || u.failed.is_some() {
                0
            } else {
                self.steps_left(slot)
            };
            if left > 0 {
                outcome = Outcome::Incomplete;
                reasons.push(
                    Reason::new(
                        ReasonCode::Incomplete,
                        format!(
                            "incomplete: the run ended with {left} of this instrument's measuring steps not done ({})",
                            run_reason.unwrap_or("no reason recorded")
                        ),
                    )
                    .with("left", left)
                    .with("why", run_reason.unwrap_or("no reason recorded")),
                );
                if !u.points.is_empty()
                    && let Ok(a) = spinbench_analysis::unit::analyze_unit_with(
                        &UnitPoints {
                            unit: serial.clone(),
                            run: None,
                            points: points.clone(),
                        },
                        self.analysis_options(slot),
                        table.as_ref(),
                    )
                {
                    k2_max = a.k2_max_ug_per_g2;
                    analysis = Some(a);
                }
            } else if let Some(f) = &u.failed {
                reasons.push(f.clone());
                // An instrument that went silent was not measured: never
                // graded pass or fail (a connector is as likely as the
                // instrument); one that failed a measured criterion in a
                // run that did not end complete is not graded either.
                if unmeasured(f.code) || !run_complete {
                    outcome = Outcome::Incomplete;
                    if !run_complete {
                        reasons.push(
                            Reason::new(
                                ReasonCode::Incomplete,
                                format!(
                                    "incomplete: the run did not end complete ({}), so no instrument is graded",
                                    run_reason.unwrap_or("no reason recorded")
                                ),
                            )
                            .with("variant", "run_ended")
                            .with("why", run_reason.unwrap_or("no reason recorded")),
                        );
                    }
                }
            } else if u.points.is_empty() {
                reasons.push(Reason::new(ReasonCode::NoPoints, "no points were taken"));
            } else {
                let graded = grade(
                    &serial,
                    points.clone(),
                    self.analysis_options(slot),
                    &limits,
                    table.as_ref(),
                );
                analysis = graded.analysis;
                k2_max = graded.k2_max_ug_per_g2;
                outcome = graded.outcome;
                reasons.extend(graded.reasons);
            }
            reasons.extend(temperature_reasons(&self.plan, self.station, &u.points));
            let (at_temperatures, temperature_coefficients) =
                self.temperature_figures(slot, &serial, &u.points, &mut reasons);
            out.push(UnitRecord {
                at_temperatures,
                temperature_coefficients,
                slot,
                serial,
                tumble: u.cal.map(|c| [c.bias_output, c.scale_factor]),
                cross_axis_ug_per_g: u.cross_axis.map(|c| c.ug_per_g()),
                radius_reading_u_ppm: u.radius_reading_u_ppm.clone(),
                drawing_radius_m: self.station.drawing_radius_m(slot),
                radius_m: u.radius.clone(),
                points: u.points.clone(),
                analysis,
                k2_max_ug_per_g2: k2_max,
                outcome,
                reasons,
                decision_rule: Some(limits.decision_rule),
                decision: Some(limits.decision()),
                table_signature: table.clone(),
                exclusions,
            });
        }
        // The lines' scatter judged over the whole batch (analysis::temperature).
        let mut batch: Vec<_> = out
            .iter()
            .filter_map(|r| r.temperature_coefficients)
            .collect();
        // The radius's growth in the chamber: k1's coefficient corrected by
        // the stated share, or bounded by the whole arm's (the radius is
        // found at the reference temperature only).
        spinbench_analysis::temperature::with_arm_expansion(
            &mut batch,
            self.station.uncertainty.chamber_radius_expansion_ppm_per_c,
            self.station.uncertainty.arm_expansion_ppm_per_c,
        );
        let mut pooled = batch.into_iter();
        for record in out
            .iter_mut()
            .filter(|r| r.temperature_coefficients.is_some())
        {
            record.temperature_coefficients = pooled.next();
        }
        out
    }
}

/// The notice of a centrifuge whose signature left the earlier runs'
/// (docs/method.md §6, "A learned centrifuge checks itself").
pub(super) fn table_change_notice(
    change: &spinbench_analysis::table_signature::SignatureChange,
) -> Event {
    let levels = change.levels_shown();
    let z = format!("{:.0}", change.largest_z);
    Event::Notice {
        message: format!(
            "the centrifuge's signature changed at {levels} since the {} earlier run(s) on this table \
             (up to {z} standard errors): this run corrects by its own signature alone and the earlier \
             runs are set aside; check the table (a fixture, the balance, a repair) if nobody changed it",
            change.earlier_runs
        ),
        wording: Some(
            Wording::new("notice.table_signature_changed")
                .with("levels", &levels)
                .with("runs", change.earlier_runs)
                .with("z", &z),
        ),
    }
}
