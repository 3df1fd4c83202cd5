//! Users of the web UI and the audit log: who may do what, and who did what.
//! The store keeps password hashes only (the station hashes; see
//! `spinbench_station::web::auth`).

use crate::db::Value;
use crate::{Store, StoreError, now_s};

/// One audit-log entry, now, in `db` (alone or inside a caller's transaction).
pub(crate) fn insert_audit(
    db: &mut crate::db::Db,
    who: &str,
    action: &str,
    detail: &str,
) -> Result<(), crate::db::DbError> {
    insert_audit_at(db, who, action, detail, now_s())
}

/// An entry of the audit log dated `at_unix_s` (when it was done, which
/// may be before the store could take it).
fn insert_audit_at(
    db: &mut crate::db::Db,
    who: &str,
    action: &str,
    detail: &str,
    at_unix_s: i64,
) -> Result<(), crate::db::DbError> {
    db.execute(
        "INSERT INTO audit (at, who, action, detail) VALUES ($1, $2, $3, $4)",
        &[
            Value::Int(Some(at_unix_s)),
            who.into(),
            action.into(),
            detail.into(),
        ],
    )
    .map(|_| ())
}

/// One user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UserRow {
    /// Login name.
    pub name: String,
    /// `operator`, `engineer` or `admin`.
    pub role: String,
    /// The password's hash (PHC string).
    pub password_hash: String,
    /// When the user was created [Unix s].
    pub created_at: i64,
}

/// One entry of the audit log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AuditRow {
    /// Sequence number.
    pub seq: i64,
    /// When [Unix s].
    pub at: i64,
    /// Who (a user name, or `spinbench` for the command line).
    pub who: String,
    /// What (`login`, `start run`, `answer prompt`, …).
    pub action: String,
    /// The details (run id, serials, the answer, …).
    pub detail: String,
}

/// What [`Store::replace_result`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Replaced {
    /// The result was replaced and the change audited.
    Done,
    /// Another change landed since the result was read: nothing written.
    ChangedMeanwhile,
}

impl Store {
    /// Add a user; an error when the name is taken.
    pub fn add_user(&self, name: &str, role: &str, password_hash: &str) -> Result<(), StoreError> {
        self.db()
            .execute(
                "INSERT INTO users (name, role, password_hash, created_at) VALUES ($1, $2, $3, $4)",
                &[
                    name.into(),
                    role.into(),
                    password_hash.into(),
                    Value::Int(Some(now_s())),
                ],
            )
            .map(|_| ())
            .map_err(self.err(&format!("add user '{name}' (is the name taken?)")))
    }

    /// Change a user's password hash and/or role; false when there is no such user.
    pub fn update_user(
        &self,
        name: &str,
        role: Option<&str>,
        password_hash: Option<&str>,
    ) -> Result<bool, StoreError> {
        let mut changed = 0;
        if let Some(role) = role {
            changed = self
                .db()
                .execute(
                    "UPDATE users SET role = $1 WHERE name = $2",
                    &[role.into(), name.into()],
                )
                .map_err(self.err(&format!("change the role of '{name}'")))?;
        }
        if let Some(hash) = password_hash {
            changed = self
                .db()
                .execute(
                    "UPDATE users SET password_hash = $1 WHERE name = $2",
                    &[hash.into(), name.into()],
                )
                .map_err(self.err(&format!("change the password of '{name}'")))?;
        }
        Ok(changed > 0)
    }

    /// Remove a user; false when there was none.
    pub fn delete_user(&self, name: &str) -> Result<bool, StoreError> {
        self.db()
            .execute("DELETE FROM users WHERE name = $1", &[name.into()])
            .map(|n| n > 0)
            .map_err(self.err(&format!("delete user '{name}'")))
    }

    /// One user.
    pub fn user(&self, name: &str) -> Result<Option<UserRow>, StoreError> {
        Ok(self
            .query(
                "read a user",
                "SELECT name, role, password_hash, created_at FROM users WHERE name = $1",
                &[name.into()],
            )?
            .first()
            .map(user_row))
    }

    /// Every user, by name.
    pub fn users(&self) -> Result<Vec<UserRow>, StoreError> {
        Ok(self
            .query(
                "list users",
                "SELECT name, role, password_hash, created_at FROM users ORDER BY name",
                &[],
            )?
            .iter()
            .map(user_row)
            .collect())
    }

    /// Record that `who` did `action`.
    pub fn audit(&self, who: &str, action: &str, detail: &str) -> Result<(), StoreError> {
        insert_audit(&mut self.db(), who, action, detail).map_err(self.err("write the audit log"))
    }

    /// An entry of the audit log for something done at `at_unix_s` and
    /// written later (a safety control taken while the store was away):
    /// dated when it was done, not when the store took it.
    pub fn audit_at(
        &self,
        who: &str,
        action: &str,
        detail: &str,
        at_unix_s: i64,
    ) -> Result<(), StoreError> {
        insert_audit_at(&mut self.db(), who, action, detail, at_unix_s)
            .map_err(self.err("write the audit log"))
    }

    /// Several entries (action, detail) of `who` in one transaction: all
    /// or none.
    pub fn audit_all(&self, who: &str, entries: &[(String, String)]) -> Result<(), StoreError> {
        self.db()
            .transaction(|db| {
                for (action, detail) in entries {
                    insert_audit(db, who, action, detail)?;
                }
                Ok(())
            })
            .map_err(self.err("write the audit log"))
    }

    /// Replace one instrument's stored result with `record` (an engineer's
    /// change after the run, such as a level left out), made from the
    /// stored revision `from_revision`, and record that `who` did `action`
    /// in the audit log, in one transaction: both or neither. When the
    /// result is no longer at `from_revision` (another change landed in
    /// between), nothing is written: [`Replaced::ChangedMeanwhile`]. The
    /// points and one-second values are untouched.
    pub fn replace_result(
        &self,
        run_id: &str,
        record: &spinbench_engine::UnitRecord,
        from_revision: i64,
        who: &str,
        action: &str,
        detail: &str,
    ) -> Result<Replaced, StoreError> {
        let json =
            serde_json::to_string(record).map_err(|e| self.err("encode a result")(Box::new(e)))?;
        let mut values = crate::record::result_row_values(run_id, record, &json);
        values.push(from_revision.into());
        self.db()
            .transaction(|db| {
                // Compare and set in one statement: of two changes made from
                // one revision, the second finds it moved on.
                let changed = db.execute(
                    "UPDATE results SET serial = $3, outcome = $4, k2_max_ug_per_g2 = $5, record_json = $6,
                       k2_p_ug_per_g2 = $7, k2_p_u95 = $8, k2_n_ug_per_g2 = $9, k2_n_u95 = $10,
                       instrument_k2_ug_per_g2 = $11, instrument_k2_u95 = $12,
                       measurand = $13, limit_ug_per_g2 = $14, revision = revision + 1
                     WHERE run_id = $1 AND slot = $2 AND revision = $15",
                    &values,
                )?;
                if changed == 1 {
                    insert_audit(db, who, action, detail)?;
                    return Ok(Replaced::Done);
                }
                let exists = db.query_one(
                    "SELECT revision FROM results WHERE run_id = $1 AND slot = $2",
                    &[run_id.into(), crate::record::stored_slot(record.slot).into()],
                )?;
                match exists {
                    Some(_) => Ok(Replaced::ChangedMeanwhile),
                    None => Err(format!(
                        "run {run_id} has no result for slot {}",
                        record.slot + 1
                    )
                    .into()),
                }
            })
            .map_err(self.err("replace a result"))
    }

    /// A user's language (a BCP 47 tag such as `zh-CN`), if they chose one.
    pub fn user_language(&self, name: &str) -> Result<Option<String>, StoreError> {
        Ok(self
            .query(
                "read a user's language",
                "SELECT language FROM users WHERE name = $1",
                &[name.into()],
            )?
            .first()
            .and_then(|r| r.opt_text(0)))
    }

    /// Set a user's language (the caller checks it is one the station speaks).
    pub fn set_user_language(&self, name: &str, language: &str) -> Result<(), StoreError> {
        self.db()
            .execute(
                "UPDATE users SET language = $2 WHERE name = $1",
                &[name.into(), language.into()],
            )
            .map(|_| ())
            .map_err(self.err("set a user's language"))
    }

    /// Keep a web session: the SHA-256 of its token (never the token), its
    /// user and CSRF token, used now.
    pub fn save_session(&self, token_hash: &str, user: &str, csrf: &str) -> Result<(), StoreError> {
        self.db()
            .execute(
                "INSERT INTO sessions (token_hash, user_name, csrf, last_seen) VALUES ($1, $2, $3, $4)
                 ON CONFLICT (token_hash) DO UPDATE SET last_seen = excluded.last_seen",
                &[
                    token_hash.into(),
                    user.into(),
                    csrf.into(),
                    Value::Int(Some(now_s())),
                ],
            )
            .map(|_| ())
            .map_err(self.err("keep a session"))
    }

    /// A kept session by its token's hash: (user, role, CSRF token, last
    /// used [Unix s]) — none when its user is gone.
    pub fn session(
        &self,
        token_hash: &str,
    ) -> Result<Option<(String, String, String, i64)>, StoreError> {
        Ok(self
            .query(
                "read a session",
                "SELECT s.user_name, u.role, s.csrf, s.last_seen FROM sessions s
                 JOIN users u ON u.name = s.user_name WHERE s.token_hash = $1",
                &[token_hash.into()],
            )?
            .first()
            .map(|r| (r.text(0), r.text(1), r.text(2), r.int(3))))
    }

    /// End a kept session.
    pub fn delete_session(&self, token_hash: &str) -> Result<(), StoreError> {
        self.db()
            .execute(
                "DELETE FROM sessions WHERE token_hash = $1",
                &[token_hash.into()],
            )
            .map(|_| ())
            .map_err(self.err("end a session"))
    }

    /// End every kept session of `user`, and every one unused since `before` [Unix s].
    pub fn delete_sessions(&self, user: Option<&str>, before: i64) -> Result<(), StoreError> {
        self.db()
            .execute(
                "DELETE FROM sessions WHERE user_name = $1 OR last_seen < $2",
                &[user.unwrap_or("").into(), Value::Int(Some(before))],
            )
            .map(|_| ())
            .map_err(self.err("end sessions"))
    }

    /// The newest `limit` audit entries, newest first.
    pub fn audit_log(&self, limit: i64) -> Result<Vec<AuditRow>, StoreError> {
        Ok(self
            .query(
                "read the audit log",
                "SELECT seq, at, who, action, detail FROM audit ORDER BY seq DESC LIMIT $1",
                &[Value::Int(Some(limit))],
            )?
            .iter()
            .map(|r| AuditRow {
                seq: r.int(0),
                at: r.int(1),
                who: r.text(2),
                action: r.text(3),
                detail: r.text(4),
            })
            .collect())
    }
}

fn user_row(r: &crate::db::Row) -> UserRow {
    UserRow {
        name: r.text(0),
        role: r.text(1),
        password_hash: r.text(2),
        created_at: r.int(3),
    }
}
