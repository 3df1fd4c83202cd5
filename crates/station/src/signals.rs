//! The signals that end a process driving hardware: SIGINT (Ctrl-C),
//! SIGTERM (a service manager's stop) and SIGHUP (the terminal closed) all
//! abort the run the same way, so the engine brings the station to its safe
//! state and records which signal ended the run before the process exits.

use anyhow::{Context, Result};
use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
use spinbench_engine::AbortFlag;

/// The signals handled, with what each usually means.
pub const TERMINATION_SIGNALS: [(i32, &str, &str); 3] = [
    (SIGINT, "SIGINT", "Ctrl-C"),
    (
        SIGTERM,
        "SIGTERM",
        "asked to stop, e.g. by a service manager",
    ),
    (SIGHUP, "SIGHUP", "the terminal closed"),
];

/// Termination signals received by this process so far.
static RECEIVED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// How many termination signals this process has received.
pub fn received() -> usize {
    RECEIVED.load(std::sync::atomic::Ordering::SeqCst)
}

/// What waiting for the safe state's keepers found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafeWait {
    /// How long the process waited for them [s] (0: nothing was left).
    pub waited_s: f64,
    /// Every stop and device is confirmed safe now.
    pub all_confirmed: bool,
}

/// Before the program exits: while a centrifuge's stop is not acknowledged,
/// keep the process (and the thread that commands the stop) alive, saying
/// so every 10 s, until it is acknowledged or another signal comes.
pub fn wait_for_unconfirmed_stops() -> SafeWait {
    use spinbench_engine::executor::{
        KEEP_RETRY, STOP_NOT_CONFIRMED, unconfirmed_safe_devices, unconfirmed_stops,
    };
    let left = || unconfirmed_stops() + unconfirmed_safe_devices();
    if left() == 0 {
        return SafeWait {
            waited_s: 0.0,
            all_confirmed: true,
        };
    }
    let signals_before = received();
    let since = std::time::Instant::now();
    let mut said = None::<std::time::Instant>;
    while left() > 0 && received() == signals_before {
        if said.is_none_or(|t| t.elapsed() >= std::time::Duration::from_secs(10)) {
            if unconfirmed_stops() > 0 {
                eprintln!(
                    "  {STOP_NOT_CONFIRMED} — the stop is commanded again every 2 s ({:.0} s so far); \
                     Ctrl-C leaves without it",
                    since.elapsed().as_secs_f64()
                );
            }
            if unconfirmed_safe_devices() > 0 {
                eprintln!(
                    "  {} device(s) not confirmed safe — tried again every {} s ({:.0} s so far); \
                     Ctrl-C leaves without it",
                    unconfirmed_safe_devices(),
                    KEEP_RETRY.as_secs(),
                    since.elapsed().as_secs_f64()
                );
            }
            said = Some(std::time::Instant::now());
        }
        std::thread::sleep(std::time::Duration::from_millis(200));
    }
    SafeWait {
        waited_s: since.elapsed().as_secs_f64(),
        all_confirmed: left() == 0,
    }
}

/// The abort reason a signal gives, e.g. "signal SIGTERM (asked to stop, …)".
pub fn reason_of(signal: i32) -> String {
    match TERMINATION_SIGNALS.iter().find(|(s, _, _)| *s == signal) {
        Some((_, name, what)) => format!("signal {name} ({what})"),
        None => format!("signal {signal}"),
    }
}

/// From now on, SIGINT, SIGTERM and SIGHUP set `flag` (naming the signal)
/// instead of ending the process: the run goes to its safe state and ends
/// `aborted`. Later signals only say that the station is being made safe.
pub fn abort_on_termination_signals(flag: AbortFlag) -> Result<()> {
    let mut signals =
        signal_hook::iterator::Signals::new(TERMINATION_SIGNALS.iter().map(|(s, _, _)| *s))
            .context("cannot install the handlers of SIGINT, SIGTERM and SIGHUP")?;
    std::thread::Builder::new()
        .name("termination signals".into())
        .spawn(move || {
            for signal in signals.forever() {
                RECEIVED.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                let reason = reason_of(signal);
                if flag.request(&reason) {
                    eprintln!(
                        "\n  {reason}: stopping the run and bringing the station to its safe state…"
                    );
                } else {
                    eprintln!("\n  {reason}: already stopping; the station is being made safe");
                }
            }
        })
        .context("cannot start the signal thread")?;
    Ok(())
}
