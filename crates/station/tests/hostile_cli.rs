//! The release binary tried as a new user or an attacker would: each defect
//! a hostile test found, through the real command line. One short simulated
//! run (made once) serves the tests that need a run and a store.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

fn spinbench(args: &[&str]) -> (bool, String, String) {
    spinbench_in(None, args)
}

fn spinbench_in(cwd: Option<&Path>, args: &[&str]) -> (bool, String, String) {
    let mut command = Command::new(env!("CARGO_BIN_EXE_spinbench"));
    command.args(args);
    if let Some(dir) = cwd {
        command.current_dir(dir);
    }
    let out = command.output().expect("run spinbench");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Serials that a spreadsheet program would take for formulas.
const FORMULA_SERIALS: [&str; 3] = [
    "=HYPERLINK(\"evil.example\",\"a\")",
    "+cmd|' /C calc'!A0",
    "@SUM(1+1)",
];

const PLAN: &str = r#"
range_g = 10
levels = [0, 1, 2, 4, 6, 8, 10]
passes = ["P"]
warmup_s = 0
dwell = { seconds = 3 }
stability = { hold_s = 3 }
[serials]
1 = '=HYPERLINK("evil.example","a")'
2 = "+cmd|' /C calc'!A0"
7 = "@SUM(1+1)"
"#;

/// One completed run: (its data directory, its run directory, the plan file).
fn the_run() -> &'static (PathBuf, PathBuf, PathBuf) {
    static RUN: OnceLock<(PathBuf, PathBuf, PathBuf)> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = tempfile::tempdir().expect("tempdir").keep();
        let plan = dir.join("plan.toml");
        std::fs::write(&plan, PLAN).expect("plan");
        let data = dir.join("data");
        let (ok, out, err) = spinbench(&[
            "run",
            "--simulate",
            "--quiet",
            "--data",
            data.to_str().expect("utf8"),
            plan.to_str().expect("utf8"),
        ]);
        assert!(ok, "{out}\n{err}");
        let run_dir = std::fs::read_dir(data.join("runs"))
            .expect("runs")
            .flatten()
            .next()
            .expect("a run")
            .path();
        (data, run_dir, plan)
    })
}

fn run_id(run_dir: &Path) -> String {
    run_dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

#[test]
fn resume_refuses_another_plan_naming_the_difference_and_keeps_the_runs_own() {
    let (data, run_dir, plan) = the_run();
    let own = std::fs::read_to_string(run_dir.join("plan.toml")).expect("own plan");
    let other = data.join("other.toml");
    std::fs::write(
        &other,
        PLAN.replace("range_g = 10", "range_g = 8")
            .replace(
                "levels = [0, 1, 2, 4, 6, 8, 10]",
                "levels = [0, 1, 2, 4, 6, 8]",
            )
            .replace("@SUM(1+1)", "RENAMED"),
    )
    .expect("other plan");
    let (ok, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--resume",
        run_dir.to_str().expect("utf8"),
        other.to_str().expect("utf8"),
    ]);
    assert!(!ok);
    assert!(err.contains("not the run's own plan"), "{err}");
    assert!(err.contains("range_g: 10.0 in the run, 8.0 given"), "{err}");
    assert!(err.contains("serials.7"), "{err}");
    assert_eq!(
        std::fs::read_to_string(run_dir.join("plan.toml")).expect("plan"),
        own,
        "the run's plan.toml is never overwritten"
    );
    // The run's own plan is accepted (and says the run is complete).
    let (ok, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--resume",
        run_dir.to_str().expect("utf8"),
        plan.to_str().expect("utf8"),
    ]);
    assert!(!ok && err.contains("already completed"), "{err}");
}

#[test]
fn resume_of_a_directory_that_is_not_a_run_is_refused_and_makes_nothing() {
    let (_, _, plan) = the_run();
    let work = tempfile::tempdir().expect("tempdir");
    let not_a_run = work.path().join("holiday-photos");
    std::fs::create_dir_all(&not_a_run).expect("dir");
    let (ok, _, err) = spinbench_in(
        Some(work.path()),
        &[
            "run",
            "--simulate",
            "--resume",
            not_a_run.to_str().expect("utf8"),
            plan.to_str().expect("utf8"),
        ],
    );
    assert!(!ok);
    assert!(err.contains("not a run directory"), "{err}");
    assert_eq!(std::fs::read_dir(&not_a_run).expect("dir").count(), 0);
    assert!(!work.path().join("spinbench-data").exists());
}

#[test]
fn export_never_overwrites_the_store_a_runs_files_or_anything_without_force() {
    let (data, run_dir, _) = the_run();
    let db = data.join("spinbench.db");
    let id = run_id(run_dir);
    let before = std::fs::read(&db).expect("store");
    let db_text = db.to_str().expect("utf8");
    for force in [false, true] {
        let mut args = vec!["export", &id, "--out", db_text, "--db", db_text];
        if force {
            args.push("--force");
        }
        let (ok, _, err) = spinbench(&args);
        assert!(!ok, "export over the store (force {force})");
        assert!(err.contains("the store"), "{err}");
    }
    let dotted = format!("{}/./spinbench.db", data.display());
    let (ok, _, err) = spinbench(&["export", &id, "--out", &dotted, "--db", db_text, "--force"]);
    assert!(!ok && err.contains("the store"), "{err}");
    assert_eq!(
        std::fs::read(&db).expect("store"),
        before,
        "the store is intact"
    );
    let journal = run_dir.join("journal.jsonl");
    let (ok, _, err) = spinbench(&[
        "export",
        &id,
        "--out",
        journal.to_str().expect("utf8"),
        "--db",
        db_text,
        "--force",
    ]);
    assert!(!ok && err.contains("inside a run directory"), "{err}");
    let out = data.join("points.csv");
    std::fs::write(&out, "keep me").expect("write");
    let out_text = out.to_str().expect("utf8");
    let (ok, _, err) = spinbench(&["export", &id, "--out", out_text, "--db", db_text]);
    assert!(!ok && err.contains("--force"), "{err}");
    assert_eq!(std::fs::read_to_string(&out).expect("kept"), "keep me");
    let (ok, _, err) = spinbench(&["export", &id, "--out", out_text, "--db", db_text, "--force"]);
    assert!(ok, "{err}");
    assert!(
        std::fs::read_to_string(&out)
            .expect("csv")
            .starts_with("unit,")
    );
}

#[test]
fn csv_files_neutralise_formulas_and_analyze_reads_the_serials_back() {
    let (data, run_dir, _) = the_run();
    let db = data.join("spinbench.db");
    let db_text = db.to_str().expect("utf8");
    let id = run_id(run_dir);
    let (ok, csv, err) = spinbench(&["export", &id, "--db", db_text]);
    assert!(ok, "{err}");
    for line in csv.lines().skip(1) {
        let first = line.trim_start_matches('"');
        assert!(
            !first.starts_with(['=', '+', '-', '@']),
            "a cell that a spreadsheet runs as a formula: {line}"
        );
    }
    assert!(csv.contains("'=HYPERLINK"), "{csv}");
    let reports = data.join("reports");
    let (ok, _, err) = spinbench(&[
        "report",
        &id,
        "--format",
        "csv",
        "--out",
        reports.to_str().expect("utf8"),
        "--db",
        db_text,
    ]);
    assert!(ok, "{err}");
    for entry in std::fs::read_dir(&reports).expect("reports").flatten() {
        let text = std::fs::read_to_string(entry.path()).expect("csv");
        for line in text.lines() {
            for cell in line.split(',') {
                let cell = cell.trim_start_matches('"');
                assert!(!cell.starts_with(['=', '@', '+']), "{line}");
            }
        }
    }
    // The exported points read back under their own serial numbers.
    let file = data.join("exported.csv");
    std::fs::write(&file, &csv).expect("write");
    let (ok, json, err) = spinbench(&["analyze", "--json", file.to_str().expect("utf8")]);
    assert!(ok, "{err}");
    let doc: serde_json::Value = serde_json::from_str(&json).expect("json");
    let mut units: Vec<String> = doc["units"]
        .as_array()
        .expect("units")
        .iter()
        .filter_map(|u| u["unit"].as_str().map(str::to_string))
        .collect();
    units.sort();
    let mut want: Vec<String> = FORMULA_SERIALS.iter().map(|s| s.to_string()).collect();
    want.sort();
    assert_eq!(units, want);
}

#[test]
fn read_only_commands_never_write_to_the_store() {
    let (data, run_dir, _) = the_run();
    let work = tempfile::tempdir().expect("tempdir");
    let copy = work.path().join("archive.db");
    // A copy in rollback-journal mode, as a store archived (or on a
    // read-only medium) is: opening it for writing would switch it to WAL.
    let conn = rusqlite::Connection::open(data.join("spinbench.db")).expect("open");
    conn.execute("VACUUM INTO ?1", [copy.to_str().expect("utf8")])
        .expect("copy");
    drop(conn);
    let conn = rusqlite::Connection::open(&copy).expect("open copy");
    let mode: String = conn
        .query_row("PRAGMA journal_mode = DELETE", [], |r| r.get(0))
        .expect("mode");
    assert_eq!(mode, "delete");
    drop(conn);
    let before = std::fs::read(&copy).expect("bytes");
    let db = copy.to_str().expect("utf8");
    let id = run_id(run_dir);
    for args in [
        vec!["runs", "list", "--db", db],
        vec!["runs", "show", &id, "--db", db],
        vec!["export", &id, "--db", db],
        vec!["unit", FORMULA_SERIALS[2], "--db", db],
    ] {
        let (ok, _, err) = spinbench(&args);
        assert!(ok, "{args:?}: {err}");
    }
    assert_eq!(
        std::fs::read(&copy).expect("bytes"),
        before,
        "the store was written"
    );
    assert!(!work.path().join("archive.db-wal").exists());
    // A file that is not a store is named in the error.
    let bogus = work.path().join("not-a-store.db");
    std::fs::write(&bogus, "hello").expect("write");
    let (ok, _, err) = spinbench(&["runs", "list", "--db", bogus.to_str().expect("utf8")]);
    assert!(!ok && err.contains("not-a-store.db"), "{err}");
}

#[test]
fn a_refused_plan_leaves_no_run_directory() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, "range_g = 500\n[serials]\n1 = \"A\"\n").expect("plan");
    let data = dir.path().join("data");
    let (ok, _, err) = spinbench(&[
        "run",
        "--simulate",
        "--data",
        data.to_str().expect("utf8"),
        plan.to_str().expect("utf8"),
    ]);
    assert!(!ok);
    assert!(err.contains("range_g"), "{err}");
    let runs = std::fs::read_dir(data.join("runs")).map_or(0, |d| d.count());
    assert_eq!(runs, 0, "an orphan run directory was left");
}

#[test]
fn sim_refuses_hostile_durations_and_configs_naming_the_key() {
    let (ok, _, err) = spinbench(&["sim", "--for", "1e20"]);
    assert!(!ok && err.contains("--for"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let dir = tempfile::tempdir().expect("tempdir");
    let config = dir.path().join("bench.toml");
    for (text, key) in [
        (
            "[faults]\nmodule_silent = [99, 10]\n",
            "faults.module_silent",
        ),
        (
            "[faults]\nsupply_trip_at_s = nan\n",
            "faults.supply_trip_at_s",
        ),
        ("[instruments]\nnoise_ug = -5\n", "instruments.noise_ug"),
        ("speed = inf\n", "speed"),
    ] {
        std::fs::write(&config, text).expect("write");
        let (ok, _, err) = spinbench(&[
            "sim",
            "--for",
            "0",
            "--config",
            config.to_str().expect("utf8"),
        ]);
        assert!(!ok, "{text} was accepted");
        assert!(err.contains(key), "{text}: {err}");
    }
}

#[test]
fn a_spreadsheet_declaring_the_last_cell_is_read_by_the_cells_that_exist() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("points.xlsx");
    let mut book = rust_xlsxwriter::Workbook::new();
    let sheet = book.add_worksheet();
    for (c, h) in ["unit", "mount", "g_nominal", "g_applied", "output"]
        .iter()
        .enumerate()
    {
        sheet.write_string(0, c as u16, *h).expect("header");
    }
    for (i, g) in [0.0, 1.0, 2.0, 4.0, 6.0, 8.0, 10.0].iter().enumerate() {
        let row = i as u32 + 1;
        sheet.write_string(row, 0, "SN1").expect("unit");
        sheet.write_string(row, 1, "P").expect("mount");
        sheet.write_number(row, 2, *g).expect("g");
        sheet
            .write_number(row, 4, 30.0 + 100.0 * g + 0.001 * g * g)
            .expect("out");
    }
    // A last point on the sheet's very last row, with a note in its very
    // last column: the declared range becomes 17 billion cells.
    let last = 1_048_575;
    sheet.write_string(last, 0, "SN1").expect("unit");
    sheet.write_string(last, 1, "P").expect("mount");
    sheet.write_number(last, 2, 12.0).expect("g");
    sheet
        .write_number(last, 4, 30.0 + 1200.0 + 0.144)
        .expect("out");
    sheet
        .write_string(last, 16_383, "note")
        .expect("XFD1048576");
    book.save(&path).expect("save");
    assert!(std::fs::metadata(&path).expect("size").len() < 20_000);
    let (ok, out, err) = spinbench(&["analyze", path.to_str().expect("utf8")]);
    assert!(ok, "{err}");
    assert!(out.contains("SN1"), "{out}");
}

#[test]
fn a_huge_serial_is_refused_with_a_short_message_and_many_columns_parse_quickly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("big.csv");
    let name = "A".repeat(5_000_000);
    std::fs::write(
        &path,
        format!("unit,mount,g_nominal,g_applied,output\n{name},P,0,,1\n"),
    )
    .expect("write");
    let (ok, _, err) = spinbench(&["analyze", path.to_str().expect("utf8")]);
    assert!(!ok);
    assert!(err.len() < 2_000, "the error echoes {} bytes", err.len());
    assert!(
        err.contains("serial number of 5000000 characters"),
        "{}",
        &err[..err.len().min(500)]
    );
    // 200 000 columns in the header: found in one pass, not one search per column.
    let mut header: Vec<String> = (0..200_000).map(|i| format!("extra{i}")).collect();
    header.extend(["unit", "mount", "g_nominal", "g_applied", "output"].map(String::from));
    let mut text = header.join(",");
    text.push('\n');
    for g in [0, 1, 2, 4, 6, 8, 10] {
        let row: Vec<String> = (0..200_000).map(|_| String::new()).collect();
        text.push_str(&row.join(","));
        text.push_str(&format!(",SN1,P,{g},,{}\n", 30 + 100 * g));
    }
    let wide = dir.path().join("wide.csv");
    std::fs::write(&wide, text).expect("write");
    let started = std::time::Instant::now();
    let (ok, out, err) = spinbench(&["analyze", wide.to_str().expect("utf8")]);
    assert!(ok, "{err}");
    assert!(out.contains("SN1"));
    // A guard against a hang, not a speed target: quadratic header
    // parsing took many minutes here.
    assert!(started.elapsed().as_secs() < 120);
}

#[test]
fn a_serial_that_looks_like_an_earlier_runs_is_refused_before_anything_moves() {
    let (data, _, _) = the_run();
    let runs_before = std::fs::read_dir(data.join("runs")).expect("runs").count();
    // A case typed differently, and a Cyrillic "с" for a Latin "c".
    for serial in ["@sum(1+1)", "+\u{0441}md|' /C calc'!A0"] {
        let dir = tempfile::tempdir().expect("tempdir");
        let plan = dir.path().join("plan.toml");
        let text = PLAN
            .lines()
            .filter(|l| !l.starts_with("1 =") && !l.starts_with("2 =") && !l.starts_with("7 ="))
            .collect::<Vec<_>>()
            .join("\n");
        std::fs::write(&plan, format!("{text}\n3 = {serial:?}\n")).expect("plan");
        let (ok, _, err) = spinbench(&[
            "run",
            "--simulate",
            "--quiet",
            "--data",
            data.to_str().expect("utf8"),
            plan.to_str().expect("utf8"),
        ]);
        assert!(
            !ok && err.contains("looks like the instrument") && err.contains("earlier run"),
            "{serial}: {err}"
        );
    }
    assert_eq!(
        std::fs::read_dir(data.join("runs")).expect("runs").count(),
        runs_before,
        "a run was started"
    );
}
