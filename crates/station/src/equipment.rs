//! The equipment register at the start of a run: a run
//! does not start while a device of the station is past its calibration's
//! due date, unless an admin overrides it with a reason (recorded in the
//! audit log). One admission gate ([`admit`]) for `spinbench run` and the
//! web API: the same rule, the same reason check and the
//! same audit line; each caller only words the refusal its own way.

use spinbench_engine::StationConfig;
use spinbench_store::Store;
use spinbench_store::equipment::{CalibrationStatus, EquipmentRow, today};

/// Every device of `station` with its register entry (if any) and status.
pub fn station_equipment(
    store: &Store,
    station: &StationConfig,
) -> Result<Vec<(String, Option<EquipmentRow>, CalibrationStatus)>, spinbench_store::StoreError> {
    let register = store.equipment(Some(&station.station))?;
    let today = today();
    Ok(station
        .device_roles()
        .into_iter()
        .map(|role| {
            let row = register.iter().find(|r| r.role == role).cloned();
            let status = row
                .as_ref()
                .map_or(CalibrationStatus::Unregistered, |r| r.status_on(today));
            (role, row, status)
        })
        .collect())
}

/// "centrifuge (due 2026-01-01), fmu 1 (due …)": the devices that hold a
/// new run back, if any: those past their due date, and with
/// `require_registered` (the station's `[equipment]`) those not in the
/// register.
pub fn overdue(
    equipment: &[(String, Option<EquipmentRow>, CalibrationStatus)],
    require_registered: bool,
) -> Option<String> {
    let late: Vec<String> = equipment
        .iter()
        .filter_map(|(role, row, status)| match status {
            CalibrationStatus::Overdue => Some(format!(
                "{role} (due {}, overdue)",
                row.as_ref().map_or("?", |r| r.due_on.as_str())
            )),
            CalibrationStatus::Unregistered if require_registered => Some(format!(
                "{role} (not in the equipment register, so its calibration is unknown)"
            )),
            _ => None,
        })
        .collect();
    (!late.is_empty()).then(|| late.join(", "))
}

/// The longest reason an override may give [characters].
pub const MAX_OVERRIDE_REASON_CHARS: usize = 500;

/// The audit log's action of an override.
pub const OVERRIDE_ACTION: &str = "override overdue calibration";

/// What the gate decided for a new run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Admission {
    /// Every device's calibration clears it.
    Clear,
    /// Devices hold it back, and an override lets it start anyway.
    Overridden {
        /// The devices ("centrifuge (due 2026-01-01, overdue)").
        devices: String,
        /// The override's reason, checked.
        reason: String,
    },
}

impl Admission {
    /// The override's audit detail for the run `started` ("RUN started"),
    /// `None` when nothing was overridden.
    pub fn audit_detail(&self, started: &str) -> Option<String> {
        match self {
            Admission::Clear => None,
            Admission::Overridden { devices, reason } => {
                Some(format!("{started} with {devices}: {reason}"))
            }
        }
    }
}

/// Why the gate refused a new run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// Devices hold it back and no override was given.
    #[error("{devices}: calibration not cleared")]
    Overdue {
        /// The devices.
        devices: String,
    },
    /// An override was given by someone who may not override.
    #[error("{devices}: calibration not cleared; only an admin may start a run anyway")]
    NotAllowed {
        /// The devices.
        devices: String,
    },
    /// The override's reason breaks the rules for text from outside.
    #[error("the override's reason: {why}")]
    BadReason {
        /// What is wrong with it.
        why: String,
    },
}

/// The one admission gate: the devices that hold a new run back
/// ([`overdue`]), and an override's `reason` (blank is none), which only
/// someone who `may_override` gives and which must be a plain text of at
/// most [`MAX_OVERRIDE_REASON_CHARS`] (`bounds::reason_text`).
pub fn admit(
    equipment: &[(String, Option<EquipmentRow>, CalibrationStatus)],
    require_registered: bool,
    reason: Option<&str>,
    may_override: bool,
) -> Result<Admission, Refusal> {
    let Some(devices) = overdue(equipment, require_registered) else {
        return Ok(Admission::Clear);
    };
    let Some(reason) = reason.map(str::trim).filter(|r| !r.is_empty()) else {
        return Err(Refusal::Overdue { devices });
    };
    if !may_override {
        return Err(Refusal::NotAllowed { devices });
    }
    let reason = spinbench_engine::bounds::reason_text(reason, MAX_OVERRIDE_REASON_CHARS).map_err(
        |why| Refusal::BadReason {
            why: why.to_string(),
        },
    )?;
    Ok(Admission::Overridden {
        devices,
        reason: reason.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn late() -> Vec<(String, Option<EquipmentRow>, CalibrationStatus)> {
        vec![
            ("centrifuge".into(), None, CalibrationStatus::Unregistered),
            ("fmu 1".into(), None, CalibrationStatus::Overdue),
        ]
    }

    #[test]
    fn the_gate_admits_refuses_and_checks_an_override_one_way_for_every_caller() {
        assert_eq!(
            admit(&late()[..1], false, None, false),
            Ok(Admission::Clear)
        );
        assert!(matches!(
            admit(&late(), false, Some("  "), true),
            Err(Refusal::Overdue { devices }) if devices == "fmu 1 (due ?, overdue)"
        ));
        assert!(matches!(
            admit(&late(), true, Some("booked"), false),
            Err(Refusal::NotAllowed { devices }) if devices.starts_with("centrifuge (not in the equipment register")
        ));
        assert!(matches!(
            admit(&late(), false, Some("line\u{202e}stop"), true),
            Err(Refusal::BadReason { .. })
        ));
        assert!(matches!(
            admit(&late(), false, Some(&"x".repeat(501)), true),
            Err(Refusal::BadReason { .. })
        ));
        let ok = admit(&late(), false, Some(" recalibration booked "), true).expect("overridden");
        assert_eq!(
            ok.audit_detail("run-1 started").as_deref(),
            Some("run-1 started with fmu 1 (due ?, overdue): recalibration booked")
        );
        assert_eq!(Admission::Clear.audit_detail("run-1 started"), None);
    }
}
