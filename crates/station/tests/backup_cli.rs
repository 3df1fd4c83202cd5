//! `spinbench backup` and `spinbench restore`:
//! a run's store backed up (checked), lost, and restored whole, on SQLite
//! and on PostgreSQL (pg_dump, pg_restore); the password never printed;
//! nothing is ever overwritten.

mod common;

use common::spinbench;

#[test]
fn a_store_is_backed_up_lost_and_restored_whole() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let db = data.join("spinbench.db");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("B")).expect("plan");
    let (data_s, db_s) = (data.to_str().expect("utf-8"), db.to_str().expect("utf-8"));
    let (_, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--quiet",
        "--data",
        data_s,
        plan.to_str().expect("utf-8"),
    ]);
    let (ok, before, _) = spinbench(&["runs", "list", "--db", db_s]);
    assert!(ok && before.contains("completed"), "{before}{err}");

    let backups = dir.path().join("backups");
    let (ok, said, err) = spinbench(&[
        "backup",
        backups.to_str().expect("utf-8"),
        "--db",
        db_s,
        "--data",
        data_s,
    ]);
    assert!(ok && said.contains("integrity ok"), "{said}{err}");
    let file = std::fs::read_dir(&backups)
        .expect("backups")
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "db"))
        .expect("a backup file");
    assert!(
        said.contains("runs' files:") && backups.join("runs").is_dir(),
        "{said}"
    );

    // The store is lost; the restore will not write over one that exists.
    let (ok, _, err) = spinbench(&["restore", file.to_str().expect("utf-8"), "--db", db_s]);
    assert!(!ok && err.contains("exists"), "{err}");
    std::fs::remove_file(&db).expect("lose the store");
    let _ = std::fs::remove_file(data.join("spinbench.db-wal"));
    let _ = std::fs::remove_file(data.join("spinbench.db-shm"));
    let (ok, said, err) = spinbench(&["restore", file.to_str().expect("utf-8"), "--db", db_s]);
    assert!(ok && said.contains("restored 1 runs"), "{said}{err}");
    let (ok, after, _) = spinbench(&["runs", "list", "--db", db_s]);
    assert!(ok);
    assert_eq!(after, before, "the same runs, as they were");
}

#[test]
fn a_postgresql_store_is_backed_up_and_restored_by_its_own_tools() {
    let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = spinbench_store::testing::fresh_postgres_database(&admin).expect("a fresh database");
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("PG")).expect("plan");
    let (ok, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--quiet",
        "--data",
        data.to_str().expect("utf-8"),
        "--db",
        &url,
        plan.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{err}");
    let (ok, before, _) = spinbench(&["runs", "list", "--db", &url]);
    assert!(ok && before.contains("completed"), "{before}");

    let backups = dir.path().join("backups");
    let (ok, said, err) = spinbench(&["backup", backups.to_str().expect("utf-8"), "--db", &url]);
    assert!(ok && said.contains("pg_dump custom format"), "{said}{err}");
    let dumps: Vec<_> = std::fs::read_dir(&backups)
        .expect("backups")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "dump"))
        .collect();
    assert_eq!(dumps.len(), 1, "{dumps:?}");

    // Restored into another, empty database: the same runs.
    let other =
        spinbench_store::testing::empty_postgres_database(&admin).expect("a fresh database");
    let dump = dumps[0].to_str().expect("utf-8");
    let (ok, said, err) = spinbench(&["restore", dump, "--db", &other]);
    assert!(ok && said.contains("restored 1 runs"), "{said}{err}");
    let (ok, after, _) = spinbench(&["runs", "list", "--db", &other]);
    assert!(ok);
    assert_eq!(after, before, "the same runs, as they were");
    // Into a database that holds a store already: refused in words, said
    // once (not pg_restore's raw error).
    let (ok, _, err) = spinbench(&["restore", dump, "--db", &other]);
    assert!(
        !ok && err.matches("the database must be empty").count() == 1
            && !err.contains("pg_restore failed"),
        "{err}"
    );
}

#[test]
fn a_postgresql_backup_without_the_tools_says_what_to_install_once_and_no_password() {
    let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = spinbench_store::testing::fresh_postgres_database(&admin).expect("a fresh database");
    // The same server, with a password in the URL (trust auth ignores it).
    let with_password = url.replacen("://spinbench@", "://spinbench:s3cret-pw@", 1);
    let dir = tempfile::tempdir().expect("tempdir");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args([
            "backup",
            dir.path().to_str().expect("utf-8"),
            "--db",
            &with_password,
        ])
        .env("PATH", "/nonexistent")
        .output()
        .expect("spinbench backup");
    let err = String::from_utf8_lossy(&out.stderr);
    let debian_has_it = std::fs::read_dir("/usr/lib/postgresql")
        .into_iter()
        .flatten()
        .filter_map(|e| e.ok())
        .any(|e| e.path().join("bin").join("pg_dump").is_file());
    if debian_has_it {
        // Debian's own directory is searched too: the backup is made.
        assert!(out.status.success(), "{err}");
    } else {
        assert!(!out.status.success());
        assert_eq!(err.matches("pg_dump is not installed").count(), 1, "{err}");
    }
    let said = format!("{}{err}", String::from_utf8_lossy(&out.stdout));
    assert!(
        !said.contains("s3cret-pw"),
        "the password was printed: {said}"
    );
}
