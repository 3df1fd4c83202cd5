//! `spinbench user`: the web UI's users (the first admin is made here).

use super::open_store;
use anyhow::{Context, Result};
use spinbench_store::StoreTarget;
use std::io::Write;

/// `spinbench user add NAME`: the password from `SPINBENCH_PASSWORD` or one
/// line of standard input; added the one way the web API adds users too.
pub(super) fn add(name: &str, role: &str, db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let password = read_password(name)?;
    // Checked before a new store file is made for it.
    crate::users::check_new_user(name, &password).map_err(anyhow::Error::msg)?;
    let store = create_store(db)?;
    let role = crate::users::add_user(&store, name, role, &password, "spinbench (command line)")
        .with_context(|| format!("{db}: user '{name}'"))?;
    writeln!(out, "user {name} added as {} in {db}", role.as_str())?;
    Ok(())
}

/// `spinbench user list`.
pub(super) fn list(db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let store = open_store(db)?;
    for u in store.users()? {
        writeln!(out, "{:<24} {}", u.name, u.role)?;
    }
    Ok(())
}

/// The password from `SPINBENCH_PASSWORD`, else one line of standard input.
fn read_password(name: &str) -> Result<String> {
    match std::env::var("SPINBENCH_PASSWORD") {
        Ok(p) => Ok(p),
        Err(_) => {
            eprintln!("password for {name} (one line on standard input):");
            let mut line = String::new();
            std::io::stdin()
                .read_line(&mut line)
                .context("cannot read the password")?;
            Ok(line.trim_end_matches(['\r', '\n']).to_string())
        }
    }
}

/// `spinbench user role NAME ROLE` and `spinbench user passwd NAME`.
pub(super) fn change(
    name: &str,
    role: Option<&str>,
    password: bool,
    db: &StoreTarget,
    out: &mut dyn Write,
) -> Result<()> {
    let password = if password {
        Some(read_password(name)?)
    } else {
        None
    };
    let store = spinbench_store::Store::connect(db)?;
    let by = format!("{} (command line)", crate::users::os_user());
    let role = crate::users::change_user(&store, name, role, password.as_deref(), &by)
        .with_context(|| format!("{db}: user '{name}'"))?;
    writeln!(
        out,
        "user {name} is {}{}; their sessions have ended",
        role.as_str(),
        if password.is_some() {
            ", password changed"
        } else {
            ""
        }
    )?;
    Ok(())
}

/// `spinbench user remove NAME`.
pub(super) fn remove(name: &str, db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let store = spinbench_store::Store::connect(db)?;
    let by = format!("{} (command line)", crate::users::os_user());
    if !crate::users::remove_user(&store, name, &by)
        .with_context(|| format!("{db}: user '{name}'"))?
    {
        anyhow::bail!("{db}: no user '{name}' (spinbench user list)");
    }
    writeln!(out, "user {name} removed; their sessions have ended")?;
    Ok(())
}

/// The store, made (with its directory) when it is not there yet.
fn create_store(db: &StoreTarget) -> Result<spinbench_store::Store> {
    if let StoreTarget::File(path) = db
        && let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
    {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
    }
    Ok(spinbench_store::Store::connect(db)?)
}

/// A store that exists, opened to be written (a token is for a station's
/// store: none is made for it).
fn open_store_to_change(db: &StoreTarget) -> Result<spinbench_store::Store> {
    drop(open_store(db)?);
    Ok(spinbench_store::Store::connect(db)?)
}

/// `spinbench token add NAME`: the secret printed this once.
pub(super) fn add_token(
    name: &str,
    role: &str,
    db: &StoreTarget,
    out: &mut dyn Write,
) -> Result<()> {
    // Made before the first `serve` as the first admin is: the store with it.
    let store = create_store(db)?;
    let by = format!("{} (command line)", crate::users::os_user());
    let made = crate::tokens::add_token(&store, name, role, &by)
        .with_context(|| format!("{db}: API token '{name}'"))?;
    writeln!(
        out,
        "API token {name} made as {} in {db}; its secret, shown this once \
         (the client sends it as 'Authorization: Bearer <secret>'):\n{}",
        made.role.as_str(),
        made.secret
    )?;
    Ok(())
}

/// `spinbench token list`.
pub(super) fn list_tokens(db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    use spinbench_report::lang::{Lang, date_time};
    let store = open_store(db)?;
    for t in store.api_tokens()? {
        let state = match (&t.revoked_at, &t.revoked_by) {
            (Some(at), by) => format!(
                "revoked {} by {}",
                date_time(Lang::En, *at),
                by.as_deref().unwrap_or("?")
            ),
            (None, _) => match t.last_used_at {
                Some(at) => format!("live, last used {}", date_time(Lang::En, at)),
                None => "live, never used".to_string(),
            },
        };
        writeln!(
            out,
            "{:<24} {:<9} made {} by {}; {state}",
            t.name,
            t.role,
            date_time(Lang::En, t.created_at),
            t.created_by
        )?;
    }
    Ok(())
}

/// `spinbench token revoke NAME`.
pub(super) fn revoke_token(name: &str, db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let store = open_store_to_change(db)?;
    let by = format!("{} (command line)", crate::users::os_user());
    crate::tokens::revoke_token(&store, name, &by).with_context(|| format!("{db}: API token"))?;
    writeln!(
        out,
        "API token {name} revoked; its calls are refused on every server within seconds"
    )?;
    Ok(())
}
