//! The PDF's first page: what a signer signs. The run's
//! identity beside the station's equipment with its due dates, the
//! decision, one row per instrument (K2 ± U95, each mounting's k2 ± U95,
//! verdict, one reason), the operator's actions and the station's notices
//! (the first few; all on the last page), and the sign-off block.

use super::{Align, Canvas, FOOTER_MM, Lang, MARGIN_MM, PAGE_H_MM, PAGE_W_MM, RunReport, tr};
use crate::signer;

/// Lines of actions or notices shown on the first page; the rest are on
/// the last page (every one of them).
const FIRST_PAGE_LINES: usize = 6;
/// Height of the sign-off block [mm].
const SIGN_OFF_MM: f32 = 17.0;

/// Lay out the first page; returns whether any action or notice was left
/// for the last page.
pub(super) fn signer_page(c: &mut Canvas, report: &RunReport, lang: Lang) -> bool {
    let run = &report.run;
    c.new_page();
    let width = PAGE_W_MM - 2.0 * MARGIN_MM;
    let mut y = MARGIN_MM + 6.0;
    c.text(
        MARGIN_MM,
        y,
        15.0,
        &rust_i18n::t!("report.title", run = run.label(), locale = lang.code()),
        Align::Left,
    );
    y += 7.0;
    // The run on the left, the equipment on the right.
    let (left_y, right_x) = (y, MARGIN_MM + width * 0.42);
    let mut yl = left_y;
    for (label, value) in signer::identity_rows(report, lang) {
        c.text(MARGIN_MM, yl, 8.0, &label, Align::Left);
        for line in c.wrap(&value, 8.0, width * 0.42 - 30.0) {
            c.text(MARGIN_MM + 24.0, yl, 8.0, &line, Align::Left);
            yl += 3.8;
        }
    }
    let mut yr = left_y;
    if let Some(devices) = crate::devices(report, lang) {
        c.text(right_x, yr, 9.0, &tr(lang, "report.devices"), Align::Left);
        yr += 4.2;
        let right_w = PAGE_W_MM - MARGIN_MM - right_x;
        for (role, identity, calibration) in devices {
            c.text(right_x, yr, 7.5, &role, Align::Left);
            let ident = c.wrap(&identity, 7.5, right_w * 0.45 - 29.0);
            let cal = c.wrap(&calibration, 7.5, right_w * 0.55);
            for (k, line) in ident.iter().enumerate() {
                c.text(right_x + 27.0, yr + k as f32 * 3.4, 7.5, line, Align::Left);
            }
            for (k, line) in cal.iter().enumerate() {
                c.text(
                    right_x + right_w * 0.45,
                    yr + k as f32 * 3.4,
                    7.5,
                    line,
                    Align::Left,
                );
            }
            yr += 3.4 * ident.len().max(cal.len()).max(1) as f32;
        }
    }
    y = yl.max(yr) + 3.0;
    c.text(
        MARGIN_MM,
        y,
        11.0,
        &tr(lang, "report.verdicts"),
        Align::Left,
    );
    y += 4.6;
    if let Some(decision) = signer::decision_text(report, lang) {
        for line in c.wrap(&decision, 8.0, width) {
            c.text(MARGIN_MM, y, 8.0, &line, Align::Left);
            y += 3.8;
        }
    }
    c.text(
        MARGIN_MM,
        y,
        8.5,
        &signer::tally_text(report, lang),
        Align::Left,
    );
    y += 1.5;
    let rows: Vec<Vec<String>> = signer::verdict_rows(report, lang)
        .into_iter()
        .map(|r| {
            vec![
                r.serial,
                r.slot.to_string(),
                r.k2,
                r.k2_p,
                r.k2_n,
                r.verdict,
                r.reason,
            ]
        })
        .collect();
    // The next heading's baseline below the table's last row, clear of it.
    y = c.table(y, &signer::verdict_headers(lang), &rows, 7.5, 1) + 5.5;
    let mut left_over = false;
    let actions: Vec<_> = signer::action_lines(report, lang);
    let notices: Vec<_> = signer::notice_lines(report, lang);
    for (heading, lines) in [("report.actions", &actions), ("report.notices", &notices)] {
        y = room(c, y, 12.0);
        c.text(MARGIN_MM, y, 9.5, &tr(lang, heading), Align::Left);
        y += 4.0;
        if lines.is_empty() {
            c.text(MARGIN_MM, y, 7.5, &tr(lang, "report.none"), Align::Left);
            y += 3.6;
        }
        for (when, who, what) in lines.iter().take(FIRST_PAGE_LINES) {
            y = room(c, y, 4.0);
            c.text(MARGIN_MM, y, 7.5, when, Align::Left);
            c.text(MARGIN_MM + 36.0, y, 7.5, who, Align::Left);
            for line in c.wrap(what, 7.5, width - 76.0) {
                c.text(MARGIN_MM + 76.0, y, 7.5, &line, Align::Left);
                y += 3.4;
            }
        }
        if lines.len() > FIRST_PAGE_LINES {
            left_over = true;
            c.text(
                MARGIN_MM,
                y,
                7.5,
                &rust_i18n::t!(
                    "report.more_on_last_page",
                    n = lines.len() - FIRST_PAGE_LINES,
                    locale = lang.code()
                ),
                Align::Left,
            );
            y += 3.6;
        }
        y += 1.5;
    }
    // The sign-off block: at the foot of the page when there is room below.
    let last_y = PAGE_H_MM - MARGIN_MM - FOOTER_MM;
    let top = if y + SIGN_OFF_MM <= last_y {
        last_y - SIGN_OFF_MM
    } else {
        c.new_page();
        MARGIN_MM
    };
    let labels = signer::sign_off_labels(lang);
    let box_w = (width - 2.0 * 6.0) / 3.0;
    for (k, label) in labels.iter().enumerate() {
        let x = MARGIN_MM + k as f32 * (box_w + 6.0);
        c.text(x, top + 4.0, 8.5, label, Align::Left);
        c.rule(x, x + box_w, top + SIGN_OFF_MM - 2.0, 0.6);
    }
    left_over
}

/// `y`, or the top of a new page when less than `need_mm` is left above
/// the sign-off block's room.
fn room(c: &mut Canvas, y: f32, need_mm: f32) -> f32 {
    if y + need_mm > PAGE_H_MM - MARGIN_MM - FOOTER_MM - SIGN_OFF_MM {
        c.new_page();
        MARGIN_MM + 4.0
    } else {
        y
    }
}

/// The last page: every operator action and every notice of the run.
pub(super) fn actions_page(c: &mut Canvas, report: &RunReport, lang: Lang) {
    c.new_page();
    let mut y = MARGIN_MM + 5.0;
    for (heading, lines) in [
        ("report.actions", signer::action_lines(report, lang)),
        ("report.notices", signer::notice_lines(report, lang)),
    ] {
        let rows: Vec<Vec<String>> = lines.into_iter().map(|(a, b, c)| vec![a, b, c]).collect();
        c.text(MARGIN_MM, y, 11.0, &tr(lang, heading), Align::Left);
        let heads = if heading == "report.actions" {
            ["report.when", "report.who", "report.what"]
        } else {
            ["report.when", "report.kind", "report.what"]
        }
        .map(|k| tr(lang, k));
        y = c.table(y + 1.0, &heads, &rows, 7.0, 1) + 6.0;
    }
}
