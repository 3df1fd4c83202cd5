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
    an_operator_runs_a_test_in_the_browser_on(web::Backend::Sqlite);
}

#[test]
fn postgres_an_operator_runs_a_test_in_the_browser() {
    an_operator_runs_a_test_in_the_browser_on(web::Backend::Postgres);
}

fn an_operator_runs_a_test_in_the_browser_on(backend: web::Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    web::add_user(dir.path(), "op", "operator", "op-password");
    web::add_user(dir.path(), "eng", "engineer", "eng-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    // A k2 limit no instrument meets: the run has an instrument to retest.
    let strict = format!("{}[limits]\nk2_max_ug_per_g2 = 0.001\n", plan());
    std::fs::write(dir.path().join("plans").join("browser.toml"), strict).expect("plan");
    // 10× real time: a few seconds per level, so the curves visibly move,
    // and light enough for a debug build on a loaded 2-core machine.
    let server = web::serve(dir.path(), "10");
    let shots = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(match backend {
        web::Backend::Sqlite => "web-browser",
        web::Backend::Postgres | web::Backend::PgBouncer => "web-browser-postgres",
    });
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
    // The shipped plans are there (a function check, a
    // check designed to decide, the full test, the temperature test), and
    // each chosen plan is summed up before anything moves: its range, the
    // judged quantity, its limit and rule, whether it can decide.
    let options = b.script(
        "return Array.from(document.querySelectorAll('#plan-select option')).map(o => o.value)",
    );
    for shipped in ["short", "check-70g", "full-70g", "temperature"] {
        assert!(
            options
                .as_array()
                .is_some_and(|o| o.iter().any(|v| v == shipped)),
            "{shipped} among {options}"
        );
    }
    b.script("const s = document.getElementById('plan-select'); s.value = 'full-70g'; s.dispatchEvent(new Event('change'));");
    b.wait_for(
        5,
        "the full plan summed up as able to decide",
        "const p = document.getElementById('plan-summary'); \
         return p.textContent.startsWith('±70 g, ') && p.textContent.includes('judged: K2 against 20 µg/g² (guarded rule)') \
           && p.dataset.canDecide === 'true'",
    );
    b.script("const s = document.getElementById('plan-select'); s.value = 'short'; s.dispatchEvent(new Event('change'));");
    b.wait_for(
        5,
        "the ±10 g function check said not to decide",
        "const p = document.getElementById('plan-summary'); \
         return p.textContent.startsWith('±10 g, ') && p.dataset.canDecide === 'false' && p.textContent.includes('⚠ the predicted K2 U95 ')",
    );
    b.script("const s = document.getElementById('plan-select'); s.value = 'browser'; s.dispatchEvent(new Event('change'));");
    assert_eq!(
        b.script("return document.getElementById('plan-editor').hidden"),
        Value::Bool(true),
        "an operator does not get the plan editor"
    );
    // The planner: a K2 U95 target, and the prediction shown
    // before anything moves; the field is left empty for this run.
    b.type_into("#target-k2-u95", "1000");
    b.click("#design-button");
    b.wait_for(
        20,
        "the design's prediction beside the published plan's",
        "const r = document.getElementById('design-result'); return !r.hidden && r.textContent.includes('predicted K2 U95') && r.textContent.includes('the published plan')",
    );
    b.type_into("#target-k2-u95", "");
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
    let mut board_at_level: Option<Value> = None;
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
        // The board (as the page gets it): the one instrument, once at a
        // level, with its mounting.
        if board_at_level.is_none() {
            let slot = b.script_async(
                "const done = arguments[0]; fetch('/api/status').then(r => r.json())\
                 .then(s => done((s.board || []).find(b => b.slot === 2) || null)).catch(e => done(null));",
            );
            if slot["serial"] == "WEB-2"
                && slot["mount"] == "N"
                && ["settling", "averaging", "radius"]
                    .iter()
                    .any(|p| slot["phase"] == *p)
            {
                b.screenshot(&shots.join("3a-board.png"));
                board_at_level = Some(slot);
            }
        }
        let prompt_shown = b.script("return !document.getElementById('prompt').hidden");
        if prompt_shown == Value::Bool(true) {
            if prompts == 0 {
                // The wait is counted on the server's clock
                // and shown, and the time to go is there from the start
                // (by the plan), once, not in the step line too.
                b.wait_for(
                    10,
                    "the prompt's waiting time",
                    "const w = document.getElementById('prompt-waiting'); \
                     return w.dataset.waitedS !== undefined && w.textContent.startsWith('waiting for the operator for ')",
                );
                b.wait_for(
                    10,
                    "a time to go from the plan while the first prompt waits",
                    "const t = document.getElementById('run-eta').textContent; \
                     return t.startsWith('about ') && t.endsWith(' to go') \
                       && !document.getElementById('progress').textContent.includes(' to go')",
                );
                b.screenshot(&shots.join("2-prompt.png"));
                // The prompt's Abort asks first; cancelled,
                // the run waits at its prompt as before.
                b.cancel_the_prompts_abort();
                // The run is still active (the button shows once the page's
                // status refresh has seen the run; it may come a moment late).
                b.wait_for(
                    5,
                    "the run still active after a cancelled Abort",
                    "return !document.getElementById('abort-button').hidden",
                );
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
                // The board: the one instrument, at a level, with its points.
                assert_eq!(
                    b.script("return [document.getElementById('pause-button').hidden, document.getElementById('resume-button').hidden, document.getElementById('abort-button').hidden]"),
                    serde_json::json!([false, true, false]),
                    "while it runs: pause and abort, no resume"
                );
                b.screenshot(&shots.join("3-live-curves.png"));
                // Pause shows the held state (since when, how long); Resume
                // takes it away.
                b.click("#pause-button");
                b.wait_for(
                    90,
                    "the held state after Pause",
                    "const h = document.getElementById('held'); \
                     return !h.hidden && h.textContent.startsWith('Held by the operator since ') \
                       && !document.getElementById('resume-button').hidden",
                );
                b.screenshot(&shots.join("3c-held.png"));
                b.click("#resume-button");
                b.wait_for(
                    30,
                    "the held state gone after Resume",
                    "return document.getElementById('held').hidden",
                );
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
    assert!(
        board_at_level.is_some(),
        "the board showed slot 2 at a level in mounting N"
    );
    // Finished: the plan's prediction beside what the run achieved.
    b.wait_for(
        10,
        "the prediction and the achievement",
        "const p = document.getElementById('run-prediction'); return !p.hidden && p.textContent.includes('predicted') && /achieved;/.test(p.textContent) && /\\d+ s achieved/.test(p.textContent)",
    );
    // Finished: the board says done, all points, k2 with U95 and the outcome.
    b.wait_for(
        10,
        "the board's final row",
        "const r = document.querySelector('#board tbody tr[data-slot=\"2\"]'); \
         return !!r && r.cells[5].textContent.startsWith('done') && r.cells[6].textContent === '11/11' \
         && r.cells[7].textContent.includes('±') && r.cells[9].textContent !== '—'",
    );
    // The end banner counts the outcomes, coloured by the
    // worst (a limit no instrument meets: none passes).
    b.wait_for(
        10,
        "the end banner's counts",
        "const a = document.getElementById('alarm'); \
         return /^Run completed — \\d+ /.test(a.textContent) && !a.textContent.includes(' pass') \
           && ['fail', 'inconclusive', 'marginal', 'incomplete'].some(o => a.classList.contains(o))",
    );
    // On a 400 px phone nothing runs off the side, Log out
    // and the language stay in reach, and the board's K2 and outcome show.
    b.set_window(400, 800);
    b.wait_for(
        10,
        "the phone layout",
        "const w = window.innerWidth; const inside = e => { const r = e.getBoundingClientRect();            return r.width > 0 && r.left >= 0 && r.right <= w; };          const row = document.querySelector('#board tbody tr[data-slot=\"2\"]');          return w <= 420 && document.documentElement.scrollWidth <= w            && inside(document.getElementById('logout-button')) && inside(document.getElementById('lang-select'))            && !!row && inside(row.cells[8]) && inside(row.cells[9]) && inside(row.cells[1]) && inside(row.cells[5])",
    );
    let phone_shots = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("phone");
    std::fs::create_dir_all(&phone_shots).expect("screenshots");
    b.screenshot(&phone_shots.join(format!("run-{backend:?}.png")));
    b.set_window(1400, 1100);
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
    // The Run page offers the retest of the run's
    // instruments to test again, and says each instrument's next step.
    b.wait_for(
        20,
        "the retest offered on the Run page",
        "const b = document.getElementById('run-retest-button'); \
         return !!b && b.textContent.startsWith('Retest 1 instrument') \
           && document.querySelector('#board tbody tr[data-slot=\"2\"]').cells[10].textContent !== '—'",
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
    // Beside each outcome, what the verdict judged and against which limit.
    let judged = b.script(
        "const t = document.querySelector('#run-detail table'); const i = [...t.tHead.rows[0].cells].findIndex(c => c.textContent === 'judged'); \
         return i < 0 ? null : [...t.rows].slice(1).map(r => r.cells[i].textContent)",
    );
    let judged = judged
        .as_array()
        .unwrap_or_else(|| panic!("no judged column: {judged}"));
    assert!(!judged.is_empty());
    for cell in judged {
        let cell = cell.as_str().unwrap_or_default();
        assert!(
            cell.starts_with("K2 ") && cell.contains("limit 0.001 µg/g², guarded"),
            "{cell}"
        );
    }
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
    // The same page in Chinese: its words, and the rules' texts (or the
    // "no rule broken" line) worded by the server in the user's language.
    b.script("const s = document.getElementById('lang-select'); s.value = 'zh-CN'; s.dispatchEvent(new Event('change'));");
    b.wait_for(
        20,
        "the control charts in Chinese",
        "const flags = document.getElementById('flags-table').tBodies[0].textContent;          return document.querySelector('#charts h2').textContent === '控制图'          && document.querySelectorAll('#chart-figures figure svg').length >= 3          && (flags.includes('未违反任何规则') || flags.includes('规则 ')) && !flags.includes('rule')",
    );
    b.screenshot(&shots.join("7b-control-charts-zh.png"));
    b.script("const s = document.getElementById('lang-select'); s.value = 'en'; s.dispatchEvent(new Event('change'));");
    b.wait_for(
        10,
        "English again",
        "return document.querySelector('#charts h2').textContent === 'Control charts'",
    );

    // Retest in one action: the run's inconclusive instrument again, linked.
    b.click("#nav-history");
    b.wait_for(
        10,
        "the runs table",
        "return document.querySelectorAll('#runs-table tbody tr').length > 0",
    );
    b.click("#runs-table tbody tr a");
    b.wait_for(
        10,
        "the retest button",
        "return !!document.getElementById('retest-button')",
    );
    // Before it starts: that the retest is measured until the verdict is
    // certain (WEB-2 was measured in one mounting, so it has no interval
    // to advise on).
    b.wait_for(
        20,
        "the retest's advice",
        "const l = document.getElementById('retest-advice'); \
         return !!l && l.textContent.includes('Measured until the verdict is certain: up to 12 level(s)')",
    );
    b.screenshot(&shots.join("8-retest-offered.png"));
    b.click("#retest-button");
    // It asks first, naming the instruments.
    b.accept_dialog();
    b.wait_for(
        20,
        "the retest on the run screen",
        "return !document.getElementById('run').hidden && document.getElementById('message').textContent.includes('retest')",
    );
    b.wait_for(
        20,
        "the retest's board",
        "const r = document.querySelector('#board tbody tr[data-slot=\"2\"]'); return !!r && r.cells[1].textContent === 'WEB-2'",
    );
    b.screenshot(&shots.join("8b-retest-running.png"));
    b.wait_for(
        10,
        "the abort button",
        "return !document.getElementById('abort-button').hidden",
    );
    b.click("#abort-button");
    b.accept_dialog();
    b.wait_for(
        30,
        "the retest aborted, its banner",
        "return document.getElementById('run-state').textContent.startsWith('aborted') \
         && !document.getElementById('alarm').hidden",
    );
    b.wait_for(
        10,
        "the controls gone",
        "return document.getElementById('abort-button').hidden",
    );
}

#[test]
fn a_fault_raises_the_banner_and_ends_the_run_safely_in_the_browser() {
    let dir = tempfile::tempdir().expect("tempdir");
    web::add_user(dir.path(), "op", "operator", "op-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(dir.path().join("plans").join("browser.toml"), plan()).expect("plan");
    // The interlocks open once the table has turned for 30 s of bench
    // time: inside the run however long the browser took to start it.
    let bench = dir.path().join("bench.toml");
    std::fs::write(&bench, "[faults]\ninterlock_open_after_spin_s = 30.0\n").expect("bench");
    let server = web::serve_with(
        dir.path(),
        "10",
        &["--sim-config", bench.to_str().expect("utf-8")],
    );
    let shots = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("web-browser");
    std::fs::create_dir_all(&shots).expect("screenshot dir");
    let b = Browser::start();
    log_in(&b, &server.base, "op", "op-password");
    b.click("#nav-new");
    b.wait_for(10, "the plans", "return document.querySelectorAll('#plan-select option').length > 0 && !!document.getElementById('serial-2')");
    b.script("const s = document.getElementById('plan-select'); s.value = 'browser'; s.dispatchEvent(new Event('change'));");
    b.type_into("#serial-2", "N:WEB-F");
    b.click("#start-button");
    let until = Instant::now() + Duration::from_secs(120);
    loop {
        let state = b.script("return document.getElementById('run-state').textContent");
        assert!(Instant::now() < until, "no fault in time: {state}");
        if state.as_str().is_some_and(|s| s.starts_with("faulted")) {
            break;
        }
        if b.script("return !document.getElementById('prompt').hidden") == Value::Bool(true) {
            b.click("#prompt-done");
        }
        std::thread::sleep(Duration::from_millis(300));
    }
    b.wait_for(
        10,
        "the fault banner",
        "const a = document.getElementById('alarm'); return !a.hidden && a.className === 'fault' && a.textContent.includes('interlock')",
    );
    b.wait_for(10, "no controls on an ended run", "return document.getElementById('abort-button').hidden && document.getElementById('pause-button').hidden");
    assert!(
        b.script("return document.getElementById('event-log').textContent")
            .as_str()
            .is_some_and(|t| t.contains("FAULT")),
        "the event log has the fault"
    );
    b.screenshot(&shots.join("9-fault-banner.png"));

    // In Chinese: the operator chooses 中文; the page, the board's words and
    // the report they download follow, and the choice is kept for next time.
    b.script("const s = document.getElementById('lang-select'); s.value = 'zh-CN'; s.dispatchEvent(new Event('change'));");
    b.wait_for(
        10,
        "the page in Chinese",
        "return document.getElementById('nav-history').textContent === '历史' \
         && document.getElementById('nav-run').textContent === '运行' && document.documentElement.lang === 'zh-CN'",
    );
    b.wait_for(
        10,
        "the board in Chinese",
        "const r = document.querySelector('#board tbody tr[data-slot=\"2\"]'); \
         return !!r && document.querySelector('#board th[data-i18n=\"web.board.state\"]').textContent === '状态' \
         && ['完成', '失效', '等待'].some(w => r.cells[5].textContent.startsWith(w))",
    );
    // The fault banner, the run's state and its step line in Chinese too,
    // worded from the engine's key and values.
    b.wait_for(
        10,
        "the fault banner in Chinese",
        "const a = document.getElementById('alarm');          return a.textContent.startsWith('故障：离心机联锁已断开')          && document.getElementById('run-state').textContent === '故障'          && /^第 \\d+\\/\\d+ 步：/.test(document.getElementById('progress').textContent)",
    );
    b.screenshot(&shots.join("9b-run-zh.png"));
    let html = b.script_async(
        "const done = arguments[0]; fetch('/api/session').then(r => r.json()).then(s => \
         fetch('/api/runs').then(r => r.json()).then(runs => fetch('/api/runs/' + runs[0].id + '/report/html'))\
         .then(r => r.text()).then(t => done([s.language, t]))).catch(e => done(String(e)));",
    );
    assert_eq!(html[0], "zh-CN", "the choice is the user's now");
    let text = html[1].as_str().unwrap_or_default();
    assert!(
        text.contains("离心机测试报告")
            && text.contains("汇总")
            && text.contains("lang=\"zh-CN\"")
            && text.contains("故障：离心机联锁已断开"),
        "the downloaded report in Chinese"
    );
    // A new page load starts in the user's language.
    b.go(&server.base);
    b.wait_for(
        10,
        "Chinese after a reload",
        "return document.getElementById('nav-history').textContent === '历史'",
    );

    // The fault's banner stays, a reload brings it back,
    // until someone acknowledges it; then it is gone for good, and the audit
    // log says who did.
    b.wait_for(
        10,
        "the fault banner after the reload, with its acknowledge button",
        "const a = document.getElementById('alarm'); return !a.hidden && a.className === 'fault' \
         && a.textContent.startsWith('故障：') && document.getElementById('ack-button').textContent === '确认'",
    );
    b.click("#ack-button");
    b.wait_for(
        10,
        "the banner acknowledged",
        "return document.getElementById('alarm').hidden",
    );
    b.go(&server.base);
    b.wait_for(
        10,
        "the page again",
        "return document.getElementById('nav-history').textContent === '历史'",
    );
    // Two status refreshes (every 2 s) bring back nothing.
    std::thread::sleep(Duration::from_secs(5));
    assert_eq!(
        b.script("return document.getElementById('alarm').hidden"),
        Value::Bool(true),
        "an acknowledged fault stays acknowledged"
    );
    let store = spinbench_store::Store::connect(&spinbench_store::StoreTarget::parse(
        web::store_of(dir.path()).to_str().expect("utf-8"),
    ))
    .expect("the store");
    let audit = store.audit_log(50).expect("audit log");
    assert!(
        audit.iter().any(|a| a.who == "op"
            && a.action == "acknowledge fault"
            && a.detail.contains("interlock")),
        "{audit:?}"
    );
}

/// A notice the station handled (a point measured again)
/// is amber, never in the red error line, and gone once the run completes:
/// the run's outcome takes its place, on every page.
#[test]
fn a_handled_notice_is_no_alarm_once_the_run_completes_in_the_browser() {
    let dir = tempfile::tempdir().expect("tempdir");
    web::add_user(dir.path(), "op", "operator", "op-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    // Every point's temperature moves more than this: each is measured
    // again once (a notice), then taken and flagged.
    let plan = plan().replace(
        "stability = { hold_s = 3 }",
        "stability = { hold_s = 3, max_restarts = 1, temperature_change_max_c = 0.0001 }",
    );
    assert!(plan.contains("temperature_change_max_c"), "{plan}");
    std::fs::write(dir.path().join("plans").join("browser.toml"), plan).expect("plan");
    let server = web::serve(dir.path(), "10");
    let b = Browser::start();
    log_in(&b, &server.base, "op", "op-password");
    b.click("#nav-new");
    b.wait_for(10, "the plans", "return document.querySelectorAll('#plan-select option').length > 0 && !!document.getElementById('serial-2')");
    b.script("const s = document.getElementById('plan-select'); s.value = 'browser'; s.dispatchEvent(new Event('change'));");
    b.click("#start-button");
    let until = Instant::now() + Duration::from_secs(240);
    let mut amber = 0;
    loop {
        let seen = b.script(
            "const a = document.getElementById('alarm'), m = document.getElementById('message'); \
             return [document.getElementById('run-state').textContent, !a.hidden && a.className === 'notice', \
                     !m.hidden && m.textContent.includes('again')]",
        );
        let state = seen[0].as_str().unwrap_or_default().to_string();
        assert!(
            Instant::now() < until,
            "the run did not complete in time: {state}"
        );
        assert_eq!(
            seen[2],
            Value::Bool(false),
            "a handled notice in the red error line"
        );
        amber += usize::from(seen[1] == Value::Bool(true));
        if state.starts_with("completed") {
            break;
        }
        assert!(
            !state.starts_with("faulted") && !state.starts_with("aborted"),
            "{state}"
        );
        if b.script("return !document.getElementById('prompt').hidden") == Value::Bool(true) {
            b.click("#prompt-done");
        }
        std::thread::sleep(Duration::from_millis(300));
    }
    assert!(
        amber > 0,
        "the notices were shown, amber, while the run went on"
    );
    assert!(
        b.script("return document.getElementById('event-log').textContent")
            .as_str()
            .is_some_and(|t| t.contains("measuring the point again")),
        "the event log keeps the notices"
    );
    // The outcome replaces the notice, and stays so as the status refreshes
    // and on the other pages.
    b.wait_for(
        10,
        "the run's outcome in the banner",
        // With the counts of the outcomes, which add up to
        // the board's instruments, coloured by the worst.
        "const a = document.getElementById('alarm'); if (a.hidden || !a.classList.contains('done')) return false; \
         const m = a.textContent.match(/^Run completed — (.*)$/); if (!m) return false; \
         const total = m[1].split(', ').reduce((t, p) => t + parseInt(p, 10), 0); \
         const rows = [...document.querySelectorAll('#board tbody tr')].filter(r => r.cells[1].textContent !== '').length; \
         const worst = ['fail', 'incomplete', 'inconclusive', 'marginal'].find(o => a.textContent.includes(' ' + o)); \
         return total === rows && (!worst || a.classList.contains(worst))",
    );
    std::thread::sleep(Duration::from_secs(5));
    b.click("#nav-history");
    b.wait_for(
        10,
        "the History page with no alarm",
        "const a = document.getElementById('alarm'); return !document.getElementById('history').hidden \
         && a.classList.contains('done') && a.textContent.startsWith('Run completed — ') \
         && !document.getElementById('message').textContent.includes('again')",
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

    // The equipment register: the engineer records the centrifuge's
    // certificate, due last January; the register shows it overdue, and a
    // run is refused until it is calibrated again.
    b.click("#nav-equipment");
    b.wait_for(10, "the register", "return document.querySelectorAll('#equipment-table tbody tr').length >= 3 && !document.getElementById('equipment-form').hidden");
    // The page says that nothing is registered yet, and
    // each device's Register… fills the form with its role (and the
    // identity the station read from it, once it has run).
    b.wait_for(
        10,
        "the unregistered devices said",
        "const n = document.getElementById('equipment-unregistered'); \
         return !n.hidden && n.textContent.includes('not in the register')",
    );
    // Validation after input only: the empty required fields are not red
    // before anyone typed.
    assert_eq!(
        b.script(
            "const c = document.getElementById('eq-certificate'); \
             return [c.required, c.value, getComputedStyle(c).borderTopColor === 'rgb(204, 0, 0)']"
        ),
        serde_json::json!([true, "", false]),
        "an untouched required field is not shown as wrong"
    );
    b.script("document.querySelector('#equipment-table tbody tr[data-role=\"centrifuge\"] button.register').click()");
    assert_eq!(
        b.script("return document.getElementById('eq-role').value"),
        Value::String("centrifuge".into())
    );
    b.script(
        "document.getElementById('eq-role').value = 'centrifuge';\
         document.getElementById('eq-identity').value = 'Acutrol 3000 SN 117';\
         document.getElementById('eq-certificate').value = 'NIM-2026-0042';\
         document.getElementById('eq-calibrated').value = '2025-01-01';\
         document.getElementById('eq-due').value = '2026-01-01';",
    );
    b.click("#eq-save");
    b.wait_for(
        10,
        "the centrifuge overdue",
        "const r = document.querySelector('#equipment-table tbody tr[data-role=\"centrifuge\"]'); return !!r && r.cells[5].textContent === 'overdue'",
    );
    b.screenshot(&shots.join("10-register-overdue.png"));
    b.click("#nav-new");
    b.wait_for(
        10,
        "the serials",
        "const s = document.getElementById('serial-1'); \
         return !document.getElementById('new').hidden && !!s && s.offsetParent !== null",
    );
    assert_eq!(
        b.script("return document.getElementById('override-box').hidden"),
        Value::Bool(true),
        "only an admin is offered the override"
    );
    b.type_into("#serial-1", "REG-1");
    b.click("#start-button");
    b.wait_for(
        10,
        "the refusal naming the device",
        "return document.getElementById('message').textContent.includes('centrifuge (due 2026-01-01, overdue)')",
    );
    b.screenshot(&shots.join("10b-run-refused.png"));
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
