//! The experiment planner through the command line: the
//! station's model learned from its runs in the store, `plan design`
//! against the published plan, a target it cannot reach refused before
//! anything moves, and a run of `levels = "auto"` designed when it starts,
//! its prediction beside what it achieved in the record and the report.

mod common;

use common::spinbench;
use serde_json::Value;

#[test]
fn a_plan_is_designed_from_the_stations_runs_and_its_prediction_is_reported() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let data_s = data.to_str().expect("utf-8");
    let short = dir.path().join("short.toml");
    std::fs::write(&short, common::short_plan("D")).expect("plan");
    // The design's plan: ±30 g (the published levels 0, 1, 5 … 30), both mountings.
    let to_30 = "range_g = 30\npasses = [\"P\", \"N\"]\nwarmup_s = 0\nstability = { hold_s = 3 }\n[serials]\n1 = \"A1\"\n2 = \"A2\"\n7 = \"A7\"\n";
    let wide = dir.path().join("wide.toml");
    std::fs::write(&wide, to_30).expect("plan");
    let design = |target: &str| {
        spinbench(&[
            "plan",
            "design",
            &format!("--target-k2-u95={target}"),
            "--plan",
            wide.to_str().expect("utf-8"),
            "--data",
            data_s,
            "--json",
        ])
    };
    // A design that must succeed, as its JSON document.
    let designed = |target: &str| {
        let (ok, said, err) = design(target);
        assert!(ok, "{said}{err}");
        serde_json::from_str::<Value>(&said).expect("json")
    };
    // No history: the defaults, said so.
    let doc = designed("1000");
    assert!(
        doc["model_source"]
            .as_str()
            .is_some_and(|s| s.contains("no history")),
        "{doc}"
    );
    // Two runs on the typical virtual bench: the model learns from them.
    let run_plan = |plan: &std::path::Path| {
        let (ok, said, err) = spinbench(&[
            "run",
            "--simulate",
            "--realism",
            "typical",
            "--quiet",
            "--data",
            data_s,
            plan.to_str().expect("utf-8"),
        ]);
        assert!(ok, "{said}{err}");
    };
    for _ in 0..2 {
        run_plan(&short);
    }
    let doc = designed("1000");
    assert!(
        doc["model_source"]
            .as_str()
            .is_some_and(|s| s.contains("learned from 2 completed run(s)")),
        "{doc}"
    );
    let white = doc["model"]["noise"]["white_ug"].as_f64().expect("white");
    assert!(white > 0.0 && white.is_finite(), "{doc}");
    // The target the published plan is predicted to reach: met in less time.
    let published = doc["prediction"]["published_k2_u95_ug_per_g2"]
        .as_f64()
        .expect("published");
    let published_time = doc["prediction"]["published_centrifuge_time_s"]
        .as_f64()
        .expect("time");
    let doc = designed(&format!("{published}"));
    let p = &doc["prediction"];
    assert!(
        p["k2_u95_ug_per_g2"].as_f64().expect("u95") <= published * (1.0 + 1e-12),
        "{doc}"
    );
    assert!(
        p["centrifuge_time_s"].as_f64().expect("time") < published_time,
        "{doc}"
    );
    let levels = doc["levels_g"].as_array().expect("levels");
    assert!(levels.len() >= 6, "{doc}");
    assert_eq!(levels.last().and_then(Value::as_f64), Some(30.0), "{doc}");

    // A target no plan reaches: refused, naming the smallest reachable.
    let (ok, said, err) = design("0.0001");
    assert!(!ok, "{said}");
    assert!(
        err.contains("cannot be reached") && err.contains("the smallest predicted is"),
        "{err}"
    );
    // Hostile targets are refused by the bounds.
    for bad in ["-1", "nan", "inf"] {
        let (ok, _, err) = design(bad);
        assert!(
            !ok && err.contains("target_k2_u95_ug_per_g2"),
            "{bad}: {err}"
        );
    }

    // A plan with levels = "auto": designed when the run starts.
    let auto = dir.path().join("auto.toml");
    let text = format!("levels = \"auto\"\ntarget_k2_u95_ug_per_g2 = {published}\n{to_30}");
    std::fs::write(&auto, text).expect("plan");
    run_plan(&auto);
    let store = spinbench_store::Store::open_read_only(&spinbench_store::StoreTarget::File(
        data.join("spinbench.db"),
    ))
    .expect("store");
    let run = store.runs().expect("runs").remove(0);
    let start = store.run_start(&run.id).expect("start").expect("run");
    let plan: spinbench_engine::TestPlan = start.plan.plan.expect("the run's plan");
    assert!(!plan.is_auto(), "the run's plan holds what was designed");
    let prediction = plan.prediction.clone().expect("prediction");
    assert!(prediction.k2_u95_ug_per_g2 <= published * (1.0 + 1e-12));
    assert_eq!(prediction.model_runs, 2);
    // The run's plan.toml is the designed plan, and reads back.
    let own = std::fs::read_to_string(data.join("runs").join(&run.id).join("plan.toml"))
        .expect("plan.toml");
    assert_eq!(
        spinbench_engine::TestPlan::from_toml(&own).expect("reads"),
        plan
    );
    // Achieved beside predicted: from the records, and in the report.
    let results = store.results(&run.id).expect("results");
    let achieved = spinbench_engine::planning::achieved(results.iter().map(|r| &r.record));
    let time = achieved.centrifuge_time_s.expect("time");
    assert!(
        (time / prediction.centrifuge_time_s - 1.0).abs() < 0.5,
        "achieved {time} s, predicted {} s",
        prediction.centrifuge_time_s
    );
    let html = std::fs::read_to_string(common::report_file(
        &data.join("runs").join(&run.id),
        &run.id,
        "html",
    ))
    .expect("report");
    assert!(
        html.contains("plan prediction"),
        "the report's prediction row"
    );
    assert!(
        html.contains(&format!(
            "{:.3} µg/g² predicted",
            prediction.k2_u95_ug_per_g2
        )),
        "the report's predicted U95"
    );
}
