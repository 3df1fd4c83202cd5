//! Adding a user, the one way both `spinbench user add` and the web API's
//! `POST /api/users` do it: the name and password checked, the role parsed,
//! the password hashed (Argon2id), the user stored and the addition audited.

use crate::web::auth::{self, Role};
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
    auth::check_new_user(name, password).map_err(AddUserError::Invalid)?;
    if store.user(name)?.is_some() {
        return Err(AddUserError::Exists(name.to_string()));
    }
    let hash = auth::hash_password(password).map_err(AddUserError::Hash)?;
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
            auth::check_new_user(name, p).map_err(AddUserError::Invalid)?;
            Some(auth::hash_password(p).map_err(AddUserError::Hash)?)
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
