//! API tokens for machine clients: an MES or a line controller calls the
//! API with `Authorization: Bearer sbt_…` instead of logging in as a
//! person. A token has a name (the machine it is for) and a role; its
//! secret is shown once, when it is made, and the store keeps its SHA-256
//! only (a token is 256 random bits, so a fast hash is enough: nothing can
//! be guessed from it, unlike a password). Made and revoked by an admin,
//! the one way `spinbench token …` and the web API do it, and audited.
//!
//! A token call needs no CSRF token: CSRF is a browser sending a cookie
//! on another site's behalf, and no browser sends a bearer header by itself.

use crate::users::{Role, normalise_user_name};
use spinbench_store::{ApiTokenRow, Store};

/// What every token's secret starts with (so a leaked one is recognisable
/// to a secret scanner, and a session cookie is never taken for one).
pub const TOKEN_PREFIX: &str = "sbt_";

/// How a token call is named in the audit log and as a run's operator.
pub fn token_user(name: &str) -> String {
    format!("token:{name}")
}

/// Why a token could not be made or revoked.
#[derive(Debug, thiserror::Error)]
pub enum TokenError {
    /// The name or role is not acceptable (what to do in words).
    #[error("{0}")]
    Invalid(String),
    /// A token of that name exists (or existed: names are not reused).
    #[error("an API token named '{0}' exists or was revoked: choose another name")]
    Exists(String),
    /// No live token of that name.
    #[error("no API token '{0}' that is not revoked (spinbench token list)")]
    Unknown(String),
    /// The store failed.
    #[error(transparent)]
    Store(#[from] spinbench_store::StoreError),
}

/// A token just made: its name, role and the secret (shown this once).
#[derive(Debug, Clone)]
pub struct NewToken {
    /// Its name.
    pub name: String,
    /// Its role.
    pub role: Role,
    /// The secret a client sends as `Authorization: Bearer <secret>`.
    pub secret: String,
}

/// The hex SHA-256 of a token's secret: what the store keeps.
pub fn secret_hash(secret: &str) -> String {
    sha256_hex(secret)
}

/// The hex SHA-256 of `text` (what the store keeps of a session's or an
/// API token's secret).
pub(crate) fn sha256_hex(text: &str) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(text.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// 256 random bits as 64 hex digits (a session's or an API token's secret).
pub(crate) fn random_hex_256() -> String {
    let bytes: [u8; 32] = rand::random();
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Whether `secret` is shaped like a token's secret (prefix and 64 hex
/// digits): anything else is refused before the store is asked.
pub fn is_token_shaped(secret: &str) -> bool {
    secret
        .strip_prefix(TOKEN_PREFIX)
        .is_some_and(|hex| hex.len() == 64 && hex.bytes().all(|b| b.is_ascii_hexdigit()))
}

/// Make the token `name` with `role` (operator, engineer or admin); `by`
/// is audited as who made it.
pub fn add_token(store: &Store, name: &str, role: &str, by: &str) -> Result<NewToken, TokenError> {
    let role = Role::parse(role).ok_or_else(|| {
        TokenError::Invalid(format!("role '{role}': use operator, engineer or admin"))
    })?;
    let normal = normalise_user_name(name)
        .map_err(|e| TokenError::Invalid(e.to_string().replace("user name", "token name")))?;
    if normal != name {
        return Err(TokenError::Invalid(format!(
            "token name '{}': use it in lower case, as '{normal}'",
            spinbench_engine::bounds::shown(name)
        )));
    }
    if store.api_tokens()?.iter().any(|t| t.name == name) {
        return Err(TokenError::Exists(name.to_string()));
    }
    let secret = format!("{TOKEN_PREFIX}{}", random_hex_256());
    store.add_api_token(name, role.as_str(), &secret_hash(&secret), by)?;
    Ok(NewToken {
        name: name.to_string(),
        role,
        secret,
    })
}

/// Revoke the token `name`; `by` is audited.
pub fn revoke_token(store: &Store, name: &str, by: &str) -> Result<(), TokenError> {
    if store.revoke_api_token(name, by)? {
        Ok(())
    } else {
        Err(TokenError::Unknown(spinbench_engine::bounds::shown(name)))
    }
}

/// The live token whose secret is `secret`, with its role (none for a
/// revoked or unknown one, or one not shaped like a secret).
pub fn token_of(store: &Store, secret: &str) -> Result<Option<(ApiTokenRow, Role)>, TokenError> {
    if !is_token_shaped(secret) {
        return Ok(None);
    }
    Ok(store
        .api_token_by_hash(&secret_hash(secret))?
        .and_then(|t| Role::parse(&t.role).map(|r| (t, r))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_token_is_made_once_found_by_its_secret_and_refused_once_revoked() {
        let dir = tempfile::tempdir().expect("tempdir");
        let store = Store::open(&dir.path().join("s.db")).expect("store");
        let made = add_token(&store, "mes-line-3", "operator", "admin").expect("made");
        assert!(is_token_shaped(&made.secret), "{}", made.secret);
        let (row, role) = token_of(&store, &made.secret)
            .expect("read")
            .expect("found");
        assert_eq!((row.name.as_str(), role), ("mes-line-3", Role::Operator));
        // The store keeps the hash, never the secret.
        let kept = store.api_tokens().expect("list");
        assert_eq!(kept.len(), 1);
        assert!(format!("{kept:?}").find(&made.secret[4..]).is_none());
        // A near miss, a cookie-like string and a second token of the name.
        let mut wrong = made.secret.clone();
        wrong.replace_range(
            10..11,
            if &made.secret[10..11] == "0" {
                "1"
            } else {
                "0"
            },
        );
        assert!(token_of(&store, &wrong).expect("read").is_none());
        assert!(token_of(&store, "abc").expect("read").is_none());
        assert!(matches!(
            add_token(&store, "mes-line-3", "admin", "admin"),
            Err(TokenError::Exists(_))
        ));
        assert!(matches!(
            add_token(&store, "MES", "operator", "admin"),
            Err(TokenError::Invalid(_))
        ));
        assert!(matches!(
            add_token(&store, "mes-2", "root", "admin"),
            Err(TokenError::Invalid(_))
        ));
        revoke_token(&store, "mes-line-3", "admin").expect("revoked");
        assert!(token_of(&store, &made.secret).expect("read").is_none());
        assert!(matches!(
            revoke_token(&store, "mes-line-3", "admin"),
            Err(TokenError::Unknown(_))
        ));
        let audit = store.audit_log(10).expect("audit");
        assert_eq!(audit[0].action, "revoke API token");
        assert_eq!(audit[1].action, "add API token");
        assert_eq!(audit[1].detail, "mes-line-3 (operator)");
        let listed = &store.api_tokens().expect("list")[0];
        assert_eq!(listed.revoked_by.as_deref(), Some("admin"));
    }
}
