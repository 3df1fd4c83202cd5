//! The equipment register, kept per station:
//! each device of each station by its station and its role in a run (`centrifuge`, `fmu 1`, `instrument supply`, …), its
//! identity, calibration certificate, the date it was calibrated and the date
//! it is due. Engineers keep it; every change is in the audit log.

use crate::db::Value;
use crate::{Store, StoreError, now_s};

/// One device in the register.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EquipmentRow {
    /// The station it belongs to (its config's `station`; '' for an entry
    /// kept from before the register was per station, used by none).
    pub station: String,
    /// Its role in a run, as the run's device list names it.
    pub role: String,
    /// What it is (the identity it answers with, or a description).
    pub identity: String,
    /// The calibration certificate's number.
    pub certificate: String,
    /// Calibrated on (YYYY-MM-DD).
    pub calibrated_on: String,
    /// Due on (YYYY-MM-DD).
    pub due_on: String,
    /// Who last changed the entry.
    pub updated_by: String,
    /// When [Unix s].
    pub updated_at: i64,
}

/// How a device stands against its due date.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum CalibrationStatus {
    /// Within its calibration, more than [`DUE_SOON_DAYS`] days to go.
    #[serde(rename = "valid")]
    Valid,
    /// Due within [`DUE_SOON_DAYS`] days.
    #[serde(rename = "due soon")]
    DueSoon,
    /// Past its due date.
    #[serde(rename = "overdue")]
    Overdue,
    /// Not in the register.
    #[serde(rename = "not in the register")]
    Unregistered,
}

/// "Due soon" this many days before the due date.
pub const DUE_SOON_DAYS: i64 = 30;

impl CalibrationStatus {
    /// Its name in reports and the API.
    pub fn as_str(self) -> &'static str {
        match self {
            CalibrationStatus::Valid => "valid",
            CalibrationStatus::DueSoon => "due soon",
            CalibrationStatus::Overdue => "overdue",
            CalibrationStatus::Unregistered => "not in the register",
        }
    }
}

/// The civil date (UTC) of a Unix time, YYYY-MM-DD (Howard Hinnant's
/// algorithm: no date crate for one conversion).
pub fn civil_date(unix_s: i64) -> String {
    let days = unix_s.div_euclid(86_400);
    let (y, m, d) = civil_from_days(days);
    format!("{y:04}-{m:02}-{d:02}")
}

/// (year, month, day) of a day count since 1970-01-01.
pub fn civil_from_days(days: i64) -> (i64, i64, i64) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

/// Days since 1970-01-01 of a YYYY-MM-DD date, if it is one (years 1970–2200).
pub fn parse_date(text: &str) -> Option<i64> {
    let mut parts = text.split('-');
    let (y, m, d) = (parts.next()?, parts.next()?, parts.next()?);
    if parts.next().is_some() || y.len() != 4 || m.len() != 2 || d.len() != 2 {
        return None;
    }
    let (y, m, d): (i64, i64, i64) = (y.parse().ok()?, m.parse().ok()?, d.parse().ok()?);
    if !(1970..=2200).contains(&y) || !(1..=12).contains(&m) || d < 1 {
        return None;
    }
    // Days from civil (the inverse of civil_from_days).
    let yy = if m <= 2 { y - 1 } else { y };
    let era = yy.div_euclid(400);
    let yoe = yy - era * 400;
    let mp = if m > 2 { m - 3 } else { m + 9 };
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    // 31 February and the like come back as another date: refused.
    (civil_from_days(days) == (y, m, d)).then_some(days)
}

/// Why a calibration's dates were refused (dates shown as YYYY-MM-DD).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CalibrationDateError {
    /// Calibrated after today.
    #[error(
        "calibrated on {calibrated} is after today ({today}): give the date on the certificate"
    )]
    CalibratedInFuture {
        /// The calibration date.
        calibrated: String,
        /// Today.
        today: String,
    },
    /// Due no later than calibrated.
    #[error("due on {due} is not after calibrated on {calibrated}")]
    DueBeforeCalibrated {
        /// The due date.
        due: String,
        /// The calibration date.
        calibrated: String,
    },
}

/// Check a calibration's dates (days since 1970-01-01): calibrated no later
/// than `today`, due after it was calibrated.
pub fn check_calibration_dates(
    calibrated: i64,
    due: i64,
    today: i64,
) -> Result<(), CalibrationDateError> {
    if calibrated > today {
        return Err(CalibrationDateError::CalibratedInFuture {
            calibrated: civil_date(calibrated * 86_400),
            today: civil_date(today * 86_400),
        });
    }
    if due <= calibrated {
        return Err(CalibrationDateError::DueBeforeCalibrated {
            due: civil_date(due * 86_400),
            calibrated: civil_date(calibrated * 86_400),
        });
    }
    Ok(())
}

/// Whether `role` can name a device of a run: `centrifuge`, `fmu N`,
/// `instrument supply`, `module supply` (a typo would leave the real device
/// unregistered while the register looks kept).
pub fn is_device_role(role: &str) -> bool {
    matches!(role, "centrifuge" | "instrument supply" | "module supply")
        || role
            .strip_prefix("fmu ")
            .and_then(|n| n.parse::<u32>().ok())
            .is_some_and(|n| (1..=64).contains(&n) && role == format!("fmu {n}"))
}

/// The status on `today` (days since 1970-01-01) of a device due on
/// `due_on` (YYYY-MM-DD; a date that is not one counts as overdue).
pub fn status_of_due(due_on: &str, today: i64) -> CalibrationStatus {
    match parse_date(due_on) {
        Some(due) if due < today => CalibrationStatus::Overdue,
        Some(due) if due - today <= DUE_SOON_DAYS => CalibrationStatus::DueSoon,
        Some(_) => CalibrationStatus::Valid,
        None => CalibrationStatus::Overdue,
    }
}

impl EquipmentRow {
    /// Its status on `today` (days since 1970-01-01).
    pub fn status_on(&self, today: i64) -> CalibrationStatus {
        status_of_due(&self.due_on, today)
    }
}

/// Today, as days since 1970-01-01 (UTC).
pub fn today() -> i64 {
    now_s().div_euclid(86_400)
}

impl Store {
    /// The register of `station` by role, or with `None` every station's
    /// (by station, then role). A station sees only its own devices: two
    /// stations of a fleet each have a centrifuge of their own.
    pub fn equipment(&self, station: Option<&str>) -> Result<Vec<EquipmentRow>, StoreError> {
        let columns = "SELECT station, role, identity, certificate, calibrated_on, due_on, updated_by, updated_at
                 FROM equipment";
        let rows = match station {
            Some(name) => self.query(
                "read the equipment register",
                &format!("{columns} WHERE station = $1 ORDER BY role"),
                &[name.into()],
            )?,
            None => self.query(
                "read the equipment register",
                &format!("{columns} ORDER BY station, role"),
                &[],
            )?,
        };
        Ok(rows
            .iter()
            .map(|r| EquipmentRow {
                station: r.text(0),
                role: r.text(1),
                identity: r.text(2),
                certificate: r.text(3),
                calibrated_on: r.text(4),
                due_on: r.text(5),
                updated_by: r.text(6),
                updated_at: r.int(7),
            })
            .collect())
    }

    /// Add or replace a device's entry, and record who did it in the audit
    /// log, in one transaction. The dates must be YYYY-MM-DD (checked by
    /// the caller, who names the field).
    pub fn set_equipment(&self, row: &EquipmentRow, who: &str) -> Result<(), StoreError> {
        let detail = format!(
            "station '{}', {}: {}, certificate {}, calibrated {}, due {}",
            row.station, row.role, row.identity, row.certificate, row.calibrated_on, row.due_on
        );
        self.db()
            .transaction(|db| {
                db.execute(
                    "INSERT INTO equipment (role, identity, certificate, calibrated_on, due_on, updated_by, updated_at, station)
                     VALUES ($1, $2, $3, $4, $5, $6, $7, $8)
                     ON CONFLICT (station, role) DO UPDATE SET identity = excluded.identity,
                       certificate = excluded.certificate, calibrated_on = excluded.calibrated_on,
                       due_on = excluded.due_on, updated_by = excluded.updated_by,
                       updated_at = excluded.updated_at",
                    &[
                        row.role.as_str().into(),
                        row.identity.as_str().into(),
                        row.certificate.as_str().into(),
                        row.calibrated_on.as_str().into(),
                        row.due_on.as_str().into(),
                        who.into(),
                        Value::Int(Some(now_s())),
                        row.station.as_str().into(),
                    ],
                )?;
                crate::users::insert_audit(db, who, "set equipment", &detail)
            })
            .map_err(self.err("write the equipment register"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_round_trip_and_impossible_ones_are_refused() {
        for (text, days) in [
            ("1970-01-01", 0),
            ("2026-11-23", 20_780),
            ("2000-02-29", 11_016),
        ] {
            assert_eq!(parse_date(text), Some(days), "{text}");
            assert_eq!(civil_date(days * 86_400), text);
        }
        for bad in [
            "2026-02-30",
            "2026-13-01",
            "2026-1-01",
            "26-01-01",
            "2026-01-01x",
            "",
            "1969-12-31",
        ] {
            assert_eq!(parse_date(bad), None, "{bad}");
        }
    }

    #[test]
    fn status_by_due_date() {
        let row = |due: &str| EquipmentRow {
            station: "A".into(),
            role: "centrifuge".into(),
            identity: String::new(),
            certificate: String::new(),
            calibrated_on: "2026-01-01".into(),
            due_on: due.into(),
            updated_by: String::new(),
            updated_at: 0,
        };
        let today = parse_date("2026-11-23").expect("date");
        assert_eq!(
            row("2026-11-22").status_on(today),
            CalibrationStatus::Overdue
        );
        assert_eq!(
            row("2026-11-23").status_on(today),
            CalibrationStatus::DueSoon
        );
        assert_eq!(
            row("2026-12-23").status_on(today),
            CalibrationStatus::DueSoon
        );
        assert_eq!(row("2026-12-24").status_on(today), CalibrationStatus::Valid);
    }
}
