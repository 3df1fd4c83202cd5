//! API tokens for machine clients (an MES, a line controller): each a
//! name, a role and the SHA-256 of its secret, never the secret. Made and
//! revoked by an admin (the station hashes and audits; see
//! `spinbench_station::tokens`); a revoked token stays listed with who
//! revoked it and when.

use crate::db::Value;
use crate::users::insert_audit;
use crate::{Store, StoreError, now_s};

/// One API token, as the store keeps it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ApiTokenRow {
    /// Its name (the machine it is for), unique.
    pub name: String,
    /// `operator`, `engineer` or `admin`.
    pub role: String,
    /// Who made it.
    pub created_by: String,
    /// When it was made [Unix s].
    pub created_at: i64,
    /// When it was last used (at most a minute late) [Unix s].
    pub last_used_at: Option<i64>,
    /// When it was revoked [Unix s]; a revoked token is refused.
    pub revoked_at: Option<i64>,
    /// Who revoked it.
    pub revoked_by: Option<String>,
}

const COLUMNS: &str =
    "name, role, created_by, created_at, last_used_at, revoked_at, revoked_by FROM api_tokens";

fn token_row(r: &crate::db::Row) -> ApiTokenRow {
    ApiTokenRow {
        name: r.text(0),
        role: r.text(1),
        created_by: r.text(2),
        created_at: r.int(3),
        last_used_at: r.opt_int(4),
        revoked_at: r.opt_int(5),
        revoked_by: r.opt_text(6),
    }
}

impl Store {
    /// Keep a new token (its secret's hash) and audit it in one
    /// transaction; an error when the name is taken (revoked names too).
    pub fn add_api_token(
        &self,
        name: &str,
        role: &str,
        secret_hash: &str,
        by: &str,
    ) -> Result<(), StoreError> {
        self.db()
            .transaction(|db| {
                db.execute(
                    "INSERT INTO api_tokens (name, role, secret_hash, created_by, created_at)
                     VALUES ($1, $2, $3, $4, $5)",
                    &[
                        name.into(),
                        role.into(),
                        secret_hash.into(),
                        by.into(),
                        Value::Int(Some(now_s())),
                    ],
                )?;
                insert_audit(db, by, "add API token", &format!("{name} ({role})"))
            })
            .map_err(self.err(&format!("add the API token '{name}' (is the name taken?)")))
    }

    /// Every token, by name (the revoked ones too).
    pub fn api_tokens(&self) -> Result<Vec<ApiTokenRow>, StoreError> {
        Ok(self
            .query(
                "list the API tokens",
                &format!("SELECT {COLUMNS} ORDER BY name"),
                &[],
            )?
            .iter()
            .map(token_row)
            .collect())
    }

    /// The token whose secret hashes to `secret_hash`, if it is not revoked.
    pub fn api_token_by_hash(&self, secret_hash: &str) -> Result<Option<ApiTokenRow>, StoreError> {
        Ok(self
            .query(
                "read an API token",
                &format!("SELECT {COLUMNS} WHERE secret_hash = $1 AND revoked_at IS NULL"),
                &[secret_hash.into()],
            )?
            .first()
            .map(token_row))
    }

    /// Note that the token `name` was used now.
    pub fn touch_api_token(&self, name: &str) -> Result<(), StoreError> {
        self.db()
            .execute(
                "UPDATE api_tokens SET last_used_at = $1 WHERE name = $2",
                &[Value::Int(Some(now_s())), name.into()],
            )
            .map(|_| ())
            .map_err(self.err("note an API token's use"))
    }

    /// Revoke the token `name` and audit it in one transaction; false when
    /// there is no such token or it was already revoked.
    pub fn revoke_api_token(&self, name: &str, by: &str) -> Result<bool, StoreError> {
        self.db()
            .transaction(|db| {
                let changed = db.execute(
                    "UPDATE api_tokens SET revoked_at = $1, revoked_by = $2
                     WHERE name = $3 AND revoked_at IS NULL",
                    &[Value::Int(Some(now_s())), by.into(), name.into()],
                )?;
                if changed > 0 {
                    insert_audit(db, by, "revoke API token", name)?;
                }
                Ok(changed > 0)
            })
            .map_err(self.err(&format!("revoke the API token '{name}'")))
    }
}
