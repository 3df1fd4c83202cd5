//! A run's report as one HTML page.

use crate::{
    Lang, POINT_HEADERS, RunReport, SUMMARY_DECIMALS, SUMMARY_HEADERS, devices,
    diagnostic_lines_in, esc, fmt, lang, meta_rows_in, numbers, plots, point_cells, signer,
    summary_in, tr, with_cjk_font,
};

/// The report as one self-contained HTML document.
pub fn html(report: &RunReport) -> String {
    html_in(report, Lang::En)
}

/// The run's report as one HTML document in `lang`.
pub fn html_in(report: &RunReport, lang: Lang) -> String {
    let run = &report.run;
    let mut h = String::new();
    h.push_str(&format!(
        "<!DOCTYPE html>\n<html lang=\"{}\"><head><meta charset=\"utf-8\">",
        lang.code()
    ));
    h.push_str(&format!(
        "<title>{}</title>",
        esc(&rust_i18n::t!(
            "report.title",
            run = run.label(),
            locale = lang.code()
        ))
    ));
    h.push_str(
        "<style>/*CJK*/body{font-family:'Noto Sans','Noto Sans CJK SC','Microsoft YaHei','PingFang SC','spinbench CJK',sans-serif;margin:2em;color:#111}\
         table{border-collapse:collapse;font-size:0.85em}td,th{border:1px solid #999;padding:2px 6px;text-align:right}\
         th{background:#eee}td.t{text-align:left}.pass{color:#060}.fail{color:#a00;font-weight:bold}.marginal{color:#a60}.inconclusive{color:#1940b3;font-weight:bold}.incomplete{color:#555;font-style:italic}\
         section.unit{page-break-before:always;margin-top:2em}table.sign td{height:3em;width:14em}figure{display:inline-block;margin:0.5em}svg text{font-family:'Noto Sans','Noto Sans CJK SC','Microsoft YaHei','spinbench CJK',sans-serif}</style></head><body>\n",
    );
    h.push_str(&format!(
        "<h1>{}</h1>\n<table class=\"meta\">",
        esc(&rust_i18n::t!(
            "report.title",
            run = run.id,
            locale = lang.code()
        ))
    ));
    for (label, value) in meta_rows_in(report, lang) {
        h.push_str(&format!(
            "<tr><th>{}</th><td class=\"t\" id=\"{label}\">{}</td></tr>",
            esc(&tr(lang, &format!("meta.{label}"))),
            esc(&value)
        ));
    }
    h.push_str("</table>\n");
    if let Some(devices) = devices(report, lang) {
        h.push_str(&format!(
            "<h2>{}</h2><table id=\"equipment\"><tr><th>{}</th><th>{}</th><th>{}</th></tr>",
            esc(&tr(lang, "report.devices")),
            esc(&tr(lang, "report.device")),
            esc(&tr(lang, "report.identity")),
            esc(&tr(lang, "report.calibration"))
        ));
        for (role, identity, calibration) in devices {
            h.push_str(&format!(
                "<tr><td class=\"t\">{}</td><td class=\"t\">{}</td><td class=\"t\">{}</td></tr>",
                esc(&role),
                esc(&identity),
                esc(&calibration)
            ));
        }
        h.push_str("</table>\n");
    }
    signer_section(&mut h, report, lang);
    h.push_str(&format!(
        "<h2>{}</h2>\n<table id=\"summary\"><tr>",
        esc(&tr(lang, "report.summary"))
    ));
    for head in SUMMARY_HEADERS {
        h.push_str(&format!("<th>{}</th>", esc(&lang::header(lang, head))));
    }
    h.push_str("</tr>\n");
    for row in summary_in(report, lang) {
        let n = numbers(&row);
        h.push_str(&format!(
            "<tr data-serial=\"{}\" data-mount=\"{}\"><td class=\"t\">{}</td><td>{}</td><td>{}</td>",
            esc(&row.serial),
            esc(&row.mount),
            esc(&row.serial),
            row.slot,
            esc(&row.mount)
        ));
        for (v, d) in n.iter().zip(SUMMARY_DECIMALS) {
            h.push_str(&format!("<td>{}</td>", fmt(*v, d)));
        }
        h.push_str(&format!(
            "<td class=\"{}\">{}</td><td class=\"t\">{}</td></tr>\n",
            esc(&row.outcome),
            esc(&lang::outcome(lang, &row.outcome)),
            esc(&row.reasons)
        ));
    }
    h.push_str("</table>\n");
    if let Some(signature) = crate::signature::of_run(report) {
        h.push_str(&format!(
            "<section class=\"signature\"><h2>{}</h2>\n<p>{}</p>\n",
            esc(&tr(lang, "signature.heading")),
            esc(&crate::signature::describe(signature, lang))
        ));
        if let Some(svg) = crate::signature::svg(signature, lang) {
            h.push_str("<figure>");
            h.push_str(&svg);
            h.push_str("</figure>\n");
        }
        h.push_str("</section>\n");
    }
    for u in &report.units {
        h.push_str(&format!(
            "<section class=\"unit\"><h2>{} — <span class=\"{}\">{}</span></h2>\n",
            esc(&rust_i18n::t!(
                "report.slot_heading",
                serial = u.result.serial,
                slot = u.result.slot + 1,
                locale = lang.code()
            )),
            esc(u.result.outcome.as_str()),
            esc(&lang::outcome(lang, u.result.outcome.as_str()))
        ));
        for line in diagnostic_lines_in(u, lang) {
            h.push_str(&format!("<p class=\"diagnostics\">{}</p>\n", esc(&line)));
        }
        for svg in plots::UNIT_PLOTS.iter().filter_map(|p| p.svg(u, lang)) {
            h.push_str("<figure>");
            h.push_str(&svg);
            h.push_str("</figure>\n");
        }
        h.push_str("<table class=\"points\"><tr>");
        for head in POINT_HEADERS {
            h.push_str(&format!("<th>{}</th>", esc(&lang::header(lang, head))));
        }
        h.push_str("</tr>\n");
        for p in &u.points {
            h.push_str("<tr>");
            for cell in point_cells(p, lang) {
                h.push_str(&format!("<td>{}</td>", esc(&cell)));
            }
            h.push_str("</tr>\n");
        }
        h.push_str("</table></section>\n");
    }
    h.push_str("</body></html>\n");
    with_cjk_font(h)
}

/// What a signer reads first (`signer`): the decision, one row per
/// instrument, the operator's actions, the station's notices, the sign-off.
fn signer_section(h: &mut String, report: &RunReport, lang: Lang) {
    h.push_str(&format!(
        "<section id=\"signer\"><h2>{}</h2>\n",
        esc(&tr(lang, "report.verdicts"))
    ));
    if let Some(decision) = signer::decision_text(report, lang) {
        h.push_str(&format!("<p id=\"decision\">{}</p>\n", esc(&decision)));
    }
    h.push_str(&format!(
        "<p id=\"tally\">{}</p>\n<table id=\"verdicts\"><tr>",
        esc(&signer::tally_text(report, lang))
    ));
    for head in signer::verdict_headers(lang) {
        h.push_str(&format!("<th>{}</th>", esc(&head)));
    }
    h.push_str("</tr>\n");
    for row in signer::verdict_rows(report, lang) {
        h.push_str(&format!(
            "<tr data-serial=\"{}\"><td class=\"t\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td class=\"{}\">{}</td><td class=\"t\">{}</td></tr>\n",
            esc(&row.serial),
            esc(&row.serial),
            row.slot,
            esc(&row.k2),
            esc(&row.k2_p),
            esc(&row.k2_n),
            esc(row.outcome.as_str()),
            esc(&row.verdict),
            esc(&row.reason)
        ));
    }
    h.push_str("</table>\n");
    let lines = |h: &mut String,
                 id: &str,
                 heading: &str,
                 heads: [&str; 3],
                 rows: Vec<(String, String, String)>| {
        h.push_str(&format!(
            "<h3>{}</h3><table id=\"{id}\"><tr><th>{}</th><th>{}</th><th>{}</th></tr>",
            esc(&tr(lang, heading)),
            esc(&tr(lang, heads[0])),
            esc(&tr(lang, heads[1])),
            esc(&tr(lang, heads[2]))
        ));
        if rows.is_empty() {
            h.push_str(&format!(
                "<tr><td class=\"t\" colspan=\"3\">{}</td></tr>",
                esc(&tr(lang, "report.none"))
            ));
        }
        for (when, who, what) in rows {
            h.push_str(&format!(
                "<tr><td class=\"t\">{}</td><td class=\"t\">{}</td><td class=\"t\">{}</td></tr>",
                esc(&when),
                esc(&who),
                esc(&what)
            ));
        }
        h.push_str("</table>\n");
    };
    lines(
        h,
        "actions",
        "report.actions",
        ["report.when", "report.who", "report.what"],
        signer::action_lines(report, lang),
    );
    lines(
        h,
        "notices",
        "report.notices",
        ["report.when", "report.kind", "report.what"],
        signer::notice_lines(report, lang),
    );
    let [tested, reviewed, date] = signer::sign_off_labels(lang);
    h.push_str(&format!(
        "<table id=\"sign-off\" class=\"sign\"><tr><th>{}</th><th>{}</th><th>{}</th></tr>\
         <tr><td></td><td></td><td></td></tr></table>\n</section>\n",
        esc(&tested),
        esc(&reviewed),
        esc(&date)
    ));
}
