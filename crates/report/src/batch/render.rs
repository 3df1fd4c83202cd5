//! The batch report as CSV, HTML and XLSX (the PDF is `crate::pdf`).

use super::{
    BatchReport, OUTLIER_HEADERS, REPEAT_HEADERS, STATISTICS_HEADERS, TEST_HEADERS, esc,
    histogram_svg, outlier_rows, repeat_rows, statistics_rows, test_numbers, test_rows, unix_date,
};

/// Every test as CSV, numbers at full precision.
pub fn batch_csv(b: &BatchReport) -> String {
    let mut out = TEST_HEADERS.join(",");
    out.push('\n');
    for t in &b.tests {
        let mut cells = vec![
            crate::csv_field(&t.run_id),
            t.started_at.to_string(),
            crate::csv_field(&t.serial),
            t.outcome.as_str().to_string(),
        ];
        cells.extend(
            test_numbers(t)
                .iter()
                .map(|v| v.map_or(String::new(), |v| format!("{v:?}"))),
        );
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

/// The batch report as one self-contained HTML document.
pub fn batch_html(b: &BatchReport) -> String {
    batch_html_in(b, crate::Lang::En)
}

/// The batch report as one HTML document in `lang`.
pub fn batch_html_in(b: &BatchReport, lang: crate::Lang) -> String {
    use crate::lang::{header, tr};
    let heads = |list: &[&str]| -> Vec<String> { list.iter().map(|h| header(lang, h)).collect() };
    let (pass, marginal, fail) = b.outcomes();
    let mut h = String::from(
        "<!DOCTYPE html>\n<html lang=\"LANG\"><head><meta charset=\"utf-8\"><title>TITLE</title>\
         <style>/*CJK*/body{font-family:'Noto Sans','Noto Sans CJK SC','Microsoft YaHei','PingFang SC','spinbench CJK',sans-serif;margin:2em;color:#111}\
         table{border-collapse:collapse;font-size:0.85em;margin-bottom:1em}td,th{border:1px solid #999;padding:2px 6px}\
         th{background:#eee}figure{display:inline-block;margin:0.5em}svg text{font-family:'Noto Sans','Noto Sans CJK SC','Microsoft YaHei','spinbench CJK',sans-serif}</style></head><body>\n",
    )
    .replacen("LANG", lang.code(), 1)
    .replacen("TITLE", &esc(&tr(lang, "batch.title")), 1);
    let serials = b
        .tests
        .iter()
        .map(|t| &t.serial)
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    let totals = rust_i18n::t!(
        "batch.totals",
        runs = b.runs.len(),
        tests = b.tests.len(),
        serials = serials,
        pass = pass,
        marginal = marginal,
        fail = fail,
        locale = lang.code()
    );
    h.push_str(&format!(
        "<h1>{}</h1>\n<p id=\"totals\">{}{}.</p>\n",
        esc(&tr(lang, "batch.title")),
        esc(&totals),
        esc(&b.incomplete_note_in(lang)),
    ));
    h.push_str(&format!(
        "<h2>{}</h2>\n",
        esc(&tr(lang, "batch.distributions"))
    ));
    crate::text::html_table(
        &mut h,
        "statistics",
        &heads(&STATISTICS_HEADERS),
        &statistics_rows(b, lang),
    );
    for svg in b
        .distributions
        .iter()
        .filter_map(|d| histogram_svg(d, lang))
    {
        h.push_str("<figure>");
        h.push_str(&svg);
        h.push_str("</figure>\n");
    }
    crate::control::html_section(&mut h, &b.control, lang);
    for (title, id, list, rows) in [
        (
            "batch.outliers",
            "outliers",
            &OUTLIER_HEADERS[..],
            outlier_rows(b, lang),
        ),
        (
            "batch.repeats",
            "repeats",
            &REPEAT_HEADERS[..],
            repeat_rows(b),
        ),
        (
            "batch.tests",
            "tests",
            &TEST_HEADERS[..],
            test_rows(b, lang),
        ),
    ] {
        h.push_str(&format!("<h2>{}</h2>\n", esc(&tr(lang, title))));
        crate::text::html_table(&mut h, id, &heads(list), &rows);
    }
    h.push_str("</body></html>\n");
    crate::text::with_cjk_font(h)
}

/// The batch report as an XLSX workbook: `tests`, `statistics`, `repeatability`
/// (the sheets keep their machine names; headers and outcomes in `lang`).
pub(crate) fn batch_xlsx(
    b: &BatchReport,
    lang: crate::Lang,
) -> Result<Vec<u8>, rust_xlsxwriter::XlsxError> {
    use crate::lang::header;
    use rust_xlsxwriter::{Format, Workbook};
    let mut book = Workbook::new();
    let bold = Format::new().set_bold();
    {
        let sheet = book.add_worksheet().set_name("tests")?;
        for (c, head) in TEST_HEADERS.iter().enumerate() {
            sheet.write_string_with_format(0, c as u16, header(lang, head), &bold)?;
        }
        for (r, t) in (1u32..).zip(&b.tests) {
            sheet.write_string(r, 0, &t.run_id)?;
            sheet.write_string(r, 1, unix_date(t.started_at))?;
            sheet.write_string(r, 2, &t.serial)?;
            sheet.write_string(r, 3, crate::lang::outcome(lang, t.outcome.as_str()))?;
            for (k, v) in test_numbers(t).iter().enumerate() {
                if let Some(v) = v {
                    sheet.write_number(r, 4 + k as u16, *v)?;
                }
            }
        }
    }
    {
        let sheet = book.add_worksheet().set_name("statistics")?;
        for (c, head) in STATISTICS_HEADERS.iter().enumerate() {
            sheet.write_string_with_format(0, c as u16, header(lang, head), &bold)?;
        }
        for (r, d) in (1u32..).zip(&b.distributions) {
            sheet.write_string(r, 0, d.name)?;
            sheet.write_string(r, 1, d.unit)?;
            sheet.write_number(r, 2, d.n as f64)?;
            for (k, v) in [d.mean, d.std, d.min, d.median, d.max].iter().enumerate() {
                sheet.write_number(r, 3 + k as u16, *v)?;
            }
            sheet.write_number(r, 8, d.outliers.len() as f64)?;
        }
    }
    for (name, headers, rows) in [
        (
            "control flags",
            &crate::control::FLAG_HEADERS[..],
            crate::control::flag_rows(&b.control, lang),
        ),
        (
            "first-pass yield",
            &crate::control::YIELD_HEADERS[..],
            crate::control::yield_rows(&b.control),
        ),
    ] {
        let sheet = book.add_worksheet().set_name(name)?;
        for (c, head) in headers.iter().enumerate() {
            sheet.write_string_with_format(0, c as u16, header(lang, head), &bold)?;
        }
        for (r, row) in (1u32..).zip(&rows) {
            for (c, cell) in row.iter().enumerate() {
                sheet.write_string(r, c as u16, cell)?;
            }
        }
    }
    {
        let sheet = book.add_worksheet().set_name("repeatability")?;
        for (c, head) in REPEAT_HEADERS.iter().enumerate() {
            sheet.write_string_with_format(0, c as u16, header(lang, head), &bold)?;
        }
        for (r, rep) in (1u32..).zip(&b.repeats) {
            sheet.write_string(r, 0, &rep.serial)?;
            sheet.write_number(r, 1, rep.tests as f64)?;
            let values: Vec<String> = rep
                .k2_max_ug_per_g2
                .iter()
                .map(|v| format!("{v}"))
                .collect();
            sheet.write_string(r, 2, values.join(" "))?;
            if let Some(v) = rep.k2_max_spread {
                sheet.write_number(r, 3, v)?;
            }
            if let Some(v) = rep.k1_repeatability_ppm {
                sheet.write_number(r, 4, v)?;
            }
        }
    }
    book.save_to_buffer()
}
