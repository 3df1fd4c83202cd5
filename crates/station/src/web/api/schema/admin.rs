//! The bodies of the station's administration: the equipment register,
//! the users, the audit log and the fleet.

use super::FleetStationState;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// One device of the equipment register.
#[derive(Debug, Serialize, ToSchema)]
pub struct EquipmentEntry {
    /// The station it belongs to (this server's: each station of a fleet
    /// keeps its own register).
    pub station: String,
    /// Its role (`centrifuge`, `fmu 1`, `instrument supply`, …).
    pub role: String,
    /// Identity as registered.
    pub identity: Option<String>,
    /// Calibration certificate.
    pub certificate: Option<String>,
    /// Calibrated on (YYYY-MM-DD).
    pub calibrated_on: Option<String>,
    /// Due on (YYYY-MM-DD).
    pub due_on: Option<String>,
    /// Who registered it.
    pub updated_by: Option<String>,
    /// `valid`, `due soon`, `overdue` or `not in the register`.
    pub status: String,
    /// The identity the station read from the device in its newest run
    /// (its `*IDN?` answer, a module's firmware): offered to an engineer
    /// to register it; absent before the station's first run.
    pub read_identity: Option<String>,
}

/// `PUT /api/equipment/{role}`.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SetEquipment {
    /// Make, model, serial (not blank, no control characters).
    #[schema(
        min_length = 1,
        max_length = 200,
        pattern = "^[^\\x00-\\x1f\\x7f-\\x9f]*[^\\s\\x00-\\x1f\\x7f-\\x9f][^\\x00-\\x1f\\x7f-\\x9f]*$"
    )]
    pub identity: String,
    /// Certificate number (not blank, no control characters).
    #[schema(
        min_length = 1,
        max_length = 200,
        pattern = "^[^\\x00-\\x1f\\x7f-\\x9f]*[^\\s\\x00-\\x1f\\x7f-\\x9f][^\\x00-\\x1f\\x7f-\\x9f]*$"
    )]
    pub certificate: String,
    /// YYYY-MM-DD, 1970 to 2200.
    #[schema(
        pattern = "^(19[7-9][0-9]|2[01][0-9][0-9]|2200)-(0[1-9]|1[0-2])-(0[1-9]|1[0-9]|2[0-8])$"
    )]
    pub calibrated_on: String,
    /// YYYY-MM-DD, after `calibrated_on`.
    #[schema(
        pattern = "^(19[7-9][0-9]|2[01][0-9][0-9]|2200)-(0[1-9]|1[0-2])-(0[1-9]|1[0-9]|2[0-8])$"
    )]
    pub due_on: String,
}

/// Its answer.
#[derive(Debug, Serialize, ToSchema)]
pub struct EquipmentSaved {
    /// The device.
    pub role: String,
    /// Its new due date.
    pub due_on: String,
}

/// One user.
#[derive(Debug, Serialize, ToSchema)]
pub struct UserEntry {
    /// Name.
    pub name: String,
    /// Role.
    pub role: String,
    /// Unix time it was made [s].
    pub created_at: i64,
}

/// `POST /api/users`.
#[derive(Debug, Deserialize, ToSchema)]
pub struct NewUser {
    /// Lower-case ASCII letters, digits, `.`, `_`, `-`, `@`, with at least one letter or digit.
    #[schema(max_length = 64, pattern = "^[a-z0-9._@-]*[a-z0-9][a-z0-9._@-]*$")]
    pub name: String,
    /// Its role.
    #[schema(value_type = crate::web::auth::Role)]
    pub role: String,
    /// At least 8 characters.
    #[schema(min_length = 8, max_length = 1024)]
    pub password: String,
}

/// A change of a user (an admin): role and/or password; either may be left out.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ChangeUser {
    /// The new role.
    #[schema(value_type = Option<crate::web::auth::Role>)]
    pub role: Option<String>,
    /// The new password, at least 8 characters.
    #[schema(min_length = 8, max_length = 1024)]
    pub password: Option<String>,
}

/// Its answer.
#[derive(Debug, Serialize, ToSchema)]
pub struct UserAdded {
    /// Name.
    pub name: String,
    /// Role.
    pub role: String,
}

/// One entry of the audit log.
#[derive(Debug, Serialize, ToSchema)]
pub struct AuditEntry {
    /// Its number.
    pub seq: i64,
    /// Unix time [s].
    pub at: i64,
    /// Who.
    pub who: String,
    /// What.
    pub action: String,
    /// The details.
    pub detail: String,
}

/// One station of the fleet (every station writing into this store).
#[derive(Debug, Serialize, ToSchema)]
pub struct FleetStation {
    /// The station's id (its config's `station`).
    pub station: String,
    /// `idle`, `running`, `waiting`, `faulted` or `offline` (no heartbeat
    /// for 10 s).
    #[schema(value_type = FleetStationState)]
    pub state: String,
    /// `server` (a `spinbench serve`) or `command line` (seen only through
    /// the runs of `spinbench run`, so never heard between runs).
    pub kind: String,
    /// Its current run (absent when offline).
    pub run_id: Option<String>,
    /// That run's label (`2026-11-24 · station 1 · #7`), as people name it.
    pub run_label: Option<String>,
    /// Steps done of the current run.
    pub steps_done: Option<i64>,
    /// Steps in the current run.
    pub steps_total: Option<i64>,
    /// Where its web UI answers.
    pub address: Option<String>,
    /// When it was last heard [Unix s].
    pub last_seen: i64,
    /// Instruments graded today (UTC) in first tests.
    pub tested_today: i64,
    /// Of them, passed.
    pub passed_today: i64,
    /// First-pass yield today (passed over tested), absent with none tested.
    pub first_pass_yield: Option<f64>,
    /// Its latest run's instruments by outcome (pass, marginal, fail,
    /// inconclusive, incomplete: how many of each; absent ones are 0).
    #[schema(value_type = std::collections::BTreeMap<String, i64>)]
    pub last_run_outcomes: std::collections::BTreeMap<String, i64>,
    /// This is the station of the server answering.
    pub this_station: bool,
}

/// One API token of a machine client (its secret is never shown again).
#[derive(Debug, Serialize, ToSchema)]
pub struct TokenEntry {
    /// Its name (the machine it is for).
    pub name: String,
    /// Its role.
    #[schema(value_type = crate::web::auth::Role)]
    pub role: String,
    /// Who made it.
    pub created_by: String,
    /// Unix time it was made [s].
    pub created_at: i64,
    /// Unix time it was last used (at most a minute late) [s].
    pub last_used_at: Option<i64>,
    /// Unix time it was revoked [s]; a revoked token is refused.
    pub revoked_at: Option<i64>,
    /// Who revoked it.
    pub revoked_by: Option<String>,
}

/// `POST /api/tokens`.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct NewToken {
    /// The machine it is for: lower-case ASCII letters, digits, `.`, `_`,
    /// `-`, `@`, with at least one letter or digit; never reused.
    #[schema(max_length = 64, pattern = "^[a-z0-9._@-]*[a-z0-9][a-z0-9._@-]*$")]
    pub name: String,
    /// Its role (what its calls may do).
    #[schema(value_type = crate::web::auth::Role)]
    pub role: String,
}

/// Its answer: the secret, shown this once.
#[derive(Debug, Serialize, ToSchema)]
pub struct TokenMade {
    /// Its name.
    pub name: String,
    /// Its role.
    #[schema(value_type = crate::web::auth::Role)]
    pub role: String,
    /// What the client sends as `Authorization: Bearer <secret>`; the
    /// station keeps its SHA-256 only and cannot show it again.
    pub secret: String,
}

/// The webhooks of this server and their last deliveries.
#[derive(Debug, Serialize, ToSchema)]
pub struct WebhooksReply {
    /// The receiver's URL (without any user or password), or null when
    /// this server sends no webhooks (`serve --webhook-url`).
    pub url: Option<String>,
    /// The last deliveries (at most 200), newest first.
    pub deliveries: Vec<crate::web::webhooks::WebhookDelivery>,
}
