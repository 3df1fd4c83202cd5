//! Acceptance for the pages: after a run, every page of the web
//! UI in Chinese and in English, screenshot into `target/tmp/issue-40/`
//! (looked at for the closing note), and no English word on a Chinese page
//! but the run's own data (the station's, plans', users' and devices' names,
//! serials, run labels); no page runs off the side of a 1400 px window.

#[path = "common/english.rs"]
mod english;
#[path = "common/web.rs"]
mod web;
#[path = "common/webdriver.rs"]
mod webdriver;

use english::english_words;
use serde_json::Value;
use std::time::{Duration, Instant};
use web::Client;
use webdriver::Browser;

/// The pages, by their menu entry and section.
const PAGES: [&str; 8] = [
    "status",
    "run",
    "new",
    "history",
    "charts",
    "equipment",
    "fleet",
    "users",
];

/// Run the plan `name` to its end through the API, answering its prompts.
fn run_to_the_end(api: &mut Client, plan: &str) -> String {
    let r = api.send(
        "POST",
        "/api/runs",
        Some(&format!(r#"{{"plan": "{plan}"}}"#)),
    );
    assert_eq!(r.status, 201, "{:?}", r.json());
    let run_id = r.json()["run_id"].as_str().expect("run id").to_string();
    let until = Instant::now() + Duration::from_secs(240);
    loop {
        assert!(Instant::now() < until, "the run did not end in time");
        let s = api.get_json("/api/status", 200);
        if s["prompt"].is_string() {
            api.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
        } else if s["active"].is_null() && s["ended"] == Value::Bool(true) {
            return run_id;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
fn every_page_in_chinese_has_no_english_and_every_page_is_shot_in_both_languages() {
    let dir = tempfile::tempdir().expect("tempdir");
    web::add_user(dir.path(), "wang.admin", "admin", "admin-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(
        dir.path().join("plans").join("pages.toml"),
        web::short_plan("页面测试", &["ZH-1", "ZH-2"]),
    )
    .expect("plan");
    let server = web::serve(dir.path(), "10");
    let mut api = Client::login(&server, "wang.admin", "admin-password");
    let run_id = run_to_the_end(&mut api, "pages");
    let shots = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("issue-40");
    std::fs::create_dir_all(&shots).expect("screenshot dir");

    // The run's own data, which no language changes.
    let status = api.get_json("/api/status", 200);
    let runs = api.get_json("/api/runs", 200);
    let mut data: Vec<String> = vec![
        run_id.clone(),
        "wang.admin".into(),
        "ZH-1".into(),
        "ZH-2".into(),
    ];
    data.extend(status["station"].as_str().map(str::to_string));
    for r in runs.as_array().into_iter().flatten() {
        data.extend(r["label"].as_str().map(str::to_string));
    }
    let plans = api.get_json("/api/plans", 200);
    for p in plans["plans"].as_array().into_iter().flatten() {
        data.extend(p["name"].as_str().map(str::to_string));
        data.extend(p["title"].as_str().map(str::to_string));
    }
    let equipment = api.get_json("/api/equipment", 200);
    for d in equipment.as_array().into_iter().flatten() {
        data.extend(d["read_identity"].as_str().map(str::to_string));
    }
    data.sort_by_key(|w| std::cmp::Reverse(w.len()));

    let b = Browser::start();
    b.go(&server.base);
    b.wait_for(
        10,
        "the login form",
        "return !document.getElementById('login').hidden",
    );
    b.screenshot(&shots.join("en-0-login.png"));
    b.type_into("#login-user", "wang.admin");
    b.type_into("#login-password", "admin-password");
    b.click("#login-button");
    b.wait_for(
        10,
        "logged in",
        "return !document.getElementById('status').hidden",
    );
    let mut english_on = Vec::new();
    for lang in ["en", "zh-CN"] {
        b.script(&format!(
            "const s = document.getElementById('lang-select'); s.value = '{lang}'; s.dispatchEvent(new Event('change'));"
        ));
        // Loaded again in that language: the event log replays the run's
        // events in it (a line is worded when it is written).
        b.go(&server.base);
        b.wait_for(
            10,
            "logged in",
            "return !document.getElementById('status').hidden",
        );
        let history = if lang == "en" { "History" } else { "历史" };
        b.wait_for(
            10,
            "the page in its language",
            &format!("return document.getElementById('nav-history').textContent === '{history}'"),
        );
        for (k, page) in PAGES.iter().enumerate() {
            b.click(&format!("#nav-{page}"));
            b.wait_for(
                10,
                "the page",
                &format!("return !document.getElementById('{page}').hidden"),
            );
            // Its data loaded (tables filled, the run's board drawn).
            std::thread::sleep(Duration::from_millis(1500));
            if *page == "history" {
                b.click("#runs-table tbody tr a");
                std::thread::sleep(Duration::from_millis(1500));
            }
            b.screenshot(&shots.join(format!("{lang}-{}-{page}.png", k + 1)));
            let wide =
                b.script("return document.documentElement.scrollWidth <= window.innerWidth + 1");
            assert_eq!(wide, Value::Bool(true), "{page} ({lang}) runs off the side");
            if lang == "zh-CN" {
                // The audit log's details are the record as it was written
                // (its actions are worded): left out of the check.
                let text = b.script(&format!(
                    "for (const td of document.querySelectorAll('#audit-table td.detail')) td.style.display = 'none'; \
                     return document.querySelector('header').innerText + '\\n' + document.getElementById('{page}').innerText"
                ));
                let words = english_words(text.as_str().unwrap_or_default(), &data);
                if !words.is_empty() {
                    english_on.push(format!("{page}:\n  {}", words.join("\n  ")));
                }
            }
        }
    }
    assert!(
        english_on.is_empty(),
        "English on the Chinese pages:\n{}",
        english_on.join("\n")
    );
}
