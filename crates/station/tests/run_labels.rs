//! Readable run labels: `runs list` shows each run's
//! `2026-11-24 · station · #N` beside its id; the label (as printed, or typed
//! with `/`, or without the station) names the run wherever a run is typed;
//! the report's files are named by it and the report shows it.

mod common;

use common::spinbench;

#[test]
fn runs_are_listed_named_and_reported_by_their_labels() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let db = data.join("spinbench.db");
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, common::short_plan("L")).expect("plan");
    let (data_s, db_s) = (data.to_str().expect("utf-8"), db.to_str().expect("utf-8"));
    for _ in 0..2 {
        let (ok, said, err) = spinbench(&[
            "run",
            "--simulate",
            "--quiet",
            "--data",
            data_s,
            plan.to_str().expect("utf-8"),
        ]);
        assert!(ok, "{said}{err}");
    }
    let store =
        spinbench_store::Store::open_read_only(&spinbench_store::StoreTarget::File(db.clone()))
            .expect("store");
    // Newest first: #2 then #1, both of today on one station.
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 2);
    let (second, first) = (&runs[0], &runs[1]);
    assert_eq!((first.seq, second.seq), (Some(1), Some(2)));
    let day = spinbench_store::equipment::civil_date(first.started_at);
    let label_1 = format!("{day} · {} · #1", first.station);
    assert_eq!(first.label(), label_1);

    // `runs list`: the label beside the id.
    let (ok, listed, err) = spinbench(&["runs", "list", "--db", db_s]);
    assert!(ok, "{err}");
    let line_of = |id: &str| {
        listed
            .lines()
            .find(|l| l.contains(id))
            .unwrap_or_else(|| panic!("{id} in {listed}"))
            .to_string()
    };
    assert!(line_of(&first.id).starts_with(&label_1), "{listed}");
    assert!(
        line_of(&second.id).starts_with(&format!("{day} · {} · #2", second.station)),
        "{listed}"
    );

    // The label names the run: as printed, typed with '/', or without the station.
    for typed in [
        label_1.clone(),
        format!("{day}/{}/#1", first.station),
        format!("{day} #1"),
    ] {
        let (ok, shown, err) = spinbench(&["runs", "show", &typed, "--db", db_s]);
        assert!(ok, "{typed}: {err}");
        assert!(
            shown.starts_with(&format!("run {label_1} ({})", first.id)),
            "{typed}: {shown}"
        );
    }
    let (ok, csv, err) = spinbench(&["export", &format!("{day} #2"), "--db", db_s]);
    assert!(ok, "{err}");
    assert_eq!(
        csv,
        store.points_csv(&second.id).expect("csv"),
        "the label's run exported"
    );
    // A label that names no run, and text that is neither: what to type.
    let (ok, _, err) = spinbench(&["runs", "show", &format!("{day} #9"), "--db", db_s]);
    assert!(
        !ok && err.contains("no run is labelled") && err.contains("runs list"),
        "{err}"
    );
    let (ok, _, err) = spinbench(&["report", "yesterday's run", "--db", db_s]);
    assert!(!ok && err.contains("2026-11-24 · station 1 · #7"), "{err}");

    // The report: files named by the label and the id, the label inside.
    let out = dir.path().join("reports");
    let (ok, said, err) = spinbench(&[
        "report",
        &label_1,
        "--db",
        db_s,
        "--format",
        "html,csv",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{said}{err}");
    let stem = format!(
        "report-{day}_{}_1-{}-en",
        first
            .station
            .replace(|c: char| !c.is_ascii_alphanumeric() && c != '-', "-"),
        first.id
    );
    let html = std::fs::read_to_string(out.join(format!("{stem}.html")))
        .unwrap_or_else(|e| panic!("{stem}.html: {e}; wrote {said}"));
    assert!(html.contains(&label_1), "the report shows its label");
    assert!(out.join(format!("{stem}.csv")).is_file());
    // The Chinese reports of the same run sit beside the
    // English ones (the file names carry the language).
    let (ok, said, err) = spinbench(&[
        "report",
        &label_1,
        "--db",
        db_s,
        "--format",
        "html",
        "--lang",
        "zh-CN",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{said}{err}");
    let zh_stem = stem.replace("-en", "-zh-CN");
    assert!(out.join(format!("{zh_stem}.html")).is_file(), "{said}");
    assert!(
        out.join(format!("{stem}.html")).is_file(),
        "the English report was written over"
    );
}
