//! The safe state's keeper for the chamber and the instruments' supply:
//! what the safe state could not confirm (a controller
//! that timed out, one away beyond its outage budget) is tried again every
//! [`KEEP_RETRY`] on a thread of its own, until the device answers or the
//! process ends, as the centrifuge's stop is ([`super::keep_stopping`]).

use spinbench_devices::chamber::Chamber;
use spinbench_devices::psu::{OutputReading, PowerSupply};
use spinbench_devices::{DeviceError, DeviceErrorKind};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// How often the keeper tries again.
pub const KEEP_RETRY: Duration = Duration::from_secs(2);

/// How often the keeper says what is still left (on stderr).
const SAY_EVERY: Duration = Duration::from_secs(30);

/// A device whose safe state is not confirmed, with what is left of it.
pub enum Kept {
    /// The chamber: purge on, then the setpoint to the laboratory's
    /// temperature (read back).
    Chamber {
        /// Its driver.
        chamber: Box<dyn Chamber>,
        /// The laboratory's temperature [°C].
        ambient_c: f64,
        /// The purge is confirmed on.
        purge_on: bool,
        /// The setpoint is confirmed at ambient.
        at_ambient: bool,
    },
    /// The instruments' supply: outputs 1 and 2 off.
    Supply {
        /// Its driver.
        supply: Box<dyn PowerSupply>,
        /// Output 1 and 2 confirmed off.
        off: [bool; 2],
    },
}

impl Kept {
    /// The device's name in messages.
    pub fn device(&self) -> &'static str {
        match self {
            Kept::Chamber { .. } => "chamber",
            Kept::Supply { .. } => "instrument supply",
        }
    }

    /// Try what is left once; what is still left after.
    pub fn try_once(&mut self) -> Vec<String> {
        match self {
            Kept::Chamber {
                chamber,
                ambient_c,
                purge_on,
                at_ambient,
            } => {
                if !*purge_on {
                    *purge_on = chamber.set_purge(true).is_ok();
                }
                if !*at_ambient {
                    *at_ambient =
                        super::ports::set_and_confirm_setpoint(chamber.as_mut(), *ambient_c)
                            .is_ok();
                }
                let mut left = Vec::new();
                if !*purge_on {
                    left.push("purge on".to_string());
                }
                if !*at_ambient {
                    left.push(format!("setpoint to ambient ({ambient_c} °C)"));
                }
                left
            }
            Kept::Supply { supply, off } => {
                for (i, done) in off.iter_mut().enumerate() {
                    if !*done {
                        *done = supply.set_output(i as u8 + 1, false).is_ok();
                    }
                }
                off.iter()
                    .enumerate()
                    .filter(|(_, d)| !**d)
                    .map(|(i, _)| format!("output {} off", i + 1))
                    .collect()
            }
        }
    }
}

/// Devices of this process whose safe state is still being tried.
static KEPT: AtomicUsize = AtomicUsize::new(0);

/// How many devices of this process (besides an unconfirmed centrifuge
/// stop) have a safe state not yet confirmed (a program about to exit
/// waits while this is above zero).
pub fn unconfirmed_safe_devices() -> usize {
    KEPT.load(Ordering::SeqCst)
}

/// Go on trying `kept` every [`KEEP_RETRY`] on a thread of its own, for as
/// long as the process lives or until all of it is confirmed (said on
/// stderr, as is what is left every 30 s).
pub fn keep_making_safe(mut kept: Kept) {
    KEPT.fetch_add(1, Ordering::SeqCst);
    let spawned = std::thread::Builder::new()
        .name(format!("{} safe-state keeper", kept.device()))
        .spawn(move || {
            let since = Instant::now();
            let mut said = Instant::now();
            loop {
                std::thread::sleep(KEEP_RETRY);
                let left = kept.try_once();
                if left.is_empty() {
                    KEPT.fetch_sub(1, Ordering::SeqCst);
                    eprintln!(
                        "  {}: its safe state was confirmed {:.0} s after the run ended",
                        kept.device(),
                        since.elapsed().as_secs_f64()
                    );
                    return;
                }
                if said.elapsed() >= SAY_EVERY {
                    said = Instant::now();
                    eprintln!(
                        "  {}: still not confirmed after {:.0} s: {} (tried every {} s)",
                        kept.device(),
                        since.elapsed().as_secs_f64(),
                        left.join(", "),
                        KEEP_RETRY.as_secs()
                    );
                }
            }
        });
    if let Err(e) = spawned {
        eprintln!("  cannot start the thread that keeps making the devices safe: {e}");
    }
}

/// The executor's stand-in for a supply handed to the keeper.
pub(super) struct HandedToKeeper;

impl HandedToKeeper {
    fn refuse(&self, command: &str) -> DeviceError {
        DeviceError {
            device: "instrument supply".into(),
            command: command.into(),
            kind: DeviceErrorKind::Rejected(
                "its safe state was not confirmed; the keeper is switching its outputs off until it answers"
                    .into(),
            ),
        }
    }
}

impl PowerSupply for HandedToKeeper {
    fn identify(&mut self) -> Result<String, DeviceError> {
        Err(self.refuse("*IDN?"))
    }
    fn configure(&mut self, _: u8, _: f64, _: f64) -> Result<(), DeviceError> {
        Err(self.refuse("configure"))
    }
    fn set_output(&mut self, _: u8, _: bool) -> Result<(), DeviceError> {
        Err(self.refuse("set output"))
    }
    fn measure(&mut self, _: u8) -> Result<OutputReading, DeviceError> {
        Err(self.refuse("measure"))
    }
    fn clear_errors(&mut self) -> Result<Vec<(i32, String)>, DeviceError> {
        Err(self.refuse("clear errors"))
    }
}

#[cfg(test)]
mod tests {
    use super::Kept;
    use spinbench_devices::chamber::Chamber;
    use spinbench_devices::{DeviceError, DeviceErrorKind};
    use std::time::Duration;

    /// A chamber that does not answer its first `silent` commands, then
    /// holds what it is told.
    struct Rebooting {
        silent: u32,
        setpoint_c: f64,
        purge: bool,
    }

    impl Rebooting {
        fn answer(&mut self) -> Result<(), DeviceError> {
            if self.silent > 0 {
                self.silent -= 1;
                return Err(DeviceError {
                    device: "chamber".into(),
                    command: "any".into(),
                    kind: DeviceErrorKind::Timeout {
                        waited: Duration::from_millis(50),
                        attempts: 3,
                    },
                });
            }
            Ok(())
        }
    }

    impl Chamber for Rebooting {
        fn set_setpoint_c(&mut self, celsius: f64) -> Result<(), DeviceError> {
            self.answer()?;
            self.setpoint_c = celsius;
            Ok(())
        }
        fn setpoint_c(&mut self) -> Result<f64, DeviceError> {
            self.answer().map(|()| self.setpoint_c)
        }
        fn temperature_c(&mut self) -> Result<f64, DeviceError> {
            self.answer().map(|()| -40.0)
        }
        fn set_running(&mut self, _on: bool) -> Result<(), DeviceError> {
            self.answer()
        }
        fn alarms(&mut self) -> Result<u16, DeviceError> {
            self.answer().map(|()| 0)
        }
        fn set_purge(&mut self, on: bool) -> Result<(), DeviceError> {
            self.answer()?;
            self.purge = on;
            Ok(())
        }
    }

    #[test]
    fn the_keeper_goes_on_until_the_chamber_answers_and_says_what_is_left() {
        let mut kept = Kept::Chamber {
            chamber: Box::new(Rebooting {
                silent: 3,
                setpoint_c: -40.0,
                purge: false,
            }),
            ambient_c: 23.0,
            purge_on: false,
            at_ambient: false,
        };
        // Silent for the purge and the setpoint: both left.
        assert_eq!(kept.try_once(), ["purge on", "setpoint to ambient (23 °C)"]);
        // Still silent for the purge; the setpoint answers, read back.
        assert_eq!(kept.try_once(), ["purge on"]);
        assert!(kept.try_once().is_empty());
        let Kept::Chamber { chamber, .. } = &mut kept else {
            unreachable!("a chamber was kept")
        };
        assert_eq!(chamber.setpoint_c().expect("answers"), 23.0);
    }
}
