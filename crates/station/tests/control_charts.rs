//! Control charts across runs end to end: 22 runs on the
//! virtual bench, one fixture position's radius drifting 5 µm a run from
//! the 12th on; the Western Electric rules flag that position's chart and
//! no other, and the batch report shows the charts and the yields.

mod common;
#[path = "common/web.rs"]
mod web;

use spinbench_store::{Store, StoreTarget};
use std::process::Command;

use common::spinbench;

/// Runs of the batch; the drift starts after `STEADY` of them.
const RUNS: usize = 22;
const STEADY: usize = 11;
/// The drift of fixture position 2's radius per run [mm].
const DRIFT_MM_PER_RUN: f64 = 0.005;

#[test]
fn a_fixture_position_coming_loose_is_flagged_and_no_other() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("plan.toml");
    let short = common::short_plan("C");
    // Slots 1 and 2 only (the plan's slot 7 is left out).
    let two_slots: String = short
        .lines()
        .filter(|l| !l.starts_with("7 ="))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&plan, two_slots).expect("plan");
    let data = dir.path().join("data");
    let data_s = data.to_str().expect("utf-8");
    for run in 1..=RUNS {
        // Every run on the same fixtures (no radius scatter between
        // benches), its own instruments and noise (its own seed); position
        // 2 moving outward once the steady runs are over.
        let shift_mm = DRIFT_MM_PER_RUN * run.saturating_sub(STEADY) as f64;
        let bench = dir.path().join(format!("bench-{run}.toml"));
        std::fs::write(
            &bench,
            format!(
                "[centrifuge]\nradius_scatter_mm = 0.0\nposition_shifts_mm = [0.0, {shift_mm}]\n"
            ),
        )
        .expect("bench");
        let seed = run.to_string();
        let (ok, _, err) = spinbench(&[
            "run",
            "--simulate",
            "--quiet",
            "--seed",
            &seed,
            "--bench",
            bench.to_str().expect("utf-8"),
            "--data",
            data_s,
            plan.to_str().expect("utf-8"),
        ]);
        // A failing instrument ends the command with an error; the run is stored.
        let _ = (ok, err);
    }
    let store = Store::connect(&StoreTarget::File(data.join("spinbench.db"))).expect("store");
    assert_eq!(store.runs().expect("runs").len(), RUNS);
    let mut batch = spinbench_report::gather_batch(&store, &[]).expect("batch");
    batch.rebaseline(10);
    let radius: Vec<&spinbench_report::control::ControlChart> = batch
        .control
        .charts
        .iter()
        .filter(|c| c.position.is_some())
        .collect();
    let names: Vec<&str> = radius.iter().map(|c| c.quantity.as_str()).collect();
    // Both mountings each run: one chart per fixture centre.
    assert_eq!(names, ["radius slot 1", "radius slot 2"]);
    let flagged: Vec<&str> = radius
        .iter()
        .filter(|c| c.flagged())
        .map(|c| c.quantity.as_str())
        .collect();
    assert_eq!(flagged, ["radius slot 2"], "{:#?}", radius[0].violations);
    let drifting = radius[1];
    let first = drifting
        .violations
        .iter()
        .map(|v| v.index)
        .min()
        .unwrap_or(0);
    assert!(
        first >= STEADY,
        "flagged only once it moved: first at run {}",
        first + 1
    );
    eprintln!(
        "radius slot 2 first flagged at run {} ({} µm moved), by {}",
        first + 1,
        (first + 1 - STEADY) as f64 * DRIFT_MM_PER_RUN * 1e3,
        drifting.violations[0].rule.describe()
    );
    // First-pass yield: the same two serials in every run, so only the
    // first run tested them for the first time.
    assert_eq!(batch.control.yield_by_run.len(), 1);
    assert_eq!(batch.control.yield_by_run[0].first_tests, 2);

    // The batch report shows them (HTML; the PDF read back by poppler).
    let out = dir.path().join("reports");
    let (ok, _, err) = spinbench(&[
        "batch-report",
        "--db",
        data.join("spinbench.db").to_str().expect("utf-8"),
        "--baseline-runs",
        "10",
        "--format",
        "html,pdf,xlsx",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{err}");
    let html = std::fs::read_to_string(common::batch_file(&out, "html")).expect("html");
    assert!(html.contains("Control charts (limits from the first 10 runs"));
    assert!(html.contains("In control: ") && html.contains("radius slot 1"));
    assert!(html.contains("id=\"control-flags\"") && html.contains("id=\"yield\""));
    let text = Command::new("pdftotext")
        .arg(common::batch_file(&out, "pdf"))
        .arg("-")
        .output()
        .expect("pdftotext (poppler-utils) runs; ./scripts/test installs it");
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains("Control charts") && text.contains("First-pass yield"),
        "{text}"
    );
    // The batch report in Chinese: HTML, PDF (read back by poppler) and XLSX
    // (read back by calamine), the rule that flagged slot 2 worded too.
    let zh = dir.path().join("zh");
    let (ok, _, err) = spinbench(&[
        "batch-report",
        "--db",
        data.join("spinbench.db").to_str().expect("utf-8"),
        "--format",
        "html,pdf,xlsx",
        "--lang",
        "zh-CN",
        "--out",
        zh.to_str().expect("utf-8"),
    ]);
    assert!(ok, "{err}");
    let html = std::fs::read_to_string(common::batch_file(&zh, "html")).expect("html");
    assert!(
        html.contains("批次报告")
            && html.contains("控制图（控制限取前 10 次运行")
            && html.contains("一次合格率")
            && html.contains("受控: ")
            && html.contains("lang=\"zh-CN\"")
            && html.contains("规则 3：连续五点中有四点在同侧超出 1σ"),
        "the batch report in Chinese"
    );
    let text = Command::new("pdftotext")
        .arg(common::batch_file(&zh, "pdf"))
        .arg("-")
        .output()
        .expect("pdftotext (poppler-utils) runs; ./scripts/test installs it");
    let text = String::from_utf8_lossy(&text.stdout);
    for words in ["批次报告", "控制图", "一次合格率", "全部测试", "规则 3"] {
        assert!(text.contains(words), "{words} in {text}");
    }
    assert!(!text.contains("Batch report") && !text.contains("Every test"));
    use calamine::{Data, Reader, open_workbook_auto};
    let mut book = open_workbook_auto(common::batch_file(&zh, "xlsx")).expect("xlsx");
    let tests = book.worksheet_range("tests").expect("the tests sheet");
    assert_eq!(tests.get((0, 2)), Some(&Data::String("序列号".into())));
    let outcomes: Vec<String> = tests.rows().skip(1).map(|r| r[3].to_string()).collect();
    assert!(
        !outcomes.is_empty()
            && outcomes
                .iter()
                .all(|o| ["合格", "临界", "不合格", "无法判定", "未完成"].contains(&o.as_str())),
        "{outcomes:?}"
    );

    // The Charts page's flags name the run by its label and the point's
    // instrument: on the web API of a server on this store.
    web::add_user(&data, "op", "operator", "op-password");
    let server = web::serve(&data, "0");
    let mut op = web::Client::login(&server, "op", "op-password");
    let charts = op.get_json("/api/control-charts?baseline_runs=10", 200);
    let flags: Vec<&serde_json::Value> = charts["charts"]
        .as_array()
        .expect("charts")
        .iter()
        .flat_map(|c| c["violations"].as_array().into_iter().flatten())
        .collect();
    assert!(!flags.is_empty(), "{charts}");
    for v in flags {
        let label = v["run_label"].as_str().unwrap_or_default();
        assert!(
            label.contains(" · #") && label != v["run_id"].as_str().unwrap_or_default(),
            "{v}"
        );
        assert!(v["serial"].is_string(), "{v}");
    }
}
