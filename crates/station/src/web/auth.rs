//! Users, roles, sessions and CSRF for the web UI.
//!
//! Passwords are hashed with Argon2id (memory-hard; the `argon2` crate's
//! defaults: 19 MiB, 2 passes). A login opens a session: a random 256-bit
//! token in a cookie that is `HttpOnly` (no script reads it) and
//! `SameSite=Strict` (no other site sends it), and a second random token
//! for CSRF that every state-changing request must echo in the
//! `X-CSRF-Token` header. Sessions live in memory: a restart logs everyone out.

use serde::Serialize;
use spinbench_store::Store;
use std::collections::HashMap;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The session cookie's name.
pub const SESSION_COOKIE: &str = "spinbench_session";
/// The header that carries the CSRF token.
pub const CSRF_HEADER: &str = "x-csrf-token";
/// A session ends after this long without a request.
const IDLE_LIMIT: Duration = Duration::from_secs(12 * 3600);

// The roles and the password and name rules live with the users
// (`crate::users`), which the command line shares: the web uses them.
pub use crate::users::{
    MAX_USER_NAME, Role, check_new_user, hash_password, normalise_user_name, verify_password,
};

/// A logged-in user.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Session {
    /// User name.
    pub user: String,
    /// Role.
    pub role: Role,
    /// The CSRF token the browser must echo.
    pub csrf: String,
    #[serde(skip)]
    last_seen: Instant,
    /// When its use was last written to the store.
    #[serde(skip)]
    kept: Instant,
    /// When the store last confirmed it (another server may have ended it).
    #[serde(skip)]
    checked: Instant,
    /// A machine client's API token, not a browser's cookie: no CSRF token
    /// is asked of it ([`crate::tokens`]).
    #[serde(skip)]
    pub by_token: bool,
}

impl Session {
    /// The session of one call with an API token: `user` as the audit log
    /// names it ([`crate::tokens::token_user`]).
    pub fn machine(user: String, role: Role) -> Session {
        Session {
            user,
            role,
            csrf: String::new(),
            last_seen: Instant::now(),
            kept: Instant::now(),
            checked: Instant::now(),
            by_token: true,
        }
    }
}

fn random_token() -> String {
    crate::tokens::random_hex_256()
}

/// The open sessions: cached here, kept in the store (the SHA-256 of each
/// token, never the token) so a restart keeps operators logged in. A kept
/// session's role is its user's now: a user removed has no session. The
/// store is the truth for a fleet of servers on one store: a
/// cached session is confirmed against it at least every [`RECHECK`], so a
/// logout, a user's removal or a role change on another server ends it
/// here within that time.
#[derive(Default)]
pub struct Sessions {
    by_token: Mutex<HashMap<String, Session>>,
}

/// What the store said of a cached session ([`Sessions::confirm`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Confirmation {
    /// Open, as cached.
    Open,
    /// Ended elsewhere, or its role changed: over here too.
    Ended,
    /// The store did not answer: not known.
    Unknown,
}

/// What the cache holds for a request's token ([`Sessions::from_cache`]).
pub enum CacheHit {
    /// Not cached: the store may have it.
    Miss,
    /// Cached, but idle past the limit: ended.
    Expired,
    /// Cached and open.
    Hit {
        /// The session.
        session: Session,
        /// The store should confirm it now.
        recheck: bool,
        /// Its use should be written now.
        keep: bool,
    },
}

/// How often a session's use is written to the store.
const TOUCH_EVERY: Duration = Duration::from_secs(60);

/// How long a cached session is trusted before the store confirms it again.
pub const RECHECK: Duration = Duration::from_secs(2);

/// How long a session check waits for the store's connection while
/// another request holds it.
const SESSION_STORE_WAIT: Duration = Duration::from_millis(500);

/// The hex SHA-256 of a session token: what the store keeps.
fn token_hash(token: &str) -> String {
    crate::tokens::sha256_hex(token)
}

impl Sessions {
    /// Open a session and keep it in `store`; its cookie token and the session.
    pub fn open(&self, store: &Store, user: &str, role: Role) -> (String, Session) {
        let token = random_token();
        let session = Session {
            user: user.to_string(),
            role,
            csrf: random_token(),
            last_seen: Instant::now(),
            kept: Instant::now(),
            checked: Instant::now(),
            by_token: false,
        };
        // A store that cannot keep it leaves a session for this process's life.
        let _ = store.save_session(&token_hash(&token), user, &session.csrf);
        let mut map = self.by_token.lock().unwrap_or_else(|e| e.into_inner());
        map.retain(|_, s| s.last_seen.elapsed() < IDLE_LIMIT);
        map.insert(token.clone(), session.clone());
        (token, session)
    }

    /// The session of a cookie token, if open (and mark it used): from the
    /// cache, or else from the store (a session from before a restart). The
    /// store is locked only to read a session the cache does not have, to
    /// end one, or to keep its use (at most once a minute): a request of a
    /// known session does not wait for the store.
    pub fn get(&self, store: &Mutex<Store>, token: &str) -> Option<Session> {
        match self.from_cache(token) {
            CacheHit::Expired => {
                self.expire(store, token);
                None
            }
            CacheHit::Hit {
                session,
                recheck,
                keep,
            } => (self.confirm(store, token, &session, recheck, keep) != Confirmation::Ended)
                .then_some(session),
            CacheHit::Miss => self.load(store, token),
        }
    }

    /// What the cache holds for a token (the session marked used), and
    /// whether the store should confirm it ([`RECHECK`]) or keep its use
    /// ([`TOUCH_EVERY`]) now; the store is not asked.
    pub fn from_cache(&self, token: &str) -> CacheHit {
        let mut map = self.by_token.lock().unwrap_or_else(|e| e.into_inner());
        let Some(session) = map.get_mut(token) else {
            return CacheHit::Miss;
        };
        if session.last_seen.elapsed() >= IDLE_LIMIT {
            map.remove(token);
            return CacheHit::Expired;
        }
        session.last_seen = Instant::now();
        let keep = session.kept.elapsed() >= TOUCH_EVERY;
        if keep {
            session.kept = Instant::now();
        }
        let recheck = session.checked.elapsed() >= RECHECK;
        if recheck {
            session.checked = Instant::now();
        }
        CacheHit::Hit {
            session: session.clone(),
            recheck,
            keep,
        }
    }

    /// A session idle past the limit, ended in the store too.
    pub fn expire(&self, store: &Mutex<Store>, token: &str) {
        if let Some(s) = crate::web::lock_within(store, SESSION_STORE_WAIT) {
            let _ = s.delete_session(&token_hash(token));
        }
    }

    /// The store's part of a cached session's use: with `recheck`, whether
    /// it was ended elsewhere (logout, the user removed) or its role
    /// changed (then it is over here too); with `keep`, its use written. A
    /// store that cannot answer (down, or its connection held by a call
    /// that does not come back) leaves the cached session standing for
    /// reading and the safety controls, [`Confirmation::Unknown`]: a change
    /// is refused on it.
    pub fn confirm(
        &self,
        store: &Mutex<Store>,
        token: &str,
        found: &Session,
        recheck: bool,
        keep: bool,
    ) -> Confirmation {
        let store = || crate::web::lock_within(store, SESSION_STORE_WAIT);
        let mut answer = Confirmation::Open;
        if recheck {
            let kept = store().map(|s| s.session(&token_hash(token)));
            let over = match &kept {
                Some(Ok(None)) => true,
                Some(Ok(Some((_, role, _, _)))) => Role::parse(role) != Some(found.role),
                _ => {
                    answer = Confirmation::Unknown;
                    self.recheck_soon(token);
                    false
                }
            };
            if over {
                self.by_token
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .remove(token);
                if let Some(s) = store() {
                    let _ = s.delete_session(&token_hash(token));
                }
                return Confirmation::Ended;
            }
        }
        if keep && let Some(s) = store() {
            let _ = s.save_session(&token_hash(token), &found.user, &found.csrf);
        }
        answer
    }

    /// Confirm the session against the store at its next use (the last
    /// check could not reach it).
    pub fn recheck_soon(&self, token: &str) {
        let mut map = self.by_token.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(s) = map.get_mut(token) {
            s.checked = Instant::now()
                .checked_sub(RECHECK)
                .unwrap_or_else(Instant::now);
        }
    }

    /// A session the cache does not have, read from the store (one from
    /// before a restart, or another server's of the fleet) and cached.
    fn load(&self, store: &Mutex<Store>, token: &str) -> Option<Session> {
        let store = crate::web::lock_within(store, SESSION_STORE_WAIT)?;
        let hash = token_hash(token);
        let (user, role, csrf, last_seen) = store.session(&hash).ok().flatten()?;
        let idle = now_unix().saturating_sub(last_seen).max(0) as u64;
        let role = Role::parse(&role)?;
        if idle >= IDLE_LIMIT.as_secs() {
            let _ = store.delete_session(&hash);
            return None;
        }
        let _ = store.save_session(&hash, &user, &csrf);
        let session = Session {
            user,
            role,
            csrf,
            last_seen: Instant::now(),
            kept: Instant::now(),
            checked: Instant::now(),
            by_token: false,
        };
        self.by_token
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(token.to_string(), session.clone());
        Some(session)
    }

    /// Close a session (logout).
    pub fn close(&self, store: &Store, token: &str) {
        self.by_token
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(token);
        let _ = store.delete_session(&token_hash(token));
    }

    /// Close every session of a user (deleted, or the role changed), and
    /// every kept session idle past the limit.
    pub fn close_user(&self, store: &Store, user: &str) {
        self.by_token
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .retain(|_, s| s.user != user);
        let _ = store.delete_sessions(Some(user), now_unix() - IDLE_LIMIT.as_secs() as i64);
    }
}

fn now_unix() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64)
}

/// The session token in a `Cookie` header, if any.
pub fn session_token(cookie_header: &str) -> Option<String> {
    cookie::Cookie::split_parse(cookie_header)
        .flatten()
        .find(|c| c.name() == SESSION_COOKIE)
        .map(|c| c.value().to_string())
}

/// The `Set-Cookie` value that opens (or, with `None`, ends) a session;
/// `secure` (served over TLS) keeps the browser from sending it over plain HTTP.
pub fn session_cookie(token: Option<&str>, secure: bool) -> String {
    let secure = if secure { "; Secure" } else { "" };
    match token {
        Some(t) => format!("{SESSION_COOKIE}={t}; HttpOnly; SameSite=Strict; Path=/{secure}"),
        None => format!("{SESSION_COOKIE}=; HttpOnly; SameSite=Strict; Path=/; Max-Age=0{secure}"),
    }
}

/// Compare two tokens in time that does not depend on where they differ.
pub fn same_token(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_password_verifies_against_its_hash_only() {
        let hash = hash_password("correct horse").expect("hash");
        assert!(hash.starts_with("$argon2id$"), "{hash}");
        assert!(verify_password("correct horse", &hash));
        assert!(!verify_password("correct horsf", &hash));
        assert!(!verify_password("correct horse", "not a hash"));
        // Salted: the same password hashes differently.
        assert_ne!(hash, hash_password("correct horse").expect("hash"));
    }

    #[test]
    fn cookies_tokens_and_names() {
        assert_eq!(
            session_token("a=1; spinbench_session=abc; b=2").as_deref(),
            Some("abc")
        );
        assert_eq!(session_token("a=1"), None);
        assert!(session_cookie(Some("t"), false).contains("HttpOnly; SameSite=Strict"));
        assert!(!session_cookie(Some("t"), false).contains("Secure"));
        assert!(session_cookie(Some("t"), true).ends_with("; Secure"));
        assert!(session_cookie(None, true).ends_with("Max-Age=0; Secure"));
        assert!(same_token("abc", "abc") && !same_token("abc", "abd") && !same_token("a", "ab"));
        assert!(check_new_user("op_1", "12345678").is_ok());
        assert!(check_new_user("bad name", "12345678").is_err());
        // Look-alikes and dot names cannot be made; names compare in lower case.
        assert!(check_new_user("\u{430}dmin", "12345678").is_err());
        assert!(check_new_user(".", "12345678").is_err());
        assert!(check_new_user("..", "12345678").is_err());
        assert!(check_new_user("Admin", "12345678").is_err());
        assert_eq!(normalise_user_name(" Admin ").as_deref(), Ok("admin"));
        let long = normalise_user_name(&"x".repeat(2_000_000))
            .expect_err("too long")
            .to_string();
        assert!(long.len() < 300, "{}", long.len());
        assert_eq!(
            check_new_user("ok", "short"),
            Err(crate::users::UserError::ShortPassword)
        );
        assert!(Role::Admin > Role::Engineer && Role::Engineer > Role::Operator);
    }
}
