//! `spinbench retest RUN`: a finished run's failed (on purpose)
//! instruments tested again, same serials, slots and plan, linked both ways
//! in the store and in both runs' reports; what cannot be retested is
//! refused with what to do.

mod common;

use spinbench_store::{Store, StoreTarget};
use std::process::Command;

use common::spinbench;

/// Run the short plan of R1, R2, R7 on seed 4's bench, warmed up, with a
/// k2 limit of `limit_ug_per_g2`, into `dir`/data: whether it exited 0,
/// its stderr and the data directory.
fn run_short_plan(
    dir: &std::path::Path,
    limit_ug_per_g2: u32,
) -> (bool, String, std::path::PathBuf, String) {
    let plan = dir.join("plan.toml");
    let text = format!(
        "{}[limits]\nk2_max_ug_per_g2 = {limit_ug_per_g2}\n",
        common::short_plan("R").replace("warmup_s = 0", "warmup_s = 600")
    );
    std::fs::write(&plan, text).expect("plan");
    let data = dir.join("data");
    let (ok, out, err) = spinbench(&[
        "run",
        "--simulate",
        "--quiet",
        "--seed",
        "4",
        "--data",
        data.to_str().expect("utf-8"),
        plan.to_str().expect("utf-8"),
    ]);
    (ok, err, data, out)
}

#[test]
fn a_runs_failed_instruments_are_tested_again_and_the_runs_are_linked() {
    let dir = tempfile::tempdir().expect("tempdir");
    // On seed 4's bench: R1 and R7 have |k2| ≈ 28 µg/g², R2 ≈ 20 — a 25 µg/g²
    // limit fails two and passes one. Warmed up first: without it the
    // warm-up drift is in the up/down pure error (no drift term)
    // and R2's U95 straddles the limit.
    let (ok, err, data, table) = run_short_plan(dir.path(), 25);
    let data_s = data.to_str().expect("utf-8");
    assert!(ok, "{err}");
    // The end-of-run table says, beside each outcome, what was judged
    // against which limit.
    let rows: Vec<&str> = table
        .lines()
        .filter(|l| l.starts_with('R') && l[1..].starts_with(|c: char| c.is_ascii_digit()))
        .collect();
    assert!(!rows.is_empty(), "{table}");
    for row in rows {
        assert!(
            row.contains("K2 ") && row.contains("(limit 25, guarded)"),
            "{row}\n{table}"
        );
    }
    let target = StoreTarget::File(data.join("spinbench.db"));
    let first = {
        let store = Store::connect(&target).expect("store");
        let runs = store.runs().expect("runs");
        assert_eq!(runs.len(), 1);
        let outcomes: Vec<(String, String)> = store
            .results(&runs[0].id)
            .expect("results")
            .into_iter()
            .map(|r| (r.serial, r.outcome.as_str().to_string()))
            .collect();
        assert_eq!(
            outcomes,
            [
                ("R1".to_string(), "fail".to_string()),
                ("R2".into(), "pass".into()),
                ("R7".into(), "fail".into())
            ]
        );
        runs[0].id.clone()
    };

    // Two clear fails and a pass: nothing needs a retest, and the refusal
    // says how to retest the fails on purpose. Nothing is run.
    let retest = |choice: &[&str]| {
        let mut args = vec!["retest", first.as_str()];
        args.extend_from_slice(choice);
        args.extend(["--simulate", "--quiet", "--seed", "4", "--data", data_s]);
        spinbench(&args)
    };
    let (ok, _, err) = retest(&[]);
    assert!(
        !ok && err.contains("nothing to retest") && err.contains("--include-fails"),
        "{err}"
    );
    let stored_runs = || {
        Store::connect(&target)
            .expect("store")
            .runs()
            .expect("runs")
    };
    assert_eq!(stored_runs().len(), 1);
    let (ok, said, err) = retest(&["--include-fails"]);
    // The same instruments fail again on the same bench: the command says so
    // by its exit status, and the retest is stored all the same.
    assert!(
        said.contains("retesting 2 instrument(s) of run") && said.contains("R1, R7"),
        "{said}{err}"
    );
    // The same plan would reproduce the same intervals: the retest adds
    // levels chosen by the data, and says so.
    assert!(
        said.contains("measured until the verdict is certain: up to 12 level(s)"),
        "{said}"
    );
    let _ = ok;
    let store = Store::connect(&target).expect("store");
    let runs = store.runs().expect("runs");
    assert_eq!(runs.len(), 2);
    let retest = runs.iter().find(|r| r.id != first).expect("the retest run");
    assert_eq!(retest.retest_of.as_deref(), Some(first.as_str()));
    assert_eq!(
        store.retests_of(&first).expect("links"),
        vec![retest.id.clone()]
    );
    let again: Vec<(i64, String)> = store
        .results(&retest.id)
        .expect("results")
        .into_iter()
        .map(|r| (r.slot, r.serial))
        .collect();
    // Same serials in the same slots (1 and 7, 0-based 0 and 6).
    assert_eq!(again, [(0, "R1".to_string()), (6, "R7".to_string())]);
    let plan: spinbench_engine::TestPlan = store
        .run_start(&retest.id)
        .expect("start")
        .expect("the retest")
        .plan
        .plan
        .expect("plan");
    assert_eq!(plan.retest_of.as_deref(), Some(first.as_str()));
    assert_eq!(plan.limits.k2_max_ug_per_g2, 25.0);

    // Both reports name the other run.
    let html = |id: &str| {
        let out = dir.path().join("reports");
        let (ok, _, err) = spinbench(&[
            "report",
            id,
            "--db",
            data.join("spinbench.db").to_str().expect("utf-8"),
            "--format",
            "html",
            "--out",
            out.to_str().expect("utf-8"),
        ]);
        assert!(ok, "{err}");
        std::fs::read_to_string(common::report_file(&out, id, "html")).expect("html")
    };
    let original = html(&first);
    assert!(original.contains("retested by") && original.contains(&retest.id));
    let second = html(&retest.id);
    assert!(second.contains("retest of") && second.contains(&first));
    // The same report in Chinese (HTML, and the PDF read back by poppler).
    let zh = dir.path().join("zh");
    let (ok, _, err) = spinbench(&[
        "report",
        &retest.id,
        "--db",
        data.join("spinbench.db").to_str().expect("utf-8"),
        "--format",
        "html,pdf",
        "--lang",
        "zh-CN",
        "--out",
        zh.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{err}");
    let zh_html =
        std::fs::read_to_string(common::report_file(&zh, &retest.id, "html")).expect("html");
    assert!(zh_html.contains("复测自") && zh_html.contains("汇总") && zh_html.contains("不合格"));
    // The reasons and the lines under the figures are worded in Chinese
    // from the records' codes and values, not copied in English.
    assert!(zh_html.contains("超过限值 25 µg/g²"), "{zh_html}");
    assert!(!zh_html.contains("above the limit"), "{zh_html}");
    assert!(zh_html.contains("两种安装方式联合") && zh_html.contains("失拟检验"));
    assert!(!zh_html.contains("both mountings (method.md") && !zh_html.contains("lack of fit"));
    assert!(html(&retest.id).contains("above the limit 25 µg/g²"));
    let pdf_text = Command::new("pdftotext")
        .arg(common::report_file(&zh, &retest.id, "pdf"))
        .arg("-")
        .output()
        .expect("pdftotext (poppler-utils) runs; ./scripts/test installs it");
    let pdf_text = String::from_utf8_lossy(&pdf_text.stdout);
    // The Chinese PDF cuts nothing either.
    assert!(!pdf_text.contains('…'), "{pdf_text}");
    assert!(
        pdf_text.contains("离心机测试报告")
            && pdf_text.contains("汇总")
            && pdf_text.contains("超过限值"),
        "{pdf_text}"
    );
    let (ok, _, err) = spinbench(&["report", &first, "--lang", "de", "--db", "x.db"]);
    assert!(!ok && err.contains("en or zh-CN"), "{err}");

    // What cannot be retested is refused with what to do.
    let (ok, _, err) = spinbench(&["retest", "no-such-run", "--simulate", "--data", data_s]);
    assert!(!ok && err.contains("no run no-such-run"), "{err}");
    let (ok, _, err) = spinbench(&["retest", "../x", "--simulate", "--data", data_s]);
    assert!(!ok && err.contains("not a run identifier"), "{err}");

    // A plan's retest_of is checked against the store. A
    // run that does not exist, and a serial the run passed (R2) or never
    // had, are refused before anything is switched on; no run is added.
    let claims = |retest_of: &str, serial: &str| {
        let text = format!("retest_of = \"{retest_of}\"\n{}", common::short_plan("R")).replace(
            "1 = \"R1\"\n2 = \"R2\"\n7 = \"R7\"\n",
            &format!("1 = \"{serial}\"\n"),
        );
        let path = dir.path().join("claim.toml");
        std::fs::write(&path, text).expect("plan");
        spinbench(&[
            "run",
            "--simulate",
            "--quiet",
            "--data",
            data_s,
            path.to_str().expect("utf-8"),
        ])
    };
    let (ok, _, err) = claims("run-that-never-was", "R1");
    assert!(!ok && err.contains("no run run-that-never-was"), "{err}");
    for serial in ["R2", "Z9"] {
        let (ok, _, err) = claims(&first, serial);
        assert!(
            !ok && err.contains(&format!(
                "{serial} is not an instrument of run {first} that needs a retest"
            )),
            "{serial}: {err}"
        );
    }
    assert_eq!(store.runs().expect("runs").len(), 2);
}

#[test]
fn an_inconclusive_instrument_is_told_what_decides_it_and_its_tries_are_counted() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Seed 4's R2 has |K2| ≈ 20 µg/g²: on a 20 µg/g² limit its interval
    // straddles it (the run's exit status says some instrument did not pass).
    let (_, err, data, _) = run_short_plan(dir.path(), 20);
    let data_s = data.to_str().expect("utf-8");
    let target = StoreTarget::File(data.join("spinbench.db"));
    let latest = || {
        let store = Store::connect(&target).expect("store");
        let runs = store.runs().expect("runs");
        let last = runs
            .iter()
            .max_by_key(|r| (r.started_at, r.id.clone()))
            .expect("a run")
            .id
            .clone();
        let r2 = store
            .results(&last)
            .expect("results")
            .into_iter()
            .find(|r| r.serial == "R2")
            .map(|r| r.outcome.as_str().to_string());
        (last, r2)
    };
    let (first, r2) = latest();
    assert_eq!(r2.as_deref(), Some("inconclusive"), "{err}");
    let retest = |run: &str| {
        let (_, said, err) = spinbench(&[
            "retest",
            run,
            "--simulate",
            "--quiet",
            "--seed",
            "4",
            "--data",
            data_s,
        ]);
        format!("{said}{err}")
    };
    // Before it runs: the value ± U95, what U95 would decide it, whether
    // the retest is predicted to get there.
    let said = retest(&first);
    let line = said
        .lines()
        .find(|l| l.trim_start().starts_with("R2"))
        .unwrap_or_else(|| panic!("no advice for R2: {said}"));
    assert!(
        line.contains("against 20: decided by a U95 under")
            && (line.contains("can decide it if its value holds")
                || line.contains("judge it by review")),
        "{line}"
    );
    assert!(!line.contains("inconclusive in"), "{line}");
    // Inconclusive again: the next retest counts the tries.
    let (second, r2) = latest();
    assert_ne!(second, first);
    if r2.as_deref() == Some("inconclusive") {
        let said = retest(&second);
        assert!(said.contains("R2 (inconclusive in 2 runs): "), "{said}");
    }
}
