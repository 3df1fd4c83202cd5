//! The dwell at a level (method.md §3.3): wait until the rate is on speed
//! for the hold time and no output drifts, then take the one-second values;
//! each instrument's own noise. The statistics are the pure functions of
//! [`super::stability`]; this is the loop around them.

use super::{EngineError, Executor, Window, stability};
use crate::event::{Event, Wording};
use crate::record::{Reason, ReasonCode};
use spinbench_analysis::Mount;
use spinbench_wire::fmu::INSTRUMENTS_PER_MODULE;
use std::collections::BTreeMap;

impl Executor<'_> {
    /// Wait for stability, then average; returns the dwell's windows. An
    /// instrument whose output keeps drifting while the rate holds (and the
    /// others settle) fails and leaves `slots`; the others go on.
    pub(super) fn acquire(&mut self, slots: &mut Vec<usize>) -> Result<Vec<Window>, EngineError> {
        let st = self.plan.plan.stability;
        let dwell = self.plan.plan.dwell;
        let mut restarts = 0;
        let mut short_restarts = 0;
        // The slope test runs on every instrument at once: its critical t
        // keeps the chance that noise alone holds the station at 1 % per
        // look (Bonferroni over the instruments; at least 3). With one
        // fixed t = 3 and 96 instruments, some instrument's noise looked
        // like drift nearly every second and a level never settled.
        let looks = slots.len().max(1) as f64;
        let t_crit = spinbench_analysis::statistics::student_t_quantile(
            1.0 - 0.01 / looks / 2.0,
            (st.hold_s as usize).saturating_sub(2),
        )
        .map_or(3.0, |t| t.max(3.0));
        'settle: loop {
            // Settle: the rate on speed for the hold time, then no output drifting.
            let mut hold: Vec<Window> = Vec::new();
            let mut waited = 0;
            // The instruments the last full hold found drifting.
            let mut drifting: Vec<usize> = Vec::new();
            loop {
                let w = self.next_window()?;
                waited += 1;
                self.emit(Event::Progress {
                    phase: "settling".into(),
                    done: hold.len() as u32,
                    of: st.hold_s,
                })?;
                if self.on_speed(w.rate_deg_s) {
                    hold.push(w);
                } else {
                    hold.clear();
                }
                if hold.len() >= st.hold_s as usize {
                    drifting = slots
                        .iter()
                        .copied()
                        .filter(|&s| self.drifting(s, &hold, t_crit))
                        .collect();
                    if drifting.is_empty() {
                        break;
                    }
                    hold.remove(0);
                }
                if waited > st.max_settle_s {
                    if !drifting.is_empty() && drifting.len() < slots.len() {
                        for &s in &drifting {
                            let rate = format!("{:.3}", self.demand_deg_s);
                            self.fail_unit(
                                s,
                                Reason::new(
                                    ReasonCode::Drifting,
                                    format!(
                                        "its output kept drifting for {} s at {rate} deg/s (more than stability.drift_limit_ug_per_s = {} µg/s)",
                                        st.max_settle_s, st.drift_limit_ug_per_s
                                    ),
                                )
                                .with("seconds", st.max_settle_s)
                                .with("rate", rate)
                                .with("limit", st.drift_limit_ug_per_s),
                            )?;
                        }
                        slots.retain(|s| !drifting.contains(s));
                        drifting.clear();
                        waited = 0;
                        continue;
                    }
                    return Err(EngineError::NotStable(format!(
                        "no stable speed and outputs within {} s at {:.3} deg/s (stability.max_settle_s)",
                        st.max_settle_s, self.demand_deg_s
                    )));
                }
            }
            // Average: n values, a rate excursion discards and restarts the point.
            let mut values: Vec<Window> = Vec::new();
            let target_n = if dwell.sem_target_ug.is_some() {
                dwell.max_seconds
            } else {
                dwell.seconds
            };
            while (values.len() as u32) < target_n {
                let w = self.next_window()?;
                if !self.on_speed(w.rate_deg_s) {
                    restarts += 1;
                    if restarts > st.max_restarts {
                        return Err(EngineError::NotStable(format!(
                            "the rate left its tolerance {restarts} times while averaging at {:.3} deg/s",
                            self.demand_deg_s
                        )));
                    }
                    continue 'settle;
                }
                values.push(w);
                self.emit(Event::Progress {
                    phase: "averaging".into(),
                    done: values.len() as u32,
                    of: target_n,
                })?;
                if let Some(target) = dwell.sem_target_ug
                    && values.len() as u32 >= dwell.min_seconds
                    && slots
                        .iter()
                        .all(|&s| self.sem_ug(s, &values).is_none_or(|sem| sem <= target))
                {
                    break;
                }
            }
            // An instrument with fewer than two whole one-second values (a
            // module's data lost — a host too busy to read its port loses
            // bytes, and a window with lost ticks is never averaged): the
            // reading is taken again before the instrument is failed for no
            // output (tumble, radius and levels alike).
            let short: Vec<String> = slots
                .iter()
                .filter(|&&s| values.iter().filter(|w| w.outputs[s].is_some()).count() < 2)
                .map(|s| (s + 1).to_string())
                .collect();
            if !short.is_empty() && short_restarts < st.max_restarts {
                short_restarts += 1;
                let short = short.join(", ");
                self.emit(Event::Notice {
                    message: format!(
                        "slot(s) {short} gave fewer than 2 whole one-second values \
                         (a module's data lost); taking the reading again ({short_restarts})"
                    ),
                    wording: Some(
                        Wording::new("notice.too_few_values")
                            .with("slots", &short)
                            .with("restarts", short_restarts),
                    ),
                })?;
                continue 'settle;
            }
            return Ok(values);
        }
    }

    pub(super) fn on_speed(&self, rate_deg_s: f64) -> bool {
        stability::on_speed(
            rate_deg_s,
            self.demand_deg_s,
            self.plan.plan.stability.rate_tolerance_ppm,
        )
    }

    /// The slope test: a drift above the limit and significant at `t_crit`.
    pub(super) fn drifting(&self, slot: usize, hold: &[Window], t_crit: f64) -> bool {
        let y: Vec<f64> = hold.iter().filter_map(|w| w.outputs[slot]).collect();
        stability::drifting(
            &y,
            self.k1(slot),
            self.plan.plan.stability.drift_limit_ug_per_s,
            t_crit,
        )
    }

    /// Each instrument's own 1-s scatter [µg], robust to what every
    /// instrument feels: the part of the output the measured rate explains
    /// (the applied acceleration of each window from its rate, (9)) is
    /// removed, so the tail of the table's settling within the rate
    /// tolerance is not taken for instrument noise; the common mode (median
    /// deviation per window) of the instruments on the same counter module is
    /// removed when there are at least three (their windows are the same
    /// ticks by construction); and the scatter is estimated from successive
    /// differences (σ = std(Δ)/√2), which ignores slow trends. A rate reading
    /// is one instant of a ripple, so the smaller of the scatter with and
    /// without the rate correction is taken.
    pub(super) fn instrument_noise_ug(
        &self,
        pass: usize,
        slots: &[usize],
        values: &[Window],
    ) -> BTreeMap<usize, f64> {
        let raw = self.scatter_ug(pass, slots, values, false);
        let corrected = self.scatter_ug(pass, slots, values, true);
        raw.into_iter()
            .map(|(s, a)| (s, corrected.get(&s).map_or(a, |&b| a.min(b))))
            .collect()
    }

    pub(super) fn scatter_ug(
        &self,
        pass: usize,
        slots: &[usize],
        values: &[Window],
        rate_corrected: bool,
    ) -> BTreeMap<usize, f64> {
        let g = self.station.g_local_m_s2;
        let mut out = BTreeMap::new();
        let mut by_module: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
        for &s in slots {
            by_module
                .entry(s / INSTRUMENTS_PER_MODULE)
                .or_default()
                .push(s);
        }
        for group in by_module.values() {
            // Series in g, per slot, over the windows where every slot of the group has a value.
            let windows: Vec<&Window> = values
                .iter()
                .filter(|w| group.iter().all(|&s| w.outputs[s].is_some()))
                .collect();
            if windows.len() < 3 {
                continue;
            }
            let series: Vec<Vec<f64>> = group
                .iter()
                .map(|&s| {
                    let mount = self.plan.passes[pass][s].unwrap_or(Mount::P);
                    let radius = self.units[s]
                        .radius
                        .get(&mount)
                        .copied()
                        .unwrap_or_else(|| self.station.drawing_radius_m(s));
                    windows
                        .iter()
                        .filter_map(|w| {
                            let y = w.outputs[s]? / self.k1(s);
                            if !rate_corrected {
                                return Some(y);
                            }
                            let rate = w.rate_deg_s.to_radians();
                            // method.md (9), signed by the mounting and the scale factor.
                            let sign = mount.input_sign() * self.k1_sign(s);
                            Some(y - sign * rate * rate * radius / g)
                        })
                        .collect()
                })
                .collect();
            for (s, scatter) in group.iter().zip(stability::own_scatter_ug(&series)) {
                out.insert(*s, scatter);
            }
        }
        out
    }

    pub(super) fn sem_ug(&self, slot: usize, values: &[Window]) -> Option<f64> {
        let y: Vec<f64> = values.iter().filter_map(|w| w.outputs[slot]).collect();
        stability::sem_ug(&y, self.k1(slot))
    }
}
