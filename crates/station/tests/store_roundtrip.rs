//! The store, on an SQLite file and on a real PostgreSQL server
//! (`SPINBENCH_TEST_POSTGRES`, started by `scripts/test`): a run is written as
//! it happens; `runs`, `unit` and `export` read it back, and `export` →
//! `analyze` reproduces the stored fits. Four stations write to one
//! PostgreSQL at once without losing or mixing anything.

mod common;

use serde_json::Value;
use spinbench_store::{Store, StoreTarget};
use std::path::Path;
use std::process::{Command, Stdio};

use common::spinbench;

#[test]
fn sqlite_a_run_is_stored_listed_exported_and_reanalysed_to_the_same_fits() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("data").join("spinbench.db");
    roundtrip(dir.path(), None, &StoreTarget::File(db.clone()));
    let (ok, _, err) = spinbench(&["runs", "list", "--db", "/no/such.db"]);
    assert!(!ok && err.contains("no store here"), "{err}");

    // A stored value that the raw bytes do not give is caught by the replay.
    let conn = rusqlite::Connection::open(&db).expect("open");
    // Slots are stored as people number them: the plan's 1, 2 and 7.
    for table in ["points", "results", "units", "values_1s"] {
        let slots: Vec<i64> = conn
            .prepare(&format!("SELECT DISTINCT slot FROM {table} ORDER BY slot"))
            .expect("prepare")
            .query_map([], |r| r.get(0))
            .expect("rows")
            .map(|r| r.expect("row"))
            .collect();
        assert_eq!(slots, [1, 2, 7], "{table}");
    }
    // values_1s has no rowid: pick one row by its key.
    let changed = conn
        .execute(
            "UPDATE values_1s SET output_hz = output_hz + 1e-6
             WHERE (run_id, t_s, slot) = (SELECT run_id, t_s, slot FROM values_1s
                                          WHERE output_hz IS NOT NULL LIMIT 1)",
            [],
        )
        .expect("tamper");
    assert_eq!(changed, 1);
    drop(conn);
    let run_dir = std::fs::read_dir(dir.path().join("data").join("runs"))
        .expect("runs")
        .flatten()
        .next()
        .expect("run")
        .path();
    let (ok, out, err) = spinbench(&["replay", run_dir.to_str().expect("utf8")]);
    assert!(!ok, "{out}");
    assert!(err.contains("does not reproduce"), "{err}");
}

#[test]
fn the_batch_report_holds_every_test_and_the_repeatability_of_serials_tested_twice() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("BATCH-")).expect("plan");
    let data = dir.path().join("data");
    for seed in ["5", "6"] {
        let (ok, _, err) = spinbench(&[
            "run",
            "--simulate",
            "--quiet",
            "--seed",
            seed,
            "--data",
            data.to_str().expect("utf8"),
            plan.to_str().expect("utf8"),
        ]);
        assert!(ok, "{err}");
    }
    let db = data.join("spinbench.db");
    let db_s = db.to_str().expect("utf8");
    let out = dir.path().join("batch");
    let (ok, listing, err) = spinbench(&[
        "batch-report",
        "--out",
        out.to_str().expect("utf8"),
        "--db",
        db_s,
    ]);
    assert!(ok, "{err}");
    assert_eq!(
        listing.lines().count(),
        4,
        "pdf, html, xlsx, csv: {listing}"
    );

    // What the store holds: full-range k2 and K1 of each test.
    let store = Store::connect(&StoreTarget::File(db.clone())).expect("store");
    let mut stored: Vec<(String, String, f64, f64)> = Vec::new();
    let mut analyses: Vec<(String, spinbench_analysis::UnitAnalysis)> = Vec::new();
    for run in store.runs().expect("runs") {
        for r in store.results(&run.id).expect("results") {
            analyses.push((
                r.serial.clone(),
                r.record.analysis.clone().expect("analysis"),
            ));
            let record: Value = serde_json::to_value(&r.record).expect("record");
            let full = &record["analysis"]["full_range"];
            stored.push((
                run.id.clone(),
                r.serial.clone(),
                full["k2_ug_per_g2"].as_f64().expect("k2"),
                full["k1"].as_f64().expect("k1"),
            ));
        }
    }
    assert_eq!(stored.len(), 6, "3 serials × 2 runs");

    // CSV: every test, full precision.
    let csv = std::fs::read_to_string(common::batch_file(&out, "csv")).expect("csv");
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 6);
    for row in &rows {
        let k2: f64 = row[4].parse().expect("k2");
        assert!(
            stored
                .iter()
                .any(|(run, serial, k, _)| run == row[0] && serial == row[2] && *k == k2),
            "{row:?}"
        );
    }

    // XLSX: the repeatability sheet has each serial once, with the scale-factor
    // repeatability of method.md §3.4: the one definition (per mounting, the
    // spread of |k1| over the runs; the larger mounting), which `analyze`
    // and `spinbench unit` give too.
    use calamine::{Data, Reader, open_workbook_auto};
    let mut book = open_workbook_auto(common::batch_file(&out, "xlsx")).expect("xlsx");
    let sheet = book.worksheet_range("repeatability").expect("sheet");
    let mut repeats = 0;
    for row in sheet.rows().skip(1) {
        let serial = row[0].to_string();
        let runs: Vec<&spinbench_analysis::UnitAnalysis> = analyses
            .iter()
            .filter(|(s, _)| *s == serial)
            .map(|(_, a)| a)
            .collect();
        assert_eq!(row[1], Data::Float(2.0), "{serial} tested twice");
        let want = spinbench_analysis::unit::repeatability_of(&runs)
            .expect("two runs")
            .scale_factor_ppm;
        // `spinbench unit` says the same number for the same serial.
        let (ok, said, err) = spinbench(&["unit", &serial, "--db", db_s]);
        assert!(ok, "{err}");
        let printed = said
            .lines()
            .find_map(|l| l.split(" runs: ").nth(1))
            .and_then(|rest| rest.split(' ').next())
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or_else(|| panic!("no repeatability in: {said}"));
        assert!(
            (printed - want).abs() <= 0.0005 + 1e-9 * want.abs(),
            "unit says {printed}, batch {want}"
        );
        let Data::Float(got) = row[4] else {
            panic!("repeatability is not a number: {:?}", row[4]);
        };
        assert!(
            (got - want).abs() <= 1e-9 * want.abs().max(1.0),
            "{got} vs {want}"
        );
        repeats += 1;
    }
    assert_eq!(repeats, 3);
    let stats = book.worksheet_range("statistics").expect("statistics");
    let k2_row = stats
        .rows()
        .find(|r| r[0] == Data::String("k2".into()))
        .expect("k2 statistics");
    let mean = stored.iter().map(|s| s.2).sum::<f64>() / 6.0;
    let Data::Float(got) = k2_row[3] else {
        panic!("mean is not a number")
    };
    assert!((got - mean).abs() < 1e-9, "k2 mean {got} vs {mean}");

    // PDF (pdftotext) and HTML carry the same.
    let text = Command::new("pdftotext")
        .args(["-layout"])
        .arg(common::batch_file(&out, "pdf"))
        .arg("-")
        .output()
        .expect("pdftotext (poppler-utils) runs; ./scripts/test installs it");
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains("Batch report") && text.contains("2 runs, 6 instrument tests"),
        "{text}"
    );
    for (_, serial, k2, _) in &stored {
        assert!(
            text.contains(&format!("{k2:.3}")),
            "{serial} k2 {k2:.3} in the PDF"
        );
    }
    let html = std::fs::read_to_string(common::batch_file(&out, "html")).expect("html");
    assert!(html.contains("<table id=\"repeats\">") && html.matches("<svg").count() >= 5);
}

#[test]
fn postgres_a_run_is_stored_listed_exported_and_reanalysed_to_the_same_fits() {
    let dir = tempfile::tempdir().expect("tempdir");
    let url = fresh_postgres();
    roundtrip(dir.path(), Some(&url), &StoreTarget::Postgres(url.clone()));
}

fn fresh_postgres() -> String {
    let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
    spinbench_store::testing::fresh_postgres_database(&admin).expect("a fresh database")
}

/// One simulated run into `target` (`--db url` when given, else the data directory's file).
/// The round trip's operator and serial numbers: not only Latin.
const OPERATOR: &str = "张伟";
const SERIAL_PREFIX: &str = "加速度计-";

fn roundtrip(dir: &Path, db_arg: Option<&str>, target: &StoreTarget) {
    let plan = dir.join("plan.toml");
    // Chinese serial numbers and operator: every report format must carry them.
    let text = format!(
        "operator = \"{OPERATOR}\"\n{}",
        common::short_plan(SERIAL_PREFIX)
    );
    std::fs::write(&plan, text).expect("plan");
    let data = dir.join("data");
    let mut args = vec![
        "run".to_string(),
        "--simulate".into(),
        "--quiet".into(),
        "--seed".into(),
        "4".into(),
        "--data".into(),
        data.display().to_string(),
        plan.display().to_string(),
    ];
    if let Some(url) = db_arg {
        args.extend(["--db".into(), url.to_string()]);
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let (ok, _, err) = spinbench(&args);
    assert!(ok, "{err}");
    let db_text = match target {
        StoreTarget::File(p) => p.display().to_string(),
        StoreTarget::Postgres(url) => url.clone(),
    };
    let db_s = db_text.as_str();

    let store = Store::connect(target).expect("open");
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
    assert!(
        ok && shown.contains(&format!("{SERIAL_PREFIX}7")),
        "{shown}"
    );
    let serial_2 = format!("{SERIAL_PREFIX}2");
    let (ok, history, _) = spinbench(&["unit", &serial_2, "--db", db_s]);
    assert!(ok && history.contains(&run.id), "{history}");
    // Each result says what its verdict judged, against which limit: the
    // quantity, its value ± U95, never k2_max beside a verdict on K2.
    for said in [&shown, &history] {
        let rows: Vec<&str> = said.lines().filter(|l| l.contains("slot")).collect();
        assert!(!rows.is_empty(), "{said}");
        for row in rows {
            assert!(
                row.contains("K2 ") && row.contains("(limit ") && !row.contains("k2_max"),
                "{row}"
            );
        }
    }

    // Every export format is valid input for `analyze`, which reproduces the stored fits.
    for format in ["csv", "xlsx", "parquet"] {
        let file = dir.join(format!("points.{format}"));
        let file_s = file.to_str().expect("utf8");
        let (ok, _, err) = spinbench(&[
            "export", &run.id, "--db", db_s, "--format", format, "--out", file_s,
        ]);
        assert!(ok, "{format}: {err}");
        let (ok, json, err) = spinbench(&["analyze", file_s, "--json"]);
        assert!(ok, "{format}: {err}");
        let analysed: Value = serde_json::from_str(&json).expect("json");
        let mut compared = 0;
        for stored in store.results(&run.id).expect("results") {
            let record: Value = serde_json::to_value(&stored.record).expect("record");
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
                        "{format}: {} {mount} {key}: {a} vs {s}",
                        stored.serial
                    );
                    compared += 1;
                }
            }
        }
        assert_eq!(compared, 3 * 2 * 4, "{format}");
    }

    // The run's reports were written at its end; their numbers are the stored ones.
    let run_dir = data.join("runs").join(&run.id);
    check_reports(&run_dir, &store, &run.id);

    // The raw capture replays to exactly the stored one-second values and points.
    let (ok, replayed, err) = spinbench(&["replay", run_dir.to_str().expect("utf8"), "--db", db_s]);
    assert!(ok, "{replayed}{err}");
    let values = store.value_count(&run.id).expect("values");
    assert!(values > 0);
    assert!(
        replayed.contains(&format!(
            "one-second values: {values} of {values} stored found bit-exact"
        )),
        "{replayed}"
    );
    assert!(
        replayed.contains("points: 78 of 78 stored re-derived"),
        "{replayed}"
    );

    let (ok, _, err) = spinbench(&["runs", "show", "nope", "--db", db_s]);
    assert!(!ok && err.contains("no run 'nope'"), "{err}");
}

#[test]
fn postgres_four_stations_write_at_once_and_nothing_is_lost_or_mixed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let url = fresh_postgres();
    let children: Vec<_> = (1..=4)
        .map(|k| {
            let plan = dir.path().join(format!("plan{k}.toml"));
            std::fs::write(&plan, common::short_plan(&format!("S{k}-"))).expect("plan");
            let data = dir.path().join(format!("station{k}"));
            let child = Command::new(env!("CARGO_BIN_EXE_spinbench"))
                .args(["run", "--simulate", "--quiet", "--seed"])
                .arg(k.to_string())
                .arg("--data")
                .arg(&data)
                .args(["--db", &url])
                .arg(&plan)
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .expect("start a station");
            (k, data, child)
        })
        .collect();
    let store = Store::connect(&StoreTarget::Postgres(url.clone())).expect("open");
    for (k, data, child) in children {
        let out = child.wait_with_output().expect("station");
        assert!(
            out.status.success(),
            "station {k}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let run_dir = std::fs::read_dir(data.join("runs"))
            .expect("runs")
            .flatten()
            .next()
            .expect("the run's directory")
            .path();
        let run_id = run_dir
            .file_name()
            .expect("name")
            .to_string_lossy()
            .into_owned();
        let run = store
            .run(&run_id)
            .expect("query")
            .expect("the run is stored");
        assert_eq!(run.state.as_str(), "completed", "station {k}");
        // Every point of the run's own record is stored, once, under this run only.
        let records: Value = serde_json::from_str(
            &std::fs::read_to_string(run_dir.join("results.json")).expect("results.json"),
        )
        .expect("json");
        let journaled: usize = records
            .as_array()
            .expect("records")
            .iter()
            .map(|r| r["points"].as_array().map_or(0, Vec::len))
            .sum();
        let points = store.points(&run_id).expect("points");
        assert_eq!(points.len(), journaled, "station {k}");
        assert_eq!(points.len(), 3 * 2 * 13, "station {k}");
        let prefix = format!("S{k}-");
        assert!(
            points.iter().all(|p| p.serial.starts_with(&prefix)),
            "station {k}: another station's points mixed in"
        );
        assert!(store.value_count(&run_id).expect("values") > 0);
        assert_eq!(store.results(&run_id).expect("results").len(), 3);
    }
    assert_eq!(store.runs().expect("runs").len(), 4);
}

/// The HTML, XLSX and CSV reports in `run_dir` against the stored results.
fn check_reports(run_dir: &Path, store: &Store, run_id: &str) {
    use calamine::{Data, Reader, open_workbook_auto};
    let stored: Vec<(String, String, f64)> = store
        .results(run_id)
        .expect("results")
        .iter()
        .flat_map(|r| {
            let record: Value = serde_json::to_value(&r.record).expect("record");
            ["P", "N"]
                .iter()
                .filter_map(|m| {
                    record["analysis"]["fits"][*m]["k2_ug_per_g2"]
                        .as_f64()
                        .map(|k2| (r.serial.clone(), m.to_string(), k2))
                })
                .collect::<Vec<_>>()
        })
        .collect();
    assert_eq!(stored.len(), 6, "3 instruments × 2 mountings");

    // CSV: full precision, so equal.
    let csv = std::fs::read_to_string(common::report_file(run_dir, run_id, "csv")).expect("csv");
    let mut rows = csv.lines();
    let header: Vec<&str> = rows.next().expect("header").split(',').collect();
    let k2_col = header
        .iter()
        .position(|h| *h == "k2 [µg/g²]")
        .expect("k2 column");
    for line in rows {
        let cells: Vec<&str> = line.split(',').collect();
        let (serial, mount) = (cells[0], cells[2]);
        let k2: f64 = cells[k2_col].parse().expect("k2 number");
        assert!(
            stored.contains(&(serial.to_string(), mount.to_string(), k2)),
            "csv {serial} {mount} {k2}"
        );
    }

    // XLSX read back with calamine: numbers are numbers, equal to the store's.
    let mut book = open_workbook_auto(common::report_file(run_dir, run_id, "xlsx")).expect("xlsx");
    assert!(
        book.sheet_names().len() >= 2 + 3,
        "results, points and one sheet per instrument"
    );
    let range = book.worksheet_range("results").expect("results sheet");
    let mut seen = 0;
    for row in range.rows().skip(1) {
        let text = |c: usize| match &row[c] {
            Data::String(s) => s.clone(),
            other => other.to_string(),
        };
        let Data::Float(k2) = row[7] else {
            panic!("k2 is not a number: {:?}", row[7]);
        };
        assert!(
            stored.contains(&(text(0), text(2), k2)),
            "xlsx {} {}",
            text(0),
            text(2)
        );
        seen += 1;
    }
    assert_eq!(seen, 6);

    // HTML: a parseable document whose summary rows carry the stored k2 (3 decimals).
    let html = std::fs::read_to_string(common::report_file(run_dir, run_id, "html")).expect("html");
    assert!(html.starts_with("<!DOCTYPE html>") && html.trim_end().ends_with("</html>"));
    assert_eq!(html.matches("<svg").count(), html.matches("</svg>").count());
    assert!(html.matches("<svg").count() >= 6, "plots inline");
    assert!(
        !html.contains("src=\"http"),
        "self-contained: nothing fetched"
    );
    for (serial, mount, k2) in &stored {
        let start = html
            .find(&format!("data-serial=\"{serial}\" data-mount=\"{mount}\""))
            .unwrap_or_else(|| panic!("summary row of {serial} {mount}"));
        let row = &html[start..start + html[start..].find("</tr>").expect("row end")];
        assert!(
            row.contains(&format!("<td>{k2:.3}</td>")),
            "{serial} {mount} k2 {k2:.3} in {row}"
        );
    }

    // PDF, read by an independent reader (poppler's pdftotext, installed by
    // scripts/test): a cover with the summary, then a page (or more) per
    // instrument; the Chinese text is real text, and every stored k2 is in
    // its summary row (3 decimals).
    let pdf = common::report_file(run_dir, run_id, "pdf");
    let out = Command::new("pdftotext")
        .args(["-layout"])
        .arg(&pdf)
        .arg("-")
        .output()
        .expect("pdftotext (poppler-utils) runs; ./scripts/test installs it");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("utf-8 text");
    // Nothing a signer reads is cut short.
    let cut: Vec<&str> = text.lines().filter(|l| l.contains('…')).collect();
    assert!(cut.is_empty(), "cut lines in the PDF: {cut:#?}");
    // Its metadata: title, author, producer, dated today.
    let info = Command::new("pdfinfo")
        .arg(&pdf)
        .output()
        .expect("pdfinfo (poppler-utils) runs; ./scripts/test installs it");
    let info = String::from_utf8_lossy(&info.stdout);
    let field = |name: &str| {
        info.lines()
            .find_map(|l| l.strip_prefix(&format!("{name}:")))
            .map(str::trim)
            .unwrap_or_else(|| panic!("no {name} in {info}"))
            .to_string()
    };
    assert_eq!(field("Title"), format!("spinbench report {run_id}"));
    assert!(field("Author").starts_with("spinbench station"), "{info}");
    assert!(field("Producer").starts_with("spinbench"), "{info}");
    let year = 1970
        + std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .expect("clock")
            .as_secs()
            / 31_556_952;
    assert!(field("CreationDate").contains(&year.to_string()), "{info}");
    let pages: Vec<&str> = text
        .split('\x0c')
        .filter(|p| !p.trim().is_empty())
        .collect();
    assert!(
        pages.len() > 3,
        "cover + 3 instruments: {} pages",
        pages.len()
    );
    assert!(pages[0].contains(&format!("run {run_id}")), "{}", pages[0]);
    assert!(pages[0].contains(OPERATOR), "operator in {}", pages[0]);
    // Page 1 is the signer's: the judged quantity and its
    // limit, K2 ± U95 per instrument, the actions and the sign-off block;
    // the figures per mounting follow on page 2.
    for said in [
        "Judged: K2",
        "K2 ± U95",
        "Operator actions",
        "Station notices",
        "Tested by",
        "Reviewed by",
    ] {
        assert!(pages[0].contains(said), "{said} on page 1: {}", pages[0]);
    }
    for (serial, mount, k2) in &stored {
        assert!(serial.starts_with(SERIAL_PREFIX));
        assert!(pages[0].contains(serial.as_str()), "{serial} on page 1");
        let row = pages[1]
            .lines()
            .find(|l| {
                let cells: Vec<&str> = l.split_whitespace().collect();
                cells.first() == Some(&serial.as_str()) && cells.get(2) == Some(&mount.as_str())
            })
            .unwrap_or_else(|| panic!("summary row of {serial} {mount} in {}", pages[1]));
        assert!(
            row.split_whitespace().any(|c| c == format!("{k2:.3}")),
            "{serial} {mount} k2 {k2:.3} in {row}"
        );
        assert!(
            pages[1..]
                .iter()
                .any(|p| p.contains(&format!("{serial} (slot"))),
            "a page of {serial}"
        );
    }
}

#[test]
fn postgres_a_whole_test_runs_with_a_role_that_has_data_rights_only() {
    // The schema made by its owner (`spinbench migrate`, here the test's
    // fresh database); the station works as a role that may read and write
    // rows and nothing else, as a plant's DBA grants it.
    let dir = tempfile::tempdir().expect("tempdir");
    let url = fresh_postgres();
    let role = common::role_for(&url, "app");
    let mut owner = postgres::Client::connect(&url, postgres::NoTls).expect("owner");
    owner
        .batch_execute(&format!(
            "CREATE ROLE {role} LOGIN;
             GRANT USAGE ON SCHEMA public TO {role};
             GRANT SELECT, INSERT, UPDATE, DELETE ON ALL TABLES IN SCHEMA public TO {role};
             GRANT USAGE, SELECT ON ALL SEQUENCES IN SCHEMA public TO {role};"
        ))
        .expect("a role with data rights only");
    let app = url.replacen("://spinbench@", &format!("://{role}@"), 1);
    // It cannot change the schema…
    let mut as_app = postgres::Client::connect(&app, postgres::NoTls).expect("app");
    let e = as_app
        .batch_execute("CREATE TABLE not_allowed (i INTEGER)")
        .expect_err("no DDL rights");
    assert_eq!(
        e.code(),
        Some(&postgres::error::SqlState::INSUFFICIENT_PRIVILEGE),
        "{e:?}"
    );
    drop(as_app);
    // …and runs, stores, lists, exports, reports and replays a whole test.
    roundtrip(dir.path(), Some(&app), &StoreTarget::Postgres(app.clone()));
    // `spinbench migrate` as that role: nothing to do on a current store.
    let (ok, said, err) = spinbench(&["migrate", "--db", &app]);
    assert!(ok && said.contains("nothing to do"), "{said}{err}");
}

#[test]
fn postgres_a_store_that_is_not_migrated_is_refused_with_the_command_to_run() {
    let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
    let url = spinbench_store::testing::empty_postgres_database(&admin).expect("an empty database");
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("M")).expect("plan");
    let data = dir.path().join("data");
    let (ok, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--quiet",
        "--data",
        data.to_str().expect("utf-8"),
        plan.to_str().expect("utf-8"),
        "--db",
        &url,
    ]);
    assert!(!ok, "a run started on a store with no schema");
    assert!(err.contains("spinbench migrate --db"), "{err}");
    let (ok, said, err) = spinbench(&["migrate", "--db", &url, "--history"]);
    let wanted = spinbench_store::MIGRATIONS.len();
    assert!(
        ok && said.contains(&format!("schema version 0 → {wanted}")),
        "{said}{err}"
    );
    // The history: every version, this release for each.
    assert_eq!(
        said.lines()
            .filter(|l| l.contains(env!("CARGO_PKG_VERSION")))
            .count(),
        wanted,
        "{said}"
    );
}

/// A store written by the previous release (`b9d354f`, schema 13: a
/// simulated run of `common::short_plan("OLD-")`, seed 4) with what that
/// release's `export` and `report --format csv` said of it.
const PREVIOUS_RELEASE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/fixtures/previous-release"
);

#[test]
fn a_store_written_by_the_previous_release_migrates_and_reads_back_the_same_record() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("spinbench.db");
    std::fs::copy(format!("{PREVIOUS_RELEASE}/spinbench.db"), &db).expect("the fixture");
    let db_s = db.to_str().expect("utf-8");
    let (ok, said, err) = spinbench(&["migrate", "--db", db_s, "--history"]);
    let wanted = spinbench_store::MIGRATIONS.len();
    assert!(
        ok && said.contains(&format!("schema version 13 → {wanted}")),
        "{said}{err}"
    );
    // The history: the first twelve from before it was kept, then each with its time.
    assert_eq!(said.matches("(before the history)").count(), 12, "{said}");
    let store = Store::connect(&StoreTarget::File(db.clone())).expect("open");
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 1);
    let id = runs[0].id.clone();
    // The same points and the same report, byte for byte.
    let (ok, points, err) = spinbench(&["export", &id, "--db", db_s]);
    assert!(ok, "{err}");
    assert_eq!(
        points,
        std::fs::read_to_string(format!("{PREVIOUS_RELEASE}/export.csv")).expect("export.csv")
    );
    let out = dir.path().join("reports");
    let (ok, _, err) = spinbench(&[
        "report",
        &id,
        "--format",
        "csv",
        "--out",
        out.to_str().expect("utf-8"),
        "--db",
        db_s,
    ]);
    assert!(ok, "{err}");
    let report = std::fs::read_dir(&out)
        .expect("reports")
        .flatten()
        .find(|e| e.path().extension().is_some_and(|x| x == "csv"))
        .expect("a csv report");
    // Every column the previous release wrote, byte for byte, where it was;
    // this release appends what the verdict judged (K2, its U95,
    // the measurand, the limit and the rule).
    let now = std::fs::read_to_string(report.path()).expect("report");
    let then =
        std::fs::read_to_string(format!("{PREVIOUS_RELEASE}/report.csv")).expect("report.csv");
    assert_eq!(now.lines().count(), then.lines().count(), "{now}");
    for (k, (new, old)) in now.lines().zip(then.lines()).enumerate() {
        assert!(
            new.starts_with(&format!("{old},")),
            "line {k}: the earlier columns changed:\n  was {old}\n  now {new}"
        );
    }
    let header = now.lines().next().expect("a header");
    assert!(
        header.ends_with(",K2 [µg/g²],K2 U95 [µg/g²],judged,limit [µg/g²],rule"),
        "{header}"
    );
    let first = now.lines().nth(1).expect("a row");
    assert!(first.ends_with(",K2,20.0,guarded"), "{first}");
    // The typed record: an old layout (no version), its plan and devices read.
    let record = store.run_record(&id).expect("read").expect("the run");
    assert_eq!(record.start.record_version, 1);
    assert!(
        record.start.plan.plan.is_some(),
        "{:?}",
        record.start.plan.unread
    );
    assert!(!record.devices.is_empty());
    assert_eq!(record.end.state, spinbench_store::StoredState::Completed);
    assert_eq!(record.results.len(), 3);
    // The migration filled the results' figure columns from the records.
    let conn = rusqlite::Connection::open(&db).expect("sqlite");
    for r in &record.results {
        let (k2_p, k2_u95_p, big_k2, measurand): (Option<f64>, Option<f64>, Option<f64>, Option<String>) = conn
            .query_row(
                "SELECT k2_p_ug_per_g2, k2_p_u95, instrument_k2_ug_per_g2, measurand FROM results WHERE run_id = ?1 AND slot = ?2",
                // The store numbers slots from 1 (migration 16); the row's is an index.
                rusqlite::params![id, r.slot + 1],
                |row| Ok((row.get(0)?, row.get(1)?, row.get(2)?, row.get(3)?)),
            )
            .expect("figures");
        let f = spinbench_store::ResultFigures::of(&r.record);
        assert_eq!(k2_p, f.k2_p, "{}", r.serial);
        assert_eq!(k2_u95_p, f.k2_p_u95, "{}", r.serial);
        assert_eq!(big_k2, f.instrument_k2, "{}", r.serial);
        assert_eq!(measurand.as_deref(), f.measurand, "{}", r.serial);
        assert!(
            f.k2_p.is_some() && f.instrument_k2.is_some(),
            "{}",
            r.serial
        );
    }
}

/// The one register of an earlier release becomes each
/// known station's at the upgrade (migration 17): nothing is lost, and each
/// station's entries are its own from then on.
#[test]
fn the_shared_register_of_the_previous_release_is_copied_to_each_station() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("spinbench.db");
    std::fs::copy(format!("{PREVIOUS_RELEASE}/spinbench.db"), &db).expect("the fixture");
    {
        let c = rusqlite::Connection::open(&db).expect("the fixture");
        c.execute_batch(
            "INSERT INTO equipment VALUES ('centrifuge', 'CT 9', 'K-9', '2025-01-01', '2099-01-01', 'eng', 0);
             INSERT INTO stations (name, first_seen, last_seen) VALUES ('second station', 0, 0);",
        )
        .expect("an entry and a second station");
    }
    let store = Store::connect(&StoreTarget::File(db.clone())).expect("migrates");
    for station in ["spinbench virtual bench", "second station"] {
        let rows = store.equipment(Some(station)).expect("register");
        assert_eq!(rows.len(), 1, "{station}: {rows:?}");
        assert_eq!(
            (rows[0].role.as_str(), rows[0].certificate.as_str()),
            ("centrifuge", "K-9")
        );
    }
    // From now on, one station's change is not the other's.
    let mut changed = store.equipment(Some("second station")).expect("register")[0].clone();
    changed.certificate = "K-10".into();
    store.set_equipment(&changed, "eng").expect("set");
    assert_eq!(
        store
            .equipment(Some("spinbench virtual bench"))
            .expect("register")[0]
            .certificate,
        "K-9"
    );
}

/// A store a newer release wrote (its schema one version past this
/// release's) is never written to: `migrate` exits non-zero saying so, and
/// a run on it is refused before anything moves. SQLite as PostgreSQL.
#[test]
fn a_store_written_by_a_newer_release_is_never_written_to() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    std::fs::create_dir_all(&data).expect("data");
    let db = data.join("spinbench.db");
    let db_s = db.to_str().expect("utf-8");
    let (ok, _, err) = spinbench(&["migrate", "--db", db_s]);
    assert!(ok, "{err}");
    let newer = spinbench_store::MIGRATIONS.len() + 1;
    {
        let conn = rusqlite::Connection::open(&db).expect("open");
        conn.execute_batch(&format!("PRAGMA user_version = {newer};"))
            .expect("as a newer release leaves it");
    }
    let before = std::fs::read(&db).expect("db");
    let (ok, said, err) = spinbench(&["migrate", "--db", db_s]);
    assert!(!ok, "migrate on a newer store succeeded: {said}");
    assert!(
        err.contains("newer release") && !err.contains("nothing to do"),
        "{said}{err}"
    );
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("NEW")).expect("plan");
    let (ok, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--quiet",
        "--data",
        data.to_str().expect("utf-8"),
        plan.to_str().expect("utf-8"),
    ]);
    assert!(!ok && err.contains("newer release"), "{err}");
    assert_eq!(
        std::fs::read(&db).expect("db"),
        before,
        "the store was written"
    );
}

#[test]
fn postgres_a_role_the_upgrade_left_without_rights_fails_loudly_until_migrate_grants_them() {
    // The README's data-only role, granted on the tables the store had;
    // then a table it may not write, as after an upgrade whose migration
    // added one (its owner's rights only).
    let dir = tempfile::tempdir().expect("tempdir");
    let url = fresh_postgres();
    let role = common::role_for(&url, "up");
    let mut owner = postgres::Client::connect(&url, postgres::NoTls).expect("owner");
    owner
        .batch_execute(&format!(
            "CREATE ROLE {role} LOGIN;
             GRANT USAGE ON SCHEMA public TO {role};
             GRANT SELECT, INSERT, UPDATE, DELETE ON ALL TABLES IN SCHEMA public TO {role};
             GRANT USAGE ON ALL SEQUENCES IN SCHEMA public TO {role};
             REVOKE ALL ON results FROM {role};"
        ))
        .expect("the role an upgrade left");
    drop(owner);
    let app = url.replacen("://spinbench@", &format!("://{role}@"), 1);
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("UP-")).expect("plan");
    let data = dir.path().join("data");
    let run = || {
        spinbench(&[
            "run",
            "--simulate",
            "--quiet",
            "--data",
            data.to_str().expect("utf-8"),
            "--db",
            &app,
            plan.to_str().expect("utf-8"),
        ])
    };
    // Never "completed, exit 0": the permission named, and what to run.
    let (ok, said, err) = run();
    assert!(
        !ok,
        "a run whose results the store refused exited 0: {said}{err}"
    );
    assert!(
        err.contains("permission denied") && err.contains("--grant"),
        "{err}"
    );
    // doctor names the right the role lacks and the command that grants it.
    let (ok, said, err) = spinbench(&["doctor", "--simulate", "--db", &app]);
    assert!(
        !ok && said.contains("lacks DELETE on results")
            && said.contains(&format!("--grant {role}")),
        "{said}{err}"
    );
    // A backup as that role leaves nothing named like a backup.
    let backups = dir.path().join("backups");
    let (ok, _, err) = spinbench(&["backup", backups.to_str().expect("utf-8"), "--db", &app]);
    assert!(!ok && err.contains("owner"), "{err}");
    let left: Vec<_> = std::fs::read_dir(&backups)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    assert!(left.is_empty(), "a failed backup left {left:?}");
    // The owner grants the role its rights; the role then runs a whole test.
    let (ok, said, err) = spinbench(&["migrate", "--db", &url, "--grant", &role]);
    assert!(
        ok && said.contains(&format!("role {role} granted")),
        "{said}{err}"
    );
    let (ok, said, err) = spinbench(&["migrate", "--db", &url, "--grant", "x; DROP TABLE runs"]);
    assert!(
        !ok && err.contains("not a PostgreSQL role name"),
        "{said}{err}"
    );
    let (ok, said, err) = run();
    assert!(ok, "{said}{err}");
    let (_, said, _) = spinbench(&["doctor", "--simulate", "--db", &app]);
    assert!(!said.contains("lacks"), "{said}");
    let (ok, listed, err) = spinbench(&["runs", "list", "--db", &app]);
    assert!(ok && listed.contains("completed"), "{listed}{err}");
}

#[test]
fn pgbouncer_runs_one_after_another_are_stored_whole_through_transaction_pooling() {
    // PgBouncer in transaction pooling over one server connection: each
    // process's statements meet the previous process's on it (named
    // prepared statements collided: "s0 already exists"), and a
    // statement's transactions may be given any server connection.
    let direct = fresh_postgres();
    let url = spinbench_store::testing::behind_pgbouncer(&direct).unwrap_or_else(|e| panic!("{e}"));
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("PGB-")).expect("plan");
    let data = dir.path().join("data");
    for _ in 0..2 {
        let (ok, said, err) = spinbench(&[
            "run",
            "--simulate",
            "--quiet",
            "--data",
            data.to_str().expect("utf-8"),
            "--db",
            &url,
            plan.to_str().expect("utf-8"),
        ]);
        assert!(ok, "{said}{err}");
    }
    // Both runs completed with their results, as the server itself holds them.
    let mut server = postgres::Client::connect(&direct, postgres::NoTls).expect("direct");
    let rows = server
        .query(
            "SELECT state, (SELECT count(*) FROM results r WHERE r.run_id = runs.id) FROM runs",
            &[],
        )
        .expect("runs");
    assert_eq!(rows.len(), 2);
    for row in rows {
        let (state, results): (String, i64) = (row.get(0), row.get(1));
        assert_eq!((state.as_str(), results), ("completed", 3));
    }
    // The connections carry the station's name for the DBA.
    let named: i64 = server
        .query_one(
            "SELECT count(*) FROM pg_stat_activity WHERE application_name LIKE 'spinbench%'",
            &[],
        )
        .expect("pg_stat_activity")
        .get(0);
    assert!(
        named >= 1,
        "PgBouncer's server connection is named by its first client"
    );
    // migrate through the pooler too (a transaction-level lock).
    let (ok, said, err) = spinbench(&["migrate", "--db", &url]);
    assert!(ok && said.contains("nothing to do"), "{said}{err}");
}
