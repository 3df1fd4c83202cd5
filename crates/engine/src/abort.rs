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
    /// The user of the web UI who asked first, when a user did: the run's
    /// wording names them (`fault.aborted_web`), not the English `by`.
    user: Mutex<Option<String>>,
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

    /// Ask the run to abort as the web UI's `user` ("the web UI (user
    /// ana)" in the record; the wording keeps the user apart, so a page in
    /// another language says it in its own words).
    pub fn request_by_user(&self, user: &str) -> bool {
        {
            let mut first = self.inner.user.lock().unwrap_or_else(|e| e.into_inner());
            let by = self.inner.by.lock().unwrap_or_else(|e| e.into_inner());
            if by.is_none() && first.is_none() {
                *first = Some(user.to_string());
            }
        }
        self.request(&format!("the web UI (user {user})"))
    }

    /// The web UI's user who asked first, if the first to ask was one.
    pub fn user(&self) -> Option<String> {
        self.inner
            .user
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
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
        assert_eq!(seen.user(), None);
        // A signal first: the user who asks later is not the one recorded.
        assert!(!flag.request_by_user("ana"));
        assert_eq!(flag.user(), None);
        let web = AbortFlag::new();
        assert!(web.request_by_user("ana"));
        assert_eq!(web.by(), "the web UI (user ana)");
        assert_eq!(web.user().as_deref(), Some("ana"));
    }
}
