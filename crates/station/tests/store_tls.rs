//! The store over TLS, as a plant whose `pg_hba.conf` allows only
//! `hostssl` has it: the server's certificate verified against the
//! plant's CA (`sslmode=verify-full`, `sslrootcert`), a wrong CA refused,
//! and the connection encrypted as the server itself reports it.

mod common;

use common::spinbench;

/// The CA that signed the test server's certificate (`scripts/postgres`).
fn test_ca() -> String {
    std::env::var("SPINBENCH_TEST_POSTGRES_CA").unwrap_or_else(|_| {
        panic!("SPINBENCH_TEST_POSTGRES_CA is not set: run the tests with ./scripts/test, whose PostgreSQL has TLS on")
    })
}

#[test]
fn postgres_over_tls_the_server_is_verified_and_a_wrong_ca_refused() {
    let ca = test_ca();
    let other_ca = std::path::Path::new(&ca).with_file_name("other-ca.crt");
    let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let direct =
        spinbench_store::testing::fresh_postgres_database(&admin).expect("a fresh database");
    // By name: the certificate is for localhost.
    let by_name = direct.replacen("@127.0.0.1:", "@localhost:", 1);
    let verified = format!("{by_name}?sslmode=verify-full&sslrootcert={ca}");
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("TLS-")).expect("plan");
    let (ok, said, err) = spinbench(&[
        "run",
        "--simulate",
        "--quiet",
        "--data",
        dir.path().join("data").to_str().expect("utf-8"),
        "--db",
        &verified,
        plan.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{said}{err}");
    let (ok, listed, err) = spinbench(&["runs", "list", "--db", &verified]);
    assert!(ok && listed.contains("completed"), "{listed}{err}");
    // The server itself says the station's connection is encrypted.
    let target = spinbench_store::StoreTarget::Postgres(verified.clone());
    let store = spinbench_store::Store::connect(&target).expect("a verified connection");
    assert!(store.runs().expect("runs").len() == 1);
    let mut server = postgres::Client::connect(&direct, postgres::NoTls).expect("direct");
    let encrypted: i64 = server
        .query_one(
            "SELECT count(*) FROM pg_stat_ssl s JOIN pg_stat_activity a USING (pid)
             WHERE s.ssl AND a.application_name LIKE 'spinbench%'",
            &[],
        )
        .expect("pg_stat_ssl")
        .get(0);
    assert!(
        encrypted >= 1,
        "no encrypted station connection on the server"
    );
    drop(store);
    // A certificate signed by another CA is refused, saying why.
    let wrong = format!(
        "{by_name}?sslmode=verify-full&sslrootcert={}",
        other_ca.display()
    );
    let (ok, _, err) = spinbench(&["runs", "list", "--db", &wrong]);
    assert!(!ok && err.to_lowercase().contains("certificate"), "{err}");
    // verify-full without a root certificate is refused before connecting.
    let no_root = format!("{by_name}?sslmode=verify-full");
    let (ok, _, err) = spinbench(&["runs", "list", "--db", &no_root]);
    assert!(!ok && err.contains("sslrootcert=FILE"), "{err}");
}
