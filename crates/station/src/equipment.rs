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
    let register = store.equipment()?;
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

/// "centrifuge (due 2026-01-01), fmu 1 (due …)": the overdue devices, if any.
pub fn overdue(equipment: &[(String, Option<EquipmentRow>, CalibrationStatus)]) -> Option<String> {
    let late: Vec<String> = equipment
        .iter()
        .filter(|(_, _, s)| *s == CalibrationStatus::Overdue)
        .map(|(role, row, _)| {
            format!(
                "{role} (due {})",
                row.as_ref().map_or("?", |r| r.due_on.as_str())
            )
        })
        .collect();
    (!late.is_empty()).then(|| late.join(", "))
}
