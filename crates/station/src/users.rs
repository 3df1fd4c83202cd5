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
