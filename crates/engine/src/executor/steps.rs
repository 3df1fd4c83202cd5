//! One handler per kind of [`Step`]: power on, alive check, warm-up, the
//! operator's remounting, the tumble, the radius at 1 g, a level's point.

use super::stability::{self, AT_REST_DEG_S, mean_std};
use super::state::Trigger;
use super::{Answer, EngineError, Executor, Window};
use crate::event::{Event, Wording};
use crate::plan::{Fixture, Step};
use crate::record::{PointRecord, Reason, ReasonCode};
use spinbench_analysis::radius::RadiusCalibration;
use spinbench_analysis::tumble::{MeanReading, TumbleCalibration};
use spinbench_analysis::{Mount, UG_PER_G, centrifuge};
use spinbench_wire::fmu::INSTRUMENTS_PER_MODULE;
use std::collections::BTreeSet;
use std::time::{Duration, Instant};

/// Resonator frequencies outside this range mean a dead or miswired input [Hz].
const RESONATOR_RANGE_HZ: (f64, f64) = (5_000.0, 200_000.0);

impl Executor<'_> {
    pub(super) fn power_on(&mut self) -> Result<(), EngineError> {
        // Errors another program or an earlier session left in a supply's
        // queue are read, reported and cleared first: a refusal after this
        // is the station's own command's.
        let mut stale = Vec::new();
        if let Some(m) = &mut self.bench.module_supply {
            stale.extend(m.clear_errors()?.into_iter().map(|e| ("module supply", e)));
        }
        stale.extend(
            self.bench
                .instrument_supply
                .clear_errors()?
                .into_iter()
                .map(|e| ("instrument supply", e)),
        );
        if !stale.is_empty() {
            let listed = stale
                .iter()
                .map(|(who, (code, text))| format!("{who}: {code}, \"{text}\""))
                .collect::<Vec<_>>()
                .join("; ");
            self.emit(Event::Notice {
                message: format!(
                    "errors left in the supplies' queues from before this run, cleared (*CLS): {listed}"
                ),
                wording: Some(Wording::new("notice.stale_supply_errors").with("errors", &listed)),
            })?;
        }
        let p = &self.station.power;
        if let Some(m) = &mut self.bench.module_supply {
            m.set_output(1, true)?;
        }
        for ch in [1, 2] {
            self.bench
                .instrument_supply
                .configure(ch, p.rail_volts, p.rail_current_limit_a)?;
            self.bench.instrument_supply.set_output(ch, true)?;
        }
        for (m, module) in self.bench.modules.iter_mut().enumerate() {
            let mask = (0..INSTRUMENTS_PER_MODULE)
                .filter(|s| {
                    self.plan
                        .serials
                        .get(m * INSTRUMENTS_PER_MODULE + s)
                        .is_some_and(Option::is_some)
                })
                .fold(0u8, |mask, s| mask | (1 << s));
            module.set_power(mask)?;
            module.start(self.station.fmu[m].mode.into())?;
        }
        self.acquisition.streaming = true;
        self.bench.centrifuge.reset_interlocks()?;
        self.bench.centrifuge.arm()?;
        let now = Instant::now();
        self.acquisition.last_data.iter_mut().for_each(|t| *t = now);
        Ok(())
    }

    pub(super) fn check_alive(&mut self) -> Result<(), EngineError> {
        let mut seen: Vec<u32> = vec![0; self.units.len()];
        for _ in 0..3 {
            let w = self.next_window()?;
            for (slot, (f1, f2)) in w.resonators.iter().enumerate() {
                let ok = |f: &Option<f64>| {
                    f.is_some_and(|f| (RESONATOR_RANGE_HZ.0..=RESONATOR_RANGE_HZ.1).contains(&f))
                };
                if ok(f1) && ok(f2) {
                    seen[slot] += 1;
                }
            }
        }
        // The instruments' total current on the +15 V rail.
        let powered = self.plan.serials.iter().filter(|s| s.is_some()).count() as f64;
        let expected = powered * self.station.power.instrument_current_a;
        let amps = self.bench.instrument_supply.measure(1)?.amps;
        if expected > 0.0 && !(0.5 * expected..=1.5 * expected).contains(&amps) {
            return Err(EngineError::Power(format!(
                "the instruments draw {amps:.3} A on the +15 V rail, expected about {expected:.3} A \
                 ({powered} × power.instrument_current_a); check the relays and the wiring"
            )));
        }
        for (slot, &count) in seen.iter().enumerate() {
            if self.live(slot) && count == 0 {
                self.fail_unit(
                    slot,
                    Reason::new(
                        ReasonCode::Dead,
                        "no output from its resonators: dead, unpowered or not connected",
                    ),
                )?;
            }
        }
        Ok(())
    }

    pub(super) fn warm_up(&mut self, seconds: f64) -> Result<(), EngineError> {
        let n = seconds.ceil() as u32;
        for i in 0..n {
            self.next_window()?;
            self.emit(Event::Progress {
                phase: "warm-up".into(),
                done: i + 1,
                of: n,
            })?;
        }
        Ok(())
    }

    pub(super) fn mount(&mut self, fixtures: &[Option<Fixture>]) -> Result<(), EngineError> {
        // The table must be at rest before anyone touches it.
        self.command_rate(0.0)?;
        let mut waited = 0;
        while self.next_window()?.rate_deg_s.abs() > AT_REST_DEG_S {
            waited += 1;
            if waited > self.plan.plan.stability.max_settle_s {
                return Err(EngineError::NotStable(
                    "the table did not come to rest for remounting".into(),
                ));
            }
        }
        self.ask_operator(&mount_text(fixtures), fixtures)
    }

    /// Put `text` to the operator (with the fixtures it asks for) and wait
    /// for the answer, reading the ports meanwhile; a "no" aborts the run.
    pub(super) fn ask_operator(
        &mut self,
        text: &str,
        fixtures: &[Option<Fixture>],
    ) -> Result<(), EngineError> {
        let text = text.to_string();
        self.set_state(Trigger::Prompt)?;
        self.emit(Event::Prompt {
            text: text.clone(),
            fixtures: fixtures.to_vec(),
        })?;
        let mut answer = self.operator.post(&text, fixtures);
        while answer.is_none() {
            if self.options.abort.is_set() {
                return Err(EngineError::Aborted(self.options.abort.by()));
            }
            // Keep the ports read while the person works.
            self.drain_ports(Duration::from_millis(100));
            answer = self.operator.poll_answer(Duration::from_millis(50));
        }
        let answer = answer.unwrap_or(Answer {
            proceed: false,
            by: "nobody".into(),
        });
        self.emit(Event::PromptAnswered {
            proceed: answer.proceed,
            by: answer.by.clone(),
        })?;
        self.set_state(Trigger::Answered)?;
        if !answer.proceed {
            return Err(EngineError::Aborted(answer.by));
        }
        Ok(())
    }

    pub(super) fn command_rate(&mut self, rate_deg_s: f64) -> Result<(), EngineError> {
        if rate_deg_s == 0.0 {
            self.bench.centrifuge.stop()?;
        } else {
            self.check_rate_allowed(rate_deg_s)?;
            self.bench.centrifuge.set_rate(rate_deg_s)?;
        }
        self.demand_deg_s = rate_deg_s;
        Ok(())
    }

    pub(super) fn tumble(&mut self, up: bool) -> Result<(), EngineError> {
        self.command_rate(0.0)?;
        let mut slots: Vec<usize> = (0..self.units.len()).filter(|&s| self.live(s)).collect();
        let values = self.acquire(&mut slots)?;
        for slot in slots {
            let y: Vec<f64> = values.iter().filter_map(|w| w.outputs[slot]).collect();
            if y.is_empty() {
                let direction = if up { "up" } else { "down" };
                self.fail_unit(
                    slot,
                    Reason::new(
                        ReasonCode::NoOutput,
                        format!("no output during the IA-{direction} tumble reading"),
                    )
                    .with("variant", format!("tumble_{direction}")),
                )?;
                continue;
            }
            let Some(reading) = MeanReading::of(&y) else {
                continue;
            };
            let u = &mut self.units[slot];
            if up {
                u.up = Some(reading);
            } else {
                u.down = Some(reading);
            }
            self.emit(Event::TumbleDone {
                slot,
                up,
                output_hz: reading.output,
                standard_error_hz: reading.standard_error,
            })?;
            let u = &self.units[slot];
            if let (Some(a), Some(b)) = (u.up, u.down) {
                match TumbleCalibration::from_up_down(a.output, b.output) {
                    Ok(cal) => self.units[slot].cal = Some(cal),
                    Err(e) => self.fail_unit(slot, tumble_failed(&e))?,
                }
            }
        }
        Ok(())
    }

    /// One of a four-position tumble's extra readings; after both, each
    /// instrument's cross-axis sensitivity (taken out of its radius).
    pub(super) fn cross_tumble(&mut self, as_on_arm: bool) -> Result<(), EngineError> {
        self.command_rate(0.0)?;
        let mut slots: Vec<usize> = (0..self.units.len()).filter(|&s| self.live(s)).collect();
        let values = self.acquire(&mut slots)?;
        for slot in slots {
            let y: Vec<f64> = values.iter().filter_map(|w| w.outputs[slot]).collect();
            let Some(reading) = MeanReading::of(&y) else {
                self.fail_unit(
                    slot,
                    Reason::new(
                        ReasonCode::NoOutput,
                        "no output during a cross-axis tumble reading",
                    )
                    .with("variant", "cross_tumble"),
                )?;
                continue;
            };
            self.units[slot].crosswise[usize::from(!as_on_arm)] = Some(reading);
            self.emit(Event::CrossTumbleDone {
                slot,
                as_on_arm,
                output_hz: reading.output,
                standard_error_hz: reading.standard_error,
            })?;
            if let Err(e) = self.units[slot].find_cross_axis() {
                self.fail_unit(slot, tumble_failed(&e))?;
            }
        }
        Ok(())
    }

    pub(super) fn radius(&mut self, pass: usize) -> Result<(), EngineError> {
        let g = self.station.g_local_m_s2;
        let r0 = self.station.arm.radius_m;
        let w = centrifuge::rate_for_acceleration_rad_s(1.0, r0, g)
            .map_err(|e| EngineError::Rate(e.to_string()))?;
        self.command_rate(w.to_degrees())?;
        let mut slots: Vec<usize> = (0..self.units.len())
            .filter(|&s| self.live(s) && self.plan.passes[pass][s].is_some())
            .collect();
        let values = self.acquire(&mut slots)?;
        let rate = values.iter().map(|w| w.rate_deg_s).sum::<f64>() / values.len().max(1) as f64;
        let w_meas = self.station.inertial_rate_rad_s(rate.to_radians());
        for slot in slots {
            let Some(mount) = self.plan.passes[pass][slot] else {
                continue;
            };
            let y: Vec<f64> = values.iter().filter_map(|w| w.outputs[slot]).collect();
            let Some(cal) = self.units[slot].cal else {
                continue;
            };
            if y.is_empty() {
                self.fail_unit(
                    slot,
                    Reason::new(ReasonCode::NoOutput, "no output during the radius step")
                        .with("variant", "radius"),
                )?;
                continue;
            }
            let Some(reading) = MeanReading::of(&y) else {
                continue;
            };
            let r0_i = self.station.drawing_radius_m(slot);
            // method.md (6)–(8) at the measured rate: the rate applies ω²·R0/g at R0.
            let nominal_g = w_meas * w_meas * r0_i / g;
            let u = &self.units[slot];
            let cross = u.cross_axis;
            match RadiusCalibration::from_reading(
                reading.output,
                &cal,
                cross,
                r0_i,
                nominal_g,
                mount,
            ) {
                Ok(r) => {
                    let reading_u_ppm = match (u.up, u.down) {
                        (Some(up), Some(down)) => r.reading_u_ppm(up, down, reading, cross),
                        _ => 0.0,
                    };
                    let u = &mut self.units[slot];
                    u.radius.insert(mount, r.radius_m);
                    u.radius_reading_u_ppm.insert(mount, reading_u_ppm);
                    self.emit(Event::RadiusDone {
                        slot,
                        mount,
                        drawing_radius_m: r0_i,
                        radius_m: r.radius_m,
                        reading_u_ppm,
                    })?;
                }
                Err(e) => self.fail_unit(
                    slot,
                    Reason::new(
                        ReasonCode::RadiusFailed,
                        format!("radius in mounting {mount}: {e}"),
                    )
                    .with("mount", mount)
                    .with("detail", e),
                )?,
            }
        }
        self.check_radii(pass)
    }

    pub(super) fn level(
        &mut self,
        step: usize,
        pass: usize,
        g_nominal: f64,
        direction: spinbench_analysis::Direction,
    ) -> Result<(), EngineError> {
        let g = self.station.g_local_m_s2;
        let r0 = self.station.arm.radius_m;
        let w = centrifuge::rate_for_acceleration_rad_s(g_nominal, r0, g)
            .map_err(|e| EngineError::Rate(e.to_string()))?;
        self.command_rate(w.to_degrees())?;
        let mut slots: Vec<usize> = (0..self.units.len())
            .filter(|&s| self.live(s) && self.plan.passes[pass][s].is_some())
            .collect();
        let noise_limit = self.plan.plan.stability.noise_limit_ug;
        let mut table_restarts = 0;
        let (values, own_noise) = loop {
            let values = self.acquire(&mut slots)?;
            let own_noise = self.instrument_noise_ug(pass, &slots, &values);
            // Every instrument scattering at once is the table (the tail of
            // its settling), not the instruments: measure the point again.
            let noisy = |s: &usize| own_noise.get(s).is_some_and(|&n| n > noise_limit);
            if slots.len() >= 2
                && slots.iter().all(noisy)
                && table_restarts < self.plan.plan.stability.max_restarts
            {
                table_restarts += 1;
                self.emit(Event::Notice {
                    message: format!(
                        "every instrument scattered more than {noise_limit} µg together at {g_nominal} g: \
                         the table, not the instruments; measuring the point again ({table_restarts})"
                    ),
                    wording: Some(
                        Wording::new("notice.table_noisy")
                            .with("limit", noise_limit)
                            .with("g", g_nominal)
                            .with("restarts", table_restarts),
                    ),
                })?;
                continue;
            }
            // An instrument whose temperature moved too much while the
            // point was averaged: measure the point again, then flag it.
            if let Some(limit) = self.plan.plan.stability.temperature_change_max_c {
                let moved: Vec<usize> = slots
                    .iter()
                    .copied()
                    .filter(|&s| temperature_of(&values, s).is_some_and(|(_, d)| d > limit))
                    .collect();
                if !moved.is_empty() && table_restarts < self.plan.plan.stability.max_restarts {
                    table_restarts += 1;
                    let moved = moved
                        .iter()
                        .map(|s| (s + 1).to_string())
                        .collect::<Vec<_>>()
                        .join(", ");
                    self.emit(Event::Notice {
                        message: format!(
                            "the temperature of slot(s) {moved} changed by more than {limit} °C \
                             (stability.temperature_change_max_c) while averaging at {g_nominal} g; \
                             measuring the point again ({table_restarts})"
                        ),
                        wording: Some(
                            Wording::new("notice.temperature_moved")
                                .with("slots", &moved)
                                .with("limit", limit)
                                .with("g", g_nominal)
                                .with("restarts", table_restarts),
                        ),
                    })?;
                    continue;
                }
            }
            break (values, own_noise);
        };
        let rate = values.iter().map(|w| w.rate_deg_s).sum::<f64>() / values.len().max(1) as f64;
        // The rate in inertial space: the Earth's vertical rate added (method.md §5).
        let w_meas = self.station.inertial_rate_rad_s(rate.to_radians());
        let mut points = Vec::new();
        for slot in slots {
            let Some(mount) = self.plan.passes[pass][slot] else {
                continue;
            };
            let y: Vec<f64> = values.iter().filter_map(|w| w.outputs[slot]).collect();
            if y.len() < 2 {
                self.fail_unit(
                    slot,
                    Reason::new(ReasonCode::NoOutput, format!("no output at {g_nominal} g"))
                        .with("variant", "level")
                        .with("g", g_nominal),
                )?;
                continue;
            }
            let (mean, std) = mean_std(&y);
            let std_ug = own_noise
                .get(&slot)
                .copied()
                .unwrap_or(std / self.k1(slot) * UG_PER_G);
            if std_ug > noise_limit {
                self.fail_unit(
                    slot,
                    Reason::new(
                        ReasonCode::Noisy,
                        format!("its own 1-s scatter is {std_ug:.0} µg at {g_nominal} g, over the noise limit of {noise_limit} µg: not measured against the limits (check its cable and connector, then retest)"),
                    )
                    .with("scatter", format!("{std_ug:.0}"))
                    .with("g", g_nominal)
                    .with("limit", noise_limit),
                )?;
                continue;
            }
            let radius = self.units[slot]
                .radius
                .get(&mount)
                .copied()
                .unwrap_or_else(|| self.station.drawing_radius_m(slot));
            let temperature = temperature_of(&values, slot);
            let resonator_sum = stability::mean_spread(
                &values
                    .iter()
                    .filter_map(|w| match w.resonators[slot] {
                        (Some(f1), Some(f2)) => Some(f1 + f2),
                        _ => None,
                    })
                    .collect::<Vec<_>>(),
            );
            points.push(PointRecord {
                setpoint_c: self.chamber.setpoint_c,
                temperature_c: temperature.map(|t| t.0),
                temperature_change_c: temperature.map(|t| t.1),
                temperature_unsettled: self
                    .plan
                    .plan
                    .stability
                    .temperature_change_max_c
                    .zip(temperature)
                    .is_some_and(|(limit, (_, change))| change > limit),
                resonator_sum_hz: resonator_sum.map(|r| r.0),
                resonator_sum_change_ppm: resonator_sum
                    .filter(|r| r.0 != 0.0)
                    .map(|r| r.1 / r.0.abs() * 1e6),
                slot,
                mount,
                g_nominal,
                direction,
                // method.md (9), (13): each instrument's own radius, stretched.
                g_applied: w_meas * w_meas * radius * self.station.stretch_factor(w_meas) / g,
                rate_deg_s: rate,
                output_hz: mean,
                std_hz: std,
                n: y.len() as u32,
                time_s: [
                    values.first().map_or(0.0, |w| w.time_s),
                    values.last().map_or(0.0, |w| w.time_s),
                ],
            });
        }
        for p in &points {
            self.units[p.slot].points.push(p.clone());
        }
        self.emit(Event::PointDone { step, points })
    }
}

/// A slot's temperature over a point's windows: (mean, highest − lowest) [°C].
fn temperature_of(values: &[Window], slot: usize) -> Option<(f64, f64)> {
    let t: Vec<f64> = values
        .iter()
        .filter_map(|w| w.temperatures_c.get(slot).copied().flatten())
        .collect();
    stability::mean_spread(&t)
}

fn mount_text(fixtures: &[Option<Fixture>]) -> String {
    let kinds: BTreeSet<String> = fixtures
        .iter()
        .flatten()
        .map(|f| format!("{f:?}"))
        .collect();
    let describe = |f: &Fixture| match f {
        Fixture::Up => "on the tumble fixture, input axis UP".to_string(),
        Fixture::Down => "on the tumble fixture, input axis DOWN".to_string(),
        Fixture::Arm(Mount::P) => {
            "on the arm in mounting P (input axis toward the spin axis)".to_string()
        }
        Fixture::Arm(Mount::N) => {
            "on the arm in mounting N (input axis away from the spin axis)".to_string()
        }
        Fixture::Crosswise { as_on_arm: true } => "on the tumble fixture, input axis horizontal, \
            the face that is up on the arm UP (gravity across the axis as on the arm)"
            .to_string(),
        Fixture::Crosswise { as_on_arm: false } => "on the tumble fixture, input axis horizontal, \
            the face that is up on the arm DOWN (gravity across the axis inverted)"
            .to_string(),
    };
    match fixtures.iter().flatten().next() {
        Some(f) if kinds.len() == 1 => format!("Mount every instrument {}", describe(f)),
        _ => {
            let list: Vec<String> = fixtures
                .iter()
                .enumerate()
                .filter_map(|(i, f)| f.map(|f| format!("slot {}: {}", i + 1, describe(&f))))
                .collect();
            format!("Mount the instruments: {}", list.join("; "))
        }
    }
}

/// The reason of a tumble that could not calibrate an instrument.
fn tumble_failed(e: &impl std::fmt::Display) -> Reason {
    Reason::new(ReasonCode::TumbleFailed, format!("tumble: {e}")).with("detail", e)
}

/// A step's label as a catalogue key (`step.<kind>`) and its values.
pub fn wording(step: &Step) -> Wording {
    match step {
        Step::PowerOn => Wording::new("step.power_on"),
        Step::CheckAlive => Wording::new("step.check_alive"),
        Step::WarmUp { seconds } => {
            Wording::new("step.warm_up").with("seconds", format!("{seconds:.0}"))
        }
        Step::Mount { .. } => Wording::new("step.mount"),
        Step::Tumble { up } => {
            Wording::new("step.tumble").with("direction", if *up { "up" } else { "down" })
        }
        Step::Soak { setpoint_c } => Wording::new("step.soak").with("setpoint", setpoint_c),
        Step::CrossTumble { as_on_arm } => Wording::new("step.cross_tumble").with(
            "position",
            if *as_on_arm { "as_on_arm" } else { "inverted" },
        ),
        Step::Radius { pass } => Wording::new("step.radius").with("pass", pass + 1),
        Step::Level {
            pass,
            g_nominal,
            direction,
        } => Wording::new("step.level")
            .with("g", g_nominal)
            .with("direction", direction.as_str())
            .with("pass", pass + 1),
        Step::Decide { pass, round } => Wording::new("step.decide")
            .with("pass", pass + 1)
            .with("round", round + 1),
        Step::Stop => Wording::new("step.stop"),
    }
}

/// A short label of a step for progress display.
pub fn label(step: &Step) -> String {
    match step {
        Step::PowerOn => "power on".into(),
        Step::CheckAlive => "check instruments".into(),
        Step::WarmUp { seconds } => format!("warm-up {seconds:.0} s"),
        Step::Mount { fixtures } => mount_text(fixtures),
        Step::Tumble { up } => format!("tumble, input axis {}", if *up { "up" } else { "down" }),
        Step::Soak { setpoint_c } => format!("soak the chamber at {setpoint_c} °C"),
        Step::CrossTumble { as_on_arm } => format!(
            "tumble, input axis horizontal, {}",
            if *as_on_arm {
                "as on the arm"
            } else {
                "inverted"
            }
        ),
        Step::Radius { pass } => format!("radius at 1 g (pass {})", pass + 1),
        Step::Level {
            pass,
            g_nominal,
            direction,
        } => format!("{g_nominal} g {direction:?} (pass {})", pass + 1),
        Step::Decide { pass, round } => {
            format!("deciding, level {} (pass {})", round + 1, pass + 1)
        }
        Step::Stop => "stop".into(),
    }
}
