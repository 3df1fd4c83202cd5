//! The counter modules' ports: drained all the time the run streams, each
//! module's freshest window paired with the others' into one second of the
//! whole station, with the rate and the per-second safety and health checks.

use super::{EngineError, Executor, Window};
use crate::config::StationConfig;
use crate::event::{Event, ModuleHealth, Wording};
use spinbench_devices::{DeviceError, DeviceErrorKind};
use spinbench_wire::fmu::{
    INSTRUMENTS_PER_MODULE, Message, WindowAccumulator, WindowConfig, WindowValue,
};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// A temperature frame's value that means "no sensor" (i16::MIN centi-°C).
const NO_TEMPERATURE: i16 = i16::MIN;

/// What the counter modules have sent: one accumulator and one queue of
/// decoded windows per module, each slot's latest temperature, and the
/// run's clock in windows. The executor's acquisition part: only this
/// module and the run's summary read it.
pub(super) struct Acquisition {
    /// One window accumulator per counter module.
    accumulators: Vec<WindowAccumulator>,
    /// Each module's decoded windows not yet paired.
    pending: Vec<VecDeque<WindowValue>>,
    /// Each slot's latest temperature from its module's temperature frames [°C].
    temperatures_c: Vec<Option<f64>>,
    /// When each module last sent anything.
    pub(super) last_data: Vec<Instant>,
    /// One-second windows taken so far: the run's clock [s].
    pub(super) windows: u64,
    /// The modules stream (set at power-on; the safe state stops them).
    pub(super) streaming: bool,
    /// Windows dropped to keep the modules aligned in time.
    pub(super) dropped_windows: u64,
    /// The instrument supply's output 1 at its last safety check: (volts, amperes).
    supply_first: (f64, f64),
}

impl Acquisition {
    /// Nothing received yet, for `station`'s modules and `slots` instruments.
    pub(super) fn new(station: &StationConfig, slots: usize) -> Self {
        let accumulators = station
            .fmu
            .iter()
            .map(|f| {
                WindowAccumulator::new(WindowConfig {
                    mode: f.mode.into(),
                    reference_hz: f.reference_hz,
                    ..WindowConfig::default()
                })
            })
            .collect();
        let modules = station.fmu.len();
        Acquisition {
            accumulators,
            pending: vec![VecDeque::new(); modules],
            temperatures_c: vec![None; slots],
            last_data: vec![Instant::now(); modules],
            windows: 0,
            streaming: false,
            dropped_windows: 0,
            supply_first: (0.0, 0.0),
        }
    }

    /// Module `m`'s messages: counts into its accumulator (windows queued),
    /// temperatures into each of its slots' latest value.
    fn take_in(&mut self, m: usize, messages: Vec<Message>) {
        if !messages.is_empty() {
            self.last_data[m] = Instant::now();
        }
        for msg in messages {
            if let Message::Temperatures { centi_celsius, .. } = &msg {
                for (k, &c) in centi_celsius.iter().enumerate() {
                    let slot = m * INSTRUMENTS_PER_MODULE + k;
                    if let Some(t) = self.temperatures_c.get_mut(slot) {
                        *t = (c != NO_TEMPERATURE).then(|| f64::from(c) / 100.0);
                    }
                }
                continue;
            }
            self.accumulators[m].feed(&msg);
            while let Some(window) = self.accumulators[m].decode() {
                self.pending[m].push_back(window);
            }
        }
    }

    /// Keep module `m`'s freshest window only, counting the ones dropped.
    fn keep_freshest(&mut self, m: usize) {
        while self.pending[m].len() > 1 {
            self.pending[m].pop_front();
            self.dropped_windows += 1;
        }
    }
}

impl Executor<'_> {
    /// Read every module's port for `time` without using the data beyond
    /// keeping each module's freshest window (a held run must not let the
    /// ports overrun).
    pub(super) fn drain_ports(&mut self, time: Duration) {
        let until = Instant::now() + time;
        while Instant::now() < until {
            for m in 0..self.bench.modules.len() {
                let Ok(got) =
                    self.bench.modules[m].receive(Instant::now() + Duration::from_millis(5))
                else {
                    continue;
                };
                self.acquisition.take_in(m, got);
                self.acquisition.keep_freshest(m);
            }
            if !self.acquisition.streaming {
                std::thread::sleep(Duration::from_millis(20));
            }
        }
    }

    /// The next one-second window of every module, with the rate and the safety checks.
    pub(super) fn next_window(&mut self) -> Result<Window, EngineError> {
        let modules = self.bench.modules.len();
        let mut values: Vec<Option<WindowValue>> = vec![None; modules];
        // Silence counts from when the station began to wait: a bench in
        // virtual time sends nothing while the run is held or a prompt is open.
        let waiting_since = Instant::now();
        loop {
            if self.options.abort.is_set() {
                return Err(EngineError::Aborted(self.options.abort.by()));
            }
            for (m, value) in values.iter_mut().enumerate() {
                // Pair each module's freshest window: an older backlog would
                // put another moment beside the other modules' values.
                self.acquisition.keep_freshest(m);
                if value.is_none() {
                    *value = self.acquisition.pending[m].pop_front();
                }
            }
            if values.iter().all(Option::is_some) {
                break;
            }
            // Drain every module on every pass: a port left unread overruns
            // (and a simulator pacing itself on the station's reads would wait).
            // Short waits: a long wait on one quiet module would leave the
            // others unread for its length.
            for m in 0..values.len() {
                let got =
                    self.bench.modules[m].receive(Instant::now() + Duration::from_millis(1))?;
                self.acquisition.take_in(m, got);
                let silent = self.acquisition.last_data[m].max(waiting_since).elapsed();
                if silent > self.options.module_silence {
                    return Err(EngineError::ModuleSilent {
                        module: m + 1,
                        seconds: silent.as_secs_f64(),
                    });
                }
            }
        }
        // Take in everything that has already arrived: after a pause the
        // ports hold a backlog, and the windows averaged must be of the same
        // moment as the rate polled below. Newer windows replace older ones.
        for (m, value) in values.iter_mut().enumerate() {
            loop {
                let got =
                    self.bench.modules[m].receive(Instant::now() + Duration::from_micros(300))?;
                if got.is_empty() {
                    break;
                }
                self.acquisition.take_in(m, got);
            }
            if let Some(newest) = self.acquisition.pending[m].pop_back() {
                self.acquisition.dropped_windows += 1 + self.acquisition.pending[m].len() as u64;
                self.acquisition.pending[m].clear();
                *value = Some(newest);
            }
        }
        self.acquisition.windows += 1;
        let rate = self.bench.centrifuge.read_rate()?;
        if self.demand_deg_s != 0.0 && !self.bench.centrifuge.read_interlocks()? {
            return Err(EngineError::InterlockOpen);
        }
        // The chamber watched throughout (not only while it soaks): an
        // alarm or a lost controller while a pass measures faults the run.
        if self.acquisition.windows.is_multiple_of(CHAMBER_WATCH_S) {
            self.watch_chamber()?;
        }
        if self.acquisition.windows.is_multiple_of(5) {
            let first = self.bench.instrument_supply.measure(1)?;
            if first.volts < 0.5 * self.station.power.rail_volts {
                return Err(EngineError::SupplyTripped { volts: first.volts });
            }
            self.acquisition.supply_first = (first.volts, first.amps);
        }
        // The status panel's health every 20 s: two more device queries,
        // which cost wall time when the bench runs faster than real time.
        if self.acquisition.windows.is_multiple_of(20) {
            let first = self.acquisition.supply_first;
            let second = self.bench.instrument_supply.measure(2)?;
            let modules = self
                .bench
                .modules
                .iter()
                .zip(&self.acquisition.accumulators)
                .map(|(module, acc)| {
                    let link = module.link_stats();
                    ModuleHealth {
                        frames: link.decoder.frames,
                        bad_crc: link.decoder.bad_crc,
                        bad_tail: link.decoder.bad_tail,
                        lost_ticks: acc.stats().lost_ticks,
                        reconnects: link.reconnects,
                    }
                })
                .collect();
            // Spinning, they were just read closed; at rest an unreadable
            // interlock shows as open.
            let interlocks_closed = self.demand_deg_s != 0.0
                || self.bench.centrifuge.read_interlocks().unwrap_or(false);
            let chamber_busy_replies = self.bench.chamber.as_ref().map(|c| c.busy_replies());
            self.emit(Event::Health {
                supply: vec![first, (second.volts, second.amps)],
                interlocks_closed,
                modules,
                chamber_busy_replies,
            })?;
        }
        let slots = self.units.len();
        let mut outputs = vec![None; slots];
        let mut resonators = vec![(None, None); slots];
        for (m, v) in values.into_iter().enumerate() {
            let Some(v) = v else { continue };
            for (k, inst) in v.instruments.iter().enumerate() {
                let slot = m * INSTRUMENTS_PER_MODULE + k;
                if slot < slots {
                    resonators[slot] = (inst.f1_hz, inst.f2_hz);
                    // A window with lost ticks is marked, never averaged as whole.
                    outputs[slot] = if v.is_complete() { inst.df_hz } else { None };
                }
            }
        }
        // An instrument over the station's temperature limit stops the run.
        if let Some(limit_c) = self.station.temperature.instrument_max_c {
            for (slot, t) in self.acquisition.temperatures_c.iter().enumerate() {
                if let Some(celsius) = *t
                    && celsius > limit_c
                    && self.plan.serials[slot].is_some()
                {
                    return Err(EngineError::OverTemperature {
                        slot: slot + 1,
                        celsius,
                        limit_c,
                    });
                }
            }
        }
        let window = Window {
            time_s: self.acquisition.windows as f64,
            rate_deg_s: rate,
            outputs,
            resonators,
            temperatures_c: self.acquisition.temperatures_c.clone(),
        };
        let on_speed = self.on_speed(rate);
        // The raw bytes of this second reach the capture's file before its
        // values reach the store: replay can check every stored value, even
        // of a run killed and resumed.
        for module in &mut self.bench.modules {
            module.flush_capture();
        }
        self.emit(Event::Values {
            time_s: window.time_s,
            rate_deg_s: rate,
            demand_deg_s: self.demand_deg_s,
            on_speed,
            outputs_hz: window.outputs.clone(),
            temperatures_c: window.temperatures_c.clone(),
        })?;
        Ok(window)
    }
}

/// How often the chamber is read while a run uses it [s of windows].
pub const CHAMBER_WATCH_S: u64 = 5;

impl Executor<'_> {
    /// Read the chamber's alarm word (and the air) when the run has given it
    /// a setpoint: an alarm is [`EngineError::ChamberAlarm`], a controller
    /// that does not answer (beyond its driver's retries and outage budget)
    /// a device error; either ends the run into the safe state.
    pub(super) fn watch_chamber(&mut self) -> Result<(), EngineError> {
        let Some(setpoint_c) = self.chamber.setpoint_c else {
            return Ok(());
        };
        let Some(chamber) = self.bench.chamber.as_mut() else {
            return Ok(());
        };
        let word = chamber.alarms()?;
        if word != 0 {
            let air_c = chamber.temperature_c().unwrap_or(f64::NAN);
            return Err(EngineError::ChamberAlarm {
                word,
                air_c,
                setpoint_c,
            });
        }
        if let Some(held) = restore_setpoint(chamber.as_mut(), setpoint_c)? {
            self.emit(setpoint_restored(held, setpoint_c))?;
        }
        self.notice_chamber_busy()
    }

    /// Tell the operator when the chamber's controller has answered busy
    /// [`CHAMBER_BUSY_NOTICE_AFTER`] more times since the last such
    /// notice: each was ridden, but a controller often busy is overloaded
    /// or polled by another program, and an outage may follow.
    pub(super) fn notice_chamber_busy(&mut self) -> Result<(), EngineError> {
        let Some(chamber) = self.bench.chamber.as_ref() else {
            return Ok(());
        };
        let busy = chamber.busy_replies();
        if busy < self.chamber.busy_noticed + CHAMBER_BUSY_NOTICE_AFTER {
            return Ok(());
        }
        self.chamber.busy_noticed = busy;
        self.emit(Event::Notice {
            message: format!(
                "the chamber controller answered busy {busy} times in this run (each asked again): is another program polling it, or is it overloaded?"
            ),
            wording: Some(Wording::new("notice.chamber_busy").with("count", busy)),
        })
    }
}

/// After how many more busy replies of the chamber the operator is told.
pub const CHAMBER_BUSY_NOTICE_AFTER: u64 = 5;

/// Read the setpoint the controller holds back, and when it is not the
/// run's (a controller that restarted forgets its setpoint and stops),
/// write the setpoint and the run command again; the setpoint it held
/// when it had to be restored.
pub(super) fn restore_setpoint(
    chamber: &mut dyn spinbench_devices::chamber::Chamber,
    setpoint_c: f64,
) -> Result<Option<f64>, DeviceError> {
    let held = chamber.setpoint_c()?;
    if (held - setpoint_c).abs() <= SETPOINT_READBACK_C {
        return Ok(None);
    }
    set_and_confirm_setpoint(chamber, setpoint_c)?;
    chamber.set_running(true)?;
    Ok(Some(held))
}

/// The notice of a setpoint written again ([`restore_setpoint`]).
pub(super) fn setpoint_restored(held_c: f64, setpoint_c: f64) -> Event {
    let held = format!("{held_c:.1}");
    Event::Notice {
        message: format!(
            "the chamber controller held {held} °C, not the run's {setpoint_c} °C (it restarted or was changed at its panel): the setpoint and the run command were written again"
        ),
        wording: Some(
            Wording::new("notice.chamber_setpoint_restored")
                .with("held", &held)
                .with("setpoint", setpoint_c),
        ),
    }
}

/// How far a chamber's setpoint read back may be from the one written [°C]
/// (a controller holding whole or tenth degrees rounds; a wrong register or
/// scale is far off).
pub const SETPOINT_READBACK_C: f64 = 0.5;

/// Write `celsius` as the chamber's setpoint and read it back: a controller
/// that holds another value (a wrong register, scale or sign in the map,
/// or a controller that ignored the write) is an error that says so.
pub(super) fn set_and_confirm_setpoint(
    chamber: &mut dyn spinbench_devices::chamber::Chamber,
    celsius: f64,
) -> Result<(), DeviceError> {
    chamber.set_setpoint_c(celsius)?;
    let held = chamber.setpoint_c()?;
    if (held - celsius).abs() > SETPOINT_READBACK_C {
        return Err(DeviceError {
            device: "chamber".into(),
            command: format!("set setpoint {celsius} °C"),
            kind: DeviceErrorKind::Rejected(format!(
                "the controller holds {held:.2} °C after the write of {celsius} °C \
                 (more than {SETPOINT_READBACK_C} °C apart): check the map's setpoint \
                 register, counts_per_c and signed, and that the controller is in remote mode"
            )),
        });
    }
    Ok(())
}
