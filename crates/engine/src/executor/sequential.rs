//! Measuring until the verdict is certain (the plan's `[sequential]`,
//! docs/method.md §6): after a pass's planned levels, while its
//! instruments are still mounted, each round judges the run so far and
//! measures the one level that serves the most undecided instruments.
//!
//! What decides an instrument whose level is off its curve is support
//! beside that level: with more levels around it, the reductions with and
//! without it agree, and the set-aside's term in its budget shrinks. The
//! level chosen is halfway between the flagged level and a measured
//! neighbour, no nearer than [`MIN_SPACING_G`] to any measured level (a
//! level inside the dip's width would meet the same dip).

use super::{EngineError, Executor};
use crate::event::{Event, Wording};
use crate::plan::Step;
use crate::record::{Outcome, UnitRecord};
use spinbench_analysis::{Direction, Mount};
use std::collections::{BTreeMap, BTreeSet};

/// The closest a chosen level comes to one already measured in the pass
/// [g]: the instruments' dips are 0.3 to 2 g wide (method.md §5), so a
/// level nearer than this meets the dip it is to step around.
pub const MIN_SPACING_G: f64 = 2.5;

/// The executor's part that remembers the passes whose rounds are over
/// (a later round of such a pass does nothing; a resumed run finds out again).
#[derive(Debug, Clone, Default)]
pub(super) struct Deciding {
    /// Passes with nothing left to decide, or nothing that would decide it.
    finished: BTreeSet<usize>,
    /// The slots the current pass's added levels were for.
    served: BTreeSet<usize>,
}

/// A level to measure and the undecided instruments it serves (slots, 0-based).
#[derive(Debug, Clone, PartialEq)]
pub struct Choice {
    /// The level [g].
    pub g_nominal: f64,
    /// The slots it serves.
    pub slots: Vec<usize>,
    /// The flagged levels it stands beside [g] (none: where the levels
    /// are farthest apart, or mirrored).
    pub beside_g: Vec<f64>,
    /// A level an earlier pass added, measured in this one too.
    pub mirrored: bool,
}

/// The levels of `mount` that an instrument's reduction found off its
/// curve: those the anomaly rule set aside and those flagged but kept [g].
pub fn flagged_levels(record: &UnitRecord, mount: Mount) -> Vec<f64> {
    let Some(a) = &record.analysis else {
        return Vec::new();
    };
    let mut gs: Vec<f64> = a
        .rule_exclusions
        .iter()
        .filter(|e| e.mount == mount)
        .map(|e| e.g)
        .collect();
    if let Some(d) = a.fits.get(&mount).and_then(|f| f.diagnostics.as_ref()) {
        gs.extend(d.outlier_levels.iter().map(|o| o.g));
    }
    gs.sort_by(f64::total_cmp);
    gs.dedup();
    gs
}

/// What an undecided instrument needs in this pass.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Needs {
    /// Slot → its own levels off the curve here [g]: support beside them.
    pub beside: BTreeMap<usize, Vec<f64>>,
    /// Slots whose mounting k2 is too wide for a verdict with no level to
    /// blame (too few levels to flag one): support where the levels are
    /// farthest apart.
    pub wide: BTreeSet<usize>,
}

/// The level that serves the most undecided instruments (`needs`), from
/// the levels measured in the pass (`measured` [g]), at most `top_g`;
/// `None` when no level would serve one. Among equals the one in the
/// widest gap, then the higher (more leverage on k2).
pub fn choose(needs: &Needs, measured: &[f64], top_g: f64) -> Option<Choice> {
    let mut measured: Vec<f64> = measured.iter().copied().filter(|g| g.is_finite()).collect();
    measured.sort_by(f64::total_cmp);
    measured.dedup();
    // Candidate level (in tenths of a g) → (slots, the flagged levels beside, its gap).
    let mut candidates: BTreeMap<i64, (BTreeSet<usize>, BTreeSet<i64>, i64)> = BTreeMap::new();
    let mut offer = |c: f64, slot: usize, beside: Option<f64>, gap: f64| {
        let c = (c * 2.0).round() / 2.0;
        let clear = measured.iter().all(|m| (m - c).abs() >= MIN_SPACING_G);
        if clear && c > 0.0 && c <= top_g {
            let entry = candidates.entry(tenths(c)).or_default();
            entry.0.insert(slot);
            entry.1.extend(beside.map(tenths));
            entry.2 = entry.2.max(tenths(gap));
        }
    };
    for (&slot, gs) in &needs.beside {
        for &g in gs {
            let below = measured.iter().rev().find(|&&m| m < g - 1e-9);
            let above = measured.iter().find(|&&m| m > g + 1e-9);
            for &neighbour in [below, above].into_iter().flatten() {
                offer((g + neighbour) / 2.0, slot, Some(g), (g - neighbour).abs());
            }
        }
    }
    for &slot in &needs.wide {
        for pair in measured.windows(2) {
            offer((pair[0] + pair[1]) / 2.0, slot, None, pair[1] - pair[0]);
        }
    }
    candidates
        .into_iter()
        .max_by_key(|(c, (slots, _, gap))| (slots.len(), *gap, *c))
        .map(|(c, (slots, beside, _))| Choice {
            g_nominal: c as f64 / 10.0,
            slots: slots.into_iter().collect(),
            beside_g: beside.into_iter().map(|g| g as f64 / 10.0).collect(),
            mirrored: false,
        })
}

/// A mounting's k2 U95 [µg/g²] over which an undecided instrument is
/// given support, as a fraction of the plan's k2 limit: K2 takes half of
/// each mounting's k2, so a fifth of the limit in one mounting already
/// spends a tenth of the limit of K2's interval.
pub const WIDE_FRACTION_OF_LIMIT: f64 = 0.2;

/// The mounting's k2 U95 [µg/g²], when its fit has one.
fn mounting_k2_u95(record: &UnitRecord, mount: Mount) -> Option<f64> {
    let u = record
        .analysis
        .as_ref()?
        .fits
        .get(&mount)?
        .uncertainty
        .as_ref()?;
    u.k2_ug_per_g2.as_ref().map(|u| u.u95)
}

impl Executor<'_> {
    /// Round `round` of pass `pass`: judge the run so far and measure the
    /// level that serves the most undecided instruments. The pass's rounds
    /// end, said once in one notice (the levels added, for whom, and how
    /// many are still undecided and why), when none is undecided, no level
    /// would serve one, or the budget is spent.
    pub(super) fn decide(
        &mut self,
        step: usize,
        pass: usize,
        round: usize,
    ) -> Result<(), EngineError> {
        if self.deciding.finished.contains(&pass) {
            return Ok(());
        }
        let budget = self
            .plan
            .plan
            .sequential
            .map_or(0, |q| q.max_levels_per_pass as usize);
        let (undecided, choice) = self.next_deciding_level(pass);
        let Some(choice) = choice else {
            return self.end_deciding(pass, undecided, false);
        };
        self.deciding.served.extend(choice.slots.iter().copied());
        self.level(step, pass, choice.g_nominal, Direction::Up)?;
        if round + 1 >= budget {
            let (undecided, _) = self.next_deciding_level(pass);
            return self.end_deciding(pass, undecided, true);
        }
        Ok(())
    }

    /// The end of pass `pass`'s rounds, said: the levels the data added
    /// (those of the pass not in the plan), the instruments they served,
    /// how many are still undecided, and whether the budget ran out.
    fn end_deciding(
        &mut self,
        pass: usize,
        undecided: usize,
        budget_spent: bool,
    ) -> Result<(), EngineError> {
        self.deciding.finished.insert(pass);
        let planned: Vec<f64> = self
            .plan
            .steps
            .iter()
            .filter_map(|s| match s {
                Step::Level {
                    pass: p, g_nominal, ..
                } if *p == pass => Some(g_nominal.abs()),
                _ => None,
            })
            .collect();
        let mut added: Vec<f64> = Vec::new();
        for (slot, u) in self.units.iter().enumerate() {
            let Some(mount) = self
                .plan
                .passes
                .get(pass)
                .and_then(|p| p.get(slot))
                .copied()
                .flatten()
            else {
                continue;
            };
            for p in u.points.iter().filter(|p| p.mount == mount) {
                let g = p.g_nominal.abs();
                if !planned.iter().chain(&added).any(|m| (m - g).abs() < 0.05) {
                    added.push(g);
                }
            }
        }
        let levels = added
            .iter()
            .map(|g| format!("{g}"))
            .collect::<Vec<_>>()
            .join(", ");
        let slots = std::mem::take(&mut self.deciding.served)
            .iter()
            .map(|s| (s + 1).to_string())
            .collect::<Vec<_>>()
            .join(", ");
        if added.is_empty() && undecided == 0 {
            return Ok(());
        }
        if added.is_empty() {
            return self.emit(Event::Notice {
                message: format!(
                    "pass {}: {undecided} instrument(s) still open, and no level would help them; none added",
                    pass + 1
                ),
                wording: Some(
                    Wording::new("notice.deciding_none")
                        .with("pass", pass + 1)
                        .with("undecided", undecided),
                ),
            });
        }
        let (key, end) = match (undecided, budget_spent) {
            (0, _) => ("notice.deciding_done", "none is open".to_string()),
            (n, true) => (
                "notice.deciding_budget",
                format!(
                    "{n} still open: the budget of {} level(s) is spent",
                    added.len()
                ),
            ),
            (n, false) => (
                "notice.deciding_stuck",
                format!("{n} still open: no other level would help them"),
            ),
        };
        let message = format!(
            "pass {}: {} level(s) added by the data ({levels} g) for slot(s) {slots}; {end}",
            pass + 1,
            added.len()
        );
        self.emit(Event::Notice {
            message,
            wording: Some(
                Wording::new(key)
                    .with("pass", pass + 1)
                    .with("added", added.len())
                    .with("levels", levels)
                    .with("slots", slots)
                    .with("undecided", undecided),
            ),
        })
    }

    /// How many of the pass's instruments are open, and the level that
    /// would serve the most of them. In the last pass an instrument is
    /// open when its verdict is inconclusive; before it (no K2 yet),
    /// when a level of this pass is off its curve or its k2 here is wide
    /// ([`WIDE_FRACTION_OF_LIMIT`]). The last pass first measures what an
    /// earlier one added.
    fn next_deciding_level(&self, pass: usize) -> (usize, Option<Choice>) {
        let last_pass = pass + 1 >= self.plan.passes.len();
        let mount_in = |p: usize, slot: usize| {
            self.plan
                .passes
                .get(p)
                .and_then(|m| m.get(slot))
                .copied()
                .flatten()
        };
        let measured_in = |p: usize| -> Vec<f64> {
            let in_p = |slot: usize| mount_in(p, slot);
            (0..self.units.len())
                .flat_map(|s| {
                    let mount = in_p(s);
                    self.units[s]
                        .points
                        .iter()
                        .filter(move |pt| {
                            mount.is_some() && Some(pt.mount) == mount && pt.setpoint_c.is_none()
                        })
                        .map(|pt| pt.g_nominal.abs())
                })
                .collect()
        };
        let measured = measured_in(pass);
        let in_pass = |slot: usize| mount_in(pass, slot);
        let records = self.records(true, None);
        let live: Vec<&UnitRecord> = records
            .iter()
            .filter(|r| in_pass(r.slot).is_some() && self.live(r.slot))
            .collect();
        // In the last pass, a level flagged in most of its instruments is
        // the table's (the learned signature corrects it and it cancels
        // from K2), not an instrument's own. Before it the two cannot be
        // told apart (the signature needs both mountings): a dip met at
        // the table's level is an instrument's too.
        let mut flagged_count: BTreeMap<i64, usize> = BTreeMap::new();
        for r in &live {
            for g in flagged_levels(r, in_pass(r.slot).unwrap_or(Mount::P)) {
                *flagged_count.entry(tenths(g)).or_default() += 1;
            }
        }
        let the_tables = |g: f64| {
            last_pass && 2 * flagged_count.get(&tenths(g)).copied().unwrap_or(0) > live.len()
        };
        // In the last pass, the levels an earlier pass added come first:
        // K2 takes the table out only where both mountings were measured.
        if last_pass {
            let earlier: Vec<f64> = (0..pass).flat_map(measured_in).collect();
            if let Some(&g) = earlier
                .iter()
                .find(|g| !measured.iter().any(|m| (*m - **g).abs() < 0.05))
            {
                let open = live
                    .iter()
                    .filter(|r| r.outcome == Outcome::Inconclusive)
                    .count();
                return (
                    open,
                    Some(Choice {
                        g_nominal: g,
                        slots: live.iter().map(|r| r.slot).collect(),
                        beside_g: Vec::new(),
                        mirrored: true,
                    }),
                );
            }
        }
        let wide_u95 = WIDE_FRACTION_OF_LIMIT * self.plan.plan.limits.k2_max_ug_per_g2;
        let mut undecided = 0;
        let mut needs = Needs::default();
        for r in &live {
            let Some(mount) = in_pass(r.slot) else {
                continue;
            };
            // The instrument's own: not the table's, and (when the other
            // mounting is measured) not flagged there at the same level.
            let elsewhere: Vec<f64> = [Mount::P, Mount::N]
                .into_iter()
                .filter(|m| *m != mount)
                .flat_map(|m| flagged_levels(r, m))
                .collect();
            let levels: Vec<f64> = flagged_levels(r, mount)
                .into_iter()
                .filter(|g| !the_tables(*g) && !elsewhere.iter().any(|e| (e - g).abs() < 0.05))
                .collect();
            let wide = mounting_k2_u95(r, mount).is_none_or(|u| u > wide_u95);
            let open = if last_pass {
                r.outcome == Outcome::Inconclusive
            } else {
                !levels.is_empty() || wide
            };
            if open {
                undecided += 1;
                if wide {
                    needs.wide.insert(r.slot);
                }
                if !levels.is_empty() {
                    needs.beside.insert(r.slot, levels);
                }
            }
        }
        (undecided, choose(&needs, &measured, self.plan.plan.range_g))
    }
}

/// A level in tenths of a g, to compare levels.
fn tenths(g: f64) -> i64 {
    (g * 10.0).round() as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn beside(pairs: &[(usize, &[f64])]) -> Needs {
        Needs {
            beside: pairs.iter().map(|(s, g)| (*s, g.to_vec())).collect(),
            wide: BTreeSet::new(),
        }
    }

    #[test]
    fn the_level_chosen_is_halfway_to_a_neighbour_and_serves_the_most_instruments() {
        let measured = [0.0, 10.0, 25.0, 45.0, 60.0, 70.0];
        let needs = beside(&[(0, &[25.0]), (3, &[45.0]), (5, &[25.0])]);
        let c = choose(&needs, &measured, 70.0).expect("a level");
        // 25 g flagged twice: 17.5 and 35 serve two each; 35 also serves 45's slot.
        assert_eq!(c.g_nominal, 35.0);
        assert_eq!(c.slots, vec![0, 3, 5]);
        assert_eq!(c.beside_g, vec![25.0, 45.0]);
    }

    #[test]
    fn no_level_nearer_than_the_spacing_to_a_measured_one_nor_over_the_top() {
        // 61 g is 4 g below: halfway is 2 g from each, too near; 70 g is 5 above.
        let needs = beside(&[(1, &[65.0])]);
        let c = choose(&needs, &[0.0, 61.0, 65.0, 70.0], 70.0).expect("above is far enough");
        assert_eq!(c.g_nominal, 67.5);
        let tight = [0.0, 60.0, 63.0, 65.0, 67.0, 70.0];
        assert_eq!(choose(&needs, &tight, 70.0), None);
        let c = choose(&beside(&[(2, &[70.0])]), &[0.0, 50.0, 70.0], 70.0).expect("below the top");
        assert_eq!(c.g_nominal, 60.0);
    }

    #[test]
    fn a_wide_instrument_gets_the_widest_gap_and_nothing_needed_chooses_nothing() {
        let mut needs = Needs::default();
        needs.wide.insert(4);
        let c = choose(&needs, &[0.0, 14.0, 28.0, 42.0, 56.0, 70.0, 7.0], 70.0).expect("a gap");
        assert_eq!(
            c.g_nominal, 63.0,
            "the widest gaps are 14 g; the highest first"
        );
        assert!(c.beside_g.is_empty());
        assert_eq!(choose(&Needs::default(), &[0.0, 10.0, 70.0], 70.0), None);
    }
}
