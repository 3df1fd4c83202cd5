//! End to end in a real browser (headless Chromium through chromedriver)
//! against `spinbench serve --simulate`: log in, start a run from the form,
//! see the live curves move, answer the operator prompts, see the run
//! finish and download its report. Screenshots go to
//! `target/tmp/web-browser/` for a person to look at.

#[path = "common/web.rs"]
mod web;
#[path = "common/webdriver.rs"]
mod webdriver;

use serde_json::Value;
use std::time::{Duration, Instant};
use webdriver::Browser;

/// A short test plan (±6 g, both mountings).
fn plan() -> String {
    web::short_plan("browser test", &["WEB-1"])
}

#[test]
fn an_operator_runs_a_test_in_the_browser() {
    let dir = tempfile::tempdir().expect("tempdir");
    web::add_user(dir.path(), "op", "operator", "op-password");
    web::add_user(dir.path(), "eng", "engineer", "eng-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(dir.path().join("plans").join("browser.toml"), plan()).expect("plan");
    // 10× real time: a few seconds per level, so the curves visibly move,
    // and light enough for a debug build on a loaded 2-core machine.
    let server = web::serve(dir.path(), "10");
    let shots = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("web-browser");
    std::fs::create_dir_all(&shots).expect("screenshot dir");

    let b = Browser::start();
    log_in(&b, &server.base, "op", "op-password");
    assert_eq!(
        b.script("return document.getElementById('who').textContent"),
        Value::String("op (operator)".into())
    );

    // The new-run form: the plan, serial numbers per slot (a wrong prefix is refused).
    b.click("#nav-new");
    b.wait_for(10, "the plans", "return document.querySelectorAll('#plan-select option').length > 0 && !!document.getElementById('serial-2')");
    b.script("const s = document.getElementById('plan-select'); s.value = 'browser'; s.dispatchEvent(new Event('change'));");
    assert_eq!(
        b.script("return document.getElementById('plan-editor').hidden"),
        Value::Bool(true),
        "an operator does not get the plan editor"
    );
    // A barcode scanner (keyboard wedge) types a serial and Enter: the focus
    // moves to the next slot; a duplicate is refused as it is scanned, the
    // slot cleared and kept for the next scan.
    b.type_into("#serial-1", "SCAN-1\u{E007}");
    assert_eq!(
        b.script("return document.activeElement.id"),
        Value::String("serial-2".into())
    );
    b.type_into("#serial-2", "N:SCAN-1\u{E007}");
    b.wait_for(
        5,
        "the duplicate refused as it is scanned",
        "return document.getElementById('message').textContent.includes('already in slot 1')",
    );
    assert_eq!(
        b.script("return [document.activeElement.id, document.getElementById('serial-2').value]"),
        serde_json::json!(["serial-2", ""])
    );
    b.type_into("#serial-2", "Q:SCAN-2\u{E007}");
    b.wait_for(
        5,
        "the malformed serial refused as it is scanned",
        "return document.getElementById('message').textContent.includes('not a mounting prefix')",
    );
    b.screenshot(&shots.join("1a-scan-refused.png"));
    b.type_into("#serial-1", "");
    b.type_into("#serial-2", "X:WEB-2");
    b.click("#start-button");
    b.wait_for(
        5,
        "the prefix refusal",
        "return document.getElementById('message').textContent.includes('mounting prefix')",
    );
    b.type_into("#serial-2", "N:WEB-2");
    b.screenshot(&shots.join("1-new-run.png"));
    b.click("#start-button");
    b.wait_for(
        10,
        "the run screen",
        "return !document.getElementById('run').hidden",
    );

    // Answer every prompt; watch the curves move in between.
    let mut prompts = 0;
    let mut moved = false;
    let until = Instant::now() + Duration::from_secs(240);
    loop {
        let state = b.script("return document.getElementById('run-state').textContent");
        assert!(
            Instant::now() < until,
            "the run did not finish in time: {state}"
        );
        if state.as_str().is_some_and(|s| s.starts_with("completed")) {
            break;
        }
        if state
            .as_str()
            .is_some_and(|s| s.starts_with("faulted") || s.starts_with("aborted"))
        {
            b.screenshot(&shots.join("3c-ended.png"));
            panic!("the run ended: {state}");
        }
        let prompt_shown = b.script("return !document.getElementById('prompt').hidden");
        if prompt_shown == Value::Bool(true) {
            if prompts == 0 {
                b.screenshot(&shots.join("2-prompt.png"));
            }
            b.click("#prompt-done");
            prompts += 1;
            std::thread::sleep(Duration::from_millis(300));
            continue;
        }
        // After the remount onto the arm the table spins level by level.
        if !moved && prompts >= 3 {
            let count = |b: &Browser| {
                b.script("return Number(document.getElementById('curves').dataset.values)")
                    .as_u64()
                    .unwrap_or(0)
            };
            let before = count(&b);
            std::thread::sleep(Duration::from_millis(1500));
            let after = count(&b);
            if after > before && before > 0 {
                moved = true;
                b.screenshot(&shots.join("3-live-curves.png"));
                // The status panel while the table spins.
                b.click("#nav-status");
                b.wait_for(
                    10,
                    "the status rate",
                    "return document.getElementById('st-rate').textContent.includes('deg/s')",
                );
                std::thread::sleep(Duration::from_millis(2500));
                b.screenshot(&shots.join("3b-status.png"));
                b.click("#nav-run");
                b.wait_for(
                    10,
                    "the run screen again",
                    "return !document.getElementById('run').hidden",
                );
            }
            continue;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    assert!(
        prompts >= 3,
        "tumble up, tumble down, remount: {prompts} prompts answered"
    );
    assert!(moved, "the live curves moved while the run went on");
    // The curves are drawn: pixels on the canvas are not all blank.
    let inked = b.script(
        "const c = document.getElementById('curves'); const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; \
         let n = 0; for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++; return n;",
    );
    assert!(
        inked.as_u64().unwrap_or(0) > 1000,
        "ink on the canvas: {inked}"
    );

    // The report downloads from the finished run's links.
    b.wait_for(
        10,
        "the report links",
        "return !!document.getElementById('report-pdf')",
    );
    b.screenshot(&shots.join("4-finished.png"));
    let got = b.script_async(
        "const done = arguments[0]; fetch(document.getElementById('report-pdf').href)\
         .then(r => r.arrayBuffer().then(buf => done([r.status, r.headers.get('content-type'), buf.byteLength, \
         String.fromCharCode(...new Uint8Array(buf.slice(0, 4)))])))\
         .catch(e => done(String(e)));",
    );
    assert_eq!(got[0], 200, "{got}");
    assert_eq!(got[1], "application/pdf");
    assert!(got[2].as_u64().unwrap_or(0) > 10_000, "{got}");
    assert_eq!(got[3], "%PDF");

    // History shows the run with its results.
    b.click("#nav-history");
    b.wait_for(
        10,
        "the runs table",
        "return document.querySelectorAll('#runs-table tbody tr').length > 0",
    );
    b.click("#runs-table tbody tr a");
    b.wait_for(
        10,
        "the results",
        "return document.getElementById('run-detail').textContent.includes('WEB-2')",
    );
    b.screenshot(&shots.join("5-history.png"));
    assert_eq!(
        b.script("return !!document.getElementById('exclude-form')"),
        Value::Bool(false),
        "an operator cannot leave levels out"
    );

    // An engineer leaves a level out of the finished run, with a reason.
    b.click("#logout-button");
    log_in(&b, &server.base, "eng", "eng-password");
    b.click("#nav-history");
    b.wait_for(
        10,
        "the runs table",
        "return document.querySelectorAll('#runs-table tbody tr').length > 0",
    );
    b.click("#runs-table tbody tr a");
    b.wait_for(
        10,
        "the exclusion form",
        "return !!document.getElementById('exclude-form')",
    );
    b.script("const s = document.getElementById('exclude-serial'); s.value = 'WEB-2';");
    b.script("document.getElementById('exclude-mount').value = 'N';");
    b.type_into("#exclude-g", "3");
    b.type_into(
        "#exclude-reason",
        "fixture screw found loose after the 3 g level",
    );
    b.click("#exclude-button");
    b.wait_for(
        20,
        "the exclusion's confirmation",
        "return document.getElementById('message').textContent.includes('left out')",
    );
    b.wait_for(
        10,
        "the results naming the exclusion",
        "return document.getElementById('run-detail').textContent.includes('EXCLUDED by eng: mounting N level 3 g')",
    );
    b.screenshot(&shots.join("5b-level-left-out.png"));
    let html = b.script_async(
        "const done = arguments[0]; fetch(document.getElementById('report-html').href)\
         .then(r => r.text().then(done)).catch(e => done(String(e)));",
    );
    assert!(
        html.as_str()
            .is_some_and(|h| h.contains("fixture screw found loose")),
        "the report names the exclusion and its reason"
    );

    // The control charts page: the product's charts drawn, the yields.
    b.click("#nav-charts");
    b.wait_for(
        20,
        "the control charts",
        "return document.querySelectorAll('#chart-figures figure svg').length >= 3 \
         && document.querySelectorAll('#yield-table tbody tr').length >= 2",
    );
    b.screenshot(&shots.join("7-control-charts.png"));
    assert_eq!(
        b.script("return document.querySelector('#chart-figures figure').dataset.quantity"),
        Value::String("k2_max".into())
    );
}

#[test]
fn an_engineer_saves_a_plan_in_the_browser() {
    let dir = tempfile::tempdir().expect("tempdir");
    web::add_user(dir.path(), "eng", "engineer", "eng-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(dir.path().join("plans").join("browser.toml"), plan()).expect("plan");
    let server = web::serve(dir.path(), "0");
    let shots = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("web-browser");
    std::fs::create_dir_all(&shots).expect("screenshot dir");

    let b = Browser::start();
    log_in(&b, &server.base, "eng", "eng-password");
    b.click("#nav-new");
    b.wait_for(10, "the plan editor", "return !document.getElementById('plan-editor').hidden && document.getElementById('plan-text').value.includes('range_g')");
    // A plan that cannot run is refused with the key named; a good one is saved and offered.
    b.type_into("#plan-name", "edited");
    b.script("document.getElementById('plan-text').value = 'range_g = 6\\nlevels = [0, 1, 2]\\n[serials]\\n1 = \"E-1\"\\n';");
    b.click("#plan-save");
    b.wait_for(
        10,
        "the refusal",
        "return document.getElementById('message').textContent.includes('levels')",
    );
    b.script(&format!(
        "document.getElementById('plan-text').value = {};",
        serde_json::to_string(&plan().replace("browser test", "edited in the browser"))
            .expect("json")
    ));
    b.click("#plan-save");
    b.wait_for(10, "the saved plan", "return Array.from(document.querySelectorAll('#plan-select option')).some(o => o.value === 'edited')");
    b.screenshot(&shots.join("6-engineer-plan.png"));
    let saved =
        std::fs::read_to_string(dir.path().join("plans").join("edited.toml")).expect("saved plan");
    assert!(saved.contains("edited in the browser"), "{saved}");
    // The virtual bench's station config is shown but not editable.
    assert_eq!(
        b.script("return document.getElementById('station-save').disabled"),
        Value::Bool(true)
    );
}

/// Open the page and log in through its form; waits for the status page.
fn log_in(b: &Browser, base: &str, user: &str, password: &str) {
    b.go(base);
    b.wait_for(
        10,
        "the login form",
        "return !document.getElementById('login').hidden",
    );
    b.type_into("#login-user", user);
    b.type_into("#login-password", password);
    b.click("#login-button");
    b.wait_for(
        10,
        "the status page",
        "return !document.getElementById('status').hidden",
    );
}
