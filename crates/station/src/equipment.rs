//! The equipment register at the start of a run (issue 16, part 4): a run
//! does not start while a device of the station is past its calibration's
//! due date, unless an admin overrides it with a reason (recorded in the
//! audit log). Shared by `spinbench run` and the web API.

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
