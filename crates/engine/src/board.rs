//! The live board of every slot: what each instrument is
//! doing now, derived from the run's events alone, so the web UI and the
//! CLI show the same. A pull-style state machine: feed it every event with
//! [`SlotBoard::apply`], read [`SlotBoard::slots`].
//!
//! A slot is `waiting` (not in the step being taken), `warming`,
//! `settling` or `averaging` (at a level, with the rest of its pass),
//! `tumble` or `radius` (the 1 g steps), `done` (graded), `noisy` or
//! `failed` (left out, the reason kept). After each pass its k2 (per
//! mounting, with the fit's U95 — Type A: the station's budget comes with
//! the record) is fitted from its points so far, and K2 once both mountings
//! have been measured; the graded record's figures replace them at the end.

use crate::event::Event;
use crate::plan::{CompiledPlan, Step};
use crate::record::{Outcome, PointRecord, ReasonCode};
use serde::Serialize;
use spinbench_analysis::unit::analyze_unit;
use spinbench_analysis::{AnalysisOptions, Mount, UnitPoints};

/// What a slot is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SlotPhase {
    /// Not in the step being taken (or the run has not begun).
    Waiting,
    /// Warming up after power-on.
    Warming,
    /// At 1 g for the tumble (the operator turns the fixtures).
    Tumble,
    /// At 1 g at R0 while its radius is found.
    Radius,
    /// At a level, waiting for the rate and the outputs to be stable.
    Settling,
    /// At a level, averaging.
    Averaging,
    /// Measured and graded.
    Done,
    /// Left out: its output too noisy.
    Noisy,
    /// Left out (dead, drifting, over temperature …).
    Failed,
}

impl SlotPhase {
    /// Its name, as it is serialised (`averaging`, `failed`, …).
    pub fn as_str(self) -> &'static str {
        match self {
            SlotPhase::Waiting => "waiting",
            SlotPhase::Warming => "warming",
            SlotPhase::Tumble => "tumble",
            SlotPhase::Radius => "radius",
            SlotPhase::Settling => "settling",
            SlotPhase::Averaging => "averaging",
            SlotPhase::Done => "done",
            SlotPhase::Noisy => "noisy",
            SlotPhase::Failed => "failed",
        }
    }
}

/// One slot of the board.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SlotState {
    /// Slot (1-based, as on the fixtures).
    pub slot: usize,
    /// Serial number.
    pub serial: String,
    /// The mounting of the pass being measured (or last measured).
    pub mount: Option<Mount>,
    /// What it is doing.
    pub phase: SlotPhase,
    /// Latest one-second output [Hz].
    pub output_hz: Option<f64>,
    /// Latest temperature [°C].
    pub temperature_c: Option<f64>,
    /// Points taken.
    pub points: usize,
    /// Points it takes in the whole plan.
    pub points_planned: usize,
    /// k2 per mounting fitted so far: (mounting, k2 [µg/g²], its U95).
    pub k2_ug_per_g2: Vec<(Mount, f64, Option<f64>)>,
    /// K2 once both mountings are measured: (value [µg/g²], U95).
    pub big_k2_ug_per_g2: Option<(f64, Option<f64>)>,
    /// The outcome once graded.
    pub outcome: Option<Outcome>,
    /// Why it was left out.
    pub reason: Option<String>,
    /// The reason's code and values (see [`crate::Reason`]), for the page's language.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason_code: Option<ReasonCode>,
    /// The values of the reason's text, by name.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub reason_args: std::collections::BTreeMap<String, String>,
}

/// The board: one [`SlotState`] per slot with an instrument.
#[derive(Debug, Clone, Default)]
pub struct SlotBoard {
    plan: Option<CompiledPlan>,
    slots: Vec<SlotState>,
    points: Vec<Vec<PointRecord>>,
    /// The step being taken.
    step: Option<usize>,
}

impl SlotBoard {
    /// An empty board (filled by `RunStarted`).
    pub fn new() -> SlotBoard {
        SlotBoard::default()
    }

    /// Every slot with an instrument, in slot order.
    pub fn slots(&self) -> &[SlotState] {
        &self.slots
    }

    fn state_mut(&mut self, slot0: usize) -> Option<&mut SlotState> {
        self.slots.iter_mut().find(|s| s.slot == slot0 + 1)
    }

    fn left_out(phase: SlotPhase) -> bool {
        matches!(
            phase,
            SlotPhase::Noisy | SlotPhase::Failed | SlotPhase::Done
        )
    }

    /// Take one event.
    pub fn apply(&mut self, event: &Event) {
        match event {
            Event::RunStarted { plan, .. } => self.start(plan),
            Event::StepStarted { index, .. } => self.step_started(*index),
            Event::StepDone { index } => self.step_done(*index),
            Event::Progress { phase, .. } => {
                let next = if phase == "averaging" {
                    SlotPhase::Averaging
                } else {
                    SlotPhase::Settling
                };
                for s in &mut self.slots {
                    if matches!(s.phase, SlotPhase::Settling | SlotPhase::Averaging) {
                        s.phase = next;
                    }
                }
            }
            Event::Values {
                outputs_hz,
                temperatures_c,
                ..
            } => {
                for s in &mut self.slots {
                    s.output_hz = outputs_hz.get(s.slot - 1).copied().flatten();
                    if let Some(t) = temperatures_c.get(s.slot - 1).copied().flatten() {
                        s.temperature_c = Some(t);
                    }
                }
            }
            Event::PointDone { points, .. } => {
                for p in points {
                    if let Some(list) = self.points.get_mut(p.slot) {
                        list.push(p.clone());
                    }
                    if let Some(s) = self.state_mut(p.slot) {
                        s.points += 1;
                    }
                }
            }
            Event::UnitFailed {
                slot,
                reason,
                code,
                args,
            } => {
                if let Some(s) = self.state_mut(*slot) {
                    s.phase = if *code == ReasonCode::Noisy {
                        SlotPhase::Noisy
                    } else {
                        SlotPhase::Failed
                    };
                    s.reason = Some(reason.clone());
                    s.reason_code = Some(*code);
                    s.reason_args = args.clone();
                }
            }
            Event::UnitResult { record } => {
                let (slot, outcome) = (record.slot, record.outcome);
                let k2 = record.analysis.as_ref().map(figures);
                if let Some(s) = self.state_mut(slot) {
                    s.outcome = Some(outcome);
                    if !matches!(s.phase, SlotPhase::Noisy | SlotPhase::Failed) {
                        // Not measured whole: not done.
                        s.phase = if outcome == Outcome::Incomplete {
                            SlotPhase::Waiting
                        } else {
                            SlotPhase::Done
                        };
                    }
                    if let Some((per_mount, big)) = k2 {
                        s.k2_ug_per_g2 = per_mount;
                        s.big_k2_ug_per_g2 = big;
                    }
                }
            }
            _ => {}
        }
    }

    fn start(&mut self, plan: &CompiledPlan) {
        let planned = |slot: usize| -> usize {
            plan.steps
                .iter()
                .filter(|s| match s {
                    Step::Level { pass, .. } => plan
                        .passes
                        .get(*pass)
                        .and_then(|p| p.get(slot))
                        .is_some_and(Option::is_some),
                    _ => false,
                })
                .count()
        };
        self.slots = plan
            .serials
            .iter()
            .enumerate()
            .filter_map(|(i, s)| {
                s.as_ref().map(|serial| SlotState {
                    slot: i + 1,
                    serial: serial.clone(),
                    mount: None,
                    phase: SlotPhase::Waiting,
                    output_hz: None,
                    temperature_c: None,
                    points: 0,
                    points_planned: planned(i),
                    k2_ug_per_g2: Vec::new(),
                    big_k2_ug_per_g2: None,
                    outcome: None,
                    reason: None,
                    reason_code: None,
                    reason_args: Default::default(),
                })
            })
            .collect();
        self.points = vec![Vec::new(); plan.serials.len()];
        self.plan = Some(plan.clone());
        self.step = None;
    }

    fn step_started(&mut self, index: usize) {
        self.step = Some(index);
        let Some(plan) = &self.plan else {
            return;
        };
        let Some(step) = plan.steps.get(index) else {
            return;
        };
        let in_pass = |pass: usize, slot1: usize| {
            plan.passes
                .get(pass)
                .and_then(|p| p.get(slot1 - 1))
                .copied()
                .flatten()
        };
        for s in &mut self.slots {
            if Self::left_out(s.phase) {
                continue;
            }
            s.phase = match step {
                Step::WarmUp { .. } => SlotPhase::Warming,
                Step::Tumble { .. } | Step::CrossTumble { .. } => SlotPhase::Tumble,
                Step::Radius { pass } | Step::Level { pass, .. } | Step::Decide { pass, .. } => {
                    match in_pass(*pass, s.slot) {
                        Some(mount) => {
                            s.mount = Some(mount);
                            if matches!(step, Step::Radius { .. }) {
                                SlotPhase::Radius
                            } else {
                                SlotPhase::Settling
                            }
                        }
                        None => SlotPhase::Waiting,
                    }
                }
                _ => SlotPhase::Waiting,
            };
        }
    }

    /// After a pass's last level: fit each of its slots' points so far.
    fn step_done(&mut self, index: usize) {
        let Some(plan) = &self.plan else {
            return;
        };
        let Some(pass @ Some(_)) = plan
            .steps
            .get(index)
            .filter(|s| matches!(s, Step::Level { .. } | Step::Decide { .. }))
            .map(Step::measured_pass)
        else {
            return;
        };
        // A pass's rounds of deciding come after its levels: the fit is
        // shown after its last measuring step.
        let last_of_pass = !plan.steps[index + 1..].iter().any(|s| {
            matches!(s, Step::Level { .. } | Step::Decide { .. }) && s.measured_pass() == pass
        });
        if !last_of_pass {
            return;
        }
        let order = plan.order;
        for s in &mut self.slots {
            if Self::left_out(s.phase) {
                continue;
            }
            let Some(records) = self.points.get(s.slot - 1) else {
                continue;
            };
            let input = UnitPoints {
                unit: s.serial.clone(),
                run: None,
                points: records.iter().map(PointRecord::point).collect(),
            };
            let options = AnalysisOptions {
                order,
                type_b: Default::default(),
                anomalies: plan.plan.anomalies,
            };
            if let Ok(a) = analyze_unit(&input, options) {
                let (per_mount, big) = figures(&a);
                s.k2_ug_per_g2 = per_mount;
                s.big_k2_ug_per_g2 = big;
            }
            // Its pass is over: off the levels until the next step says.
            s.phase = SlotPhase::Waiting;
        }
    }
}

type Figures = (Vec<(Mount, f64, Option<f64>)>, Option<(f64, Option<f64>)>);

/// k2 per mounting with its U95, and K2 with its U95, from a reduction.
fn figures(a: &spinbench_analysis::UnitAnalysis) -> Figures {
    let per_mount = a
        .fits
        .iter()
        .filter_map(|(&m, f)| {
            let k2 = f.fit.k2_ug_per_g2?;
            let u95 = f
                .uncertainty
                .as_ref()
                .and_then(|u| u.k2_ug_per_g2.as_ref())
                .map(|u| u.u95)
                .or_else(|| f.fit.ci95.k2_ug_per_g2.map(|[lo, hi]| (hi - lo) / 2.0));
            Some((m, k2, u95))
        })
        .collect();
    let big = a
        .joint
        .as_ref()
        .map(|j| (j.k2_even_ug_per_g2, j.k2_even_u95));
    (per_mount, big)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_phases_name_is_its_serialised_name() {
        for phase in [
            SlotPhase::Waiting,
            SlotPhase::Warming,
            SlotPhase::Tumble,
            SlotPhase::Radius,
            SlotPhase::Settling,
            SlotPhase::Averaging,
            SlotPhase::Done,
            SlotPhase::Noisy,
            SlotPhase::Failed,
        ] {
            assert_eq!(
                serde_json::to_value(phase).ok(),
                Some(serde_json::Value::from(phase.as_str()))
            );
        }
    }
}
