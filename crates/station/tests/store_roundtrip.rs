//! The store: a run is written as it happens; `runs`, `unit` and `export`
//! read it back, and `export` → `analyze` reproduces the stored fits.

mod common;

use serde_json::Value;
use std::process::Command;

fn spinbench(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(args)
        .output()
        .expect("run spinbench");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_run_is_stored_listed_exported_and_reanalysed_to_the_same_fits() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("ST")).expect("plan");
    let data = dir.path().join("data");
    let (ok, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--quiet",
        "--seed",
        "4",
        "--data",
        data.to_str().expect("utf8"),
        plan.to_str().expect("utf8"),
    ]);
    assert!(ok, "{err}");
    let db = data.join("spinbench.db");
    let db_s = db.to_str().expect("utf8");

    let store = spinbench_store::Store::open(&db).expect("open");
    assert_eq!(store.integrity_check().expect("check"), "ok");
    assert_eq!(
        store.schema_version().expect("version"),
        spinbench_store::MIGRATIONS.len() as i64
    );
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 1);
    let run = &runs[0];
    assert_eq!(
        (run.state.as_str(), run.units, run.points),
        ("completed", 3, 78)
    );

    let (ok, listing, err) = spinbench(&["runs", "list", "--db", db_s]);
    assert!(
        ok && listing.contains(&run.id) && listing.contains("completed"),
        "{listing}{err}"
    );
    let (ok, shown, _) = spinbench(&["runs", "show", &run.id, "--db", db_s]);
    assert!(ok && shown.contains("ST7"), "{shown}");
    let (ok, history, _) = spinbench(&["unit", "ST2", "--db", db_s]);
    assert!(ok && history.contains(&run.id), "{history}");

    let csv = dir.path().join("points.csv");
    let (ok, _, err) = spinbench(&[
        "export",
        &run.id,
        "--db",
        db_s,
        "--out",
        csv.to_str().expect("utf8"),
    ]);
    assert!(ok, "{err}");
    let (ok, json, err) = spinbench(&["analyze", csv.to_str().expect("utf8"), "--json"]);
    assert!(ok, "{err}");
    let analysed: Value = serde_json::from_str(&json).expect("json");
    let mut compared = 0;
    for stored in store.results(&run.id).expect("results") {
        let record: Value = serde_json::from_str(&stored.record_json).expect("record");
        let unit = analysed["units"]
            .as_array()
            .expect("units")
            .iter()
            .find(|u| u["unit"] == stored.serial.as_str())
            .expect("unit in export");
        for mount in ["P", "N"] {
            for key in ["k0_g", "k1", "k2_ug_per_g2", "k3_ug_per_g3"] {
                let a = unit["fits"][mount][key].as_f64().expect("analysed");
                let s = record["analysis"]["fits"][mount][key]
                    .as_f64()
                    .expect("stored");
                assert!(
                    (a - s).abs() <= 1e-9 * s.abs().max(1e-9),
                    "{} {mount} {key}: {a} vs {s}",
                    stored.serial
                );
                compared += 1;
            }
        }
    }
    assert_eq!(compared, 3 * 2 * 4);

    let (ok, _, err) = spinbench(&["runs", "show", "nope", "--db", db_s]);
    assert!(!ok && err.contains("no run 'nope'"), "{err}");
    let (ok, _, err) = spinbench(&["runs", "list", "--db", "/no/such.db"]);
    assert!(!ok && err.contains("no store here"), "{err}");
}
