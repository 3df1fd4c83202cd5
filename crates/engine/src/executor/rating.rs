//! The table's speed bounded by what the station measured: the configured
//! radius checked against the instruments' own radii at 1 g, and every
//! commanded rate held under the fixtures' rating at the largest radius
//! known (measured or drawn, whichever gives more g).
//!
//! Why here and not only in the plan check: the plan is checked at the
//! drawing radius, which is a number someone typed. A drawing radius of
//! 0.5 m on an arm whose fixtures sit at 0.8 m passes a 70 g plan and spins
//! the fixtures at 112 g. The radius step (1 g at the drawing radius, safe
//! on any arm) measures where the instruments really are before any level.

use super::{EngineError, Executor};
use crate::plan::Step;
use crate::record::{Reason, ReasonCode};
use spinbench_analysis::centrifuge;

/// How far the instruments' measured radius (their median over a pass) may
/// sit from the configured drawing radius before the configured radius is
/// taken as wrong and the run stopped [fraction]. A real arm's effective
/// radii differ from the drawing by millimetres (a fixture's tolerance, the
/// proof mass's offset): 1 % of 0.8 m is 8 mm. One instrument alone this
/// far off (the others agreeing with the drawing) is its fixture or its
/// reading: that instrument is set aside instead.
pub const RADIUS_TOLERANCE: f64 = 0.01;

/// The rating is enforced with this slack, as the plan check does (a level
/// of exactly `arm.max_g` is not refused for rounding).
const RATING_SLACK: f64 = 1.001;

impl Executor<'_> {
    /// The largest radius of any fixture position the station knows of [m]
    /// and its slot: every drawing radius, and every radius measured of an
    /// instrument not set aside for its radius.
    fn largest_radius_m(&self) -> (usize, f64) {
        let mut largest = (0, self.station.arm.radius_m);
        for slot in 0..self.units.len() {
            let drawn = self.station.drawing_radius_m(slot);
            let measured = self.units[slot].radius.values().copied();
            for r in std::iter::once(drawn).chain(measured) {
                if r.is_finite() && r > largest.1 {
                    largest = (slot, r);
                }
            }
        }
        largest
    }

    /// The acceleration a table rate puts on the fixture at the largest
    /// known radius [g] (method.md (3), with the Earth's rate and the arm's
    /// stretch as the points are reduced), and that radius's slot.
    fn applied_at_largest_g(&self, rate_deg_s: f64) -> (usize, f64, f64) {
        let (slot, radius_m) = self.largest_radius_m();
        let table_rad_s = rate_deg_s.to_radians();
        let w = self.station.inertial_rate_rad_s(table_rad_s);
        let stretch = self.station.stretch_factor(table_rad_s).max(1.0);
        let g = w * w * radius_m * stretch / self.station.g_local_m_s2;
        (slot, radius_m, g)
    }

    /// Refuse a rate the table's limit or the fixtures' rating does not
    /// allow at the largest known radius. Called for every nonzero rate the
    /// station commands, so no path spins the table past either.
    pub(super) fn check_rate_allowed(&self, rate_deg_s: f64) -> Result<(), EngineError> {
        if !rate_deg_s.is_finite() {
            return Err(EngineError::Rate(format!(
                "a rate of {rate_deg_s} deg/s cannot be commanded"
            )));
        }
        let max_rate = self
            .station
            .centrifuge
            .max_rate_deg_s()
            .map_err(|e| EngineError::Rate(e.to_string()))?;
        if rate_deg_s.abs() > max_rate * RATING_SLACK {
            return Err(EngineError::Rate(format!(
                "{rate_deg_s:.1} deg/s is above the centrifuge's limit of {max_rate} deg/s; \
                 the table was stopped"
            )));
        }
        let (slot, radius_m, applied_g) = self.applied_at_largest_g(rate_deg_s);
        let max_g = self.station.arm.max_g;
        if applied_g > max_g * RATING_SLACK {
            let g_nominal = centrifuge::applied_acceleration_g(
                rate_deg_s.to_radians(),
                self.station.arm.radius_m,
                self.station.g_local_m_s2,
            )
            .unwrap_or(f64::NAN);
            return Err(EngineError::OverRating {
                g_nominal,
                applied_g,
                slot: slot + 1,
                radius_m,
                max_g,
            });
        }
        Ok(())
    }

    /// After a pass's radius step: the configured radius against the
    /// measured ones (a whole pass off by more than [`RADIUS_TOLERANCE`]
    /// stops the run before its first level; one instrument off alone is set
    /// aside), then every level still to come against the rating at the
    /// largest radius now known, so a level that would be over it stops the
    /// run here, at 1 g, and not when the table gets there.
    pub(super) fn check_radii(&mut self, pass: usize) -> Result<(), EngineError> {
        let measured: Vec<(usize, f64, f64)> = (0..self.units.len())
            .filter(|&s| self.live(s))
            .filter_map(|s| {
                let mount = self.plan.passes[pass][s]?;
                let r = *self.units[s].radius.get(&mount)?;
                Some((s, r, self.station.drawing_radius_m(s)))
            })
            .collect();
        if !measured.is_empty() {
            let mut ratios: Vec<f64> = measured.iter().map(|(_, r, r0)| r / r0).collect();
            ratios.sort_by(f64::total_cmp);
            let median = ratios[ratios.len() / 2];
            if (median - 1.0).abs() > RADIUS_TOLERANCE {
                let mut radii: Vec<f64> = measured.iter().map(|(_, r, _)| *r).collect();
                radii.sort_by(f64::total_cmp);
                return Err(EngineError::RadiusMismatch {
                    measured_m: radii[radii.len() / 2],
                    configured_m: self.station.arm.radius_m,
                    tolerance_pct: RADIUS_TOLERANCE * 100.0,
                });
            }
            for &(slot, r, r0) in &measured {
                if (r / r0 - 1.0).abs() > RADIUS_TOLERANCE {
                    // Its radius no longer bounds the speed: it is not measured.
                    if let Some(mount) = self.plan.passes[pass][slot] {
                        self.units[slot].radius.remove(&mount);
                    }
                    self.fail_unit(
                        slot,
                        Reason::new(
                            ReasonCode::RadiusFailed,
                            format!(
                                "its radius measured {r:.4} m, {:.1} % from its position's {r0} m \
                                 while the others agree with theirs: check its fixture",
                                (r / r0 - 1.0) * 100.0
                            ),
                        )
                        .with("variant", "off_drawing")
                        .with("radius", format!("{r:.4}"))
                        .with("drawing", r0),
                    )?;
                }
            }
        }
        self.check_levels_to_come()
    }

    /// Every level not yet done, against the rating at the largest known radius.
    fn check_levels_to_come(&self) -> Result<(), EngineError> {
        let r0 = self.station.arm.radius_m;
        let g = self.station.g_local_m_s2;
        for (index, step) in self.plan.steps.iter().enumerate() {
            let Step::Level { g_nominal, .. } = step else {
                continue;
            };
            if self.progress.completed.contains(&index) {
                continue;
            }
            let w = centrifuge::rate_for_acceleration_rad_s(*g_nominal, r0, g)
                .map_err(|e| EngineError::Rate(e.to_string()))?;
            self.check_rate_allowed(w.to_degrees())
                .map_err(|e| match e {
                    EngineError::OverRating {
                        applied_g,
                        slot,
                        radius_m,
                        max_g,
                        ..
                    } => EngineError::OverRating {
                        g_nominal: *g_nominal,
                        applied_g,
                        slot,
                        radius_m,
                        max_g,
                    },
                    other => other,
                })?;
        }
        Ok(())
    }
}
