//! The soak at a chamber temperature: the purge on
//! before the air goes below the dew point, the setpoint, then the air in
//! band and the instruments' temperatures still for the plan's window; the
//! chamber watched all the while (an alarm or a silent controller stops the
//! run into the safe state, which sends the chamber back to the room).

use super::{EngineError, Executor, ports, stability};
use crate::event::{Event, Wording};
use std::collections::VecDeque;

/// The executor's chamber part: what the run has asked of the chamber.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct ChamberState {
    /// The setpoint since the last soak [°C]; `None` before any.
    pub(super) setpoint_c: Option<f64>,
    /// The dry-air purge is on.
    pub(super) purge_on: bool,
    /// The controller's busy replies the last notice told of.
    pub(super) busy_noticed: u64,
}

/// The purge goes on this far above the dew point [°C].
const DEW_MARGIN_C: f64 = 2.0;
/// The chamber is read every this many seconds of the soak.
const CHAMBER_POLL_S: u64 = 5;

impl Executor<'_> {
    pub(super) fn soak(&mut self, setpoint_c: f64) -> Result<(), EngineError> {
        let soak = self.plan.plan.soak;
        let dew_c = self.station.temperature.dew_point_c + DEW_MARGIN_C;
        self.command_rate(0.0)?;
        let chamber = self.bench.chamber.as_mut().ok_or(EngineError::NoChamber)?;
        if setpoint_c < dew_c && !self.chamber.purge_on {
            chamber.set_purge(true)?;
            self.chamber.purge_on = true;
        }
        ports::set_and_confirm_setpoint(chamber.as_mut(), setpoint_c)?;
        chamber.set_running(true)?;
        self.chamber.setpoint_c = Some(setpoint_c);
        self.emit(Event::Notice {
            message: format!(
                "soaking at {setpoint_c} °C: the air within ±{} °C and the instruments still for {} s (at most {} s)",
                soak.tolerance_c, soak.window_s, soak.max_soak_s
            ),
            wording: Some(
                Wording::new("notice.soaking")
                    .with("setpoint", setpoint_c)
                    .with("tolerance", soak.tolerance_c)
                    .with("window", soak.window_s)
                    .with("max", soak.max_soak_s),
            ),
        })?;
        let slots: Vec<usize> = (0..self.units.len()).filter(|&s| self.live(s)).collect();
        // (air in band, each live slot's temperature) of the last seconds.
        let mut history: VecDeque<(bool, Vec<Option<f64>>)> = VecDeque::new();
        let mut air_c = f64::NAN;
        for second in 1..=u64::from(soak.max_soak_s) {
            let w = self.next_window()?;
            if second % CHAMBER_POLL_S == 1 {
                let chamber = self.bench.chamber.as_mut().ok_or(EngineError::NoChamber)?;
                air_c = chamber.temperature_c()?;
                let word = chamber.alarms()?;
                if word != 0 {
                    return Err(EngineError::ChamberAlarm {
                        word,
                        air_c,
                        setpoint_c,
                    });
                }
                // Warm again: the purge may go off.
                if self.chamber.purge_on && setpoint_c >= dew_c && air_c >= dew_c {
                    chamber.set_purge(false)?;
                    self.chamber.purge_on = false;
                }
                // A controller that restarted holds its own setpoint, stopped.
                if let Some(held) = ports::restore_setpoint(chamber.as_mut(), setpoint_c)? {
                    self.emit(ports::setpoint_restored(held, setpoint_c))?;
                }
                self.notice_chamber_busy()?;
            }
            let in_band = (air_c - setpoint_c).abs() <= soak.tolerance_c;
            history.push_back((
                in_band,
                slots.iter().map(|&s| w.temperatures_c[s]).collect(),
            ));
            while history.len() > soak.window_s as usize {
                history.pop_front();
            }
            let still = history.len() >= soak.window_s as usize
                && history.iter().all(|(band, _)| *band)
                && (0..slots.len()).all(|k| {
                    let t: Vec<f64> = history.iter().filter_map(|(_, ts)| ts[k]).collect();
                    stability::mean_spread(&t).is_none_or(|(_, spread)| spread <= soak.tolerance_c)
                });
            let settled = history.iter().rev().take_while(|(band, _)| *band).count();
            self.emit(Event::Progress {
                phase: "soaking".into(),
                done: settled as u32,
                of: soak.window_s,
            })?;
            if still {
                return Ok(());
            }
        }
        Err(EngineError::NotStable(format!(
            "the chamber and the instruments did not soak at {setpoint_c} °C within soak.max_soak_s = {} s (the air at {air_c:.2} °C)",
            soak.max_soak_s
        )))
    }
}
