//! `spinbench prune`: an ended run's one-second values and
//! events archived to Parquet, read back, then deleted; its record, reports
//! and exports unchanged; on SQLite and PostgreSQL.

mod common;

use common::spinbench;
use parquet::file::reader::{FileReader, SerializedFileReader};
use parquet::record::RowAccessor;
use spinbench_store::{Store, StoreTarget};

fn rows(path: &std::path::Path) -> Vec<parquet::record::Row> {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let reader = SerializedFileReader::new(file).expect("parquet");
    reader
        .get_row_iter(None)
        .expect("rows")
        .map(|r| r.expect("row"))
        .collect()
}

fn prune_on(db_arg: Option<String>) {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("PR-")).expect("plan");
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
    assert!(ok, "{err}");
    let target = StoreTarget::parse(&db);
    let store = Store::connect(&target).expect("store");
    let id = store.runs().expect("runs")[0].id.clone();
    let values = store.values(&id).expect("values");
    let events = store.events(&id).expect("events");
    assert!(values.len() > 100 && events.len() > 10);
    let before = store.run_record(&id).expect("read").expect("run");
    let (ok, csv_before, _) = spinbench(&["export", &id, "--db", &db]);
    assert!(ok);

    // Checked before anything is read.
    for bad in ["-1", "NaN", "1e9"] {
        let (ok, _, err) = spinbench(&["prune", "--older-than", bad, "--db", &db]);
        assert!(!ok && err.contains("--older-than"), "{bad}: {err}");
    }
    // The run is minutes old: the default retention keeps it.
    let archive = dir.path().join("archive");
    let a = archive.to_str().expect("utf-8");
    let (ok, said, err) = spinbench(&["prune", "--archive", a, "--db", &db]);
    assert!(ok && said.contains("nothing to do"), "{said}{err}");
    // A dry run says and keeps.
    let (ok, said, _) = spinbench(&[
        "prune",
        "--older-than",
        "0",
        "--dry-run",
        "--archive",
        a,
        "--db",
        &db,
    ]);
    assert!(ok && said.contains("dry run"), "{said}");
    assert_eq!(store.value_count(&id).expect("count"), values.len() as i64);

    let (ok, said, err) = spinbench(&["prune", "--older-than", "0", "--archive", a, "--db", &db]);
    assert!(ok && said.contains("pruned 1 runs"), "{said}{err}");
    // The archive holds every row, as stored.
    let archived = rows(&archive.join(format!("{id}-values.parquet")));
    assert_eq!(archived.len(), values.len());
    for (row, v) in archived.iter().zip(&values) {
        assert_eq!(row.get_double(1).expect("t_s"), v.t_s);
        assert_eq!(
            row.get_long(2).expect("slot"),
            v.slot + 1,
            "numbered from 1"
        );
        assert_eq!(row.get_double(3).ok(), v.output_hz);
        assert_eq!(row.get_bool(5).expect("on_speed"), v.on_speed);
    }
    let archived = rows(&archive.join(format!("{id}-events.parquet")));
    assert_eq!(archived.len(), events.len());
    for (row, e) in archived.iter().zip(&events) {
        assert_eq!(row.get_long(1).expect("seq"), e.seq);
        assert_eq!(
            row.get_timestamp_millis(2).expect("at, a timestamp"),
            e.at * 1000
        );
        assert_eq!(row.get_string(4).expect("json"), &e.json);
    }
    // Each file stands alone: the run, its station and software, and the
    // serial in each slot, in its metadata.
    let units = store.unit_radii(&id).expect("units");
    assert!(!units.is_empty());
    for file in [
        format!("{id}-values.parquet"),
        format!("{id}-events.parquet"),
    ] {
        let path = archive.join(&file);
        let reader =
            SerializedFileReader::new(std::fs::File::open(&path).expect("open")).expect("parquet");
        let kv: std::collections::BTreeMap<String, String> = reader
            .metadata()
            .file_metadata()
            .key_value_metadata()
            .expect("key-value metadata")
            .iter()
            .filter_map(|k| Some((k.key.clone(), k.value.clone()?)))
            .collect();
        assert_eq!(kv["spinbench.run"], id, "{file}");
        assert_eq!(kv["spinbench.layout"], "2");
        assert_eq!(kv["spinbench.station"], before.start.station);
        assert_eq!(kv["spinbench.software"], before.start.software_version);
        assert!(kv["spinbench.label"].contains('#'), "{kv:?}");
        assert!(
            kv["spinbench.started_at"].len() == 20 && kv["spinbench.started_at"].ends_with('Z'),
            "{kv:?}"
        );
        assert!(kv["spinbench.columns"].contains("[Hz]") || file.contains("events"));
        let slots: serde_json::Value =
            serde_json::from_str(&kv["spinbench.slots"]).expect("the slots as JSON");
        for u in &units {
            assert_eq!(
                slots[(u.slot + 1).to_string()],
                u.serial.as_str(),
                "{file}: {slots}"
            );
        }
    }
    // Deleted from the store; the record, the export and the report unchanged.
    assert_eq!(store.value_count(&id).expect("count"), 0);
    assert_eq!(store.event_count(&id).expect("count"), 0);
    assert_eq!(store.run_record(&id).expect("read").expect("run"), before);
    let (ok, csv_after, _) = spinbench(&["export", &id, "--db", &db]);
    assert!(ok && csv_after == csv_before);
    let reports = dir.path().join("reports");
    let (ok, _, err) = spinbench(&[
        "report",
        &id,
        "--format",
        "pdf",
        "--out",
        reports.to_str().expect("utf-8"),
        "--db",
        &db,
    ]);
    assert!(ok, "{err}");
    // Once: nothing left to prune, and an archive is never overwritten.
    let (ok, said, _) = spinbench(&["prune", "--older-than", "0", "--archive", a, "--db", &db]);
    assert!(ok && said.contains("nothing to do"), "{said}");
}

#[test]
fn an_old_runs_values_and_events_are_archived_then_deleted() {
    prune_on(None);
}

#[test]
fn postgres_an_old_runs_values_and_events_are_archived_then_deleted() {
    let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = spinbench_store::testing::fresh_postgres_database(&admin).expect("a fresh database");
    prune_on(Some(url));
}

/// Hostile archive folders: a link at the old fixed partial name, a link
/// at a run's final name, an interrupted prune's files; a link is never
/// written through, one run's problem does not stop the others, and a
/// complete archive made before is used, not written again.
#[test]
fn prune_never_writes_through_a_link_and_one_runs_problem_stops_no_other() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let plan = dir.path().join("plan.toml");
    let db = data.join("spinbench.db").display().to_string();
    for prefix in ["PL-", "PM-", "PN-"] {
        std::fs::write(&plan, common::short_plan(prefix)).expect("plan");
        let (ok, _, err) = spinbench(&[
            "run",
            "--simulate",
            "--quiet",
            "--data",
            data.to_str().expect("utf-8"),
            plan.to_str().expect("utf-8"),
        ]);
        assert!(ok, "{err}");
    }
    let store = Store::connect(&StoreTarget::parse(&db)).expect("store");
    let ids: Vec<String> = store
        .runs()
        .expect("runs")
        .into_iter()
        .map(|r| r.id)
        .collect();
    assert_eq!(ids.len(), 3);
    let archive = dir.path().join("archive");
    std::fs::create_dir_all(&archive).expect("archive");
    let precious = dir.path().join("precious.txt");
    std::fs::write(&precious, "not the archive's").expect("precious");
    let link = |name: String| {
        std::os::unix::fs::symlink(&precious, archive.join(name)).expect("symlink");
    };
    // Run 1: a link at the fixed partial name an older prune used.
    link(format!("{}-values.parquet.partial", ids[0]));
    // Run 2: a link at its final name.
    link(format!("{}-events.parquet", ids[1]));
    let a = archive.to_str().expect("utf-8");
    let (ok, said, err) = spinbench(&["prune", "--older-than", "0", "--archive", a, "--db", &db]);
    assert!(!ok, "a link at a final name went unreported: {said}");
    assert!(
        said.contains("pruned 2 runs") && err.contains(&ids[1]) && err.contains("exists already"),
        "{said}{err}"
    );
    assert_eq!(
        std::fs::read_to_string(&precious).expect("precious"),
        "not the archive's",
        "written through a link"
    );
    assert_eq!(store.value_count(&ids[0]).expect("count"), 0);
    assert_eq!(store.value_count(&ids[2]).expect("count"), 0);
    assert!(store.value_count(&ids[1]).expect("count") > 0, "kept");
    // The link moved aside, and an interrupted prune's complete archive of
    // run 2 in place (as if it stopped before deleting): used, not rewritten.
    std::fs::remove_file(archive.join(format!("{}-events.parquet", ids[1]))).expect("rm");
    let (ok, said, err) = spinbench(&["prune", "--older-than", "0", "--archive", a, "--db", &db]);
    assert!(ok && said.contains("pruned 1 runs"), "{said}{err}");
    assert_eq!(store.value_count(&ids[1]).expect("count"), 0);
    let leftovers: Vec<String> = std::fs::read_dir(&archive)
        .expect("archive")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".partial"))
        .collect();
    assert_eq!(
        leftovers,
        vec![format!("{}-values.parquet.partial", ids[0])],
        "only the planted link"
    );
}
