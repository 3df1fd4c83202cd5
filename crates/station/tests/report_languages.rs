//! Acceptance for the reports: a typical-bench run's reports in
//! English and Chinese sit side by side in one folder; the Chinese PDF,
//! HTML and batch report carry no English sentence, caption or axis label
//! (read through poppler's pdftotext and the HTML's text); and the PDF's
//! first page holds what a signer signs: the limit, K2 ± U95 and the
//! verdict of every instrument, the operator's actions and the sign-off
//! block.

mod common;
#[path = "common/english.rs"]
mod english;

use common::spinbench;
use english::english_words;
use spinbench_store::{Store, StoreTarget};
use std::path::Path;
use std::process::Command;

/// The text of `pdf`, page by page (poppler's pdftotext).
fn pdf_pages(pdf: &Path) -> Vec<String> {
    let out = Command::new("pdftotext")
        .args(["-layout"])
        .arg(pdf)
        .arg("-")
        .output()
        .expect("pdftotext (poppler-utils) runs; ./scripts/test installs it");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .expect("utf-8 text")
        .split('\x0c')
        .map(str::to_string)
        .collect()
}

/// `html` without its `open`…`close` blocks.
fn without_blocks(html: &str, open: &str, close: &str) -> String {
    let mut kept = String::new();
    let mut rest = html;
    while let Some(start) = rest.find(open) {
        kept.push_str(&rest[..start]);
        rest = rest[start..]
            .find(close)
            .map_or("", |end| &rest[start + end + close.len()..]);
    }
    kept.push_str(rest);
    kept
}

/// The text a reader sees in an HTML report: no style, script or tags;
/// the SVG plots' text kept.
fn html_text(html: &str) -> String {
    let html = without_blocks(html, "<style", "</style>");
    let html = without_blocks(&html, "<script", "</script>");
    let mut out = String::new();
    let mut in_tag = false;
    for c in html.chars() {
        match c {
            '<' => in_tag = true,
            '>' => {
                in_tag = false;
                out.push(' ');
            }
            _ if !in_tag => out.push(c),
            _ => {}
        }
    }
    out.replace("&amp;", "&")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&#39;", "'")
}

#[test]
fn chinese_reports_carry_no_english_and_page_one_holds_what_a_signer_signs() {
    let dir = tempfile::tempdir().expect("tempdir");
    let data = dir.path().join("data");
    let data_s = data.to_str().expect("utf-8");
    let (ok, out, err) = spinbench(&[
        "demo",
        "--realism",
        "typical",
        "--seed",
        "3",
        "--data",
        data_s,
    ]);
    assert!(ok, "{out}{err}");
    // Progress into a pipe, as into a log file: the lines, no escape codes.
    assert!(err.contains("run Completed"), "{err}");
    assert!(
        !err.contains('\x1b'),
        "escape codes in a redirected stderr: {err:?}"
    );
    let db = data.join("spinbench.db");
    let db_s = db.to_str().expect("utf-8");
    let (ok, listed, err) = spinbench(&["runs", "list", "--db", db_s]);
    assert!(ok, "{err}");
    let run_id = listed
        .split_whitespace()
        .find(|w| w.starts_with("run-"))
        .expect("the demo's run")
        .to_string();

    // Both languages into one folder: eight files, none written over.
    let reports = dir.path().join("reports");
    let reports_s = reports.to_str().expect("utf-8");
    for lang in ["en", "zh-CN"] {
        let (ok, _, err) = spinbench(&[
            "report", &run_id, "--db", db_s, "--out", reports_s, "--lang", lang,
        ]);
        assert!(ok, "{err}");
        let (ok, _, err) = spinbench(&[
            "batch-report",
            "--db",
            db_s,
            "--out",
            reports_s,
            "--lang",
            lang,
        ]);
        assert!(ok, "{err}");
    }
    let files: Vec<String> = std::fs::read_dir(&reports)
        .expect("reports")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    for lang in ["en", "zh-CN"] {
        for ext in ["pdf", "html", "xlsx", "csv"] {
            let run_file = format!("{run_id}-{lang}.{ext}");
            assert!(
                files
                    .iter()
                    .any(|f| f.starts_with("report-") && f.ends_with(&run_file)),
                "{run_file} among {files:?}"
            );
            let batch_file = format!("-{lang}.{ext}");
            assert!(
                files
                    .iter()
                    .any(|f| f.starts_with("batch-report-") && f.ends_with(&batch_file)),
                "batch-report-…{batch_file} among {files:?}"
            );
        }
    }
    let file = |prefix: &str, tail: &str| {
        reports.join(
            files
                .iter()
                .find(|f| f.starts_with(prefix) && f.ends_with(tail))
                .unwrap_or_else(|| panic!("{prefix}…{tail}")),
        )
    };

    // The run's own data, which no language changes.
    let store = Store::connect(&StoreTarget::File(db.clone())).expect("the store");
    let record = store.run_record(&run_id).expect("read").expect("the run");
    let serials: Vec<String> = record.results.iter().map(|r| r.serial.clone()).collect();
    assert_eq!(serials.len(), 12);
    let mut data_words: Vec<String> = vec![
        run_id.clone(),
        record.start.station.clone(),
        record.start.plan.name(),
        record.start.plan.operator(),
    ];
    data_words.extend(serials.iter().cloned());
    data_words.extend(record.devices.iter().map(|d| d.identity.clone()));
    // Who answered the prompts (here the virtual bench's automatic operator).
    data_words.extend(record.operator_actions.iter().map(|a| a.who.clone()));
    // Longest first: a name inside another is taken out after it.
    data_words.sort_by_key(|w| std::cmp::Reverse(w.len()));

    // The first two pages of each report as pictures, for the closing note
    // (poppler's pdftoppm).
    let shots = Path::new(env!("CARGO_TARGET_TMPDIR")).join("issue-40");
    std::fs::create_dir_all(&shots).expect("screenshot dir");
    for (prefix, tail, name) in [
        ("report-", format!("{run_id}-en.pdf"), "report-en"),
        ("report-", format!("{run_id}-zh-CN.pdf"), "report-zh-CN"),
        ("batch-report-", "-en.pdf".to_string(), "batch-en"),
        ("batch-report-", "-zh-CN.pdf".to_string(), "batch-zh-CN"),
    ] {
        let done = Command::new("pdftoppm")
            .args(["-png", "-r", "70", "-f", "1", "-l", "2"])
            .arg(file(prefix, &tail))
            .arg(shots.join(name))
            .status()
            .expect("pdftoppm (poppler-utils) runs");
        assert!(done.success(), "pdftoppm {name}");
    }
    let zh_pdf = pdf_pages(&file("report-", &format!("{run_id}-zh-CN.pdf")));
    let zh_html = html_text(
        &std::fs::read_to_string(file("report-", &format!("{run_id}-zh-CN.html"))).expect("html"),
    );
    let batch_pdf = pdf_pages(&file("batch-report-", "-zh-CN.pdf"));
    let batch_html = html_text(
        &std::fs::read_to_string(file("batch-report-", "-zh-CN.html")).expect("batch html"),
    );
    for (what, text) in [
        ("the zh-CN PDF", zh_pdf.join("\n")),
        ("the zh-CN HTML", zh_html.clone()),
        ("the zh-CN batch PDF", batch_pdf.join("\n")),
        ("the zh-CN batch HTML", batch_html),
    ] {
        let english = english_words(&text, &data_words);
        assert!(
            english.is_empty(),
            "English in {what} ({} words):\n{}",
            english.len(),
            english
                .iter()
                .take(40)
                .cloned()
                .collect::<Vec<_>>()
                .join("\n")
        );
    }

    // The details say each mounting's span of the instruments' temperatures.
    let en_html =
        std::fs::read_to_string(file("report-", &format!("{run_id}-en.html"))).expect("html");
    assert!(
        en_html.contains("instrument temperature (each mounting)") && en_html.contains(" °C"),
        "no temperature spans in the English HTML"
    );
    assert!(
        zh_html.contains("仪表温度（各安装方向）"),
        "no temperature spans in the zh-CN HTML"
    );

    // Page 1 of each language: the limit, K2 ± U95 and the verdict of
    // every instrument, the operator's actions, the sign-off block.
    let en_pdf = pdf_pages(&file("report-", &format!("{run_id}-en.pdf")));
    for (page, limit, words) in [
        (
            &en_pdf[0],
            "limit 20 µg/g²",
            [
                "K2 ± U95",
                "Operator actions",
                "Tested by",
                "Reviewed by",
                "Date",
            ],
        ),
        (
            &zh_pdf[0],
            "限值 20 µg/g²",
            ["K2 ± U95", "操作员操作", "测试人", "审核人", "日期"],
        ),
    ] {
        assert!(page.contains(limit), "{limit} on page 1:\n{page}");
        for w in words {
            assert!(page.contains(w), "{w} on page 1:\n{page}");
        }
        for serial in &serials {
            let row = page
                .lines()
                .find(|l| l.split_whitespace().next() == Some(serial.as_str()))
                .unwrap_or_else(|| panic!("{serial}'s row on page 1:\n{page}"));
            // K2 ± U95: "value ± U" with three decimals each.
            let cells: Vec<&str> = row.split_whitespace().collect();
            let pm = cells
                .iter()
                .position(|c| *c == "±")
                .unwrap_or_else(|| panic!("K2 ± U95 in {row}"));
            assert!(
                cells[pm - 1].parse::<f64>().is_ok() && cells[pm + 1].parse::<f64>().is_ok(),
                "{row}"
            );
        }
        // An action of the run: the operator's answers at the prompts.
        assert!(
            page.contains("went on at the prompt") || page.contains("在提示处继续"),
            "an operator action on page 1:\n{page}"
        );
    }
    // The verdict of each instrument on page 1 is the stored one.
    for r in &record.results {
        let row = en_pdf[0]
            .lines()
            .find(|l| l.split_whitespace().next() == Some(r.serial.as_str()))
            .expect("row");
        assert!(
            row.contains(r.outcome.as_str()),
            "{} {} in {row}",
            r.serial,
            r.outcome
        );
    }
}
