//! Acceptance of `spinbench demo`: a complete simulated test, compared with
//! the simulator's truth.

use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// `spinbench demo --json` with `args`, its data in `data`: the document.
fn demo(args: &[&str], data: &Path) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["demo", "--json"])
        .args(args)
        .arg("--data")
        .arg(data)
        .output()
        .expect("run the demo");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON document")
}

/// The document without what differs by design between two runs: the run
/// directory (its run id) and the wall-clock time.
fn without_run_id_and_wall_time(mut doc: Value) -> Value {
    if let Some(run) = doc["run"].as_object_mut() {
        run.remove("dir");
        run.remove("wall_duration_s");
    }
    doc
}

/// Run the demo twice with `args`; the two documents must be the same.
fn twice_the_same(args: &[&str]) -> (Value, tempfile::TempDir) {
    let (first_dir, second_dir) = (
        tempfile::tempdir().expect("tempdir"),
        tempfile::tempdir().expect("tempdir"),
    );
    let first = demo(args, first_dir.path());
    let second = demo(args, second_dir.path());
    assert_eq!(
        without_run_id_and_wall_time(first.clone()),
        without_run_id_and_wall_time(second),
        "two demos with {args:?} differ"
    );
    (first, first_dir)
}

#[test]
fn the_demo_finds_k2_and_the_radii_of_every_instrument() {
    // The same seed gives the same results, byte for byte (virtual time in lockstep).
    let (doc, _dir) = twice_the_same(&["--seed", "3"]);
    assert_eq!(doc["run"]["state"], "completed");
    // The default plan is the shipped check's: designed for a K2 U95 of
    // 8 µg/g² and measured until the verdict is certain, in less centrifuge
    // time than the published plan.
    let run = &doc["run"];
    assert_eq!(run["prediction"]["target_k2_u95_ug_per_g2"], 8.0, "{run}");
    let spun = run["achieved"]["centrifuge_time_s"].as_f64().expect("time");
    let published = run["prediction"]["published_centrifuge_time_s"]
        .as_f64()
        .expect("published time");
    assert!(
        spun < published,
        "{spun} s against the published {published} s"
    );
    // Within the prediction's time and what the data's levels may add.
    let most = run["prediction"]["centrifuge_time_s"]
        .as_f64()
        .expect("time")
        + run["prediction"]["sequential_centrifuge_time_max_s"]
            .as_f64()
            .expect("the sequential levels' time");
    assert!(spun <= most, "{spun} s against at most {most} s");
    let journal =
        std::fs::read_to_string(Path::new(run["dir"].as_str().expect("dir")).join("journal.jsonl"))
            .expect("journal");
    assert!(
        journal.contains(r#""sequential":{"max_levels_per_pass":12}"#),
        "the plan in the journal is not sequential"
    );
    assert!(
        doc["run"]["dir"]
            .as_str()
            .is_some_and(|d| std::path::Path::new(d).join("results.json").exists())
    );
    let units = doc["units"].as_array().expect("units");
    // 12 instruments × 2 mountings.
    assert_eq!(units.len(), 24);
    let (mut inside, mut within_twice, mut radius_better) = (0, 0, 0);
    for u in units {
        for key in [
            "serial",
            "slot",
            "mount",
            "radius_m",
            "true_radius_m",
            "k2_ug_per_g2",
            "k2_ci95",
            "true_k2_ug_per_g2",
            "outcome",
        ] {
            assert!(!u[key].is_null(), "{key} missing in {u}");
        }
        let ci = u["k2_ci95"].as_array().expect("interval");
        let (lo, hi) = (ci[0].as_f64().expect("lo"), ci[1].as_f64().expect("hi"));
        let truth = u["true_k2_ug_per_g2"].as_f64().expect("truth");
        inside += usize::from(lo <= truth && truth <= hi);
        // Twice the 95 % half-width is about 4 σ.
        within_twice += usize::from((0.5 * (lo + hi) - truth).abs() <= hi - lo);
        // The interval says something: far narrower than the k2 it bounds.
        assert!(
            hi - lo < 0.5,
            "a k2 interval {:.3} µg/g² wide: {u}",
            hi - lo
        );
        let r = u["radius_m"].as_f64().expect("radius");
        let r_true = u["true_radius_m"].as_f64().expect("true radius");
        let r0 = u["drawing_radius_m"].as_f64().expect("R0");
        // The radius found is within 0.1 mm, and better than the drawing radius.
        assert!((r - r_true).abs() < 1e-4, "{u}");
        radius_better += usize::from((r - r_true).abs() < (r0 - r_true).abs());
        // In mounting N the per-mounting k2 has the opposite sign of the truth's IEEE value.
        let k2 = u["k2_ug_per_g2"].as_f64().expect("k2");
        assert!((k2 - truth).abs() < 2.0, "{u}");
    }
    // The 24 intervals are not 24 independent trials: the table's rate
    // error at a level is common to every instrument on the arm, so their
    // k2 errors move together and one run is about one draw (the coverage
    // over many independent runs is measured by the analysis tests). Within
    // one run every error must stay within twice its half-width (≈ 4 σ).
    assert_eq!(
        within_twice, 24,
        "k2 errors beyond twice the interval ({inside} of 24 intervals hold the truth)"
    );
    assert!(
        radius_better >= 20,
        "the radius found beats R0 for only {radius_better} of 24"
    );
}

/// Export a demo run's points and reduce them with `spinbench analyze --json`.
fn analyze_run(doc: &Value, data: &Path) -> Value {
    let dir = doc["run"]["dir"].as_str().expect("run dir");
    let run_id = Path::new(dir)
        .file_name()
        .and_then(|n| n.to_str())
        .expect("run id");
    let points = data.join("points.csv");
    let db = data.join("spinbench.db");
    let export = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["export", run_id, "--out"])
        .arg(&points)
        .arg("--db")
        .arg(&db)
        .output()
        .expect("export");
    assert!(
        export.status.success(),
        "{}",
        String::from_utf8_lossy(&export.stderr)
    );
    let analyze = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["analyze", "--json"])
        .arg(&points)
        .output()
        .expect("analyze");
    assert!(
        analyze.status.success(),
        "{}",
        String::from_utf8_lossy(&analyze.stderr)
    );
    serde_json::from_slice(&analyze.stdout).expect("analysis JSON")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn the_typical_bench_reproduces_and_shows_the_published_datas_signature() {
    let (doc, dir) = twice_the_same(&["--seed", "2", "--realism", "typical", "--published"]);
    assert_eq!(doc["run"]["state"], "completed");
    assert_eq!(doc["run"]["realism"], "typical");
    let units = doc["units"].as_array().expect("units");
    assert_eq!(
        units.len(),
        24,
        "no instrument faulted on the typical bench"
    );
    // The per-mounting U95 holds what a perfect per-mounting fit would
    // return (the table's resonance corrected by the signature the run
    // learned, its broad error's unseen part in the Type B bound: 91.8 % of
    // 576 mountings over 24 seeds, scripts/coverage), and the per-mounting
    // truth is the instrument's K2 plus the centrifuge's part.
    let mut held = 0;
    for u in units {
        let k2 = u["k2_ug_per_g2"].as_f64().expect("k2");
        let u95 = u["k2_U95"].as_f64().expect("U95");
        let truth = u["true_mounting_k2_ug_per_g2"].as_f64().expect("truth");
        held += usize::from((k2 - truth).abs() <= u95);
        let sign = if u["mount"] == "P" { 1.0 } else { -1.0 };
        let own = u["true_instrument_k2_ug_per_g2"].as_f64().expect("K2");
        assert_eq!(u["true_k2_ug_per_g2"].as_f64(), Some(sign * own));
    }
    assert!(held >= 20, "per-mounting U95 held the truth in {held}/24");
    // The published signature (method.md §5): a cubic leaves thousands of µg
    // (published ≈ 4,700 µg), far above the up/down disagreement, with one
    // level off the curve in every instrument: the table's resonance, which
    // `analyze` on the run's exported points learns from its twelve
    // instruments as the run did (docs/method.md §6) and takes out.
    let analysis = analyze_run(&doc, dir.path());
    let signature = &analysis["table_signatures"][0]["signature"];
    assert_eq!(signature["instruments"].as_u64(), Some(12), "{signature}");
    let levels = signature["levels"].as_array().expect("signature levels");
    let seen: Vec<f64> = levels
        .iter()
        .map(|l| l["residual_ug"].as_f64().expect("residual"))
        .collect();
    let rms = (seen.iter().map(|x| x * x).sum::<f64>() / seen.len() as f64).sqrt();
    assert!(
        (4_700.0 / 2.0..=4_700.0 * 2.0).contains(&rms),
        "the mountings' median cubic residual RMS {rms:.0} µg, published about 4,700 µg"
    );
    let spikes = signature["correction"]["spikes"]
        .as_array()
        .expect("spikes");
    assert_eq!(spikes.len(), 1, "one resonance: {signature}");
    let disturbed = spikes[0]["g"].as_f64().expect("level");
    assert_eq!(disturbed, 40.0, "the typical table's resonance is at 40 g");
    assert!(
        spikes[0]["height_ug"].as_f64().is_some_and(|h| h > 5_000.0),
        "{signature}"
    );
    let mut up_down = Vec::new();
    let (mut fits, mut still_flagged) = (0, 0);
    for unit in analysis["units"].as_array().expect("units") {
        for fit in unit["fits"].as_object().expect("fits").values() {
            let k1 = fit["k1"].as_f64().expect("k1").abs();
            let mut by_level: std::collections::BTreeMap<String, [Option<f64>; 2]> =
                Default::default();
            for r in fit["residuals"].as_array().expect("residuals") {
                let g = r["g_nominal"].as_f64().expect("g");
                let e = by_level.entry(format!("{g}")).or_default();
                let k = usize::from(r["direction"] == "down");
                e[k] = r["output"].as_f64();
            }
            let d: Vec<f64> = by_level
                .values()
                .filter_map(|[u, d]| Some((u.as_ref()? - d.as_ref()?) / k1 * 1e6))
                .collect();
            up_down.push((d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt());
            // With the table taken out, the resonance is off the curve only
            // where an instrument's coupling to it (its place on the arm,
            // ±20 %) or its own anomaly there differs from the median.
            let d = &fit["diagnostics"];
            let flagged: Vec<f64> = d["outlier_levels"]
                .as_array()
                .map(|o| o.iter().filter_map(|l| l["g"].as_f64()).collect())
                .unwrap_or_default();
            fits += 1;
            still_flagged += usize::from(flagged.contains(&disturbed));
        }
    }
    assert!(
        2 * still_flagged < fits,
        "the resonance still off the curve in {still_flagged} of {fits} fits"
    );
    let agreement = median(up_down);
    assert!(
        rms >= 10.0 * agreement,
        "residual {rms:.0} µg, up/down {agreement:.0} µg"
    );
    // The report shows the signature and names its decision rule.
    let run_dir = Path::new(doc["run"]["dir"].as_str().expect("dir"));
    let html = std::fs::read_dir(run_dir)
        .expect("run dir")
        .filter_map(Result::ok)
        .find(|e| e.path().extension().is_some_and(|x| x == "html"))
        .map(|e| std::fs::read_to_string(e.path()).expect("report"))
        .expect("an HTML report");
    assert!(
        html.contains("The centrifuge&#39;s signature")
            || html.contains("The centrifuge's signature"),
        "no signature section"
    );
    assert!(html.contains("µg @ 40 g"), "the resonance is not named");
    // The station knows it as its table's signature (the web's station page).
    let store =
        spinbench_store::Store::open(&dir.path().join("spinbench.db")).expect("the demo's store");
    let config = spinbench_engine::StationConfig::from_toml(
        &std::fs::read_to_string(run_dir.join("station.toml")).expect("station.toml"),
    )
    .expect("the run's station config");
    let (run_id, learned) =
        spinbench_station::station_model::latest_signature(&store, &config).expect("learned");
    assert_eq!(
        Some(run_id.as_str()),
        run_dir.file_name().and_then(|n| n.to_str())
    );
    assert!(
        learned.correction.spikes.iter().any(|s| s.g == 40.0),
        "{}",
        learned.describe()
    );
    assert!(html.contains("centrifuge signature"), "no signature plot");
    assert!(
        html.contains("guarded acceptance"),
        "the decision rule is not named"
    );
    assert!(
        html.contains("both mountings (method.md (15))"),
        "no joint reduction"
    );
}

#[test]
fn arm_stretch_is_the_part_of_k2_common_to_both_mountings_end_to_end() {
    // The ideal bench with a large arm stretch: c = k_s·g/R0² = 8 µg/g².
    let dir = tempfile::tempdir().expect("tempdir");
    let config = dir.path().join("stretch.toml");
    let k_s = 8e-6 * 0.64 / 9.80665;
    std::fs::write(
        &config,
        format!("[centrifuge]\narm_stretch_m_per_rad2_s2 = {k_s:e}\n"),
    )
    .expect("write");
    let doc = demo(
        &[
            "--seed",
            "4",
            "--sim-config",
            config.to_str().expect("utf-8"),
        ],
        dir.path(),
    );
    let units = doc["units"].as_array().expect("units");
    for pair in units.chunks(2) {
        let k2 = |u: &Value| u["k2_ug_per_g2"].as_f64().expect("k2");
        let (p, n) = (&pair[0], &pair[1]);
        assert_eq!(
            (p["mount"].as_str(), n["mount"].as_str()),
            (Some("P"), Some("N"))
        );
        let common = 0.5 * (k2(p) + k2(n));
        let own = 0.5 * (k2(p) - k2(n));
        let true_common = 0.5
            * (p["true_mounting_k2_ug_per_g2"].as_f64().expect("P")
                + n["true_mounting_k2_ug_per_g2"].as_f64().expect("N"));
        assert!((true_common - 8.0).abs() < 0.05, "{true_common}");
        assert!(
            (common - true_common).abs() < 0.2,
            "common part {common:.3}, true {true_common:.3}: {p}"
        );
        let true_own = p["true_instrument_k2_ug_per_g2"].as_f64().expect("K2");
        assert!(
            (own - true_own).abs() < 0.2,
            "K2 {own:.3}, true {true_own:.3}: {p}"
        );
    }
    // The station's joint reduction separates them: within its U95 of what
    // perfect fits would return (the demo's per-mounting truths hold every
    // cross term, e.g. k3 times the stretch) for most instruments, within
    // twice it (about 4 σ) for every one.
    let run_dir = Path::new(doc["run"]["dir"].as_str().expect("dir"));
    let results: Value = serde_json::from_str(
        &std::fs::read_to_string(run_dir.join("results.json")).expect("results"),
    )
    .expect("json");
    let records = results.as_array().expect("records");
    let mut within = 0;
    for (r, pair) in records.iter().zip(units.chunks(2)) {
        assert_eq!(r["serial"], pair[0]["serial"]);
        let j = &r["analysis"]["joint"];
        let value = |k: &str| j[k].as_f64().unwrap_or_else(|| panic!("{k} in {j}"));
        let (even, odd) = (value("k2_even_ug_per_g2"), value("k2_odd_ug_per_g2"));
        let (u_even, u_odd) = (value("k2_even_U95"), value("k2_odd_U95"));
        let perfect = |u: &Value| u["true_mounting_k2_ug_per_g2"].as_f64().expect("truth");
        let (tp, tn) = (perfect(&pair[0]), perfect(&pair[1]));
        let (true_even, true_odd) = (0.5 * (tp - tn), 0.5 * (tp + tn));
        assert!(
            (even - true_even).abs() <= 2.0 * u_even,
            "K2 {even} ± {u_even}, true {true_even}"
        );
        assert!(
            (odd - true_odd).abs() <= 2.0 * u_odd,
            "odd {odd} ± {u_odd}, true {true_odd}"
        );
        within += usize::from((even - true_even).abs() <= u_even);
        within += usize::from((odd - true_odd).abs() <= u_odd);
    }
    assert!(
        within >= 18,
        "only {within} of 24 joint values within their U95"
    );
}

#[test]
fn the_harsh_bench_completes_and_only_its_bad_instruments_are_failed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let doc = demo(
        &["--seed", "5", "--realism", "harsh", "--published"],
        dir.path(),
    );
    assert_eq!(doc["run"]["state"], "completed");
    let run_dir = Path::new(doc["run"]["dir"].as_str().expect("dir"));
    let results: Value = serde_json::from_str(
        &std::fs::read_to_string(run_dir.join("results.json")).expect("results"),
    )
    .expect("json");
    // Every reason that is not a figure judged against its limit, nor a
    // note of the reduction (what the anomaly rule left out and what its
    // refit found), is a fault of the instrument.
    let mut failed = std::collections::BTreeMap::new();
    for r in results.as_array().expect("records") {
        // Only the dead and the noisy instrument, which gave nothing to
        // judge against the limits, are incomplete.
        let unmeasured = r["reasons"].as_array().is_some_and(|rs| {
            rs.iter()
                .any(|x| x["code"] == "dead" || x["code"] == "noisy")
        });
        assert_eq!(r["outcome"] == "incomplete", unmeasured, "{r}");
        for reason in r["reasons"].as_array().expect("reasons") {
            let code = reason["code"].as_str().unwrap_or("?");
            if !(code.ends_with("_limit") || code == "k2_inconclusive" || code == "analysis_note") {
                failed.insert(r["slot"].as_u64().expect("slot"), code.to_string());
            }
        }
    }
    // harsh: module 0 slot 2 noisy, module 1 slot 5 dead; nothing else.
    let want: std::collections::BTreeMap<u64, String> =
        [(2, "noisy".to_string()), (11, "dead".to_string())].into();
    assert_eq!(failed, want, "{results}");
    // No false stability faults: no notice of a point measured again.
    let journal = std::fs::read_to_string(run_dir.join("journal.jsonl")).expect("journal");
    assert!(
        !journal.contains("measuring the point again"),
        "a point was measured again"
    );
}
