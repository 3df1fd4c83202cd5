//! The two database backends behind one small interface: SQL is written once
//! with `$1`, `$2`, … placeholders (rewritten to SQLite's `?1`, `?2`, …),
//! values are typed ([`Value`]) so that PostgreSQL's strict parameter types
//! are met, and rows come back as [`Row`]s of values.
//!
//! Written by hand because no maintained crate offers a synchronous interface
//! over both rusqlite and the `postgres` client without an async runtime or a
//! build-time database (sqlx's macros); this layer is a thin translation.

use postgres::types::{IsNull, ToSql, Type};
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

thread_local! {
    /// Statements this thread has sent to a database (a test's measure of
    /// what a query costs; each call runs on its caller's thread).
    static STATEMENTS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// How many statements this thread has sent to a database so far.
pub fn statements_on_this_thread() -> u64 {
    STATEMENTS.with(std::cell::Cell::get)
}

fn count_statement() {
    STATEMENTS.with(|n| n.set(n.get() + 1));
}

/// An open connection.
pub enum Db {
    /// An SQLite file.
    Sqlite(rusqlite::Connection),
    /// A PostgreSQL server, with what it said of each statement's
    /// parameters.
    Postgres(Box<postgres::Client>, PgStatements),
}

/// What a PostgreSQL connection knows of the statements it ran: each one's
/// parameter types by SQL text, and whether a transaction is open.
///
/// Statements run unnamed (one round trip: parse, bind, execute), never as
/// named prepared statements kept on the server connection: behind a
/// pooler in transaction pooling (PgBouncer's default in most plants) the
/// next transaction may be on another server connection, where a named
/// statement does not exist, or meets another process's of the same name.
/// A statement's parameter types are asked once, by preparing it inside a
/// transaction and closing it before the transaction ends, so that nothing
/// stays on the server connection the pooler hands on.
#[derive(Default)]
pub struct PgStatements {
    parameters: HashMap<String, Vec<Type>>,
    in_transaction: bool,
}

impl PgStatements {
    /// Forget everything (a connection made again).
    pub fn clear(&mut self) {
        *self = PgStatements::default();
    }

    /// Follow the transaction state through a batch of SQL that began,
    /// committed or rolled one back.
    fn follow(&mut self, sql: &str) {
        let word = sql
            .trim_start()
            .split(|c: char| !c.is_ascii_alphabetic())
            .next()
            .unwrap_or("")
            .to_ascii_uppercase();
        match word.as_str() {
            "BEGIN" | "START" => self.in_transaction = true,
            "COMMIT" | "ROLLBACK" | "END" | "ABORT" => self.in_transaction = false,
            _ => {}
        }
    }
}

/// The parameter types of `sql`, asked of the server once per connection
/// ([`PgStatements`]).
fn pg_parameters(
    client: &mut postgres::Client,
    known: &mut PgStatements,
    sql: &str,
) -> Result<Vec<Type>, DbError> {
    if let Some(types) = known.parameters.get(sql) {
        return Ok(types.clone());
    }
    let own_transaction = !known.in_transaction;
    if own_transaction {
        client.batch_execute("BEGIN")?;
    }
    // The statement is closed when dropped, at the end of this block,
    // inside the transaction.
    let asked = client.prepare(sql).map(|s| s.params().to_vec());
    if own_transaction {
        client.batch_execute(if asked.is_ok() { "COMMIT" } else { "ROLLBACK" })?;
    }
    let types = asked?;
    known.parameters.insert(sql.to_string(), types.clone());
    Ok(types)
}

/// `params` bound to the types `types` the server gave for them.
fn typed<'a>(
    bound: &'a [PgParam<'a>],
    types: &[Type],
) -> Result<Vec<(&'a (dyn ToSql + Sync), Type)>, DbError> {
    if bound.len() != types.len() {
        return Err(format!(
            "the statement takes {} parameter(s), {} given",
            types.len(),
            bound.len()
        )
        .into());
    }
    Ok(bound
        .iter()
        .zip(types)
        .map(|(b, t)| (b as &(dyn ToSql + Sync), t.clone()))
        .collect())
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

/// A value bound to a PostgreSQL parameter of whatever type its column
/// has: the store's code writes times as Unix seconds, dates as
/// YYYY-MM-DD, flags as 0/1 and JSON as text, on both back ends; here
/// they become `timestamptz`, `date`, `boolean` and `jsonb` where the
/// PostgreSQL column is one (migration 15). Written by hand: the
/// conversions are the store's own conventions, not a general mapping a
/// crate could know.
#[derive(Debug)]
struct PgParam<'a>(&'a Value);

/// Days from 1970-01-01 to PostgreSQL's epoch, 2000-01-01.
const PG_EPOCH_DAYS: i64 = 10_957;

impl ToSql for PgParam<'_> {
    fn to_sql(
        &self,
        ty: &Type,
        out: &mut postgres::types::private::BytesMut,
    ) -> Result<IsNull, Box<dyn std::error::Error + Sync + Send>> {
        match self.0 {
            Value::Int(None) | Value::Real(None) | Value::Text(None) => Ok(IsNull::Yes),
            Value::Int(Some(v)) => match *ty {
                Type::INT4 => i32::try_from(*v)?.to_sql(ty, out),
                Type::INT2 => i16::try_from(*v)?.to_sql(ty, out),
                Type::FLOAT8 => (*v as f64).to_sql(ty, out),
                Type::BOOL => (*v != 0).to_sql(ty, out),
                Type::TIMESTAMPTZ | Type::TIMESTAMP => unix_time(*v).to_sql(ty, out),
                _ => v.to_sql(ty, out),
            },
            Value::Real(Some(v)) => match *ty {
                Type::FLOAT4 => (*v as f32).to_sql(ty, out),
                _ => v.to_sql(ty, out),
            },
            Value::Text(Some(t)) => match *ty {
                Type::JSONB => {
                    // jsonb's binary form: version 1, then the text.
                    out.extend_from_slice(&[1]);
                    out.extend_from_slice(jsonb_safe(t).as_bytes());
                    Ok(IsNull::No)
                }
                Type::JSON => {
                    out.extend_from_slice(t.as_bytes());
                    Ok(IsNull::No)
                }
                Type::DATE => {
                    let days = crate::equipment::parse_date(t)
                        .ok_or_else(|| format!("'{t}' is not a date (YYYY-MM-DD)"))?;
                    i32::try_from(days - PG_EPOCH_DAYS)?.to_sql(&Type::INT4, out)
                }
                // PostgreSQL's text cannot hold a NUL (a device's reply
                // may): it is kept as U+FFFD rather than the write refused.
                _ if t.contains('\0') => t.replace('\0', "\u{fffd}").as_str().to_sql(ty, out),
                _ => t.as_str().to_sql(ty, out),
            },
        }
    }

    fn accepts(_ty: &Type) -> bool {
        true
    }

    postgres::types::to_sql_checked!();
}

/// Unix seconds as a time.
fn unix_time(seconds: i64) -> std::time::SystemTime {
    let d = std::time::Duration::from_secs(seconds.unsigned_abs());
    if seconds >= 0 {
        std::time::UNIX_EPOCH + d
    } else {
        std::time::UNIX_EPOCH - d
    }
}

/// JSON text jsonb takes: a NUL escape (`\u0000`, which jsonb cannot
/// hold) becomes U+FFFD; an escaped backslash before `u0000` is left alone.
fn jsonb_safe(text: &str) -> std::borrow::Cow<'_, str> {
    if !text.contains("\\u0000") {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len());
    let mut backslashes = 0usize;
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        if c == '\\' && backslashes.is_multiple_of(2) && rest.starts_with("\\u0000") {
            out.push_str("\\ufffd");
            rest = &rest[6..];
            backslashes = 0;
            continue;
        }
        backslashes = if c == '\\' { backslashes + 1 } else { 0 };
        out.push(c);
        rest = &rest[c.len_utf8()..];
    }
    std::borrow::Cow::Owned(out)
}

/// A `jsonb`, `json` or `date` column read as the text the store's code
/// reads (JSON; YYYY-MM-DD).
struct PgText(String);

impl<'a> postgres::types::FromSql<'a> for PgText {
    fn from_sql(
        ty: &Type,
        raw: &'a [u8],
    ) -> Result<PgText, Box<dyn std::error::Error + Sync + Send>> {
        match *ty {
            Type::JSONB => match raw.split_first() {
                Some((1, text)) => Ok(PgText(std::str::from_utf8(text)?.to_string())),
                _ => Err("a jsonb value of an unknown version".into()),
            },
            Type::DATE => {
                let days = i32::from_sql(&Type::INT4, raw)?;
                Ok(PgText(crate::equipment::civil_date(
                    (i64::from(days) + PG_EPOCH_DAYS) * 86_400,
                )))
            }
            _ => Ok(PgText(std::str::from_utf8(raw)?.to_string())),
        }
    }

    fn accepts(ty: &Type) -> bool {
        matches!(*ty, Type::JSONB | Type::JSON | Type::DATE)
    }
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
        } else if *ty == Type::TIMESTAMPTZ || *ty == Type::TIMESTAMP {
            Value::Int(
                row.try_get::<_, Option<std::time::SystemTime>>(i)?
                    .map(|t| match t.duration_since(std::time::UNIX_EPOCH) {
                        Ok(d) => d.as_secs() as i64,
                        Err(e) => -(e.duration().as_secs_f64().ceil() as i64),
                    }),
            )
        } else if matches!(*ty, Type::JSONB | Type::JSON | Type::DATE) {
            Value::Text(row.try_get::<_, Option<PgText>>(i)?.map(|t| t.0))
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
        count_statement();
        match self {
            Db::Sqlite(c) => c.execute_batch(sql)?,
            Db::Postgres(c, known) => {
                c.batch_execute(sql)?;
                known.follow(sql);
            }
        }
        Ok(())
    }

    /// Run one statement; returns the rows it changed.
    pub fn execute(&mut self, sql: &str, params: &[Value]) -> Result<u64, DbError> {
        count_statement();
        match self {
            Db::Sqlite(c) => {
                let mut stmt = c.prepare_cached(&sqlite_sql(sql))?;
                let n = stmt.execute(rusqlite::params_from_iter(sqlite_params(params)))?;
                Ok(n as u64)
            }
            Db::Postgres(c, known) => {
                let types = pg_parameters(c, known, sql)?;
                let bound: Vec<PgParam<'_>> = params.iter().map(PgParam).collect();
                Ok(c.execute_typed(sql, &typed(&bound, &types)?)?)
            }
        }
    }

    /// Run a query; returns every row.
    pub fn query(&mut self, sql: &str, params: &[Value]) -> Result<Vec<Row>, DbError> {
        count_statement();
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
            Db::Postgres(c, known) => {
                let types = pg_parameters(c, known, sql)?;
                let bound: Vec<PgParam<'_>> = params.iter().map(PgParam).collect();
                c.query_typed(sql, &typed(&bound, &types)?)?
                    .iter()
                    .map(pg_row)
                    .collect()
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
    fn a_nul_escape_becomes_a_replacement_character_for_jsonb_and_nothing_else_changes() {
        assert_eq!(jsonb_safe(r#"{"a":"x\u0000y"}"#), r#"{"a":"x\ufffdy"}"#);
        // An escaped backslash before `u0000` is text, not an escape.
        assert_eq!(jsonb_safe(r#"{"a":"x\\u0000"}"#), r#"{"a":"x\\u0000"}"#);
        assert_eq!(jsonb_safe(r#"{"a":"x\\\u0000"}"#), r#"{"a":"x\\\ufffd"}"#);
        assert_eq!(jsonb_safe("{\"a\":\"中文\"}"), "{\"a\":\"中文\"}");
        let text = serde_json::to_string("a\u{0}b").expect("json");
        let safe = jsonb_safe(&text);
        assert_eq!(
            serde_json::from_str::<String>(&safe).expect("json"),
            "a\u{fffd}b"
        );
    }

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
