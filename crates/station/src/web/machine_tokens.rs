//! The API tokens this server has seen, cached as the sessions are: the
//! store is the truth (a token revoked on another server of the fleet is
//! refused here within [`auth::RECHECK`]), and a cached token answers the
//! safety controls (abort, pause) while the store does not.

use super::auth::{self, Role, Session};
use spinbench_store::Store;
use std::collections::HashMap;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// How often a token's use is written to the store.
const TOUCH_EVERY: Duration = Duration::from_secs(60);

/// How long a token check waits for the store's connection.
const STORE_WAIT: Duration = Duration::from_millis(500);

/// Where a token's role was read.
struct Known {
    name: String,
    role: Role,
    checked: Instant,
    touched: Instant,
}

/// What a check of a token's secret found.
pub enum TokenCheck {
    /// A live token: the session of this call.
    Valid(Session),
    /// Unknown or revoked.
    Refused,
    /// The store did not answer and the token is not cached (or the call
    /// changes something, and a token revoked elsewhere must not).
    Unknown,
}

/// The cache of tokens by their secret's hash.
#[derive(Default)]
pub struct MachineTokens {
    by_hash: Mutex<HashMap<String, Known>>,
}

impl MachineTokens {
    /// Check `secret` (blocking: may ask the store). With `confirm`, a
    /// token due for a check is confirmed against the store first; without,
    /// a cached token stands when the store cannot answer.
    pub fn check(&self, store: &Mutex<Store>, secret: &str, confirm: bool) -> TokenCheck {
        if !crate::tokens::is_token_shaped(secret) {
            return TokenCheck::Refused;
        }
        let hash = crate::tokens::secret_hash(secret);
        let cached = {
            let map = self.lock();
            map.get(&hash)
                .map(|k| (k.name.clone(), k.role, k.checked.elapsed() < auth::RECHECK))
        };
        if let Some((name, role, true)) = &cached {
            return TokenCheck::Valid(Session::machine(crate::tokens::token_user(name), *role));
        }
        let Some(store) = super::lock_within(store, STORE_WAIT) else {
            return self.stale(cached, confirm);
        };
        match crate::tokens::token_of(&store, secret) {
            Ok(Some((row, role))) => {
                let mut map = self.lock();
                let touch = map
                    .get(&hash)
                    .is_none_or(|k| k.touched.elapsed() >= TOUCH_EVERY);
                let touched = if touch {
                    // A use not noted costs nothing but the column's freshness.
                    let _ = store.touch_api_token(&row.name);
                    Instant::now()
                } else {
                    map.get(&hash).map_or_else(Instant::now, |k| k.touched)
                };
                map.insert(
                    hash,
                    Known {
                        name: row.name.clone(),
                        role,
                        checked: Instant::now(),
                        touched,
                    },
                );
                TokenCheck::Valid(Session::machine(crate::tokens::token_user(&row.name), role))
            }
            Ok(None) => {
                self.lock().remove(&hash);
                TokenCheck::Refused
            }
            Err(_) => self.stale(cached, confirm),
        }
    }

    /// A token the store could not confirm: standing from the cache for a
    /// call that changes nothing or is a safety control.
    fn stale(&self, cached: Option<(String, Role, bool)>, confirm: bool) -> TokenCheck {
        match cached {
            Some((name, role, _)) if !confirm => {
                TokenCheck::Valid(Session::machine(crate::tokens::token_user(&name), role))
            }
            _ => TokenCheck::Unknown,
        }
    }

    /// Forget the token `name` (revoked here).
    pub fn forget(&self, name: &str) {
        self.lock().retain(|_, k| k.name != name);
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<String, Known>> {
        self.by_hash.lock().unwrap_or_else(|e| e.into_inner())
    }
}
