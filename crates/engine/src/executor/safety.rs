//! The safe state at the end of every run (controlled stop confirmed by
//! reading the controller back, streaming off, relays open, rails off), and
//! the thread that keeps commanding a stop the controller did not confirm.

use super::{Executor, keeper};
use spinbench_devices::{Centrifuge, DeviceError, DeviceErrorKind};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// What the safe state at the end of the run confirmed.
#[derive(Debug, Clone, Copy)]
pub(super) struct SafeOutcome {
    /// The controller acknowledged the last stop command.
    pub(super) stop_confirmed: bool,
    /// The chamber and the supply confirmed their safe state.
    pub(super) safe_devices_confirmed: bool,
}

impl Default for SafeOutcome {
    /// Before the end: no stop confirmed, nothing left unconfirmed.
    fn default() -> Self {
        SafeOutcome {
            stop_confirmed: false,
            safe_devices_confirmed: true,
        }
    }
}

/// What every screen and record says when the centrifuge did not confirm its stop.
pub const STOP_NOT_CONFIRMED: &str = "stop not confirmed: check the centrifuge";

/// Times the stop is commanded at the end of a run before it counts as unconfirmed.
const STOP_ATTEMPTS: usize = 3;

/// How often an unconfirmed stop is commanded again, for as long as the process lives.
const STOP_RETRY: Duration = Duration::from_secs(2);

impl Executor<'_> {
    /// Controlled stop, streaming off, relays open, supplies off. Every
    /// action is tried; the problems are returned. The stop is commanded up
    /// to [`STOP_ATTEMPTS`] times; when the controller never acknowledges
    /// it, the first problem is [`STOP_NOT_CONFIRMED`] and `stop_confirmed`
    /// stays false (the caller keeps commanding it, see [`keep_stopping`]).
    pub(super) fn safe_state(&mut self) -> Vec<String> {
        let mut problems = Vec::new();
        let mut last_stop_error = None;
        let mut budget = SafeStateBudget::new(Instant::now() + SAFE_STATE_BUDGET);
        self.safe.stop_confirmed = false;
        for attempt in 0..STOP_ATTEMPTS {
            // Confirmed: the stop was sent and the controller answers after
            // it (a dialect whose stop has no acknowledgement would
            // otherwise "succeed" into a controller that hears nothing).
            match stop_and_confirm(self.bench.centrifuge.as_mut()) {
                Ok(()) => {
                    self.safe.stop_confirmed = true;
                    break;
                }
                Err(e) => {
                    // A controller that said nothing through all of the
                    // driver's own retries is not asked again here: the stop
                    // keeper goes on asking after the run is recorded.
                    let silent = matches!(e.kind, DeviceErrorKind::Timeout { .. });
                    last_stop_error = Some(e.to_string());
                    if silent || budget.spent() {
                        break;
                    }
                    if attempt + 1 < STOP_ATTEMPTS {
                        std::thread::sleep(Duration::from_millis(200));
                    }
                }
            }
        }
        if !self.safe.stop_confirmed {
            problems.push(format!(
                "{STOP_NOT_CONFIRMED} (the controller did not acknowledge the stop: {}; \
                 the station keeps commanding it while this program runs)",
                last_stop_error.unwrap_or_default()
            ));
        }
        if self.safe.stop_confirmed {
            let centrifuge = self.bench.centrifuge.as_mut();
            budget.attempt("centrifuge", "disarm", &mut problems, || {
                centrifuge.disarm()
            });
        }
        for (index, m) in self.bench.modules.iter_mut().enumerate() {
            let device = format!("counter module {}", index + 1);
            if self.acquisition.streaming {
                budget.attempt(&device, "stop streaming", &mut problems, || m.stop());
            }
            budget.attempt(&device, "power off", &mut problems, || m.set_power(0));
        }
        for ch in [1, 2] {
            let supply = self.bench.instrument_supply.as_mut();
            budget.attempt(
                "instrument supply",
                &format!("output {ch} off"),
                &mut problems,
                || supply.set_output(ch, false),
            );
        }
        // The chamber back to the laboratory's temperature with the purge on
        // first, so cold air never meets humid air on the instruments; a
        // controller away is waited for briefly here, then by the keeper.
        let ambient_c = self.station.temperature.ambient_c;
        if let Some(chamber) = self.bench.chamber.as_mut() {
            chamber.set_outage_budget(SAFE_STATE_OUTAGE);
            budget.attempt("chamber", "purge on", &mut problems, || {
                chamber.set_purge(true)
            });
            budget.attempt("chamber", "setpoint to ambient", &mut problems, || {
                super::ports::set_and_confirm_setpoint(chamber.as_mut(), ambient_c)
            });
        }
        if !budget.skipped.is_empty() {
            problems.push(format!(
                "not tried, since the devices did not answer within the safe state's {} s: {}",
                SAFE_STATE_BUDGET.as_secs(),
                budget.skipped.join(", ")
            ));
        }
        // What was not confirmed goes to a keeper that tries again every
        // 2 s while the process lives.
        self.safe.safe_devices_confirmed = true;
        if budget.unconfirmed("chamber")
            && let Some(chamber) = self.bench.chamber.take()
        {
            problems.push(format!(
                "chamber: purge on and setpoint to ambient ({ambient_c} °C) not confirmed at the run's end; \
                 the station tries again every {} s while it runs — check the chamber",
                keeper::KEEP_RETRY.as_secs()
            ));
            keeper::keep_making_safe(keeper::Kept::Chamber {
                chamber,
                ambient_c,
                purge_on: false,
                at_ambient: false,
            });
            self.safe.safe_devices_confirmed = false;
        }
        if budget.unconfirmed("instrument supply") {
            let supply = std::mem::replace(
                &mut self.bench.instrument_supply,
                Box::new(keeper::HandedToKeeper),
            );
            problems.push(format!(
                "instrument supply: outputs 1 and 2 off not confirmed at the run's end; \
                 the station tries again every {} s while it runs — switch the rails off by hand",
                keeper::KEEP_RETRY.as_secs()
            ));
            keeper::keep_making_safe(keeper::Kept::Supply {
                supply,
                off: [false, false],
            });
            self.safe.safe_devices_confirmed = false;
        }
        self.demand_deg_s = 0.0;
        problems
    }
}

/// Longest the safe state goes on trying devices once it has started.
/// With every command bounded by
/// [`spinbench_devices::line::MAX_COMMAND_MS`], a stop with silent devices
/// ends within this plus one command, and the run is recorded well inside
/// the service's stop time (`TimeoutStopSec=90`).
pub const SAFE_STATE_BUDGET: Duration = Duration::from_secs(30);

/// How long the safe state waits for a chamber controller that is away or
/// busy before leaving it to the keeper.
pub const SAFE_STATE_OUTAGE: Duration = Duration::from_secs(5);

/// The safe state's time: a device that timed out is not asked again (its
/// driver already retried), and nothing is started after the deadline.
struct SafeStateBudget {
    until: Instant,
    silent: Vec<String>,
    skipped: Vec<String>,
    /// Devices with an action that failed or was not tried.
    failed: Vec<String>,
}

impl SafeStateBudget {
    fn new(until: Instant) -> Self {
        SafeStateBudget {
            until,
            silent: Vec::new(),
            skipped: Vec::new(),
            failed: Vec::new(),
        }
    }

    /// Whether an action of `device` failed or was not tried.
    fn unconfirmed(&self, device: &str) -> bool {
        self.failed.iter().any(|d| d == device)
    }

    fn spent(&self) -> bool {
        Instant::now() >= self.until
    }

    /// Try `action` on `device` unless the device was silent or the time is
    /// spent (then `what` is listed as not tried); its error is a problem.
    fn attempt(
        &mut self,
        device: &str,
        what: &str,
        problems: &mut Vec<String>,
        action: impl FnOnce() -> Result<(), DeviceError>,
    ) {
        if self.spent() || self.silent.iter().any(|d| d == device) {
            self.skipped.push(format!("{device}: {what}"));
            self.failed.push(device.to_string());
            return;
        }
        if let Err(e) = action() {
            self.failed.push(device.to_string());
            if matches!(e.kind, DeviceErrorKind::Timeout { .. }) {
                self.silent.push(device.to_string());
            }
            problems.push(e.to_string());
        }
    }
}

/// The executor's stand-in for a centrifuge whose controller was handed to
/// [`keep_stopping`]: every command says where it went.
pub(super) struct HandedToStopKeeper;

impl Centrifuge for HandedToStopKeeper {
    fn identify(&mut self) -> Result<String, DeviceError> {
        Err(self.refuse("*IDN?"))
    }
    fn arm(&mut self) -> Result<(), DeviceError> {
        Err(self.refuse("arm"))
    }
    fn reset_interlocks(&mut self) -> Result<(), DeviceError> {
        Err(self.refuse("reset interlocks"))
    }
    fn set_rate(&mut self, _rate_deg_s: f64) -> Result<(), DeviceError> {
        Err(self.refuse("set rate"))
    }
    fn read_rate(&mut self) -> Result<f64, DeviceError> {
        Err(self.refuse("read rate"))
    }
    fn read_interlocks(&mut self) -> Result<bool, DeviceError> {
        Err(self.refuse("read interlocks"))
    }
    fn stop(&mut self) -> Result<(), DeviceError> {
        Err(self.refuse("stop"))
    }
    fn disarm(&mut self) -> Result<(), DeviceError> {
        Err(self.refuse("disarm"))
    }
}

impl HandedToStopKeeper {
    fn refuse(&self, command: &str) -> DeviceError {
        DeviceError {
            device: "centrifuge".into(),
            command: command.into(),
            kind: DeviceErrorKind::Rejected(format!(
                "{STOP_NOT_CONFIRMED}; the controller is being sent the stop until it answers"
            )),
        }
    }
}

/// Command the stop and read the rate back: the stop counts as confirmed
/// only when the controller answers after it.
fn stop_and_confirm(centrifuge: &mut dyn Centrifuge) -> Result<(), DeviceError> {
    centrifuge.stop()?;
    centrifuge.read_rate().map(|_| ())
}

/// Keep commanding the stop of a centrifuge whose controller did not
/// acknowledge it, every [`STOP_RETRY`], on a thread of its own, for as
/// long as the process lives (or until it is acknowledged, said on stderr).
pub fn keep_stopping(mut centrifuge: Box<dyn Centrifuge>) {
    UNCONFIRMED_STOPS.fetch_add(1, Ordering::SeqCst);
    let spawned = std::thread::Builder::new()
        .name("centrifuge stop keeper".into())
        .spawn(move || {
            let since = Instant::now();
            loop {
                std::thread::sleep(STOP_RETRY);
                if stop_and_confirm(centrifuge.as_mut()).is_ok() {
                    let _ = centrifuge.disarm();
                    UNCONFIRMED_STOPS.fetch_sub(1, Ordering::SeqCst);
                    eprintln!(
                        "  centrifuge: the stop was acknowledged {:.0} s after the run ended",
                        since.elapsed().as_secs_f64()
                    );
                    return;
                }
            }
        });
    if let Err(e) = spawned {
        eprintln!(
            "  {STOP_NOT_CONFIRMED}: cannot start the thread that keeps commanding the stop: {e}"
        );
    }
}

/// Centrifuges of this process whose stop is still being commanded.
static UNCONFIRMED_STOPS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// How many centrifuges of this process have a stop not yet acknowledged
/// (a program about to exit waits while this is above zero).
pub fn unconfirmed_stops() -> usize {
    UNCONFIRMED_STOPS.load(Ordering::SeqCst)
}
