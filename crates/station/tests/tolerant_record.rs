//! A stored result this release cannot read costs that instrument, never
//! the run: with one field taken out of one instrument's stored record,
//! `spinbench report` and `runs show` still succeed, show the other
//! instruments whole, and name the unreadable one with the reason; on
//! SQLite and PostgreSQL.

mod common;

use common::spinbench;
use spinbench_store::{Store, StoreTarget};

/// The keys put before a stored run's station config: its zone, and a key
/// of a later release this one does not know.
const FUTURE_CONFIG: &str = "time_zone = \"UTC+08:00\"\nkey_of_a_later_release = 1\n";

/// Run the short plan (three instruments) into `db`, then take `points`
/// out of slot 2's stored record and put [`FUTURE_CONFIG`] before the
/// run's station config with `break_record`.
fn tolerant_on(db_arg: Option<String>, break_record: impl Fn(&str, &str)) {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("TR-")).expect("plan");
    let db = db_arg.unwrap_or_else(|| data.join("spinbench.db").display().to_string());
    let (ok, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--quiet",
        "--data",
        data.to_str().expect("utf-8"),
        plan.to_str().expect("utf-8"),
        "--db",
        &db,
    ]);
    // A failing instrument ends the command with an error; the run is stored.
    let _ = (ok, err);
    let store = Store::connect(&StoreTarget::parse(&db)).expect("store");
    let id = store.runs().expect("runs")[0].id.clone();
    drop(store);
    break_record(&db, &id);

    let store = Store::connect(&StoreTarget::parse(&db)).expect("store");
    let results = store.results(&id).expect("the results, one unreadable");
    assert_eq!(results.len(), 3, "three instruments");
    let unreadable: Vec<&str> = results
        .iter()
        .filter(|r| r.unreadable.is_some())
        .map(|r| r.serial.as_str())
        .collect();
    assert!(
        !unreadable.is_empty() && unreadable.iter().all(|s| *s == "TR-2"),
        "{unreadable:?}"
    );
    for r in results.iter().filter(|r| r.serial != "TR-2") {
        assert!(r.record.analysis.is_some(), "{} read whole", r.serial);
    }
    let why = results
        .iter()
        .find_map(|r| r.unreadable.clone())
        .unwrap_or_default();
    assert!(why.contains("points"), "names what is missing: {why}");

    let reports = dir.path().join("reports");
    let (ok, said, err) = spinbench(&[
        "report",
        &id,
        "--format",
        "html",
        "--out",
        reports.to_str().expect("utf-8"),
        "--db",
        &db,
    ]);
    assert!(ok, "the report of the run: {said}{err}");
    let html: String = std::fs::read_dir(&reports)
        .expect("reports")
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "html"))
        .map(|e| std::fs::read_to_string(e.path()).expect("html"))
        .collect();
    for serial in ["TR-1", "TR-2", "TR-7"] {
        assert!(html.contains(serial), "{serial} in the report");
    }
    assert!(html.contains("cannot be read"), "the unreadable one named");
    // The station's zone read from a config with a key this release does
    // not know (never silently UTC).
    assert!(
        html.contains("UTC+08:00"),
        "the report's times in the station's zone"
    );
    let (ok, said, err) = spinbench(&["runs", "show", &id, "--db", &db]);
    assert!(ok, "{err}");
    assert!(
        said.lines()
            .any(|l| l.contains("TR-2") && l.contains("cannot be read")),
        "{said}"
    );
    assert!(said.contains("TR-1") && said.contains("TR-7"), "{said}");
}

#[test]
fn an_unreadable_stored_record_costs_its_instrument_not_the_run() {
    tolerant_on(None, |db, id| {
        let c = rusqlite::Connection::open(db).expect("sqlite");
        let n = c
            .execute(
                "UPDATE results SET record_json = json_remove(record_json, '$.points')
                 WHERE run_id = ?1 AND serial = 'TR-2'",
                [id],
            )
            .expect("update");
        assert!(n > 0);
        c.execute(
            "UPDATE runs SET station_config = ?2 || station_config WHERE id = ?1",
            [id, FUTURE_CONFIG],
        )
        .expect("update");
    });
}

#[test]
fn postgres_an_unreadable_stored_record_costs_its_instrument_not_the_run() {
    let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = spinbench_store::testing::fresh_postgres_database(&admin).expect("a fresh database");
    tolerant_on(Some(url), |db, id| {
        let mut c = postgres::Client::connect(db, postgres::NoTls).expect("postgres");
        let n = c
            .execute(
                "UPDATE results SET record_json = record_json - 'points'
                 WHERE run_id = $1 AND serial = 'TR-2'",
                &[&id],
            )
            .expect("update");
        assert!(n > 0);
        c.execute(
            "UPDATE runs SET station_config = $2 || station_config WHERE id = $1",
            &[&id, &FUTURE_CONFIG],
        )
        .expect("update");
    });
}
