//! Reports of a run, from the store: a PDF (rendered from Rust, vector plots,
//! an embedded font that also covers Chinese), a self-contained HTML file
//! (inline SVG plots, opens offline), an XLSX workbook (results, points, and
//! one sheet of plot data per instrument; numbers as numbers, units in the
//! headers) and CSV (the summary table).
//!
//! Every number comes from the stored records (the same values `spinbench
//! runs show` prints); nothing is recomputed here.

mod batch;
pub mod control;
pub mod diagnostics;
pub mod lang;
mod pdf;
mod plots;

pub use batch::{
    BatchReport, BatchTest, Distribution, Outlier, Repeat, batch_csv, batch_html, batch_html_in,
    gather_batch, render_batch, render_batch_in,
};
pub use pdf::{batch_pdf, pdf, web_font};

pub use diagnostics::{diagnostic_lines, diagnostic_lines_in, temperature_line};
pub use lang::{Lang, tr};
use serde_json::Value;

rust_i18n::i18n!("../../locales", fallback = "en");
use spinbench_store::{PointRow, ResultRow, RunContext, RunRow, Store, StoreError};
use std::path::{Path, PathBuf};

/// A report could not be made; says what and where.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// No such run.
    #[error("no run '{0}' in the store (see `spinbench runs list`)")]
    NoRun(String),
    /// A stored record is not valid JSON.
    #[error("the stored record of {serial} cannot be read: {problem}")]
    Record {
        /// Serial number.
        serial: String,
        /// Why.
        problem: String,
    },
    /// The PDF could not be rendered.
    #[error("cannot render the PDF: {0}")]
    Pdf(String),
    /// The workbook could not be made.
    #[error("cannot make the XLSX workbook: {0}")]
    Xlsx(String),
    /// Writing a file failed.
    #[error("{path}: cannot write: {problem}")]
    Write {
        /// The file.
        path: String,
        /// Why.
        problem: String,
    },
}

/// Report formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReportFormat {
    /// A PDF document.
    Pdf,
    /// A self-contained HTML file.
    Html,
    /// An XLSX workbook.
    Xlsx,
    /// The summary table as CSV.
    Csv,
}

impl ReportFormat {
    /// Every format, as the engine writes them at the end of a run.
    pub const ALL: [ReportFormat; 4] = [
        ReportFormat::Pdf,
        ReportFormat::Html,
        ReportFormat::Xlsx,
        ReportFormat::Csv,
    ];

    /// Parse `pdf`, `html`, `xlsx` or `csv`.
    pub fn parse(text: &str) -> Option<ReportFormat> {
        match text.to_ascii_lowercase().as_str() {
            "pdf" => Some(ReportFormat::Pdf),
            "html" => Some(ReportFormat::Html),
            "xlsx" => Some(ReportFormat::Xlsx),
            "csv" => Some(ReportFormat::Csv),
            _ => None,
        }
    }

    fn extension(self) -> &'static str {
        match self {
            ReportFormat::Pdf => "pdf",
            ReportFormat::Html => "html",
            ReportFormat::Xlsx => "xlsx",
            ReportFormat::Csv => "csv",
        }
    }
}

/// One instrument of a run.
#[derive(Debug, Clone)]
pub struct UnitReport {
    /// The stored result row, with the whole record as the engine wrote it.
    pub result: ResultRow,
    /// The instrument's points, in the order taken.
    pub points: Vec<PointRow>,
}

impl UnitReport {
    /// The instrument's record.
    pub fn record(&self) -> &spinbench_engine::UnitRecord {
        &self.result.record
    }

    /// Its reasons in one line, then any level left out (who, why), so a
    /// result that was reduced without some readings says so wherever it is shown.
    pub fn reasons_text(&self) -> String {
        self.reasons_text_in(Lang::En)
    }

    /// [`UnitReport::reasons_text`] in `lang` (`lang::reason`, `lang::exclusion`).
    pub fn reasons_text_in(&self, lang: Lang) -> String {
        let r = &self.result.record;
        let separator = if lang == Lang::En { "; " } else { "；" };
        r.reasons
            .iter()
            .map(|reason| lang::reason(lang, reason))
            .chain(r.exclusions.iter().map(|e| lang::exclusion(lang, e)))
            .collect::<Vec<_>>()
            .join(separator)
    }
}

/// Everything a run's report shows.
#[derive(Debug, Clone)]
pub struct RunReport {
    /// The run.
    pub run: RunRow,
    /// Station config, devices, plan, operator actions.
    pub context: RunContext,
    /// Every instrument, in slot order.
    pub units: Vec<UnitReport>,
    /// The runs that retest this one (`spinbench retest`), oldest first.
    pub retested_by: Vec<String>,
}

/// Read a run's report data from the store.
pub fn gather(store: &Store, run_id: &str) -> Result<RunReport, ReportError> {
    let run = store
        .run(run_id)?
        .ok_or_else(|| ReportError::NoRun(run_id.to_string()))?;
    let context = store.run_context(run_id)?.unwrap_or_default();
    let points = store.points(run_id)?;
    let mut units = Vec::new();
    for result in store.results(run_id)? {
        let own = points
            .iter()
            .filter(|p| p.slot == result.slot)
            .cloned()
            .collect();
        units.push(UnitReport {
            result,
            points: own,
        });
    }
    let retested_by = store.retests_of(run_id)?;
    Ok(RunReport {
        run,
        context,
        units,
        retested_by,
    })
}

/// One row of the summary table.
#[derive(Debug, Clone, PartialEq)]
pub struct SummaryRow {
    /// Serial number.
    pub serial: String,
    /// Slot (1-based).
    pub slot: i64,
    /// P or N.
    pub mount: String,
    /// Radius found [m].
    pub radius_m: Option<f64>,
    /// Drawing radius R0 [m].
    pub drawing_radius_m: Option<f64>,
    /// k0 [g].
    pub k0_g: Option<f64>,
    /// k1 [Hz/g].
    pub k1_hz_per_g: Option<f64>,
    /// k2 [µg/g²].
    pub k2_ug_per_g2: Option<f64>,
    /// Half-width of k2's 95 % interval from the fit alone (Type A) [µg/g²].
    pub k2_ci95_half_ug_per_g2: Option<f64>,
    /// k2's expanded uncertainty at 95 % from its GUM budget (Type A and B),
    /// the one the guarded decision uses [µg/g²].
    pub k2_u95_ug_per_g2: Option<f64>,
    /// k3 [µg/g³].
    pub k3_ug_per_g3: Option<f64>,
    /// k2_max of the instrument [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// Scale-factor nonlinearity: the largest residual of (11) [ppm].
    pub sf_nonlinearity_ppm: Option<f64>,
    /// Asymmetry [ppm].
    pub asymmetry_ppm: Option<f64>,
    /// Hysteresis [µg].
    pub hysteresis_ug: Option<f64>,
    /// pass, marginal or fail.
    pub outcome: String,
    /// Why, when not a plain pass.
    pub reasons: String,
}

/// The summary rows: one per instrument and mounting measured.
pub fn summary(report: &RunReport) -> Vec<SummaryRow> {
    summary_in(report, Lang::En)
}

/// The summary rows with their reasons in `lang`.
pub fn summary_in(report: &RunReport, lang: Lang) -> Vec<SummaryRow> {
    let mut rows = Vec::new();
    for u in &report.units {
        let r = u.record();
        let analysis = r.analysis.as_ref();
        let fits: Vec<Option<(&spinbench_analysis::Mount, &spinbench_analysis::MountingFit)>> =
            match analysis.map(|a| &a.fits) {
                Some(fits) if !fits.is_empty() => fits.iter().map(Some).collect(),
                _ => vec![None],
            };
        for entry in fits {
            let mount = entry.map(|(m, _)| *m);
            let fit = entry.map(|(_, f)| &f.fit);
            rows.push(SummaryRow {
                serial: u.result.serial.clone(),
                slot: u.result.slot + 1,
                mount: mount.map(|m| m.to_string()).unwrap_or_default(),
                radius_m: mount.and_then(|m| r.radius_m.get(&m).copied()),
                drawing_radius_m: Some(r.drawing_radius_m),
                k0_g: fit.map(|f| f.k0_g),
                k1_hz_per_g: fit.map(|f| f.k1),
                k2_ug_per_g2: fit.and_then(|f| f.k2_ug_per_g2),
                k2_ci95_half_ug_per_g2: fit
                    .and_then(|f| f.ci95.k2_ug_per_g2)
                    .map(|[a, b]| (b - a) / 2.0),
                k2_u95_ug_per_g2: entry
                    .and_then(|(_, f)| f.uncertainty.as_ref())
                    .and_then(|u| u.k2_ug_per_g2.as_ref())
                    .map(|u| u.u95),
                k3_ug_per_g3: fit.and_then(|f| f.k3_ug_per_g3),
                k2_max_ug_per_g2: u.result.k2_max_ug_per_g2,
                sf_nonlinearity_ppm: analysis
                    .and_then(|a| a.scale_factor.as_ref())
                    .map(|s| s.residual_max_ppm),
                asymmetry_ppm: analysis.and_then(|a| a.figures.asymmetry_ppm),
                hysteresis_ug: analysis.and_then(|a| a.figures.hysteresis_ug),
                outcome: u.result.outcome.to_string(),
                reasons: u.reasons_text_in(lang),
            });
        }
    }
    rows
}

/// The summary table's columns, with units.
pub const SUMMARY_HEADERS: [&str; 16] = [
    "serial",
    "slot",
    "mount",
    "radius [m]",
    "R0 [m]",
    "k0 [g]",
    "k1 [Hz/g]",
    "k2 [µg/g²]",
    "k2 ±95% [µg/g²]",
    "k3 [µg/g³]",
    "k2_max [µg/g²]",
    "SF nonlinearity [ppm]",
    "asymmetry [ppm]",
    "hysteresis [µg]",
    "outcome",
    "reasons",
];

/// Decimals shown for the summary's numbers (HTML and PDF), in [`numbers`] order.
const SUMMARY_DECIMALS: [usize; 11] = [6, 3, 6, 6, 3, 3, 3, 3, 1, 1, 1];

/// The point table's columns (HTML and PDF).
const POINT_HEADERS: [&str; 10] = [
    "step",
    "mount",
    "level [g]",
    "direction",
    "applied [g]",
    "rate [deg/s]",
    "output [Hz]",
    "σ [Hz]",
    "n",
    "T [°C]",
];

/// One row of the point table, as shown.
fn point_cells(p: &PointRow, lang: Lang) -> [String; 10] {
    let direction = lang::tr_or(
        lang,
        &format!("arg.direction.{}", p.direction),
        &p.direction,
    );
    [
        p.step.to_string(),
        p.mount.clone(),
        p.g_nominal.to_string(),
        direction,
        format!("{:.6}", p.g_applied),
        format!("{:.4}", p.rate_deg_s),
        format!("{:.6}", p.output_hz),
        format!("{:.6}", p.std_hz),
        p.n.to_string(),
        p.temperature_c
            .map_or("—".to_string(), |t| format!("{t:.2}")),
    ]
}

/// The run's header block: (label — the catalogue's `meta.` key — and its
/// value, dates as `lang` writes them).
fn meta_rows_in(report: &RunReport, lang: Lang) -> Vec<(&'static str, String)> {
    let run = &report.run;
    let plan: Value = serde_json::from_str(&report.context.plan_json).unwrap_or_default();
    let mut rows = vec![("station", run.station.clone())];
    if let Some(original) = &run.retest_of {
        rows.push((
            "retest of",
            rust_i18n::t!("report.retest_of", run = original, locale = lang.code()).into_owned(),
        ));
    }
    if !report.retested_by.is_empty() {
        let runs: Vec<String> = report
            .retested_by
            .iter()
            .map(|id| rust_i18n::t!("report.run", run = id, locale = lang.code()).into_owned())
            .collect();
        rows.push(("retested by", runs.join(&tr(lang, "report.list_separator"))));
    }
    rows.extend([
        (
            "operator",
            plan["operator"].as_str().unwrap_or("").to_string(),
        ),
        ("started", lang::date_time(lang, run.started_at)),
        (
            "state",
            match (lang, &run.reason) {
                // English: the state and the reason as recorded.
                (Lang::En, Some(r)) => format!("{}: {r}", run.state),
                (Lang::En, None) => run.state.clone(),
                (_, Some(r)) => format!(
                    "{}：{}",
                    lang::state(lang, &run.state),
                    run.reason_wording
                        .as_ref()
                        .and_then(|w| lang::say(lang, w))
                        .unwrap_or_else(|| r.clone())
                ),
                (_, None) => lang::state(lang, &run.state),
            },
        ),
        ("plan", plan["name"].as_str().unwrap_or("").to_string()),
        (
            "decision rule",
            // Plans made before the rule was recorded were judged by value alone.
            match serde_json::from_value::<spinbench_engine::plan::DecisionRule>(
                plan["limits"]["decision_rule"].clone(),
            ) {
                Ok(rule) => lang::decision_rule(lang, rule),
                Err(_) => lang::decision_rule(lang, spinbench_engine::plan::DecisionRule::Simple),
            },
        ),
        (
            "software",
            format!("spinbench {}", report.context.software_version),
        ),
    ]);
    rows
}

/// The station's devices, their identities and calibration as the run
/// recorded them: (role, identity, calibration — "certificate C, due D
/// (status)", "not in the register", or empty for runs before the register).
pub(crate) fn devices(report: &RunReport, lang: Lang) -> Option<Vec<(String, String, String)>> {
    let devices: Vec<Value> = serde_json::from_str(report.context.devices_json.as_deref()?).ok()?;
    let text = |d: &Value, key: &str| d[key].as_str().unwrap_or("").to_string();
    Some(
        devices
            .iter()
            .map(|d| {
                let status = |s: &str| {
                    lang::tr_or(
                        lang,
                        &format!("calibration_status.{}", s.replace(' ', "_")),
                        s,
                    )
                };
                let calibration = match (d["certificate"].as_str(), d["calibration"].as_str()) {
                    (Some(cert), Some(s)) => rust_i18n::t!(
                        "report.certificate_due",
                        certificate = cert,
                        due = text(d, "due_on"),
                        status = status(s),
                        locale = lang.code()
                    )
                    .into_owned(),
                    (None, Some(s)) => status(s),
                    _ => String::new(),
                };
                (
                    lang::device_role(lang, &text(d, "role")),
                    text(d, "identity"),
                    calibration,
                )
            })
            .collect(),
    )
}

fn numbers(row: &SummaryRow) -> [Option<f64>; 11] {
    [
        row.radius_m,
        row.drawing_radius_m,
        row.k0_g,
        row.k1_hz_per_g,
        row.k2_ug_per_g2,
        // The ±95 % shown is the one the decision uses: the GUM U95 where
        // there is a budget, else the fit's interval.
        row.k2_u95_ug_per_g2.or(row.k2_ci95_half_ug_per_g2),
        row.k3_ug_per_g3,
        row.k2_max_ug_per_g2,
        row.sf_nonlinearity_ppm,
        row.asymmetry_ppm,
        row.hysteresis_ug,
    ]
}

fn csv_field(s: &str) -> String {
    spinbench_store::csv_text_field(s)
}

/// The summary table as CSV (full precision: `{:?}` reads back to the same number).
pub fn summary_csv(report: &RunReport) -> String {
    let mut out = SUMMARY_HEADERS.join(",");
    out.push('\n');
    for row in summary(report) {
        let mut cells = vec![
            csv_field(&row.serial),
            row.slot.to_string(),
            row.mount.clone(),
        ];
        cells.extend(
            numbers(&row)
                .iter()
                .map(|v| v.map_or(String::new(), |v| format!("{v:?}"))),
        );
        cells.push(row.outcome.clone());
        cells.push(csv_field(&row.reasons));
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

/// Escape text for HTML. Five replacements: no crate needed for this.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&#39;")
}

fn fmt(v: Option<f64>, decimals: usize) -> String {
    v.map_or("—".into(), |v| format!("{v:.decimals$}"))
}

fn unix_date(t: i64) -> String {
    let secs = t.rem_euclid(86_400);
    format!(
        "{} {:02}:{:02} UTC",
        spinbench_store::equipment::civil_date(t),
        secs / 3600,
        secs % 3600 / 60
    )
}

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
    if !report.context.operator_actions.is_empty() {
        h.push_str(
            "<h2>Operator actions</h2><table><tr><th>time</th><th>who</th><th>what</th></tr>",
        );
        for (t, who, what) in &report.context.operator_actions {
            h.push_str(&format!(
                "<tr><td>{}</td><td class=\"t\">{}</td><td class=\"t\">{}</td></tr>",
                unix_date(*t),
                esc(who),
                esc(what)
            ));
        }
        h.push_str("</table>\n");
    }
    h.push_str("</body></html>\n");
    h
}

/// The report as an XLSX workbook: `results` (the summary), `points`, and
/// one sheet per instrument with its plot data.
fn xlsx_in(report: &RunReport, lang: Lang) -> Result<Vec<u8>, rust_xlsxwriter::XlsxError> {
    use rust_xlsxwriter::{Format, Workbook};
    let mut book = Workbook::new();
    let bold = Format::new().set_bold();
    {
        let sheet = book.add_worksheet().set_name("results")?;
        for (c, head) in SUMMARY_HEADERS.iter().enumerate() {
            sheet.write_string_with_format(0, c as u16, lang::header(lang, head), &bold)?;
        }
        for (i, row) in summary_in(report, lang).iter().enumerate() {
            let r = (i + 1) as u32;
            sheet.write_string(r, 0, &row.serial)?;
            sheet.write_number(r, 1, row.slot as f64)?;
            sheet.write_string(r, 2, &row.mount)?;
            for (k, v) in numbers(row).iter().enumerate() {
                if let Some(v) = v {
                    sheet.write_number(r, 3 + k as u16, *v)?;
                }
            }
            sheet.write_string(r, 14, lang::outcome(lang, &row.outcome))?;
            sheet.write_string(r, 15, &row.reasons)?;
        }
    }
    // The point table's columns, after the serial number.
    let point_headers: Vec<&str> = std::iter::once("serial").chain(POINT_HEADERS).collect();
    {
        let sheet = book.add_worksheet().set_name("points")?;
        for (c, head) in point_headers.iter().enumerate() {
            sheet.write_string_with_format(0, c as u16, lang::header(lang, head), &bold)?;
        }
        let mut r = 1u32;
        for u in &report.units {
            for p in &u.points {
                sheet.write_string(r, 0, &u.result.serial)?;
                sheet.write_number(r, 1, p.step as f64)?;
                sheet.write_string(r, 2, &p.mount)?;
                sheet.write_number(r, 3, p.g_nominal)?;
                sheet.write_string(r, 4, &p.direction)?;
                sheet.write_number(r, 5, p.g_applied)?;
                sheet.write_number(r, 6, p.rate_deg_s)?;
                sheet.write_number(r, 7, p.output_hz)?;
                sheet.write_number(r, 8, p.std_hz)?;
                sheet.write_number(r, 9, p.n as f64)?;
                if let Some(t) = p.temperature_c {
                    sheet.write_number(r, 10, t)?;
                }
                r += 1;
            }
        }
    }
    {
        // The run's header block, as the PDF and HTML covers give it.
        let sheet = book.add_worksheet().set_name("run")?;
        sheet.write_string(0, 0, "run")?;
        sheet.write_string(0, 1, &report.run.id)?;
        let meta = meta_rows_in(report, lang);
        for (r, (label, value)) in meta.iter().enumerate() {
            sheet.write_string_with_format(
                r as u32 + 1,
                0,
                tr(lang, &format!("meta.{label}")),
                &bold,
            )?;
            sheet.write_string(r as u32 + 1, 1, value)?;
        }
        // The station's devices with their calibration.
        let mut r = meta.len() as u32 + 2;
        for (c, head) in ["report.device", "report.identity", "report.calibration"]
            .iter()
            .enumerate()
        {
            sheet.write_string_with_format(r, c as u16, tr(lang, head), &bold)?;
        }
        for (role, identity, calibration) in devices(report, lang).unwrap_or_default() {
            r += 1;
            sheet.write_string(r, 0, &role)?;
            sheet.write_string(r, 1, &identity)?;
            sheet.write_string(r, 2, &calibration)?;
        }
    }
    for u in &report.units {
        // Sheet names: at most 31 characters, none of []:*?/\ .
        let name: String = format!("{} s{}", u.result.serial, u.result.slot + 1)
            .chars()
            .map(|c| if "[]:*?/\\".contains(c) { '_' } else { c })
            .take(31)
            .collect();
        let sheet = book.add_worksheet().set_name(&name)?;
        let heads = [
            "mount",
            "level [g]",
            "input [g]",
            "direction",
            "output [Hz]",
            "residual [µg]",
        ];
        for (c, head) in heads.iter().enumerate() {
            sheet.write_string_with_format(0, c as u16, *head, &bold)?;
        }
        for (r, res) in (1u32..).zip(plots::residuals(u)) {
            sheet.write_string(r, 0, &res.mount)?;
            sheet.write_number(r, 1, res.g_nominal)?;
            sheet.write_number(r, 2, res.g_input)?;
            sheet.write_string(r, 3, &res.direction)?;
            sheet.write_number(r, 4, res.output)?;
            sheet.write_number(r, 5, res.residual_ug)?;
        }
    }
    book.save_to_buffer()
}

/// The run's report in one format, as bytes (for a download).
pub fn render(report: &RunReport, format: ReportFormat) -> Result<Vec<u8>, ReportError> {
    render_in(report, format, Lang::En)
}

/// The run's report in one format and language, as bytes (the CSV's
/// headers are machine names in every language).
pub fn render_in(
    report: &RunReport,
    format: ReportFormat,
    lang: Lang,
) -> Result<Vec<u8>, ReportError> {
    match format {
        ReportFormat::Pdf => pdf::pdf_in(report, lang),
        ReportFormat::Html => Ok(html_in(report, lang).into_bytes()),
        ReportFormat::Csv => Ok(summary_csv(report).into_bytes()),
        ReportFormat::Xlsx => xlsx_in(report, lang).map_err(|e| ReportError::Xlsx(e.to_string())),
    }
}

impl ReportFormat {
    /// The MIME type of the format.
    pub fn mime(self) -> &'static str {
        match self {
            ReportFormat::Pdf => "application/pdf",
            ReportFormat::Html => "text/html; charset=utf-8",
            ReportFormat::Xlsx => {
                "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet"
            }
            ReportFormat::Csv => "text/csv; charset=utf-8",
        }
    }

    /// The file name extension of the format.
    pub fn ext(self) -> &'static str {
        self.extension()
    }
}

/// Write the run's report in each format into `dir` (created if needed);
/// returns the files written (`report-<run>.<ext>`).
pub fn write_reports(
    store: &Store,
    run_id: &str,
    formats: &[ReportFormat],
    dir: &Path,
) -> Result<Vec<PathBuf>, ReportError> {
    write_reports_in(store, run_id, formats, dir, Lang::En)
}

/// As [`write_reports`], in `lang`.
pub fn write_reports_in(
    store: &Store,
    run_id: &str,
    formats: &[ReportFormat],
    dir: &Path,
    lang: Lang,
) -> Result<Vec<PathBuf>, ReportError> {
    let report = gather(store, run_id)?;
    write_files(dir, &format!("report-{run_id}"), formats, |f| {
        render_in(&report, f, lang)
    })
}

/// Write the batch report of `run_ids` (every run when empty) in each
/// format into `dir`; returns the files written (`batch-report.<ext>`).
pub fn write_batch_reports(
    store: &Store,
    run_ids: &[String],
    baseline_runs: usize,
    formats: &[ReportFormat],
    dir: &Path,
    lang: Lang,
) -> Result<Vec<PathBuf>, ReportError> {
    let mut batch = gather_batch(store, run_ids)?;
    batch.rebaseline(baseline_runs);
    write_files(dir, "batch-report", formats, |f| {
        batch::render_batch_in(&batch, f, lang)
    })
}

/// `dir/<stem>.<ext>` for each format, from `render`.
fn write_files(
    dir: &Path,
    stem: &str,
    formats: &[ReportFormat],
    render: impl Fn(ReportFormat) -> Result<Vec<u8>, ReportError>,
) -> Result<Vec<PathBuf>, ReportError> {
    let failed = |path: &Path, e: std::io::Error| ReportError::Write {
        path: path.display().to_string(),
        problem: e.to_string(),
    };
    std::fs::create_dir_all(dir).map_err(|e| failed(dir, e))?;
    let mut written = Vec::new();
    for &format in formats {
        let path = dir.join(format!("{stem}.{}", format.extension()));
        std::fs::write(&path, render(format)?).map_err(|e| failed(&path, e))?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn html_text_is_escaped_and_dates_are_civil() {
        assert_eq!(esc("<a&'\">"), "&lt;a&amp;&#39;&quot;&gt;");
        assert_eq!(unix_date(0), "1970-01-01 00:00 UTC");
        assert_eq!(unix_date(1_795_277_084), "2026-11-21 16:04 UTC");
        assert_eq!(unix_date(951_782_400), "2000-02-29 00:00 UTC");
    }
}
