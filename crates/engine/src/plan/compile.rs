//! A plan checked against a station (rate limit, fixtures' rating, chamber,
//! temperature limit) and compiled into the list of steps one executor runs.

use super::{
    CompiledPlan, Direction, Fixture, ModelOrder, Mount, PlanError, StationConfig, Step, TestPlan,
    centrifuge,
};

/// The longest reason a plan's exclusion may give [characters], as on
/// the web page's exclusion of a finished run.
pub const MAX_EXCLUSION_REASON_CHARS: usize = 500;

impl TestPlan {
    /// Check the plan against the station and compile it into steps. This
    /// is where a plan that would exceed the centrifuge's rate limit or the
    /// fixtures' rating at any position is refused, before anything moves.
    pub fn compile(&self, station: &StationConfig) -> Result<CompiledPlan, PlanError> {
        let err = |key: &str, problem: String| {
            Err(PlanError {
                key: key.into(),
                problem,
            })
        };
        self.validate()?;
        if !self.temperatures_c.is_empty() {
            if station.chamber.is_none() {
                return err(
                    "temperatures_c",
                    "the station has no [chamber] to reach them; add one to the station config or leave temperatures_c out".into(),
                );
            }
            let (lo, hi) = spinbench_devices::chamber::SETPOINT_RANGE_C;
            if let Some(t) = self
                .temperatures_c
                .iter()
                .find(|t| !(t.is_finite() && (lo..=hi).contains(*t)))
            {
                return err(
                    "temperatures_c",
                    format!(
                        "{t} is not a chamber temperature from {lo} to {hi} °C (SETPOINT_RANGE_C)"
                    ),
                );
            }
            // A setpoint the station's own limit would stop the run at:
            // refused before anything moves, not faulted after a pass.
            if let Some(max) = station.temperature.instrument_max_c
                && let Some(t) = self.temperatures_c.iter().find(|t| **t >= max)
            {
                return err(
                    "temperatures_c",
                    format!(
                        "{t} °C reaches the station's temperature.instrument_max_c = {max} °C, which stops a run; leave it out or raise the limit if the instruments allow"
                    ),
                );
            }
            if self.temperatures_c.len() > crate::bounds::MAX_TEMPERATURES {
                return err(
                    "temperatures_c",
                    format!(
                        "{} temperatures; at most {} (MAX_TEMPERATURES)",
                        self.temperatures_c.len(),
                        crate::bounds::MAX_TEMPERATURES
                    ),
                );
            }
            if let Err((key, problem)) = self.soak.validate() {
                return err(&key, problem);
            }
        }
        if !matches!(self.tumble_positions, 2 | 4) {
            return err(
                "tumble_positions",
                format!(
                    "{} is not 2 (IA up, IA down) or 4 (also the two cross-axis positions)",
                    self.tumble_positions
                ),
            );
        }
        let order = ModelOrder::from_degree(self.order).ok_or_else(|| PlanError {
            key: "order".into(),
            problem: format!("{} is not 1, 2 or 3", self.order),
        })?;
        if self.is_auto() {
            return err(
                "levels",
                "\"auto\" is designed when a run starts on a station (spinbench run, or spinbench plan design to see the design first)".into(),
            );
        }
        if self.target_k2_u95_ug_per_g2.is_some() && self.prediction.is_none() {
            return err(
                "target_k2_u95_ug_per_g2",
                "a target is for levels = \"auto\"; leave it out with explicit levels".into(),
            );
        }
        let levels = self.level_table();
        if levels.first() != Some(&0.0) {
            return err("levels", "the levels must start at 0 g".into());
        }
        if levels.iter().any(|g| !g.is_finite()) || levels.windows(2).any(|w| w[1] <= w[0]) {
            return err(
                "levels",
                "the levels must be finite and strictly ascending".into(),
            );
        }
        if levels.len() < 6 {
            return err(
                "levels",
                format!(
                    "{} levels; method.md §3.3 asks for at least 6 from 0 to m",
                    levels.len()
                ),
            );
        }
        for (i, e) in self.exclusions.iter().enumerate() {
            let key = format!("exclusions[{i}]");
            if e.reason.trim().is_empty() {
                return err(
                    &key,
                    "a reason is required: nothing is excluded without one".into(),
                );
            }
            // The same rules as an exclusion made on a finished run's page.
            if let Err(why) = crate::bounds::reason_text(&e.reason, MAX_EXCLUSION_REASON_CHARS) {
                return err(&format!("{key}.reason"), why.to_string());
            }
            if !levels.contains(&e.g) {
                return err(
                    &key,
                    format!("{} g is not one of the plan's levels {levels:?}", e.g),
                );
            }
            if let Some(serial) = &e.serial
                && !self.serials.values().any(|s| {
                    let s = s.trim();
                    s == serial
                        || s.strip_prefix("P:")
                            .or_else(|| s.strip_prefix("N:"))
                            .map(str::trim)
                            == Some(serial.as_str())
                })
            {
                return err(
                    &key,
                    format!("no instrument '{serial}' in the plan's serials"),
                );
            }
        }
        if levels.len() < usize::from(self.order) + 2 {
            return err(
                "levels",
                format!(
                    "{} levels cannot fit an order-{} model with a residual",
                    levels.len(),
                    self.order
                ),
            );
        }
        if self.dwell.seconds < 2
            || self.dwell.min_seconds < 2
            || self.dwell.max_seconds < self.dwell.min_seconds
        {
            return err(
                "dwell",
                "need seconds ≥ 2 and 2 ≤ min_seconds ≤ max_seconds".into(),
            );
        }
        if self.stability.hold_s < 3 {
            return err(
                "stability.hold_s",
                "the drift test needs at least 3 seconds of hold".into(),
            );
        }
        if !(self.limits.k2_max_ug_per_g2 > 0.0
            && (0.0..=1.0).contains(&self.limits.marginal_fraction))
        {
            return err(
                "limits",
                "need k2_max_ug_per_g2 > 0 and 0 ≤ marginal_fraction ≤ 1".into(),
            );
        }

        // Serials and their mountings.
        let slots = station.slots();
        let mut serials = vec![None; slots];
        let mut fixed: Vec<Option<Mount>> = vec![None; slots];
        for (key, serial) in &self.serials {
            let slot: usize = key
                .parse()
                .ok()
                .filter(|s| (1..=slots).contains(s))
                .ok_or_else(|| PlanError {
                    key: format!("serials.{key}"),
                    problem: format!("slots are numbered 1 to {slots}"),
                })?;
            // "01" or "+1" beside "1" would name one slot twice and one
            // instrument would be dropped without a word: only the plain
            // number names a slot.
            if key != &slot.to_string() {
                return err(
                    &format!("serials.{key}"),
                    format!("write the slot as {slot} (no sign, no leading zero)"),
                );
            }
            let (mount, bare) = match serial.split_once(':') {
                Some((m, rest)) => match Mount::parse(m) {
                    Some(mount) => (Some(mount), rest.trim()),
                    None => {
                        return err(
                            &format!("serials.{key}"),
                            format!("'{m}:' is not a mounting prefix; use P: or N:"),
                        );
                    }
                },
                None => (None, serial.trim()),
            };
            let normal = match crate::bounds::person_text(bare) {
                Ok(n) => n,
                Err(why) => return err(&format!("serials.{key}"), why.to_string()),
            };
            let bare = normal.as_str();
            if bare.is_empty() {
                return err(
                    &format!("serials.{key}"),
                    "the serial number is empty".into(),
                );
            }
            // One instrument, one slot: its history must not mix two.
            if let Some(other) = serials.iter().position(|s| s.as_deref() == Some(bare)) {
                return err(
                    &format!("serials.{key}"),
                    format!(
                        "'{bare}' is already in slot {}; an instrument takes one slot",
                        other + 1
                    ),
                );
            }
            // Latin and Cyrillic (or Greek) letters in one
            // serial, or two serials that look alike (`SN-A1`, `SN-А1`), are
            // a typing slip or a forgery, never two instruments.
            if let Some(why) = crate::bounds::mixed_script(bare) {
                return err(&format!("serials.{key}"), why);
            }
            if let Some(other) = serials.iter().position(|s| {
                s.as_deref()
                    .is_some_and(|s| crate::bounds::look_alike(s, bare))
            }) {
                return err(
                    &format!("serials.{key}"),
                    format!(
                        "'{bare}' looks like '{}' in slot {} but is written with other characters ({}); type both serials again from their labels",
                        serials[other].as_deref().unwrap_or_default(),
                        other + 1,
                        crate::bounds::non_ascii(bare)
                    ),
                );
            }
            serials[slot - 1] = Some(bare.to_string());
            fixed[slot - 1] = mount;
        }
        if serials.iter().all(Option::is_none) {
            return err("serials", "no instrument in the plan".into());
        }
        let passes: Vec<Vec<Option<Mount>>> = if !self.passes.is_empty() {
            self.passes
                .iter()
                .map(|&m| {
                    (0..slots)
                        .map(|i| {
                            serials[i]
                                .as_ref()
                                .and(fixed[i].map_or(Some(m), |f| (f == m).then_some(m)))
                        })
                        .collect()
                })
                .collect()
        } else if serials
            .iter()
            .zip(&fixed)
            .all(|(s, f)| s.is_none() || f.is_some())
        {
            // Every serial carries its mounting: one mixed pass.
            vec![fixed.clone()]
        } else {
            vec![
                (0..slots)
                    .map(|i| serials[i].as_ref().and(Some(fixed[i].unwrap_or(Mount::P))))
                    .collect(),
            ]
        };
        // A pass nobody takes part in (every instrument's prefix fixes the
        // other mounting) is not spun: the table would run its levels for nothing.
        let passes: Vec<Vec<Option<Mount>>> = passes
            .into_iter()
            .filter(|p| p.iter().any(Option::is_some))
            .collect();

        // Safety: every level within the rate limit and every position within its rating.
        let max_rate = station.centrifuge.max_rate_deg_s().map_err(|e| PlanError {
            key: e.key,
            problem: e.problem,
        })?;
        let g = station.g_local_m_s2;
        let r0 = station.arm.radius_m;
        for &level in &levels {
            let w =
                centrifuge::rate_for_acceleration_rad_s(level, r0, g).map_err(|e| PlanError {
                    key: "levels".into(),
                    problem: e.to_string(),
                })?;
            if w.to_degrees() > max_rate {
                return err(
                    "range_g",
                    format!(
                        "{level} g needs {:.1} deg/s at R0 = {r0} m, above the centrifuge's limit of {max_rate} deg/s; lower the range",
                        w.to_degrees()
                    ),
                );
            }
            for i in 0..slots {
                let at = level * station.drawing_radius_m(i) / r0;
                if at > station.arm.max_g * 1.001 {
                    return err(
                        "range_g",
                        format!(
                            "{level} g puts {at:.2} g on position {} (rated {} g, arm.max_g); lower the range",
                            i + 1,
                            station.arm.max_g
                        ),
                    );
                }
            }
        }

        let top = levels.last().copied().unwrap_or(0.0);
        if let Some(down) = &self.down_levels {
            if !self.up_down {
                return err(
                    "down_levels",
                    "down_levels needs up_down = true (the way down)".into(),
                );
            }
            if let Some(g) = down.iter().find(|g| !levels.contains(g) || **g >= top) {
                return err(
                    "down_levels",
                    format!("{g} g is not one of the plan's levels below the top {top} g"),
                );
            }
            if (1..down.len()).any(|i| down[..i].contains(&down[i])) {
                return err("down_levels", "a level is listed twice".into());
            }
        }

        // The steps.
        let sequence = self.level_sequence();
        let all = |f: Fixture| {
            serials
                .iter()
                .map(|s| s.as_ref().map(|_| f))
                .collect::<Vec<_>>()
        };
        let mut steps = vec![
            Step::PowerOn,
            Step::CheckAlive,
            Step::WarmUp {
                seconds: self.warmup_s.max(0.0),
            },
            Step::Mount {
                fixtures: all(Fixture::Up),
            },
            Step::Tumble { up: true },
            Step::Mount {
                fixtures: all(Fixture::Down),
            },
            Step::Tumble { up: false },
        ];
        if self.tumble_positions == 4 {
            for as_on_arm in [true, false] {
                steps.push(Step::Mount {
                    fixtures: all(Fixture::Crosswise { as_on_arm }),
                });
                steps.push(Step::CrossTumble { as_on_arm });
            }
        }
        let orders = crate::soak::visiting_order(
            &self.temperatures_c,
            passes.len(),
            station.temperature.ambient_c,
        );
        let reference =
            crate::soak::reference_c(&self.temperatures_c, station.temperature.ambient_c);
        for (p, pass) in passes.iter().enumerate() {
            steps.push(Step::Mount {
                fixtures: pass.iter().map(|m| m.map(Fixture::Arm)).collect(),
            });
            // Without temperatures: one visit at the room's.
            let temperatures: Vec<Option<f64>> = match orders.get(p) {
                Some(o) if !o.is_empty() => o.iter().copied().map(Some).collect(),
                _ => vec![None],
            };
            for setpoint in temperatures {
                if let Some(setpoint_c) = setpoint {
                    steps.push(Step::Soak { setpoint_c });
                }
                // The radius at the reference temperature (or the room's),
                // which each pass visits first (see `soak::visiting_order`).
                if setpoint == reference {
                    steps.push(Step::Radius { pass: p });
                }
                let mut passed_top = false;
                for &level in &sequence {
                    let direction = if passed_top {
                        Direction::Down
                    } else {
                        Direction::Up
                    };
                    if level == top {
                        passed_top = true;
                    }
                    steps.push(Step::Level {
                        pass: p,
                        g_nominal: level,
                        direction,
                    });
                }
                // Measuring until the verdict is certain, while the pass's
                // instruments are still mounted (refused with temperatures).
                if let Some(q) = &self.sequential {
                    for round in 0..q.max_levels_per_pass as usize {
                        steps.push(Step::Decide { pass: p, round });
                    }
                }
                steps.push(Step::Stop);
            }
        }
        Ok(CompiledPlan {
            plan: self.clone(),
            serials,
            passes,
            steps,
            order,
            table_prior: None,
        })
    }
}
