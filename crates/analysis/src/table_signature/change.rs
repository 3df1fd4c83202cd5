//! Whether the table is still the one the earlier runs learned
//! (docs/method.md §6, "A learned centrifuge checks itself").
//!
//! A resonance moves when a fixture or the arm's balance is changed, goes
//! when it is repaired, shrinks when a mount is tightened. Pooled with the
//! earlier runs, the run's correction would then take out a resonance that
//! is gone and never the new one. So each run's own signature (its
//! measurement alone) is tested level by level against the earlier runs'
//! pooled one before they are pooled: a difference larger than
//! [`CHANGE_Z`] standard errors at any level (Bonferroni over about twenty
//! levels at a family-wise 10⁻⁴ is 4.6) is a change. The standard error of
//! the difference is the two signatures' own, and a share
//! [`CHANGE_RELATIVE`] of the larger of the two: each run divides its
//! mountings by couplings it estimates itself, which moves a 16,000 µg
//! resonance by up to about 1 % from run to run on an unchanged table.
//! After a change the run learns alone and its signature says where the
//! table changed; the next runs pool only the runs since.

use super::{SE_FLOOR_UG, SignatureLevel};
use serde::{Deserialize, Serialize};

/// A level at which two signatures differ by more than this many standard
/// errors shows a changed table.
pub const CHANGE_Z: f64 = 5.0;

/// The share of a signature's value counted into the standard error of a
/// difference (the run-to-run spread of the couplings' normalisation).
pub const CHANGE_RELATIVE: f64 = 0.03;

/// A run whose own signature disagrees with the earlier runs on the same
/// table: the table changed, and the run's correction rests on it alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SignatureChange {
    /// The levels at which the run's signature left the earlier runs' [g],
    /// ascending.
    pub levels_g: Vec<f64>,
    /// The largest difference, in standard errors of the difference.
    pub largest_z: f64,
    /// The earlier runs set aside.
    pub earlier_runs: usize,
}

impl SignatureChange {
    /// The levels as the operator reads them ("40 g, 55 g").
    pub fn levels_shown(&self) -> String {
        self.levels_g
            .iter()
            .map(|g| format!("{g} g"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// The levels at which the signature `own` differs from the pooled
/// `(level [g], signature [µg], standard error [µg])` by more than
/// [`CHANGE_Z`] standard errors: (level [g], difference in standard
/// errors, difference [µg]), ascending by level. Levels only one of them
/// measured are not compared.
pub fn disagreement(pooled: &[(f64, f64, f64)], own: &[SignatureLevel]) -> Vec<(f64, f64, f64)> {
    let mut out: Vec<(f64, f64, f64)> = own
        .iter()
        .filter_map(|l| {
            let &(_, ps, pse) = pooled.iter().find(|(g, _, _)| *g == l.g)?;
            let scale = CHANGE_RELATIVE * ps.abs().max(l.residual_ug.abs());
            let se =
                (l.se_ug.max(SE_FLOOR_UG).powi(2) + pse.max(SE_FLOOR_UG).powi(2) + scale.powi(2))
                    .sqrt();
            let difference_ug = l.residual_ug - ps;
            let z = difference_ug.abs() / se;
            (z.is_finite() && z > CHANGE_Z).then_some((l.g, z, difference_ug))
        })
        .collect();
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// The change that the disagreement `off` ([`disagreement`]) with a prior
/// of `earlier_runs` runs shows, `None` when there is none. A moved
/// resonance moves the polynomial's residuals at every level a little;
/// the table changed where the difference is largest (at least half the
/// largest, in µg).
pub fn change_of(off: &[(f64, f64, f64)], earlier_runs: usize) -> Option<SignatureChange> {
    let largest_ug = off.iter().fold(0.0_f64, |m, (_, _, d)| m.max(d.abs()));
    (!off.is_empty()).then(|| SignatureChange {
        levels_g: off
            .iter()
            .filter(|(_, _, d)| d.abs() >= 0.5 * largest_ug)
            .map(|(g, _, _)| *g)
            .collect(),
        largest_z: off.iter().fold(0.0_f64, |m, (_, z, _)| m.max(*z)),
        earlier_runs,
    })
}
