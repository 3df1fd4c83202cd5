//! The two database backends behind one small interface: SQL is written once
//! with `$1`, `$2`, … placeholders (rewritten to SQLite's `?1`, `?2`, …),
//! values are typed ([`Value`]) so that PostgreSQL's strict parameter types
//! are met, and rows come back as [`Row`]s of values.
//!
//! Written by hand because no maintained crate offers a synchronous interface
//! over both rusqlite and the `postgres` client without an async runtime or a
//! build-time database (sqlx's macros); this layer is a thin translation.

use postgres::types::{ToSql, Type};
use rusqlite::types::ValueRef;
use std::collections::HashMap;

/// A typed SQL value (a NULL keeps its type: PostgreSQL checks it).
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// A 64-bit integer (BIGINT / INTEGER).
    Int(Option<i64>),
    /// A double (DOUBLE PRECISION / REAL).
    Real(Option<f64>),
    /// Text.
    Text(Option<String>),
}

impl From<i64> for Value {
    fn from(v: i64) -> Value {
        Value::Int(Some(v))
    }
}
impl From<f64> for Value {
    fn from(v: f64) -> Value {
        Value::Real(Some(v))
    }
}
impl From<Option<f64>> for Value {
    fn from(v: Option<f64>) -> Value {
        Value::Real(v)
    }
}
impl From<&str> for Value {
    fn from(v: &str) -> Value {
        Value::Text(Some(v.to_string()))
    }
}
impl From<String> for Value {
    fn from(v: String) -> Value {
        Value::Text(Some(v))
    }
}
impl From<&String> for Value {
    fn from(v: &String) -> Value {
        Value::Text(Some(v.clone()))
    }
}
impl From<Option<String>> for Value {
    fn from(v: Option<String>) -> Value {
        Value::Text(v)
    }
}

/// One row of a query.
#[derive(Debug, Clone, PartialEq)]
pub struct Row(pub Vec<Value>);

impl Row {
    /// Column `i` as an integer (0 when NULL or of another type).
    pub fn int(&self, i: usize) -> i64 {
        match self.0.get(i) {
            Some(Value::Int(Some(v))) => *v,
            Some(Value::Real(Some(v))) => *v as i64,
            _ => 0,
        }
    }
    /// Column `i` as an integer, if any.
    pub fn opt_int(&self, i: usize) -> Option<i64> {
        match self.0.get(i) {
            Some(Value::Int(v)) => *v,
            Some(Value::Real(v)) => v.map(|v| v as i64),
            Some(Value::Text(v)) => v.as_deref().and_then(|t| t.parse().ok()),
            _ => None,
        }
    }
    /// Column `i` as a number, if any.
    pub fn opt_real(&self, i: usize) -> Option<f64> {
        match self.0.get(i) {
            Some(Value::Real(v)) => *v,
            Some(Value::Int(v)) => v.map(|v| v as f64),
            _ => None,
        }
    }
    /// Column `i` as a number (NaN when NULL).
    pub fn real(&self, i: usize) -> f64 {
        self.opt_real(i).unwrap_or(f64::NAN)
    }
    /// Column `i` as text, if any.
    pub fn opt_text(&self, i: usize) -> Option<String> {
        match self.0.get(i) {
            Some(Value::Text(v)) => v.clone(),
            Some(Value::Int(Some(v))) => Some(v.to_string()),
            Some(Value::Real(Some(v))) => Some(v.to_string()),
            _ => None,
        }
    }
    /// Column `i` as text (empty when NULL).
    pub fn text(&self, i: usize) -> String {
        self.opt_text(i).unwrap_or_default()
    }
}

/// Which database.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dialect {
    /// An SQLite file.
    Sqlite,
    /// A PostgreSQL server.
    Postgres,
}

/// A database error: the backend's own message.
pub type DbError = Box<dyn std::error::Error + Send + Sync>;

/// An open connection.
pub enum Db {
    /// An SQLite file.
    Sqlite(rusqlite::Connection),
    /// A PostgreSQL server, with its prepared statements by SQL text.
    Postgres(Box<postgres::Client>, HashMap<String, postgres::Statement>),
}

/// The prepared statement for `sql`, prepared once per connection.
fn pg_statement(
    client: &mut postgres::Client,
    cache: &mut HashMap<String, postgres::Statement>,
    sql: &str,
) -> Result<postgres::Statement, DbError> {
    if let Some(s) = cache.get(sql) {
        return Ok(s.clone());
    }
    let s = client.prepare(sql)?;
    cache.insert(sql.to_string(), s.clone());
    Ok(s)
}

/// `$12` → `?12` (SQLite's numbered parameters); other text unchanged.
fn sqlite_sql(sql: &str) -> String {
    let mut out = String::with_capacity(sql.len());
    let mut chars = sql.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '$' && chars.peek().is_some_and(char::is_ascii_digit) {
            out.push('?');
        } else {
            out.push(c);
        }
    }
    out
}

fn sqlite_params(params: &[Value]) -> Vec<rusqlite::types::Value> {
    use rusqlite::types::Value as V;
    params
        .iter()
        .map(|p| match p {
            Value::Int(Some(v)) => V::Integer(*v),
            Value::Real(Some(v)) => V::Real(*v),
            Value::Text(Some(v)) => V::Text(v.clone()),
            _ => V::Null,
        })
        .collect()
}

fn pg_params(params: &[Value]) -> Vec<Box<dyn ToSql + Sync>> {
    params
        .iter()
        .map(|p| -> Box<dyn ToSql + Sync> {
            match p {
                Value::Int(v) => Box::new(*v),
                Value::Real(v) => Box::new(*v),
                Value::Text(v) => Box::new(v.clone()),
            }
        })
        .collect()
}

fn pg_row(row: &postgres::Row) -> Result<Row, DbError> {
    let mut out = Vec::with_capacity(row.len());
    for (i, column) in row.columns().iter().enumerate() {
        let ty = column.type_();
        out.push(if *ty == Type::INT8 {
            Value::Int(row.try_get::<_, Option<i64>>(i)?)
        } else if *ty == Type::INT4 {
            Value::Int(row.try_get::<_, Option<i32>>(i)?.map(i64::from))
        } else if *ty == Type::INT2 {
            Value::Int(row.try_get::<_, Option<i16>>(i)?.map(i64::from))
        } else if *ty == Type::FLOAT8 {
            Value::Real(row.try_get::<_, Option<f64>>(i)?)
        } else if *ty == Type::FLOAT4 {
            Value::Real(row.try_get::<_, Option<f32>>(i)?.map(f64::from))
        } else if *ty == Type::BOOL {
            Value::Int(row.try_get::<_, Option<bool>>(i)?.map(i64::from))
        } else {
            Value::Text(row.try_get::<_, Option<String>>(i)?)
        });
    }
    Ok(Row(out))
}

impl Db {
    /// Which database this is.
    pub fn dialect(&self) -> Dialect {
        match self {
            Db::Sqlite(_) => Dialect::Sqlite,
            Db::Postgres(..) => Dialect::Postgres,
        }
    }

    /// Run statements without parameters (DDL, BEGIN, COMMIT).
    pub fn batch(&mut self, sql: &str) -> Result<(), DbError> {
        match self {
            Db::Sqlite(c) => c.execute_batch(sql)?,
            Db::Postgres(c, _) => c.batch_execute(sql)?,
        }
        Ok(())
    }

    /// Run one statement; returns the rows it changed.
    pub fn execute(&mut self, sql: &str, params: &[Value]) -> Result<u64, DbError> {
        match self {
            Db::Sqlite(c) => {
                let mut stmt = c.prepare_cached(&sqlite_sql(sql))?;
                let n = stmt.execute(rusqlite::params_from_iter(sqlite_params(params)))?;
                Ok(n as u64)
            }
            Db::Postgres(c, cache) => {
                let boxed = pg_params(params);
                let refs: Vec<&(dyn ToSql + Sync)> = boxed.iter().map(|b| b.as_ref()).collect();
                let stmt = pg_statement(c, cache, sql)?;
                Ok(c.execute(&stmt, &refs)?)
            }
        }
    }

    /// Run a query; returns every row.
    pub fn query(&mut self, sql: &str, params: &[Value]) -> Result<Vec<Row>, DbError> {
        match self {
            Db::Sqlite(c) => {
                let mut stmt = c.prepare_cached(&sqlite_sql(sql))?;
                let columns = stmt.column_count();
                let mut rows = stmt.query(rusqlite::params_from_iter(sqlite_params(params)))?;
                let mut out = Vec::new();
                while let Some(r) = rows.next()? {
                    let mut row = Vec::with_capacity(columns);
                    for i in 0..columns {
                        row.push(match r.get_ref(i)? {
                            ValueRef::Null => Value::Text(None),
                            ValueRef::Integer(v) => Value::Int(Some(v)),
                            ValueRef::Real(v) => Value::Real(Some(v)),
                            ValueRef::Text(t) | ValueRef::Blob(t) => {
                                Value::Text(Some(String::from_utf8_lossy(t).into_owned()))
                            }
                        });
                    }
                    out.push(Row(row));
                }
                Ok(out)
            }
            Db::Postgres(c, cache) => {
                let boxed = pg_params(params);
                let refs: Vec<&(dyn ToSql + Sync)> = boxed.iter().map(|b| b.as_ref()).collect();
                let stmt = pg_statement(c, cache, sql)?;
                c.query(&stmt, &refs)?.iter().map(pg_row).collect()
            }
        }
    }

    /// The first row of a query, if any.
    pub fn query_one(&mut self, sql: &str, params: &[Value]) -> Result<Option<Row>, DbError> {
        Ok(self.query(sql, params)?.into_iter().next())
    }

    /// Run `f` in one transaction: committed when it returns `Ok`, rolled back otherwise.
    pub fn transaction<T>(
        &mut self,
        f: impl FnOnce(&mut Db) -> Result<T, DbError>,
    ) -> Result<T, DbError> {
        self.batch("BEGIN")?;
        match f(self) {
            Ok(v) => {
                self.batch("COMMIT")?;
                Ok(v)
            }
            Err(e) => {
                let _ = self.batch("ROLLBACK");
                Err(e)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placeholders_become_sqlite_numbered_parameters() {
        assert_eq!(
            sqlite_sql("UPDATE t SET a = $2, b = '$x' WHERE id = $1 AND c = $10"),
            "UPDATE t SET a = ?2, b = '$x' WHERE id = ?1 AND c = ?10"
        );
    }

    #[test]
    fn sqlite_round_trips_typed_values_and_rolls_back_failed_transactions() {
        let mut db = Db::Sqlite(rusqlite::Connection::open_in_memory().expect("memory db"));
        db.batch("CREATE TABLE t (i INTEGER, r REAL, s TEXT)")
            .expect("create");
        db.execute(
            "INSERT INTO t VALUES ($1, $2, $3)",
            &[7i64.into(), 2.5.into(), Value::Text(None)],
        )
        .expect("insert");
        let failed: Result<(), DbError> = db.transaction(|db| {
            db.execute(
                "INSERT INTO t VALUES ($1, $2, $3)",
                &[1i64.into(), 1.0.into(), "x".into()],
            )?;
            Err("abandon".into())
        });
        assert!(failed.is_err());
        let rows = db.query("SELECT i, r, s FROM t", &[]).expect("query");
        assert_eq!(rows.len(), 1, "the failed transaction left nothing");
        assert_eq!(rows[0].int(0), 7);
        assert_eq!(rows[0].real(1), 2.5);
        assert_eq!(rows[0].opt_text(2), None);
    }
}
