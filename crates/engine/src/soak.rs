//! Temperatures in a plan: when a chamber temperature
//! counts as reached (`[soak]`), and the order the temperatures are visited
//! in so the chamber and the operator change as little as possible.

use serde::{Deserialize, Serialize};

/// `[soak]`: a temperature is reached when the chamber's air is within
/// `tolerance_c` of the setpoint and no instrument's temperature moved more
/// than `tolerance_c` over the last `window_s` seconds; not within
/// `max_soak_s` stops the run.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SoakConfig {
    /// Band around the setpoint, and the instruments' largest change over the window [°C].
    pub tolerance_c: f64,
    /// How long everything must stay in band [s].
    pub window_s: u32,
    /// The longest soak before the run stops [s].
    pub max_soak_s: u32,
}

impl Default for SoakConfig {
    fn default() -> Self {
        SoakConfig {
            tolerance_c: 0.5,
            window_s: 300,
            max_soak_s: 4 * 3600,
        }
    }
}

impl SoakConfig {
    /// Whether it is the default (a plan file without `[soak]` stays so).
    pub fn is_default(&self) -> bool {
        *self == SoakConfig::default()
    }

    /// Check every number against its bound; `Err((key, problem))`.
    pub fn validate(&self) -> Result<(), (String, String)> {
        use crate::bounds::{MAX_SETTLE_S, MAX_TEMPERATURE_CHANGE_C};
        if !(self.tolerance_c.is_finite()
            && self.tolerance_c > 0.0
            && self.tolerance_c <= MAX_TEMPERATURE_CHANGE_C)
        {
            return Err((
                "soak.tolerance_c".into(),
                format!(
                    "{} is not a band from 0 to {MAX_TEMPERATURE_CHANGE_C} °C (MAX_TEMPERATURE_CHANGE_C)",
                    self.tolerance_c
                ),
            ));
        }
        for (key, v) in [
            ("soak.window_s", self.window_s),
            ("soak.max_soak_s", self.max_soak_s),
        ] {
            if !(1..=MAX_SETTLE_S).contains(&v) {
                return Err((
                    key.into(),
                    format!("{v} is not from 1 to {MAX_SETTLE_S} s (MAX_SETTLE_S)"),
                ));
            }
        }
        if self.window_s > self.max_soak_s {
            return Err((
                "soak.window_s".into(),
                format!(
                    "{} s is longer than soak.max_soak_s = {} s: no soak could ever finish",
                    self.window_s, self.max_soak_s
                ),
            ));
        }
        Ok(())
    }
}

/// The plan's temperature nearest the laboratory's `room_c`: the reference,
/// where each pass finds its radius and the outcome is graded.
pub fn reference_c(temperatures_c: &[f64], room_c: f64) -> Option<f64> {
    temperatures_c
        .iter()
        .copied()
        .min_by(|a, b| (a - room_c).abs().total_cmp(&(b - room_c).abs()))
}

/// The temperatures of each pass, in the order visited. Each pass begins
/// at the reference temperature: the radius is found there, since the
/// tumble that calibrates the 1 g reading was taken at room temperature (a
/// radius found at another temperature would take the scale factor's change
/// with temperature for a radius change, and that change would vanish from
/// k1). The other temperatures follow ascending in even passes and
/// descending in odd ones, so consecutive passes do not repeat one sweep.
/// Within that constraint this is the fewest chamber transitions: one to
/// the reference and one per other temperature.
pub fn visiting_order(temperatures_c: &[f64], passes: usize, room_c: f64) -> Vec<Vec<f64>> {
    let mut ascending = temperatures_c.to_vec();
    ascending.sort_by(f64::total_cmp);
    ascending.dedup();
    let Some(reference) = reference_c(&ascending, room_c) else {
        return vec![Vec::new(); passes];
    };
    let others: Vec<f64> = ascending
        .iter()
        .copied()
        .filter(|&t| t != reference)
        .collect();
    (0..passes)
        .map(|p| {
            let mut order = vec![reference];
            if p % 2 == 0 {
                order.extend(others.iter().copied());
            } else {
                order.extend(others.iter().rev().copied());
            }
            order
        })
        .collect()
}

/// The chamber's transitions a visiting order makes from `start_c` (the room).
pub fn transitions(order: &[Vec<f64>], start_c: f64) -> usize {
    let mut at = start_c;
    let mut n = 0;
    for t in order.iter().flatten() {
        if *t != at {
            n += 1;
            at = *t;
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_pass_begins_at_the_reference_and_makes_one_transition_per_temperature() {
        let order = visiting_order(&[70.0, -40.0, 25.0], 2, 23.0);
        assert_eq!(
            order,
            vec![vec![25.0, -40.0, 70.0], vec![25.0, 70.0, -40.0]]
        );
        assert_eq!(transitions(&order, 23.0), 6);
        // Every order that begins each pass at the reference: none fewer.
        let others = [-40.0, 70.0];
        for a in [[0, 1], [1, 0]] {
            for b in [[0, 1], [1, 0]] {
                let other = vec![
                    vec![25.0, others[a[0]], others[a[1]]],
                    vec![25.0, others[b[0]], others[b[1]]],
                ];
                assert!(transitions(&other, 23.0) >= 6, "{other:?}");
            }
        }
        assert_eq!(
            reference_c(&[-40.0, 70.0], 23.0),
            Some(70.0),
            "nearest the room"
        );
    }

    #[test]
    fn a_soak_window_longer_than_the_longest_soak_is_refused() {
        let s = SoakConfig {
            window_s: 600,
            max_soak_s: 300,
            ..SoakConfig::default()
        };
        assert_eq!(
            s.validate().err().map(|e| e.0),
            Some("soak.window_s".into())
        );
        let s = SoakConfig {
            tolerance_c: f64::NAN,
            ..SoakConfig::default()
        };
        assert!(s.validate().is_err());
    }
}
