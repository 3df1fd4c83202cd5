//! `spinbench backup` and `spinbench restore` (issue 17, part 5): a run's
//! store backed up (checked), lost, and restored whole; a PostgreSQL store
//! is pointed at its own tools; nothing is ever overwritten.

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
fn a_postgresql_store_is_pointed_at_its_own_tools() {
    let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = spinbench_store::testing::fresh_postgres_database(&admin).expect("a fresh database");
    let dir = tempfile::tempdir().expect("tempdir");
    let (ok, _, err) = spinbench(&["backup", dir.path().to_str().expect("utf-8"), "--db", &url]);
    assert!(
        !ok && err.contains("pg_dump --format=custom") && err.contains("pg_restore"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_dir(dir.path()).expect("dir").count(),
        0,
        "nothing written"
    );
}
