//! `spinbench equipment`: the register of the station's devices and their
//! calibration (kept by engineers; the web UI's register is the same table).

use super::open_store;
use anyhow::{Context, Result};
use spinbench_store::StoreTarget;
use spinbench_store::equipment::{EquipmentRow, parse_date, today};
use std::io::Write;

/// `spinbench equipment list [--station NAME]`.
pub(super) fn list(station: Option<&str>, db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let store = open_store(db)?;
    let today = today();
    writeln!(
        out,
        "{:<24} {:<18} {:<28} {:<16} {:<11} {:<11} status",
        "station", "role", "identity", "certificate", "calibrated", "due"
    )?;
    for r in store.equipment(station)? {
        writeln!(
            out,
            "{:<24} {:<18} {:<28} {:<16} {:<11} {:<11} {}",
            if r.station.is_empty() {
                "(none: set again with --station)"
            } else {
                r.station.as_str()
            },
            r.role,
            r.identity,
            r.certificate,
            r.calibrated_on,
            r.due_on,
            r.status_on(today).as_str()
        )?;
    }
    Ok(())
}

/// One entry of `spinbench equipment set`, as typed.
pub(super) struct Entry<'a> {
    /// ROLE.
    pub role: &'a str,
    /// --identity.
    pub identity: &'a str,
    /// --certificate.
    pub certificate: &'a str,
    /// --calibrated.
    pub calibrated: &'a str,
    /// --due.
    pub due: &'a str,
    /// --station, if given.
    pub station: Option<&'a str>,
}

/// The station an entry is for: `--station` as given (checked as every
/// name from outside), or the only station the store knows.
fn station_of(store: &spinbench_store::Store, given: Option<&str>) -> Result<String> {
    if let Some(name) = given {
        let name = spinbench_engine::bounds::person_text(name)
            .map_err(|why| anyhow::anyhow!("--station: {why}"))?;
        anyhow::ensure!(
            !name.is_empty() && name.chars().count() <= spinbench_engine::bounds::MAX_NAME_CHARS,
            "--station: 1 to {} characters",
            spinbench_engine::bounds::MAX_NAME_CHARS
        );
        return Ok(name);
    }
    let known: Vec<String> = store
        .stations()?
        .into_iter()
        .map(|s| s.beat.station)
        .collect();
    match known.as_slice() {
        [only] => Ok(only.clone()),
        [] => anyhow::bail!(
            "--station NAME is needed: this store knows no station yet (give the `station` of its station.toml)"
        ),
        many => anyhow::bail!(
            "--station NAME is needed: this store keeps the register of {} stations ({})",
            many.len(),
            many.join(", ")
        ),
    }
}

/// `spinbench equipment set ROLE …`.
pub(super) fn set(entry: &Entry<'_>, db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let Entry {
        role,
        identity,
        certificate,
        calibrated,
        due,
        station,
    } = *entry;
    let text_ok = |t: &str| {
        !t.trim().is_empty() && t.chars().count() <= 200 && !t.chars().any(char::is_control)
    };
    for (what, t) in [
        ("ROLE", role),
        ("--identity", identity),
        ("--certificate", certificate),
    ] {
        anyhow::ensure!(
            text_ok(t),
            "{what}: 1 to 200 characters, no control characters"
        );
    }
    let c = parse_date(calibrated).with_context(|| {
        format!("--calibrated '{calibrated}': a date YYYY-MM-DD (1970 to 2200)")
    })?;
    let d = parse_date(due)
        .with_context(|| format!("--due '{due}': a date YYYY-MM-DD (1970 to 2200)"))?;
    anyhow::ensure!(
        spinbench_store::equipment::is_device_role(role),
        "ROLE '{role}' is not a device of a run: centrifuge, fmu 1, fmu 2 …, instrument supply or module supply"
    );
    let today_days = spinbench_store::now_s().div_euclid(86_400);
    spinbench_store::equipment::check_calibration_dates(c, d, today_days)
        .map_err(|why| anyhow::anyhow!("--calibrated {calibrated} --due {due}: {why}"))?;
    let store = spinbench_store::Store::connect(db)?;
    let station = station_of(&store, station)?;
    let who = std::env::var("USER").unwrap_or_else(|_| "spinbench".into());
    let row = EquipmentRow {
        station,
        role: role.trim().to_string(),
        identity: spinbench_engine::bounds::person_text(identity)
            .map_err(|why| anyhow::anyhow!("--identity: {why}"))?,
        certificate: spinbench_engine::bounds::person_text(certificate)
            .map_err(|why| anyhow::anyhow!("--certificate: {why}"))?,
        calibrated_on: calibrated.to_string(),
        due_on: due.to_string(),
        updated_by: who.clone(),
        updated_at: 0,
    };
    store.set_equipment(&row, &format!("{who} (command line)"))?;
    writeln!(
        out,
        "{} of station '{}': certificate {}, due {} ({})",
        row.role,
        row.station,
        row.certificate,
        row.due_on,
        row.status_on(today()).as_str()
    )?;
    Ok(())
}
