//! A plan's levels as data the planner writes: `levels = "auto"` designed
//! for a K2 U95 target from the station's model, the order the passes
//! visit the levels, and the prediction a plan carries into its run
//! ([`spinbench_analysis::design`] holds the arithmetic).

use super::{AutoLevels, DecisionRule, LevelTable, Measurand, PlanError, PlanPrediction, TestPlan};
use spinbench_analysis::{Mount, points};

impl TestPlan {
    /// Ask for the levels to be designed for `target` [µg/g²] (`levels =
    /// "auto"` with `target_k2_u95_ug_per_g2`, any earlier prediction
    /// dropped): the command line's `--target-k2-u95` and the web's target
    /// field, checked against the plan's bounds.
    pub fn set_target(&mut self, target_k2_u95_ug_per_g2: f64) -> Result<(), PlanError> {
        self.levels = Some(LevelTable::Auto(AutoLevels::Auto));
        self.target_k2_u95_ug_per_g2 = Some(target_k2_u95_ug_per_g2);
        self.prediction = None;
        self.validate()
    }

    /// The instruments of a run of this plan: its serials, else as many as
    /// the station's past runs had on average (at least 1).
    fn run_size(&self, model: &spinbench_analysis::design::StationModel) -> usize {
        if self.serials.is_empty() && model.runs > 0 {
            (model.instruments as f64 / model.runs as f64)
                .round()
                .max(1.0) as usize
        } else {
            self.serials.len().max(1)
        }
    }

    /// Whether this plan can decide, said before anything moves: `None`
    /// when its prediction leaves room for a verdict, else why not, naming
    /// the prediction and the limit. Under the guarded rule a K2 whose U95
    /// is the limit or wider can never pass, and one wider than half the
    /// limit passes only instruments with |K2| under limit − U95. The
    /// prediction is of K2; a plan that judges k2_max is told that its
    /// verdict's U95 is not the predicted one (each mounting's k2 carries
    /// the centrifuge's common part, docs/method.md (15)).
    pub fn decision_warning(&self) -> Option<String> {
        self.undecidable().map(|u| u.text())
    }

    /// The same as [`TestPlan::decision_warning`], as a wording for another
    /// language (the catalogue's `say.plan.decision.<case>`).
    pub fn decision_wording(&self) -> Option<crate::event::Wording> {
        self.undecidable().map(|u| u.wording())
    }

    /// Why this plan may not decide (module docs of [`Undecidable`]).
    fn undecidable(&self) -> Option<Undecidable> {
        let limits = &self.limits;
        let limit = limits.k2_max_ug_per_g2;
        // Without both passes (or with a slot fixed to one mounting by its
        // P:/N: prefix) an instrument has one mounting and no K2.
        let both = [Mount::P, Mount::N].iter().all(|m| self.passes.contains(m));
        let fixed: Vec<&str> = self
            .serials
            .values()
            .filter(|s| s.trim_start().starts_with("P:") || s.trim_start().starts_with("N:"))
            .map(String::as_str)
            .collect();
        if limits.decide_on == Measurand::K2 && !both {
            return Some(Undecidable::OneMounting { limit });
        }
        if limits.decide_on == Measurand::K2 && !fixed.is_empty() {
            return Some(Undecidable::FixedSlots {
                limit,
                slots: fixed.join(", "),
            });
        }
        let u = self.prediction.as_ref()?.k2_u95_ug_per_g2;
        let guarded = limits.decision_rule == DecisionRule::Guarded;
        match limits.decide_on {
            Measurand::K2Max => Some(Undecidable::JudgesK2Max { limit, u }),
            Measurand::K2 if guarded && u >= limit => Some(Undecidable::TooWide { limit, u }),
            Measurand::K2 if guarded && u > 0.5 * limit => Some(Undecidable::OverHalf { limit, u }),
            Measurand::K2 => None,
        }
    }

    /// Whether the levels are still to be designed (`levels = "auto"`).
    pub fn is_auto(&self) -> bool {
        matches!(self.levels, Some(LevelTable::Auto(_)))
    }

    /// The order in which each pass visits the levels: up, then down
    /// through `down_levels` (every level when absent), or up only.
    pub fn level_sequence(&self) -> Vec<f64> {
        let levels = self.level_table();
        if !self.up_down {
            return levels;
        }
        match &self.down_levels {
            None => points::up_down(&levels),
            Some(down) => {
                let mut down = down.clone();
                down.sort_by(|a, b| b.total_cmp(a));
                levels.into_iter().chain(down).collect()
            }
        }
    }

    /// The plan as the prediction sees it.
    pub fn candidate(&self) -> spinbench_analysis::design::Candidate {
        let levels = self.level_table();
        let top = levels.last().copied().unwrap_or(0.0);
        let down = if !self.up_down {
            Vec::new()
        } else {
            self.down_levels
                .clone()
                .unwrap_or_else(|| levels.iter().copied().filter(|g| *g < top).collect())
        };
        spinbench_analysis::design::Candidate {
            levels_g: levels,
            down_levels_g: down,
            dwell_s: self.dwell.seconds,
            passes: self.passes.len().max(1),
        }
    }

    /// The plan with its prediction from the station's `model`; with
    /// `levels = "auto"` first designed (the levels, the readings on the
    /// way down and a fixed dwell of least predicted time for
    /// `target_k2_u95_ug_per_g2`; every level read on the way down when
    /// the plan limits the hysteresis). A target the station cannot reach
    /// is refused, saying what it can reach, before anything moves.
    pub fn designed(
        &self,
        model: &spinbench_analysis::design::StationModel,
    ) -> Result<TestPlan, PlanError> {
        use spinbench_analysis::design;
        let err = |key: &str, problem: String| PlanError {
            key: key.into(),
            problem,
        };
        self.validate()?;
        let mut plan = self.clone();
        if self.is_auto() {
            if self.order != 3 {
                return Err(err(
                    "levels",
                    format!(
                        "\"auto\" designs for K2 of the cubic model (order = 3), not order {}",
                        self.order
                    ),
                ));
            }
            let target = self.target_k2_u95_ug_per_g2.ok_or_else(|| {
                err(
                    "levels",
                    "\"auto\" needs target_k2_u95_ug_per_g2, the K2 U95 to reach [µg/g²]".into(),
                )
            })?;
            let hysteresis = self.limits.hysteresis_max_ug.is_some();
            let found = design::design(
                model,
                target,
                self.range_g,
                self.passes.len().max(1),
                hysteresis,
            )
            .map_err(|e| err("levels", e.to_string()))?
            .map_err(|e| err("target_k2_u95_ug_per_g2", e.to_string()))?;
            plan.levels = Some(LevelTable::List(found.plan.levels_g.clone()));
            plan.up_down = true;
            plan.down_levels = Some(found.plan.down_levels_g.clone());
            plan.dwell.seconds = found.plan.dwell_s;
            plan.dwell.sem_target_ug = None;
        }
        // A plan the prediction cannot fit (too few levels, a model below
        // the cubic) runs without one; its compilation says what is wrong.
        let published = design::predict(
            model,
            &design::Candidate::published(
                &points::published_levels(self.range_g),
                self.passes.len().max(1),
            ),
        )
        .ok();
        let candidate = plan.candidate();
        let range = design::run_median_range(model, &candidate, self.run_size(model))
            .ok()
            .flatten();
        plan.prediction = design::predict(model, &candidate)
            .ok()
            .filter(|_| self.order == 3)
            .map(|predicted| PlanPrediction {
                k2_u95_run_range_ug_per_g2: range,
                k2_u95_ug_per_g2: predicted.k2_u95_ug_per_g2,
                centrifuge_time_s: predicted.centrifuge_time_s,
                published_k2_u95_ug_per_g2: published.map(|p| p.k2_u95_ug_per_g2),
                published_centrifuge_time_s: published.map(|p| p.centrifuge_time_s),
                target_k2_u95_ug_per_g2: self.target_k2_u95_ug_per_g2,
                model_runs: model.runs,
                sequential_centrifuge_time_max_s: plan.sequential.map(|q| {
                    let per_level_s = model.settle_s
                        + model.settle_s_per_g * plan.range_g
                        + f64::from(plan.dwell.seconds);
                    f64::from(q.max_levels_per_pass) * candidate.passes as f64 * per_level_s
                }),
            });
        Ok(plan)
    }
}

/// Why a plan may not decide ([`TestPlan::decision_warning`]): one case,
/// its English text and its wording from the same values.
enum Undecidable {
    /// The verdict is on K2 but the plan measures one mounting.
    OneMounting { limit: f64 },
    /// The verdict is on K2 but these slots are fixed to one mounting.
    FixedSlots { limit: f64, slots: String },
    /// The verdict is on k2_max, the prediction of K2.
    JudgesK2Max { limit: f64, u: f64 },
    /// The predicted K2 U95 is the limit or wider (guarded rule).
    TooWide { limit: f64, u: f64 },
    /// The predicted K2 U95 is over half the limit (guarded rule).
    OverHalf { limit: f64, u: f64 },
}

impl Undecidable {
    /// The case's key, its values as shown.
    fn values(&self) -> (&'static str, Vec<(&'static str, String)>) {
        let n = |v: f64| format!("{v:.3}");
        match self {
            Undecidable::OneMounting { limit } => {
                ("one_mounting", vec![("limit", limit.to_string())])
            }
            Undecidable::FixedSlots { limit, slots } => (
                "fixed_slots",
                vec![("limit", limit.to_string()), ("slots", slots.clone())],
            ),
            Undecidable::JudgesK2Max { limit, u } => (
                "judges_k2_max",
                vec![("limit", limit.to_string()), ("u95", n(*u))],
            ),
            Undecidable::TooWide { limit, u } => (
                "too_wide",
                vec![
                    ("limit", limit.to_string()),
                    ("u95", n(*u)),
                    ("target", n(0.5 * limit)),
                ],
            ),
            Undecidable::OverHalf { limit, u } => (
                "over_half",
                vec![
                    ("limit", limit.to_string()),
                    ("u95", n(*u)),
                    ("pass_below", n(limit - u)),
                    ("fail_over", n(limit + u)),
                    ("target", n(0.25 * limit)),
                ],
            ),
        }
    }

    /// The wording (`plan.decision.<case>`).
    fn wording(&self) -> crate::event::Wording {
        let (case, values) = self.values();
        values.into_iter().fold(
            crate::event::Wording::new(&format!("plan.decision.{case}")),
            |w, (name, value)| w.with(name, value),
        )
    }

    /// The English text (the catalogue's `en` entry says the same).
    fn text(&self) -> String {
        let (_, values) = self.values();
        let v = |name: &str| {
            values
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, v)| v.as_str())
                .unwrap_or_default()
        };
        let (limit, u95, target) = (v("limit"), v("u95"), v("target"));
        match self {
            Undecidable::OneMounting { .. } => format!(
                "the verdict is on K2 (decide_on = \"K2\") against {limit} µg/g², which needs both mountings, but the plan measures one mounting (passes = [\"P\", \"N\"] measures both): those instruments cannot be decided; measure both mountings or judge k2_max (decide_on = \"k2_max\")"
            ),
            Undecidable::FixedSlots { .. } => format!(
                "the verdict is on K2 (decide_on = \"K2\") against {limit} µg/g², which needs both mountings, but the slots of {} are fixed to one mounting: those instruments cannot be decided; measure both mountings or judge k2_max (decide_on = \"k2_max\")",
                v("slots")
            ),
            Undecidable::JudgesK2Max { .. } => format!(
                "the verdict is on k2_max (decide_on = \"k2_max\") against {limit} µg/g², but the prediction (K2 U95 {u95} µg/g²) is of the instrument's K2: each mounting's k2 also carries the centrifuge's common part and its U95 can be several times wider, so most instruments may be inconclusive; judge K2 (decide_on = \"K2\") to decide on the instrument"
            ),
            Undecidable::TooWide { .. } => format!(
                "the predicted K2 U95 {u95} µg/g² is as wide as the limit {limit} µg/g² or wider: under the guarded rule no instrument can pass; add levels or dwell (levels = \"auto\" with a target below {target}), or widen the limit"
            ),
            Undecidable::OverHalf { .. } => format!(
                "the predicted K2 U95 {u95} µg/g² is over half the limit {limit} µg/g²: only instruments with |K2| under {} can pass and over {} can fail, the rest will be inconclusive; a target below {target} decides more",
                v("pass_below"),
                v("fail_over")
            ),
        }
    }
}
