//! A run's report as one HTML page.

use super::*;
use crate::*;

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
    h.push_str(&format!("<title>spinbench report {}</title>", esc(&run.id)));
    h.push_str(
        "<style>body{font-family:'Noto Sans','Noto Sans CJK SC','Microsoft YaHei','PingFang SC',sans-serif;margin:2em;color:#111}\
         table{border-collapse:collapse;font-size:0.85em}td,th{border:1px solid #999;padding:2px 6px;text-align:right}\
         th{background:#eee}td.t{text-align:left}.pass{color:#060}.fail{color:#a00;font-weight:bold}.marginal{color:#a60}.inconclusive{color:#1940b3;font-weight:bold}.incomplete{color:#555;font-style:italic}\
         section.unit{page-break-before:always;margin-top:2em}figure{display:inline-block;margin:0.5em}</style></head><body>\n",
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
        for svg in plots::UNIT_PLOTS.iter().filter_map(|p| p.svg(u)) {
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
    if !report.record.operator_actions.is_empty() {
        h.push_str(
            "<h2>Operator actions</h2><table><tr><th>time</th><th>who</th><th>what</th></tr>",
        );
        for a in &report.record.operator_actions {
            h.push_str(&format!(
                "<tr><td>{}</td><td class=\"t\">{}</td><td class=\"t\">{}</td></tr>",
                unix_date(a.at),
                esc(&a.who),
                esc(&a.action)
            ));
        }
        h.push_str("</table>\n");
    }
    h.push_str("</body></html>\n");
    h
}
