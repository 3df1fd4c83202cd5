//! Several processes (here, threads with their own connections) creating
//! the same new SQLite store at once: the migrations run once, under an
//! exclusive transaction, and every opener gets a whole store.

use spinbench_store::{MIGRATIONS, Store, StoreTarget};
use std::sync::{Arc, Barrier};

#[test]
fn many_openers_of_a_new_store_at_once_all_get_the_whole_schema() {
    for round in 0..10 {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("new.db");
        let openers = 8;
        let start = Arc::new(Barrier::new(openers));
        let handles: Vec<_> = (0..openers)
            .map(|_| {
                let (path, start) = (path.clone(), start.clone());
                std::thread::spawn(move || {
                    start.wait();
                    Store::connect(&StoreTarget::File(path)).map(|s| s.schema_version())
                })
            })
            .collect();
        for h in handles {
            let version = h
                .join()
                .expect("no panic")
                .unwrap_or_else(|e| panic!("round {round}: an opener failed: {e}"))
                .expect("version");
            assert_eq!(version, MIGRATIONS.len() as i64, "round {round}");
        }
    }
}

#[test]
fn csv_text_that_looks_like_a_formula_is_neutralised_and_read_back() {
    use spinbench_store::{csv_text_field, csv_text_unguarded};
    for (given, written) in [
        ("=HYPERLINK(\"x\")", "\"'=HYPERLINK(\"\"x\"\")\""),
        ("+cmd|' /C calc'!A0", "'+cmd|' /C calc'!A0"),
        ("@SUM(1+1)", "'@SUM(1+1)"),
        ("-2+3", "'-2+3"),
        ("SN-01", "SN-01"),
        ("a,b", "\"a,b\""),
    ] {
        assert_eq!(csv_text_field(given), written, "{given}");
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(written.as_bytes());
        let record = reader.records().next().expect("a record").expect("csv");
        assert_eq!(csv_text_unguarded(&record[0]), given);
    }
}
