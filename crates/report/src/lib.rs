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
mod run;
pub mod signature;
mod text;

pub use batch::{
    BatchReport, BatchTest, Distribution, Outlier, Repeat, batch_csv, batch_html, batch_html_in,
    batch_of, gather_batch, newest_batch,
};
pub use pdf::{batch_pdf, pdf, web_font};
pub use run::{
    DECISION_HEADERS, RunReport, SUMMARY_HEADERS, SummaryRow, UnitReport, gather, html, html_in,
    signer, summary, summary_csv, summary_in,
};
pub(crate) use run::{
    POINT_HEADERS, SUMMARY_DECIMALS, meta_rows_in, numbers, point_cells, xlsx_in,
};
pub(crate) use text::{csv_field, esc, fmt, unix_date, unix_date_in, with_cjk_font};

pub use diagnostics::{diagnostic_lines, diagnostic_lines_in, temperature_line};
pub use lang::{Lang, tr};

rust_i18n::i18n!("../../locales", fallback = "en");
use spinbench_store::{Store, StoreError};
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

/// The station's devices, their identities and calibration as the run
/// recorded them: (role, identity, calibration — "certificate C, due D
/// (status)", "not in the register", or empty for runs before the register).
pub(crate) fn devices(report: &RunReport, lang: Lang) -> Option<Vec<(String, String, String)>> {
    let devices = &report.record.devices;
    if devices.is_empty() {
        return None;
    }
    Some(
        devices
            .iter()
            .map(|d| {
                let status = |s: spinbench_store::equipment::CalibrationStatus| {
                    let s = s.as_str();
                    lang::tr_or(
                        lang,
                        &format!("calibration_status.{}", s.replace(' ', "_")),
                        s,
                    )
                };
                let calibration = match (&d.certificate, d.calibration) {
                    (Some(cert), Some(s)) => rust_i18n::t!(
                        "report.certificate_due",
                        certificate = cert,
                        due = d.due_on.as_deref().unwrap_or_default(),
                        status = status(s),
                        locale = lang.code()
                    )
                    .into_owned(),
                    (None, Some(s)) => status(s),
                    _ => String::new(),
                };
                (
                    lang::device_role(lang, d.role),
                    d.identity.clone(),
                    calibration,
                )
            })
            .collect(),
    )
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
/// returns the files written (`<report_file_stem>.<ext>`).
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
    write_files(dir, &report_file_stem_in(&report.run, lang), formats, |f| {
        render_in(&report, f, lang)
    })
}

/// As [`report_file_stem`], with the language (`…-en`, `…-zh-CN`): a
/// run's reports in two languages sit side by side in one folder.
pub fn report_file_stem_in(run: &spinbench_store::RunRow, lang: Lang) -> String {
    format!("{}-{}", report_file_stem(run), lang.code())
}

/// The batch report's file name without its extension: `batch-report-`,
/// its runs (the one run's label; or how many, the first's and the last's
/// labels), then the language, so batch reports of other runs or another
/// language do not write over each other.
pub fn batch_file_stem(batch: &BatchReport, lang: Lang) -> String {
    let part = |r: &spinbench_store::RunRow| r.label_file_part().unwrap_or_else(|| r.id.clone());
    let runs = match batch.runs.as_slice() {
        [] => "no-runs".to_string(),
        [only] => part(only),
        [first, .., last] => format!("{}-runs-{}--{}", batch.runs.len(), part(first), part(last)),
    };
    format!("batch-report-{runs}-{}", lang.code())
}

/// A run report's file name without its extension: `report-`, the run's
/// label as a file-name part, then its id
/// (`report-2026-11-24_station-1_7-run-1795561294-193cfe02a89e`), so the
/// files sort by day and are found by either; `report-<id>` for a run
/// stored before labels were given.
pub fn report_file_stem(run: &spinbench_store::RunRow) -> String {
    match run.label_file_part() {
        Some(label) => format!("report-{label}-{}", run.id),
        None => format!("report-{}", run.id),
    }
}

/// Write the batch report of `run_ids` (every run when empty) in each
/// format into `dir`; returns the files written ([`batch_file_stem`]`.<ext>`).
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
    write_files(dir, &batch_file_stem(&batch, lang), formats, |f| {
        render_batch_in(&batch, f, lang)
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

/// The batch report in one format, as bytes.
pub fn render_batch(b: &BatchReport, format: crate::ReportFormat) -> Result<Vec<u8>, ReportError> {
    render_batch_in(b, format, crate::Lang::En)
}

/// The batch report in one format and language, as bytes (the CSV's
/// headers are machine names, in every language).
pub fn render_batch_in(
    b: &BatchReport,
    format: crate::ReportFormat,
    lang: crate::Lang,
) -> Result<Vec<u8>, ReportError> {
    use crate::ReportFormat;
    match format {
        ReportFormat::Pdf => pdf::batch_pdf_in(b, lang),
        ReportFormat::Html => Ok(batch::batch_html_in(b, lang).into_bytes()),
        ReportFormat::Csv => Ok(batch::batch_csv(b).into_bytes()),
        ReportFormat::Xlsx => {
            batch::batch_xlsx(b, lang).map_err(|e| ReportError::Xlsx(e.to_string()))
        }
    }
}
