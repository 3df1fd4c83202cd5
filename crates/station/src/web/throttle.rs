//! Login throttling: failed logins are counted per user name and per
//! client address; past a limit within a window the name (or address) is
//! locked for a while and every login for it gets 429 with `Retry-After`,
//! so passwords cannot be guessed at the server's speed. The table is
//! bounded: old entries go first when it is full.

use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Failed logins of one user name within [`WINDOW`] before it is locked.
pub const FAILURES_PER_NAME: u32 = 5;
/// Failed logins from one address within [`WINDOW`] before it is locked.
pub const FAILURES_PER_ADDRESS: u32 = 20;
/// The window failures are counted in.
pub const WINDOW: Duration = Duration::from_secs(60);
/// How long a lock lasts.
pub const LOCKOUT: Duration = Duration::from_secs(60);
/// Most names and addresses remembered.
const MAX_ENTRIES: usize = 10_000;

/// What is counted: a user name or a client address.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Key {
    /// A (normalised, bounded) user name.
    Name(String),
    /// A client address.
    Address(IpAddr),
}

#[derive(Debug, Clone, Copy)]
struct Entry {
    first_failure: Instant,
    failures: u32,
    locked_until: Option<Instant>,
}

/// The counters; one per server.
#[derive(Debug, Default)]
pub struct LoginThrottle {
    entries: Mutex<HashMap<Key, Entry>>,
    refusals: Mutex<RefusalBudget>,
}

/// Most refused logins written to the audit log one by one per minute;
/// beyond, they are counted and written as one line (a
/// flood from many addresses wrote 120 rows a second and slowed every
/// request).
pub const REFUSALS_AUDITED_PER_MINUTE: u32 = 60;

/// This minute's refused logins: written one by one, and counted only.
#[derive(Debug, Default)]
struct RefusalBudget {
    since: Option<Instant>,
    written: u32,
    counted: u32,
}

/// What to write to the audit log for one refused login.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RefusalAudit {
    /// Write this refusal's own line.
    pub write: bool,
    /// First write one line for this many refusals counted, not written,
    /// in the minute before.
    pub counted_before: u32,
}

/// A login refused before the password is checked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Locked {
    /// What is locked.
    pub what: String,
    /// Seconds until it may try again.
    pub retry_after_s: u64,
}

impl LoginThrottle {
    /// Refuse a login for `name` from `address` while either is locked.
    pub fn check(&self, name: &str, address: IpAddr) -> Result<(), Locked> {
        let entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        let now = Instant::now();
        for (key, what) in [
            (Key::Name(name.to_string()), format!("user name '{name}'")),
            (Key::Address(address), format!("address {address}")),
        ] {
            if let Some(until) = entries.get(&key).and_then(|e| e.locked_until)
                && until > now
            {
                return Err(Locked {
                    what,
                    retry_after_s: (until - now).as_secs().max(1),
                });
            }
        }
        Ok(())
    }

    /// Count a failed login; returns what became locked by it (for the audit log).
    pub fn failed(&self, name: &str, address: IpAddr) -> Vec<String> {
        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        let now = Instant::now();
        if entries.len() >= MAX_ENTRIES {
            entries.retain(|_, e| {
                e.locked_until.is_some_and(|u| u > now) || now - e.first_failure < WINDOW
            });
            if entries.len() >= MAX_ENTRIES {
                // Still full of live entries: forget the oldest half.
                let mut ages: Vec<Instant> = entries.values().map(|e| e.first_failure).collect();
                ages.sort();
                let cut = ages[ages.len() / 2];
                entries.retain(|_, e| e.first_failure > cut);
            }
        }
        let mut locked = Vec::new();
        for (key, limit, what) in [
            (
                Key::Name(name.to_string()),
                FAILURES_PER_NAME,
                format!("user name '{name}'"),
            ),
            (
                Key::Address(address),
                FAILURES_PER_ADDRESS,
                format!("address {address}"),
            ),
        ] {
            let entry = entries.entry(key).or_insert(Entry {
                first_failure: now,
                failures: 0,
                locked_until: None,
            });
            if now - entry.first_failure > WINDOW {
                entry.first_failure = now;
                entry.failures = 0;
            }
            entry.failures += 1;
            if entry.failures >= limit && entry.locked_until.is_none_or(|u| u <= now) {
                entry.locked_until = Some(now + LOCKOUT);
                entry.failures = 0;
                entry.first_failure = now;
                locked.push(what);
            }
        }
        locked
    }

    /// A login was refused: whether its own audit line is written, and how
    /// many refusals of the minute before were only counted.
    pub fn refusal_audit(&self) -> RefusalAudit {
        let mut b = self.refusals.lock().unwrap_or_else(|e| e.into_inner());
        let now = Instant::now();
        let mut counted_before = 0;
        if b.since.is_none_or(|t| now - t >= WINDOW) {
            counted_before = b.counted;
            *b = RefusalBudget {
                since: Some(now),
                written: 0,
                counted: 0,
            };
        }
        let write = b.written < REFUSALS_AUDITED_PER_MINUTE;
        if write {
            b.written += 1;
        } else {
            b.counted += 1;
        }
        RefusalAudit {
            write,
            counted_before,
        }
    }

    /// A successful login clears the name's failures.
    pub fn succeeded(&self, name: &str) {
        self.entries
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&Key::Name(name.to_string()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_is_locked_after_its_failures_and_others_are_not() {
        let t = LoginThrottle::default();
        let here: IpAddr = [127, 0, 0, 1].into();
        for i in 1..FAILURES_PER_NAME {
            assert!(t.check("admin", here).is_ok(), "failure {i}");
            assert!(t.failed("admin", here).is_empty());
        }
        assert_eq!(
            t.failed("admin", here),
            vec!["user name 'admin'".to_string()]
        );
        let locked = t.check("admin", here).expect_err("locked");
        assert!(locked.retry_after_s >= 1 && locked.retry_after_s <= LOCKOUT.as_secs());
        assert!(t.check("ana", here).is_ok());
    }

    #[test]
    fn a_flood_of_refusals_writes_a_bounded_number_of_audit_lines() {
        let t = LoginThrottle::default();
        let written = (0..500).filter(|_| t.refusal_audit().write).count();
        assert_eq!(written, REFUSALS_AUDITED_PER_MINUTE as usize);
        // The next minute starts by writing one line for the 440 counted.
        t.refusals.lock().expect("lock").since = Some(Instant::now() - WINDOW);
        let next = t.refusal_audit();
        assert!(next.write);
        assert_eq!(next.counted_before, 440);
    }
}
