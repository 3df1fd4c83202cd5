//! The station's role's rights on a PostgreSQL store, granted by the
//! store's owner when it migrates (`spinbench migrate --grant ROLE`).
//!
//! A migration that adds a table or a sequence adds it with its owner's
//! rights only: a station whose data-only role was granted the tables of
//! the last release cannot write the new one. Granting once after every
//! migration, and the owner's default privileges for what later
//! migrations create, keep the role's rights whole across upgrades.

use crate::db::Dialect;
use crate::{Store, StoreError};

/// The longest role name PostgreSQL keeps (NAMEDATALEN − 1).
const MAX_ROLE_LEN: usize = 63;

/// Whether `role` is a plain PostgreSQL role name (letters, digits, `_`,
/// not starting with a digit, at most [`MAX_ROLE_LEN`]), so that it can be
/// written into a GRANT without quoting surprises.
pub fn is_role_name(role: &str) -> bool {
    !role.is_empty()
        && role.len() <= MAX_ROLE_LEN
        && role
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && role.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

impl Store {
    /// Grant `role` the data rights a station needs on every table and
    /// sequence of the store (`SELECT, INSERT, UPDATE, DELETE`; `USAGE,
    /// SELECT`), and make them the owner's default for what later
    /// migrations create. PostgreSQL only; run as the store's owner.
    pub fn grant_data_rights(&self, role: &str) -> Result<(), StoreError> {
        self.check_grantee(role, "grant the station's role")?;
        let mut db = self.db();
        let r = format!("\"{role}\"");
        db.batch(&format!(
            "GRANT USAGE ON SCHEMA public TO {r};
             GRANT SELECT, INSERT, UPDATE, DELETE ON ALL TABLES IN SCHEMA public TO {r};
             GRANT USAGE, SELECT ON ALL SEQUENCES IN SCHEMA public TO {r};
             ALTER DEFAULT PRIVILEGES IN SCHEMA public GRANT SELECT, INSERT, UPDATE, DELETE ON TABLES TO {r};
             ALTER DEFAULT PRIVILEGES IN SCHEMA public GRANT USAGE, SELECT ON SEQUENCES TO {r};"
        ))
        .map_err(self.err(&format!("grant the role {role} its data rights")))
    }

    /// Grant `role` the analyst's read of the view `analyst_results` and
    /// nothing else: no table, so the users' password hashes, the sessions
    /// and the raw records stay the station's. PostgreSQL only; run as the
    /// store's owner.
    pub fn grant_analyst_rights(&self, role: &str) -> Result<(), StoreError> {
        self.check_grantee(role, "grant the analyst's role")?;
        let r = format!("\"{role}\"");
        self.db()
            .batch(&format!(
                "GRANT USAGE ON SCHEMA public TO {r};
                 GRANT SELECT ON analyst_results TO {r};"
            ))
            .map_err(self.err(&format!("grant the role {role} the analyst's view")))
    }

    /// A role a grant may name, on a store that has roles.
    fn check_grantee(&self, role: &str, what: &str) -> Result<(), StoreError> {
        if !is_role_name(role) {
            return Err(StoreError::message(
                &self.target,
                what,
                format!(
                    "{role:?} is not a role name (letters, digits and _, not starting with a digit, at most {MAX_ROLE_LEN})"
                ),
            ));
        }
        if self.db().dialect() != Dialect::Postgres {
            return Err(StoreError::message(
                &self.target,
                what,
                "an SQLite file has no roles: a grant is for a PostgreSQL store".into(),
            ));
        }
        Ok(())
    }
}

impl Store {
    /// The rights a station needs that this connection's role lacks, as
    /// (table or sequence, right), sorted: `SELECT, INSERT, UPDATE,
    /// DELETE` on every table and `USAGE` on every sequence of the store.
    /// Empty on SQLite (a file has no roles) and for a role with them all.
    pub fn missing_rights(&self) -> Result<Vec<(String, String)>, StoreError> {
        let mut db = self.db();
        if db.dialect() != Dialect::Postgres {
            return Ok(Vec::new());
        }
        let rows = db
            .query(
                "SELECT c.relname::text, p.priv
                 FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace
                 CROSS JOIN (VALUES ('SELECT'), ('INSERT'), ('UPDATE'), ('DELETE')) AS p(priv)
                 WHERE n.nspname = 'public' AND c.relkind IN ('r', 'p')
                   AND NOT has_table_privilege(c.oid, p.priv)
                 UNION ALL
                 SELECT c.relname::text, 'USAGE'
                 FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace
                 WHERE n.nspname = 'public'
                   AND CASE WHEN c.relkind = 'S' THEN NOT has_sequence_privilege(c.oid, 'USAGE') ELSE false END
                 ORDER BY 1, 2",
                &[],
            )
            .map_err(self.err("read the role's rights"))?;
        Ok(rows.into_iter().map(|r| (r.text(0), r.text(1))).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::is_role_name;

    #[test]
    fn only_plain_role_names_are_granted() {
        for good in ["spinbench_station", "app_1", "_x", "Station"] {
            assert!(is_role_name(good), "{good}");
        }
        let long = "a".repeat(64);
        for bad in [
            "",
            "1st",
            "a b",
            "x\"; DROP TABLE runs; --",
            "rôle",
            long.as_str(),
        ] {
            assert!(!is_role_name(bad), "{bad}");
        }
    }
}
