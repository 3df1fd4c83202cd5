//! An engineer's exclusion of a level from a reduction, with the reason and
//! who made it. Exclusions are applied before the fits and always reported
//! beside them: nothing is ever excluded silently.

use crate::AnalysisError;
use crate::points::Mount;
use crate::points::UnitPoints;
use serde::{Deserialize, Serialize};

/// One level left out of the reduction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LevelExclusion {
    /// Only this unit (`None`: every unit).
    pub unit: Option<String>,
    /// The mounting.
    pub mount: Mount,
    /// The level, |g_nominal| [g].
    pub g: f64,
    /// Why (required).
    pub reason: String,
    /// Who excluded it.
    pub by: String,
    /// Readings it removed (filled in when applied).
    #[serde(default)]
    pub points_removed: usize,
}

impl LevelExclusion {
    /// Parse `P:30` or `SN12:P:30` with the reason and who.
    pub fn parse(text: &str, reason: &str, by: &str) -> Result<LevelExclusion, AnalysisError> {
        let bad = |why: &str| {
            AnalysisError::InvalidInput(format!(
                "exclusion '{text}': {why}; write MOUNT:LEVEL (e.g. P:30) or UNIT:MOUNT:LEVEL (e.g. SN12:N:65)"
            ))
        };
        let parts: Vec<&str> = text.trim().split(':').collect();
        let (unit, mount, level) = match parts.as_slice() {
            [m, g] => (None, *m, *g),
            [u, m, g] if !u.is_empty() => (Some(u.to_string()), *m, *g),
            _ => return Err(bad("not two or three parts")),
        };
        let mount = Mount::parse(mount).ok_or_else(|| bad("the mounting is P or N"))?;
        let g: f64 = level
            .trim()
            .parse()
            .map_err(|_| bad("the level is a number of g"))?;
        if !(g.is_finite() && (0.0..=1e4).contains(&g)) {
            return Err(bad("the level is a finite number of g from 0 to 10000"));
        }
        if reason.trim().is_empty() {
            return Err(bad(
                "a reason is required (nothing is excluded without one)",
            ));
        }
        Ok(LevelExclusion {
            unit,
            mount,
            g,
            reason: reason.trim().to_string(),
            by: by.to_string(),
            points_removed: 0,
        })
    }

    fn applies(&self, unit: &str, mount: Mount, g_nominal: f64) -> bool {
        self.unit.as_deref().is_none_or(|u| u == unit)
            && self.mount == mount
            && g_nominal.abs() == self.g
    }
}

impl std::fmt::Display for LevelExclusion {
    /// One line for `analyze` and the reports.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "EXCLUDED by {}: mounting {} level {} g{} ({} reading(s)) — reason: {}",
            self.by,
            self.mount,
            self.g,
            self.unit
                .as_deref()
                .map(|u| format!(" of unit {u}"))
                .unwrap_or_default(),
            self.points_removed,
            self.reason
        )
    }
}

/// Remove the excluded levels' readings from `units`; each exclusion's
/// `points_removed` says how many it removed (0: it matched nothing).
pub fn apply(units: &mut [UnitPoints], exclusions: &mut [LevelExclusion]) {
    for e in exclusions.iter_mut() {
        e.points_removed = 0;
    }
    for u in units.iter_mut() {
        u.points.retain(|p| {
            match exclusions
                .iter_mut()
                .find(|e| e.applies(&u.unit, p.mount, p.g_nominal))
            {
                Some(e) => {
                    e.points_removed += 1;
                    false
                }
                None => true,
            }
        });
    }
}

/// [`apply`], refusing an exclusion that matches nothing (a typing mistake
/// must not pass as a reduction that left something out).
pub fn apply_all(
    units: &mut [UnitPoints],
    exclusions: &mut [LevelExclusion],
) -> Result<(), AnalysisError> {
    apply(units, exclusions);
    match exclusions.iter().find(|e| e.points_removed == 0) {
        Some(e) => Err(AnalysisError::InvalidInput(format!(
            "exclusion of {} {} g{}: no reading of that level in the file",
            e.mount,
            e.g,
            e.unit
                .as_deref()
                .map(|u| format!(" of unit {u}"))
                .unwrap_or_default()
        ))),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::points::Point;

    #[test]
    fn an_exclusion_needs_a_reason_removes_its_level_and_says_how_many() {
        assert!(LevelExclusion::parse("P:30", " ", "me").is_err());
        assert!(LevelExclusion::parse("X:30", "r", "me").is_err());
        assert!(LevelExclusion::parse("P:inf", "r", "me").is_err());
        assert!(LevelExclusion::parse("P", "r", "me").is_err());
        let point = |mount, g| Point {
            mount,
            g_nominal: g,
            g_applied: g,
            output: g,
            direction: None,
        };
        let mut units = vec![UnitPoints {
            unit: "A".into(),
            run: None,
            points: vec![
                point(Mount::P, 30.0),
                point(Mount::P, 35.0),
                point(Mount::P, 30.0),
                point(Mount::N, 30.0),
            ],
        }];
        let mut ex = vec![LevelExclusion::parse("A:P:30", "resonance", "eng").expect("parse")];
        apply_all(&mut units, &mut ex).expect("applied");
        assert_eq!(units[0].points.len(), 2);
        assert_eq!(ex[0].points_removed, 2);
        assert_eq!(
            (ex[0].reason.as_str(), ex[0].by.as_str()),
            ("resonance", "eng")
        );
        // Nothing left to match: refused.
        assert!(apply_all(&mut units, &mut ex).is_err());
    }
}
