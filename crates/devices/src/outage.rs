//! Riding out a device that is briefly away: a controller rebooting (its
//! connection refused or reset), or one that answers "busy, ask again"
//! (Modbus exceptions 05 and 06). Written by hand: the back-off is a few
//! lines, and the retry crates are built around async or closures that own
//! the driver, which a driver calling itself cannot give them.

use std::time::{Duration, Instant};

/// First pause after a failure.
pub const FIRST_PAUSE: Duration = Duration::from_millis(100);

/// Longest pause between two tries.
pub const LONGEST_PAUSE: Duration = Duration::from_secs(2);

/// Default outage budget of a chamber controller: long enough for one to
/// reboot.
pub const DEFAULT_OUTAGE_S: f64 = 30.0;

/// Largest outage budget a config may give [s].
pub const MAX_OUTAGE_S: f64 = 300.0;

/// The outage of one command: since when, the next pause, and the budget.
#[derive(Debug, Clone)]
pub struct Outage {
    since: Instant,
    pause: Duration,
    budget: Duration,
    tries: u32,
}

impl Outage {
    /// An outage starting now, to be ridden for at most `budget`.
    pub fn new(budget: Duration) -> Outage {
        Outage {
            since: Instant::now(),
            pause: FIRST_PAUSE,
            budget,
            tries: 0,
        }
    }

    /// Wait before the next try (doubling from [`FIRST_PAUSE`] up to
    /// [`LONGEST_PAUSE`]) and say true; false, without waiting, when the
    /// next try would fall outside the budget.
    pub fn wait(&mut self) -> bool {
        if self.since.elapsed() + self.pause > self.budget {
            return false;
        }
        std::thread::sleep(self.pause);
        self.pause = (self.pause * 2).min(LONGEST_PAUSE);
        self.tries += 1;
        true
    }

    /// How long the outage has lasted.
    pub fn lasted(&self) -> Duration {
        self.since.elapsed()
    }

    /// Tries after the first.
    pub fn tries(&self) -> u32 {
        self.tries
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pauses_double_and_the_budget_ends_the_wait() {
        let mut o = Outage::new(Duration::from_millis(1000));
        let started = Instant::now();
        let mut tries = 0;
        while o.wait() {
            tries += 1;
        }
        // 100 + 200 + 400 ms fit in one second; 800 more would not.
        assert_eq!(tries, 3);
        assert!(started.elapsed() < Duration::from_millis(1000));
        assert!(started.elapsed() >= Duration::from_millis(700));
        assert_eq!(o.tries(), 3);
        assert!(!Outage::new(Duration::ZERO).wait());
    }
}
