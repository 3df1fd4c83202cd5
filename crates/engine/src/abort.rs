//! The abort request a run watches: set once by whoever stops the run (an
//! operator at the terminal or the web UI, or a signal that ends the
//! process), with who or what asked, so the run's record names it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// What the run records when the flag was set without a reason.
const UNNAMED: &str = "an operator's abort";

/// A shared abort request: cheap to clone, checked by the run loop every
/// time it waits. The first reason given is kept; later requests only add
/// nothing (the run is already going to its safe state).
#[derive(Debug, Clone, Default)]
pub struct AbortFlag {
    inner: Arc<Inner>,
}

#[derive(Debug, Default)]
struct Inner {
    set: AtomicBool,
    by: Mutex<Option<String>>,
}

impl AbortFlag {
    /// A flag not (yet) set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Ask the run to abort; `by` says who or what asked ("signal SIGTERM",
    /// "the web UI (user ana)"). Returns false when it was already set.
    pub fn request(&self, by: &str) -> bool {
        let mut who = self.inner.by.lock().unwrap_or_else(|e| e.into_inner());
        if who.is_none() {
            *who = Some(by.to_string());
        }
        !self.inner.set.swap(true, Ordering::SeqCst)
    }

    /// True once any abort was requested.
    pub fn is_set(&self) -> bool {
        self.inner.set.load(Ordering::SeqCst)
    }

    /// Who or what asked first.
    pub fn by(&self) -> String {
        self.inner
            .by
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
            .unwrap_or_else(|| UNNAMED.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_reason_is_kept_and_clones_share_the_flag() {
        let flag = AbortFlag::new();
        let seen = flag.clone();
        assert!(!seen.is_set());
        assert!(flag.request("signal SIGTERM"));
        assert!(!flag.request("signal SIGINT"));
        assert!(seen.is_set());
        assert_eq!(seen.by(), "signal SIGTERM");
    }
}
