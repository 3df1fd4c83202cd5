//! For tests and benchmarks: a fresh, empty database on a PostgreSQL server.

pub use crate::db::statements_on_this_thread;

/// The environment variable that names the test server
/// (`scripts/test` starts one and sets it).
pub const POSTGRES_ENV: &str = "SPINBENCH_TEST_POSTGRES";

/// The environment variable that names the tests' PgBouncer in transaction
/// pooling in front of the test server (`scripts/test` starts one).
pub const PGBOUNCER_ENV: &str = "SPINBENCH_TEST_PGBOUNCER";

/// `direct_url` (a database on the test server) reached through the tests'
/// PgBouncer instead, or an error that says how to get one.
pub fn behind_pgbouncer(direct_url: &str) -> Result<String, String> {
    let bouncer = std::env::var(PGBOUNCER_ENV).map_err(|_| {
        format!("{PGBOUNCER_ENV} is not set: run the tests with ./scripts/test, which starts PgBouncer (scripts/pgbouncer)")
    })?;
    let authority = |url: &str| -> Option<(String, String)> {
        let rest = url.strip_prefix("postgres://")?;
        let (authority, path) = rest.split_once('/')?;
        Some((authority.to_string(), path.to_string()))
    };
    let (Some((bouncer_at, _)), Some((_, database))) = (authority(&bouncer), authority(direct_url))
    else {
        return Err(format!(
            "cannot read {bouncer} or {direct_url} as postgres://USER@HOST:PORT/DB"
        ));
    };
    Ok(format!("postgres://{bouncer_at}/{database}"))
}

/// Create a new database (a random name) on the server at `admin_url`,
/// migrated to this release's schema (as `spinbench migrate` does), and
/// return the URL that reaches it.
pub fn fresh_postgres_database(admin_url: &str) -> Result<String, super::DbError> {
    let url = empty_postgres_database(admin_url)?;
    super::Store::migrate_target(&super::StoreTarget::Postgres(url.clone()))
        .map_err(|e| -> super::DbError { e.to_string().into() })?;
    Ok(url)
}

/// Create a new, empty database (a random name) on the server at
/// `admin_url` (no schema: for tests of `spinbench migrate` itself) and
/// return the URL that reaches it.
pub fn empty_postgres_database(admin_url: &str) -> Result<String, super::DbError> {
    let mut admin = postgres::Client::connect(admin_url, postgres::NoTls)?;
    let name = format!("spinbench_test_{:016x}", rand_u64());
    admin.batch_execute(&format!("CREATE DATABASE {name}"))?;
    let base = admin_url
        .rsplit_once('/')
        .map_or(admin_url, |(base, _)| base);
    Ok(format!("{base}/{name}"))
}

/// No test PostgreSQL server is named; says how to get one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "{POSTGRES_ENV} is not set: run the tests with ./scripts/test, which starts a throwaway PostgreSQL on loopback, or set it to postgres://user@host:port/database"
)]
pub struct NoTestPostgres;

/// The test server's URL, or an error that says how to get one.
pub fn postgres_url() -> Result<String, NoTestPostgres> {
    std::env::var(POSTGRES_ENV).map_err(|_| NoTestPostgres)
}

fn rand_u64() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    // RandomState is seeded randomly per process; the clock and the pid separate calls.
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u128(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos()),
    );
    h.write_u32(std::process::id());
    h.finish()
}
