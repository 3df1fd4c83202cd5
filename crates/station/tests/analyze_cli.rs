//! `spinbench analyze` end to end: golden output, the JSON document's public
//! shape, spreadsheets, and errors for bad input (through the real binary).

use serde_json::Value;
use spinbench_station::cli::analyze_file;
use spinbench_station::render::render_dataset;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo_file(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn spinbench(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(args)
        .output()
        .expect("run spinbench");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn golden_human_output_of_the_shipped_example() {
    let analysis = analyze_file(&repo_file("examples/points.csv"), 3, None).expect("analysis");
    insta::assert_snapshot!(
        "example_human",
        render_dataset("examples/points.csv", &analysis)
    );
}

#[test]
fn golden_json_output_of_a_small_file() {
    let analysis = analyze_file(&fixture("small.csv"), 3, None).expect("analysis");
    insta::assert_json_snapshot!("small_json", analysis);
}

#[test]
fn json_has_the_documented_public_shape() {
    let path = fixture("small.csv");
    let (code, stdout, stderr) =
        spinbench(&["analyze", path.to_str().expect("utf8 path"), "--json"]);
    assert_eq!(code, 0, "{stderr}");
    let doc: Value = serde_json::from_str(&stdout).expect("one JSON document");
    let units = doc["units"].as_array().expect("units array");
    assert_eq!(units.len(), 2);
    let a1 = &units[0];
    assert_eq!(a1["unit"], "A1");
    for mount in ["P", "N"] {
        let fit = &a1["fits"][mount];
        for key in [
            "k0_g",
            "k1",
            "k2_ug_per_g2",
            "k3_ug_per_g3",
            "residual_rms",
            "points",
        ] {
            assert!(fit[key].is_number(), "fits.{mount}.{key} missing: {fit}");
        }
        for key in ["k0_g", "k1", "k2_ug_per_g2", "k3_ug_per_g3"] {
            let ci = fit["ci95"][key].as_array().expect("ci95 interval");
            assert_eq!(ci.len(), 2);
            let value = fit[key].as_f64().expect("value");
            let (lo, hi) = (ci[0].as_f64().expect("lo"), ci[1].as_f64().expect("hi"));
            assert!(lo < value && value < hi, "{key}: {lo} < {value} < {hi}");
        }
        assert_eq!(fit["points"], 11);
    }
    // In mounting N the scale factor comes out negative (method.md §3.4).
    assert!(a1["fits"]["P"]["k1"].as_f64().expect("k1") > 0.0);
    assert!(a1["fits"]["N"]["k1"].as_f64().expect("k1") < 0.0);
    let k2p = a1["fits"]["P"]["k2_ug_per_g2"].as_f64().expect("k2").abs();
    let k2n = a1["fits"]["N"]["k2_ug_per_g2"].as_f64().expect("k2").abs();
    assert_eq!(
        a1["k2_max_ug_per_g2"].as_f64().expect("k2_max"),
        k2p.max(k2n)
    );
    for key in ["full_range", "scale_factor", "figures"] {
        assert!(a1[key].is_object(), "{key} missing");
    }
    // A unit with one mounting has only that key under fits.
    let b2 = &units[1];
    let keys: Vec<&String> = b2["fits"].as_object().expect("fits").keys().collect();
    assert_eq!(keys, vec!["P"]);
    assert!(b2["figures"]["asymmetry_ppm"].is_null());
}

#[test]
fn the_reduction_finds_the_example_truth() {
    // examples/README.md lists the truth the example was generated from.
    let analysis = analyze_file(&repo_file("examples/points.csv"), 3, None).expect("analysis");
    let truth = [("SN2601", 12.0), ("SN2602", 6.5), ("SN2603", 24.0)];
    for (serial, k2) in truth {
        for unit in analysis.units.iter().filter(|u| u.unit == serial) {
            for fit in unit.fits.values() {
                let [lo, hi] = fit.fit.ci95.k2_ug_per_g2.expect("ci");
                let (lo, hi) = (lo.abs().min(hi.abs()), lo.abs().max(hi.abs()));
                // 2 µg noise: well inside ±0.1 µg/g², and the interval is a few hundredths wide.
                assert!(hi - lo < 0.05, "{serial} {}: [{lo}, {hi}]", fit.mount);
                assert!((fit.fit.k2_ug_per_g2.expect("k2").abs() - k2).abs() < 0.1);
            }
        }
    }
}

#[test]
fn spreadsheet_input_gives_the_same_reduction_as_csv() {
    let csv_path = fixture("small.csv");
    let from_csv = analyze_file(&csv_path, 3, None).expect("csv");

    let text = std::fs::read_to_string(&csv_path).expect("fixture");
    let dir = tempfile::tempdir().expect("tempdir");
    let xlsx = dir.path().join("points.xlsx");
    let mut book = rust_xlsxwriter::Workbook::new();
    let sheet = book.add_worksheet();
    sheet.set_name("points").expect("name");
    for (r, line) in text.lines().enumerate() {
        for (c, field) in line.split(',').enumerate() {
            let (r, c) = (r as u32, c as u16);
            // Numbers as numbers, as a spreadsheet user would have them.
            match field.parse::<f64>() {
                Ok(v) if r > 0 => sheet.write_number(r, c, v).map(|_| ()),
                _ => sheet.write_string(r, c, field).map(|_| ()),
            }
            .expect("write cell");
        }
    }
    book.save(&xlsx).expect("save xlsx");
    let from_xlsx = analyze_file(&xlsx, 3, None).expect("xlsx");
    assert_eq!(
        serde_json::to_value(&from_csv).expect("json"),
        serde_json::to_value(&from_xlsx).expect("json")
    );

    // A bad cell is named the way the spreadsheet names it.
    let bad = dir.path().join("bad.xlsx");
    let mut book = rust_xlsxwriter::Workbook::new();
    let sheet = book.add_worksheet();
    for (c, h) in ["unit", "mount", "g_nominal", "g_applied", "output"]
        .iter()
        .enumerate()
    {
        sheet.write_string(0, c as u16, *h).expect("header");
    }
    sheet.write_string(1, 0, "SN1").expect("cell");
    sheet.write_string(1, 1, "P").expect("cell");
    sheet.write_number(1, 2, 0.0).expect("cell");
    sheet.write_string(1, 4, "twelve").expect("cell");
    book.save(&bad).expect("save");
    let err = analyze_file(&bad, 3, None)
        .expect_err("text in output")
        .to_string();
    assert!(
        err.contains("sheet 'Sheet1', cell E2 (output): expected a number, found 'twelve'"),
        "{err}"
    );
    let err = analyze_file(&bad, 3, Some("nope"))
        .expect_err("no such sheet")
        .to_string();
    assert!(
        err.contains("no sheet named 'nope'; the sheets are: Sheet1"),
        "{err}"
    );
}

#[test]
fn bad_input_exits_non_zero_with_file_line_and_column() {
    let dir = tempfile::tempdir().expect("tempdir");
    let head = "unit,mount,g_nominal,g_applied,output\n";
    let three_levels = format!("{head}A,P,0,,1\nA,P,5,,501\nA,P,10,,1001\nA,P,5,,501.0001\n");
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "empty.csv",
            String::new(),
            "empty.csv: the file has no rows",
        ),
        (
            "nohead.csv",
            "A,P,0,,1\n".into(),
            "nohead.csv:1: expected a header row",
        ),
        (
            "nocol.csv",
            "unit,mount,g_nominal,g_applied\nA,P,0,\n".into(),
            "missing column(s) output",
        ),
        (
            "dup.csv",
            "unit,mount,g_nominal,g_applied,output,mount\n".into(),
            "dup.csv:1: column 6 (mount): duplicate header",
        ),
        (
            "mount.csv",
            format!("{head}A,Q,0,,1\n"),
            "mount.csv:2: column 2 (mount): expected P",
        ),
        (
            "num.csv",
            format!("{head}A,P,0,,1\nA,P,1,x1,2\n"),
            "num.csv:3: column 4 (g_applied): expected a number, found 'x1'",
        ),
        (
            "nan.csv",
            format!("{head}A,P,0,,NaN\n"),
            "nan.csv:2: column 5 (output): expected a finite number",
        ),
        (
            "few.csv",
            three_levels,
            "few.csv: 1 of 1 unit(s) could not be reduced (the others are above):\n  A: unit 'A' mounting P has 3 distinct level(s); an order-3 fit needs at least 4",
        ),
    ];
    for (name, text, want) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, text).expect("write");
        let (code, stdout, stderr) = spinbench(&["analyze", path.to_str().expect("utf8")]);
        assert_eq!(code, 1, "{name}: {stderr}");
        // A file that cannot be read prints nothing; one whose unit cannot be
        // reduced prints what it could (here: that unit, not reduced).
        if name == "few.csv" {
            assert!(
                stdout.contains("A — NOT REDUCED"),
                "{name}: printed {stdout}"
            );
        } else {
            assert!(stdout.is_empty(), "{name}: printed {stdout}");
        }
        assert!(stderr.starts_with("error: "), "{name}: {stderr}");
        assert!(
            stderr.contains(want),
            "{name}:\n  got: {stderr}\n want: {want}"
        );
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
    }
    // The same too-few-levels file is fine at order 2.
    let (code, _, stderr) = spinbench(&[
        "analyze",
        dir.path().join("few.csv").to_str().expect("utf8"),
        "--order",
        "2",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let (code, _, stderr) = spinbench(&["analyze", "/no/such/file.csv"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("/no/such/file.csv: cannot read the file"),
        "{stderr}"
    );
    let (code, _, _) = spinbench(&["analyze", "x.csv", "--order", "4"]);
    assert_eq!(code, 2, "clap refuses order 4 as a usage error");
}

#[test]
fn a_unit_that_cannot_be_reduced_is_named_and_the_others_are_reduced() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("batch.csv");
    let mut text = std::fs::read_to_string(repo_file("examples/points.csv")).expect("example");
    // A unit with one level only: no order-3 fit.
    text.push_str("LONELY,P,5,5,501\n");
    std::fs::write(&path, text).expect("write");
    let file = path.to_str().expect("utf-8");
    let (code, stdout, stderr) = spinbench(&["analyze", "--json", file]);
    assert_eq!(code, 1, "{stderr}");
    let doc: Value = serde_json::from_str(&stdout).expect("the reduced units are printed");
    assert!(!doc["units"].as_array().expect("units").is_empty());
    assert_eq!(doc["failed"][0]["unit"], "LONELY");
    assert!(
        stderr.contains("LONELY") && stderr.contains("1 of"),
        "{stderr}"
    );
    let (code, stdout, _) = spinbench(&["analyze", file]);
    assert_eq!(code, 1);
    assert!(stdout.contains("LONELY — NOT REDUCED"), "{stdout}");
}

#[test]
fn an_excluded_level_needs_a_reason_and_is_reported_with_it() {
    let example = repo_file("examples/points.csv");
    let file = example.to_str().expect("utf-8");
    // No reason: refused, nothing reduced.
    let (code, stdout, stderr) = spinbench(&["analyze", file, "--exclude-level", "P:40"]);
    assert_eq!(code, 1);
    assert!(
        stdout.is_empty() && stderr.contains("a reason is required"),
        "{stderr}"
    );
    // A level that is not in the file: refused (a typing mistake is no exclusion).
    let (code, _, stderr) = spinbench(&[
        "analyze",
        file,
        "--exclude-level",
        "P:41",
        "--reason",
        "resonance",
    ]);
    assert_eq!(code, 1);
    assert!(stderr.contains("no reading of that level"), "{stderr}");
    // With a reason: the fits lose that level, and the output says so.
    let (code, stdout, stderr) = spinbench(&[
        "analyze",
        "--json",
        file,
        "--exclude-level",
        "P:40",
        "--reason",
        "structural resonance at 40 g",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let doc: Value = serde_json::from_str(&stdout).expect("json");
    let e = &doc["exclusions"][0];
    assert_eq!(e["mount"], "P");
    assert_eq!(e["g"], 40.0);
    assert_eq!(e["reason"], "structural resonance at 40 g");
    assert!(e["points_removed"].as_u64().is_some_and(|n| n >= 2), "{e}");
    for unit in doc["units"].as_array().expect("units") {
        let residuals = unit["fits"]["P"]["residuals"]
            .as_array()
            .expect("residuals");
        assert!(residuals.iter().all(|r| r["g_nominal"] != 40.0));
        let n = unit["fits"]["N"]["residuals"].as_array().expect("N");
        assert!(
            n.iter().any(|r| r["g_nominal"] == 40.0),
            "only P was excluded"
        );
    }
    let (_, human, _) = spinbench(&[
        "analyze",
        file,
        "--exclude-level",
        "P:40",
        "--reason",
        "structural resonance at 40 g",
    ]);
    assert!(
        human.contains("EXCLUDED by") && human.contains("structural resonance"),
        "{human}"
    );
}

#[test]
fn type_b_inputs_from_a_file_enter_every_budget_and_bad_ones_are_refused_by_key() {
    let dir = tempfile::tempdir().expect("tempdir");
    let good = dir.path().join("type_b.toml");
    std::fs::write(
        &good,
        "radius_ppm = 30\nrate_accuracy_ppm = 10\ntemperature_rise_c_at_100g = 1.5\nk1_tempco_ppm_per_c = 15\n",
    )
    .expect("write");
    let example = repo_file("examples/points.csv");
    let example = example.to_str().expect("path");
    let (code, out, err) = spinbench(&[
        "analyze",
        example,
        "--json",
        "--type-b",
        good.to_str().expect("path"),
    ]);
    assert_eq!(code, 0, "{err}");
    let doc: serde_json::Value = serde_json::from_str(&out).expect("json");
    let k2 = &doc["units"][0]["fits"]["P"]["uncertainty"]["k2_ug_per_g2"];
    let sources: Vec<&str> = k2["budget"]
        .as_array()
        .expect("budget")
        .iter()
        .filter_map(|c| c["source"].as_str())
        .collect();
    for s in [
        "repeatability",
        "radius",
        "rate_accuracy",
        "temperature_scale",
    ] {
        assert!(sources.contains(&s), "{s} in {sources:?}");
    }
    let u = k2["u"].as_f64().expect("u");
    let u95 = k2["U95"].as_f64().expect("U95");
    assert!(u > 0.0 && u95 > 1.9 * u, "{u} {u95}");
    // Without the file the budget is Type A only, and smaller.
    let (_, plain, _) = spinbench(&["analyze", example, "--json"]);
    let plain: serde_json::Value = serde_json::from_str(&plain).expect("json");
    let plain_u = plain["units"][0]["fits"]["P"]["uncertainty"]["k2_ug_per_g2"]["u"]
        .as_f64()
        .expect("u");
    assert!(plain_u < u, "{plain_u} vs {u}");

    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "timebase_ppm = -2\n").expect("write");
    let (code, _, err) = spinbench(&["analyze", example, "--type-b", bad.to_str().expect("path")]);
    assert_ne!(code, 0);
    assert!(err.contains("timebase_ppm"), "{err}");
    std::fs::write(&bad, "radius = 3\n").expect("write");
    let (code, _, err) = spinbench(&["analyze", example, "--type-b", bad.to_str().expect("path")]);
    assert_ne!(code, 0);
    assert!(err.contains("radius"), "{err}");
}

/// The published station's Tables 1–2 (method.md §5), the only real data.
fn published_tables() -> PathBuf {
    repo_file("../shared/data/published-tables-1-2.csv")
}

fn reduce_published(anomalies: &str, exclude: &[&str]) -> Value {
    let path = published_tables();
    let mut args = vec![
        "analyze",
        path.to_str().expect("utf8 path"),
        "--json",
        "--anomalies",
        anomalies,
    ];
    for e in exclude {
        args.extend(["--exclude-level", e]);
    }
    if !exclude.is_empty() {
        args.extend(["--reason", "an alternative reduction", "--by", "test"]);
    }
    let (code, stdout, stderr) = spinbench(&args);
    assert_eq!(code, 0, "{stderr}");
    serde_json::from_str(&stdout).expect("one JSON document")
}

fn joint(doc: &Value) -> (f64, f64) {
    let j = &doc["units"][0]["joint"];
    (
        j["k2_even_ug_per_g2"].as_f64().expect("K2"),
        j["k2_even_U95"].as_f64().expect("U95"),
    )
}

#[test]
fn the_published_tables_flag_their_anomalies_and_every_defensible_reduction_agrees_within_u() {
    let all = reduce_published("flag", &[]);
    let flagged = |mount: &str| -> Vec<f64> {
        all["units"][0]["fits"][mount]["diagnostics"]["outlier_levels"]
            .as_array()
            .expect("outliers")
            .iter()
            .map(|o| o["g"].as_f64().expect("g"))
            .collect()
    };
    // P's dip at 30 g, N's at 65 and/or 70 g, at most one more level each
    // (the repeated search flagged 6 and 4).
    let (p, n) = (flagged("P"), flagged("N"));
    assert!(p.contains(&30.0) && p.len() <= 2, "P flagged {p:?}");
    assert!(
        (n.contains(&65.0) || n.contains(&70.0)) && n.len() <= 3,
        "N flagged {n:?}"
    );
    // The model does not fit: the budget carries the misfit, so the K2
    // interval is no longer ten times narrower than one level's effect.
    let source = |mount: &str| {
        all["units"][0]["fits"][mount]["uncertainty"]["k2_ug_per_g2"]["budget"]
            .as_array()
            .expect("budget")
            .iter()
            .map(|c| c["source"].as_str().unwrap_or("").to_string())
            .collect::<Vec<_>>()
    };
    assert!(source("P").contains(&"model_inadequacy".to_string()));
    // The defensible reductions: all levels (flag), the anomaly rule, and
    // the levels left out by hand; each pair agrees within its U95s (E_n ≤ 1).
    let reductions = [
        ("all levels", joint(&all)),
        ("anomaly rule", joint(&reduce_published("exclude", &[]))),
        (
            "without P 30 g",
            joint(&reduce_published("flag", &["P:30"])),
        ),
        (
            "without P 30, N 65, N 70 g",
            joint(&reduce_published("flag", &["P:30", "N:65", "N:70"])),
        ),
    ];
    for (a, (ka, ua)) in &reductions {
        for (b, (kb, ub)) in &reductions {
            let en = (ka - kb).abs() / ua.hypot(*ub);
            assert!(
                en <= 1.0,
                "{a} {ka:.3} ± {ua:.3} vs {b} {kb:.3} ± {ub:.3}: E_n {en:.2}"
            );
        }
    }
    // The anomaly rule left its levels out by name, with the rule and why.
    let excluded = reduce_published("exclude", &[]);
    let rule = excluded["units"][0]["rule_exclusions"]
        .as_array()
        .expect("rule exclusions");
    assert!(
        rule.iter().any(|e| e["mount"] == "P" && e["g"] == 30.0),
        "{rule:?}"
    );
    assert!(
        rule.iter()
            .all(|e| e["by"].as_str().unwrap_or("").contains("anomaly rule"))
    );
    let budget = excluded["units"][0]["joint"]["uncertainty"]["k2_even_ug_per_g2"]["budget"]
        .as_array()
        .expect("K2 budget");
    assert!(
        budget.iter().any(|c| c["source"] == "anomaly_rule"),
        "{budget:?}"
    );
    // The rule leaves out once; what the refit finds next (P 35 g, N 60 g:
    // the dips' wings) is shown as such, and kept.
    let notes: Vec<&str> = excluded["units"][0]["notes"]
        .as_array()
        .expect("notes")
        .iter()
        .filter_map(Value::as_str)
        .collect();
    assert!(
        notes
            .iter()
            .any(|n| n.contains("mounting P") && n.contains("refit finds 35 g")),
        "{notes:?}"
    );
    assert!(
        !rule.iter().any(|e| e["g"] == 35.0),
        "the refit's candidate was left out: {rule:?}"
    );
}

#[test]
fn one_interval_per_coefficient_in_the_human_output() {
    let path = published_tables();
    let (code, stdout, stderr) = spinbench(&["analyze", path.to_str().expect("utf8")]);
    assert_eq!(code, 0, "{stderr}");
    let doc = reduce_published("flag", &[]);
    let u95 = doc["units"][0]["fits"]["P"]["uncertainty"]["k2_ug_per_g2"]["U95"]
        .as_f64()
        .expect("U95");
    let row = stdout
        .lines()
        .find(|l| l.trim_start().starts_with("k2 [µg/g²]"))
        .expect("k2 row");
    // The table's ± is the budget's U95, not the regression interval.
    assert!(
        row.contains(&format!("± {u95:.3}")),
        "{row} vs U95 {u95:.3}"
    );
    let ci = doc["units"][0]["fits"]["P"]["ci95"]["k2_ug_per_g2"]
        .as_array()
        .expect("ci95 stays in the JSON");
    let half = (ci[1].as_f64().unwrap_or(0.0) - ci[0].as_f64().unwrap_or(0.0)) / 2.0;
    assert!(!row.contains(&format!("± {half:.3}")), "{row}");
}

#[test]
fn a_bad_number_refuses_its_unit_only_and_names_the_row() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("two.csv");
    let mut text = String::from("unit,mount,g_nominal,g_applied,output\n");
    for unit in ["GOOD", "BAD"] {
        for (i, g) in [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0]
            .iter()
            .enumerate()
        {
            let out = if unit == "BAD" && i == 3 {
                "NaN".to_string()
            } else {
                format!("{}", 100.0 * g + 1e-4 * g * g)
            };
            text.push_str(&format!("{unit},P,{g},{g},{out}\n"));
        }
    }
    std::fs::write(&path, text).expect("write");
    let (code, stdout, stderr) = spinbench(&["analyze", path.to_str().expect("utf8"), "--json"]);
    // The good unit is reduced; the bad one is named with its line; exit 1.
    assert_eq!(code, 1, "{stderr}");
    let doc: Value = serde_json::from_str(&stdout).expect("JSON");
    assert_eq!(doc["units"][0]["unit"], "GOOD");
    let failed = &doc["failed"][0];
    assert_eq!(failed["unit"], "BAD");
    let error = failed["error"].as_str().expect("error");
    assert!(
        error.contains("two.csv:13") && error.contains("finite"),
        "{error}"
    );
}

#[test]
fn a_row_written_twice_is_dropped_not_counted_as_a_replicate() {
    let dir = tempfile::tempdir().expect("tempdir");
    let clean = dir.path().join("clean.csv");
    let doubled = dir.path().join("doubled.csv");
    let mut a = String::from("unit,mount,g_nominal,g_applied,output\n");
    let mut b = a.clone();
    let levels = [0.0, 5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0];
    let pass: Vec<f64> = levels
        .iter()
        .chain(levels.iter().rev().skip(1))
        .copied()
        .collect();
    for (i, g) in pass.iter().enumerate() {
        let row = format!(
            "U,P,{g},{g},{:.6}\n",
            100.0 * g + 1e-3 * g * g + 1e-4 * (i as f64).sin()
        );
        a.push_str(&row);
        b.push_str(&row);
        if i % 2 == 0 {
            b.push_str(&row);
        }
    }
    std::fs::write(&clean, a).expect("write");
    std::fs::write(&doubled, b).expect("write");
    let dof = |path: &Path| {
        let (code, stdout, stderr) =
            spinbench(&["analyze", path.to_str().expect("utf8"), "--json"]);
        assert_eq!(code, 0, "{stderr}");
        let doc: Value = serde_json::from_str(&stdout).expect("JSON");
        (
            doc["units"][0]["fits"]["P"]["diagnostics"]["lack_of_fit"]["dof"][1].clone(),
            stderr,
        )
    };
    let (clean_dof, _) = dof(&clean);
    let (doubled_dof, warnings) = dof(&doubled);
    assert_eq!(clean_dof, doubled_dof, "pure-error dof changed: {warnings}");
    assert!(warnings.contains("written twice; dropped"), "{warnings}");
}

#[test]
fn an_exclusion_from_the_command_line_names_who_made_it() {
    let path = published_tables();
    let doc = reduce_published("flag", &["P:30"]);
    assert_eq!(doc["exclusions"][0]["by"], "test");
    // Without --by: the operating-system user, never "unknown".
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args([
            "analyze",
            path.to_str().expect("utf8"),
            "--json",
            "--exclude-level",
            "P:30",
            "--reason",
            "dip",
        ])
        .env_remove("USER")
        .env_remove("LOGNAME")
        .output()
        .expect("run");
    let doc: Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let by = doc["exclusions"][0]["by"].as_str().expect("by");
    assert!(!by.is_empty() && by != "unknown", "{by}");
}
