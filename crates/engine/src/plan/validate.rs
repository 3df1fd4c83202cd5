//! A plan checked on its own, against the named bounds (`crate::bounds`),
//! before it is compared with a station.

use super::{LevelTable, PlanError, TestPlan};

impl TestPlan {
    /// Check every number and name of the plan against its named bound
    /// ([`crate::bounds`]) before anything is allocated in proportion to
    /// it: finite, of the right sign, within the bound.
    pub fn validate(&self) -> Result<(), PlanError> {
        use crate::bounds::*;
        for (key, text) in [("name", &self.name), ("operator", &self.operator)] {
            if text.chars().count() > MAX_NAME_CHARS || text.chars().any(char::is_control) {
                return Err(at(key)(format!(
                    "'{}': at most {MAX_NAME_CHARS} characters, no control characters (MAX_NAME_CHARS)",
                    shown(text)
                )));
            }
        }
        if let Some(id) = &self.retest_of
            && !crate::bounds::is_run_id(id)
        {
            return Err(at("retest_of")(format!(
                "'{}' is not a run identifier (1 to 64 letters, digits, '-' or '_')",
                shown(id)
            )));
        }
        for (slot, serial) in &self.serials {
            if slot.len() > 8 {
                return Err(at("serials")(format!(
                    "'{}' is not a slot number",
                    shown(slot)
                )));
            }
            if serial.chars().count() > MAX_NAME_CHARS || serial.chars().any(char::is_control) {
                return Err(at(&format!("serials.{slot}"))(format!(
                    "'{}': at most {MAX_NAME_CHARS} characters, no control characters (MAX_NAME_CHARS)",
                    shown(serial)
                )));
            }
        }
        check_positive(self.range_g, MAX_LEVEL_G, "g", "MAX_LEVEL_G").map_err(at("range_g"))?;
        if let Some(t) = self.target_k2_u95_ug_per_g2 {
            check_positive(t, MAX_FIGURE_LIMIT, "µg/g²", "MAX_FIGURE_LIMIT")
                .map_err(at("target_k2_u95_ug_per_g2"))?;
        }
        if let Some(down) = &self.down_levels {
            if down.len() > MAX_LEVELS {
                return Err(at("down_levels")(format!(
                    "{} levels; at most {MAX_LEVELS} (MAX_LEVELS)",
                    down.len()
                )));
            }
            for (i, g) in down.iter().enumerate() {
                check(*g, 0.0..=MAX_LEVEL_G, "g", "MAX_LEVEL_G")
                    .map_err(at(&format!("down_levels[{i}]")))?;
            }
        }
        if let Some(LevelTable::List(levels)) = &self.levels {
            if levels.len() > MAX_LEVELS {
                return Err(at("levels")(format!(
                    "{} levels; at most {MAX_LEVELS} (MAX_LEVELS)",
                    levels.len()
                )));
            }
            for (i, g) in levels.iter().enumerate() {
                check(*g, 0.0..=MAX_LEVEL_G, "g", "MAX_LEVEL_G")
                    .map_err(at(&format!("levels[{i}]")))?;
            }
        }
        check(self.warmup_s, 0.0..=MAX_WARMUP_S, "s", "MAX_WARMUP_S").map_err(at("warmup_s"))?;
        let d = &self.dwell;
        for (key, v, min) in [
            ("dwell.seconds", d.seconds, 2),
            ("dwell.min_seconds", d.min_seconds, 2),
            ("dwell.max_seconds", d.max_seconds, 2),
        ] {
            if !(min..=MAX_DWELL_S).contains(&v) {
                return Err(at(key)(format!(
                    "{v} s is outside {min} to {MAX_DWELL_S} s (MAX_DWELL_S)"
                )));
            }
        }
        if d.max_seconds < d.min_seconds {
            return Err(at("dwell")(format!(
                "max_seconds {} is below min_seconds {}",
                d.max_seconds, d.min_seconds
            )));
        }
        if let Some(t) = d.sem_target_ug {
            check_positive(t, MAX_UG, "µg", "MAX_UG").map_err(at("dwell.sem_target_ug"))?;
        }
        let s = &self.stability;
        check_positive(
            s.rate_tolerance_ppm,
            MAX_RATE_TOLERANCE_PPM,
            "ppm",
            "MAX_RATE_TOLERANCE_PPM",
        )
        .map_err(at("stability.rate_tolerance_ppm"))?;
        check_positive(s.drift_limit_ug_per_s, MAX_UG, "µg/s", "MAX_UG")
            .map_err(at("stability.drift_limit_ug_per_s"))?;
        check_positive(s.noise_limit_ug, MAX_UG, "µg", "MAX_UG")
            .map_err(at("stability.noise_limit_ug"))?;
        if let Some(c) = s.temperature_change_max_c {
            check_positive(
                c,
                MAX_TEMPERATURE_CHANGE_C,
                "°C",
                "MAX_TEMPERATURE_CHANGE_C",
            )
            .map_err(at("stability.temperature_change_max_c"))?;
        }
        for (key, v, min, max, bound) in [
            (
                "stability.hold_s",
                s.hold_s,
                3,
                MAX_SETTLE_S,
                "MAX_SETTLE_S",
            ),
            (
                "stability.max_settle_s",
                s.max_settle_s,
                1,
                MAX_SETTLE_S,
                "MAX_SETTLE_S",
            ),
            (
                "stability.max_restarts",
                s.max_restarts,
                0,
                MAX_RESTARTS,
                "MAX_RESTARTS",
            ),
        ] {
            if !(min..=max).contains(&v) {
                return Err(at(key)(format!("{v} is outside {min} to {max} ({bound})")));
            }
        }
        let l = &self.limits;
        check_positive(
            l.k2_max_ug_per_g2,
            MAX_FIGURE_LIMIT,
            "µg/g²",
            "MAX_FIGURE_LIMIT",
        )
        .map_err(at("limits.k2_max_ug_per_g2"))?;
        for (key, v, unit) in [
            (
                "limits.nonlinearity_max_ppm_fs",
                l.nonlinearity_max_ppm_fs,
                "ppm FS",
            ),
            ("limits.asymmetry_max_ppm", l.asymmetry_max_ppm, "ppm"),
            ("limits.hysteresis_max_ug", l.hysteresis_max_ug, "µg"),
        ] {
            if let Some(v) = v {
                check_positive(v, MAX_FIGURE_LIMIT, unit, "MAX_FIGURE_LIMIT").map_err(at(key))?;
            }
        }
        check(l.marginal_fraction, 0.0..=1.0, "", "a fraction")
            .map_err(at("limits.marginal_fraction"))?;
        if let Some(q) = &self.sequential {
            if !(1..=MAX_SEQUENTIAL_LEVELS).contains(&q.max_levels_per_pass) {
                return Err(at("sequential.max_levels_per_pass")(format!(
                    "{} is outside 1 to {MAX_SEQUENTIAL_LEVELS} (MAX_SEQUENTIAL_LEVELS)",
                    q.max_levels_per_pass
                )));
            }
            if !self.temperatures_c.is_empty() {
                return Err(at("sequential")(
                    "a plan with temperatures_c cannot add levels (each would need every \
                     temperature again); remove [sequential] or temperatures_c",
                ));
            }
        }
        Ok(())
    }
}

/// A problem (a bound's refusal, or a sentence) at the plan's key `key`.
fn at<P: std::fmt::Display>(key: &str) -> impl FnOnce(P) -> PlanError {
    let key = key.to_string();
    move |problem: P| PlanError {
        key,
        problem: problem.to_string(),
    }
}
