//! The users: their roles, the rules for names and passwords, the password
//! hash (Argon2id), and adding or changing a user, the one way both
//! `spinbench user …` and the web API do it (checked, hashed, stored and
//! audited). The web's sessions (`web::auth`) build on this; nothing here
//! reaches into the web.

use argon2::Argon2;
use argon2::password_hash::{PasswordHash, PasswordHasher, PasswordVerifier, SaltString};
use serde::Serialize;
use spinbench_store::Store;

/// Why a user could not be added.
#[derive(Debug, thiserror::Error)]
pub enum AddUserError {
    /// The name, password or role is not acceptable (what to do in words).
    #[error("{0}")]
    Invalid(String),
    /// A user of that name exists.
    #[error("user '{0}' exists")]
    Exists(String),
    /// The password could not be hashed.
    #[error("{0}")]
    Hash(String),
    /// The store failed.
    #[error(transparent)]
    Store(#[from] spinbench_store::StoreError),
}

/// Add user `name` with `role` (operator, engineer or admin) and
/// `password` to `store`; `by` is recorded in the audit log as who did it.
pub fn add_user(
    store: &Store,
    name: &str,
    role: &str,
    password: &str,
    by: &str,
) -> Result<Role, AddUserError> {
    let role = Role::parse(role).ok_or_else(|| {
        AddUserError::Invalid(format!("role '{role}': use operator, engineer or admin"))
    })?;
    check_new_user(name, password).map_err(|e| AddUserError::Invalid(e.to_string()))?;
    if store.user(name)?.is_some() {
        return Err(AddUserError::Exists(name.to_string()));
    }
    let hash = hash_password(password).map_err(|e| AddUserError::Hash(e.to_string()))?;
    store.add_user(name, role.as_str(), &hash)?;
    store.audit(by, "add user", &format!("{name} ({})", role.as_str()))?;
    Ok(role)
}

/// Change a user's role and/or password, the one way the command line and
/// the web API do it: checked, written, every session of the user ended (on
/// every server of the fleet: the store is the sessions' truth), audited.
/// The role as it now is.
pub fn change_user(
    store: &Store,
    name: &str,
    role: Option<&str>,
    password: Option<&str>,
    by: &str,
) -> Result<Role, AddUserError> {
    let Some(user) = store.user(name)? else {
        return Err(AddUserError::Invalid(format!(
            "no user '{}'",
            spinbench_engine::bounds::shown(name)
        )));
    };
    let role = match role {
        Some(r) => Role::parse(r).ok_or_else(|| {
            AddUserError::Invalid(format!("role '{r}': use operator, engineer or admin"))
        })?,
        None => Role::parse(&user.role).unwrap_or(Role::Operator),
    };
    if role.as_str() != user.role && user.role == Role::Admin.as_str() && only_admin(store, name)? {
        return Err(AddUserError::Invalid(format!(
            "{name} is the only admin; make another admin first"
        )));
    }
    let hash = match password {
        Some(p) => {
            check_new_user(name, p).map_err(|e| AddUserError::Invalid(e.to_string()))?;
            Some(hash_password(p).map_err(|e| AddUserError::Hash(e.to_string()))?)
        }
        None => None,
    };
    store.update_user(name, Some(role.as_str()), hash.as_deref())?;
    store.delete_sessions(Some(name), 0)?;
    let mut what = Vec::new();
    if role.as_str() != user.role {
        what.push(format!("role {} → {}", user.role, role.as_str()));
    }
    if hash.is_some() {
        what.push("password".to_string());
    }
    store.audit(by, "change user", &format!("{name}: {}", what.join(", ")))?;
    Ok(role)
}

/// Remove a user, the one way the command line and the web API do it:
/// their sessions end everywhere, audited. False when there was none.
pub fn remove_user(store: &Store, name: &str, by: &str) -> Result<bool, AddUserError> {
    if store
        .user(name)?
        .is_some_and(|u| u.role == Role::Admin.as_str())
        && only_admin(store, name)?
    {
        return Err(AddUserError::Invalid(format!(
            "{name} is the only admin; make another admin first"
        )));
    }
    if !store.delete_user(name)? {
        return Ok(false);
    }
    store.delete_sessions(Some(name), 0)?;
    store.audit(by, "remove user", name)?;
    Ok(true)
}

/// Whether `name` is the store's only admin.
fn only_admin(store: &Store, name: &str) -> Result<bool, AddUserError> {
    let admins: Vec<String> = store
        .users()?
        .into_iter()
        .filter(|u| u.role == Role::Admin.as_str())
        .map(|u| u.name)
        .collect();
    Ok(admins == [name])
}

/// The name of the operating-system user running this process, for records
/// of who did something from the command line: `$USER` or `$LOGNAME`, else
/// the name `/etc/passwd` gives the process's user id, else `uid N`.
pub fn os_user() -> String {
    for key in ["USER", "LOGNAME"] {
        if let Ok(name) = std::env::var(key)
            && !name.trim().is_empty()
        {
            return name.trim().to_string();
        }
    }
    // The real uid from /proc (no libc call needed), then its passwd entry.
    let uid = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("Uid:"))
                .and_then(|rest| rest.split_whitespace().next().map(str::to_string))
        });
    let Some(uid) = uid else {
        return "unknown user".into();
    };
    std::fs::read_to_string("/etc/passwd")
        .ok()
        .and_then(|passwd| {
            passwd.lines().find_map(|line| {
                let fields: Vec<&str> = line.split(':').collect();
                (fields.len() > 2 && fields[2] == uid).then(|| fields[0].to_string())
            })
        })
        .unwrap_or_else(|| format!("uid {uid}"))
}

/// What a user may do; each role may do everything the ones before it may.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// Runs tests: start, answer prompts, pause, resume, abort; reads everything.
    Operator,
    /// Also edits plans and the station config.
    Engineer,
    /// Also manages users and reads the audit log.
    Admin,
}

impl Role {
    /// Parse `operator`, `engineer` or `admin`.
    pub fn parse(text: &str) -> Option<Role> {
        match text {
            "operator" => Some(Role::Operator),
            "engineer" => Some(Role::Engineer),
            "admin" => Some(Role::Admin),
            _ => None,
        }
    }

    /// The role's name.
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Operator => "operator",
            Role::Engineer => "engineer",
            Role::Admin => "admin",
        }
    }
}

/// Why a user's name or password was refused, in words.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UserError {
    /// The name is empty, too long, or holds other characters.
    #[error(
        "user name '{shown}': 1 to {MAX_USER_NAME} ASCII letters, digits or . _ - @, with at least one letter or digit"
    )]
    BadName {
        /// The name as shown (a short prefix, invisible characters escaped).
        shown: String,
    },
    /// A new name not given in lower case.
    #[error("user name '{shown}': use it in lower case, as '{normal}'")]
    NotLowerCase {
        /// The name as given, shown.
        shown: String,
        /// The name as it would be kept.
        normal: String,
    },
    /// The password is too short.
    #[error("the password needs at least 8 characters")]
    ShortPassword,
    /// The password could not be hashed (the hashing library's words).
    #[error("the password could not be hashed: {0}")]
    Hash(String),
}

/// Hash a password (Argon2id, random salt) into a PHC string.
pub fn hash_password(password: &str) -> Result<String, UserError> {
    let salt: [u8; 16] = rand::random();
    let salt = SaltString::encode_b64(&salt).map_err(|e| UserError::Hash(e.to_string()))?;
    Argon2::default()
        .hash_password(password.as_bytes(), &salt)
        .map(|h| h.to_string())
        .map_err(|e| UserError::Hash(e.to_string()))
}

/// Whether `password` matches the stored `hash` (false for a malformed hash).
pub fn verify_password(password: &str, hash: &str) -> bool {
    PasswordHash::new(hash).is_ok_and(|h| {
        Argon2::default()
            .verify_password(password.as_bytes(), &h)
            .is_ok()
    })
}

/// Longest user name [characters].
pub const MAX_USER_NAME: usize = 64;

/// A user name as stored and compared: trimmed and lower-case, 1 to 64 of
/// the ASCII letters, digits and `. _ - @`, with at least one letter or
/// digit. Look-alikes (a Cyrillic "а" beside "admin") and names that are
/// only dots cannot be made. The problem in words, showing at most a short
/// prefix of what was given.
pub fn normalise_user_name(name: &str) -> Result<String, UserError> {
    let name = name.trim();
    let ok = !name.is_empty()
        && name.len() <= MAX_USER_NAME
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "._-@".contains(c))
        && name.chars().any(|c| c.is_ascii_alphanumeric());
    if !ok {
        return Err(UserError::BadName {
            shown: spinbench_engine::bounds::shown(name),
        });
    }
    Ok(name.to_ascii_lowercase())
}

/// Check a new user's name and password; the problem in words.
pub fn check_new_user(name: &str, password: &str) -> Result<(), UserError> {
    let normal = normalise_user_name(name)?;
    if normal != name {
        return Err(UserError::NotLowerCase {
            shown: spinbench_engine::bounds::shown(name),
            normal,
        });
    }
    if password.chars().count() < 8 {
        return Err(UserError::ShortPassword);
    }
    Ok(())
}
