//! The batch report: every instrument test of many runs together — the
//! distributions of k2 and the scale-factor figures (histogram, mean, σ),
//! outliers, and the repeatability of serial numbers tested more than once.

use crate::{ReportError, esc, fmt, unix_date};
use plotters::coord::Shift;
use plotters::prelude::*;
use spinbench_analysis::UnitAnalysis;
use spinbench_analysis::unit::repeatability_of;
use spinbench_engine::Outcome;
use spinbench_store::{RunRow, Store};
use std::collections::BTreeMap;

/// One instrument test (one unit of one run).
#[derive(Debug, Clone, PartialEq)]
pub struct BatchTest {
    /// Run identifier.
    pub run_id: String,
    /// When the run started [Unix s].
    pub started_at: i64,
    /// Serial number.
    pub serial: String,
    /// Slot (0-based): the fixture position.
    pub slot: usize,
    /// The radius found per mounting [m].
    pub radius_m: BTreeMap<spinbench_analysis::Mount, f64>,
    /// Pass, marginal, fail or incomplete.
    pub outcome: Outcome,
    /// k2_max [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// k2 of the full-range IEEE 1293 fit (signed input) [µg/g²].
    pub k2_ug_per_g2: Option<f64>,
    /// K1 of the full-range fit [Hz/g].
    pub k1_hz_per_g: Option<f64>,
    /// Scale-factor nonlinearity: largest residual of (11) [ppm].
    pub sf_nonlinearity_ppm: Option<f64>,
    /// Asymmetry [ppm].
    pub asymmetry_ppm: Option<f64>,
    /// The whole reduction of the test, when it was made.
    pub analysis: Option<UnitAnalysis>,
    /// Its temperature coefficients, when the plan had temperatures.
    pub temperature_coefficients: Option<spinbench_analysis::temperature::TemperatureCoefficients>,
}

/// The figures whose distributions the batch report shows: (name, unit, value).
type Figure = (&'static str, &'static str, fn(&BatchTest) -> Option<f64>);
const FIGURES: [Figure; 8] = [
    ("k2", "µg/g²", |t| t.k2_ug_per_g2),
    ("k2_max", "µg/g²", |t| t.k2_max_ug_per_g2),
    ("K1", "Hz/g", |t| t.k1_hz_per_g),
    ("SF nonlinearity", "ppm", |t| t.sf_nonlinearity_ppm),
    ("asymmetry", "ppm", |t| t.asymmetry_ppm),
    // Only batches tested at several temperatures have these.
    ("k0 temperature coefficient", "µg/°C", |t| {
        t.temperature_coefficients.map(|c| c.k0_ug_per_c)
    }),
    ("k1 temperature coefficient", "ppm/°C", |t| {
        t.temperature_coefficients.map(|c| c.k1_ppm_per_c)
    }),
    ("K2 temperature coefficient", "µg/g²/°C", |t| {
        t.temperature_coefficients
            .and_then(|c| c.k2_ug_per_g2_per_c)
    }),
];

/// An outlying test of one figure.
#[derive(Debug, Clone, PartialEq)]
pub struct Outlier {
    /// Serial number.
    pub serial: String,
    /// Run identifier.
    pub run_id: String,
    /// The value.
    pub value: f64,
    /// Robust z-score 0.6745·(x − median)/MAD (Iglewicz–Hoaglin; |z| > 3.5 is an outlier).
    pub robust_z: f64,
}

/// The distribution of one figure over the batch.
#[derive(Debug, Clone, PartialEq)]
pub struct Distribution {
    /// Figure name.
    pub name: &'static str,
    /// Unit.
    pub unit: &'static str,
    /// Number of tests with a value.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (n − 1).
    pub std: f64,
    /// Smallest value.
    pub min: f64,
    /// Median.
    pub median: f64,
    /// Largest value.
    pub max: f64,
    /// Histogram: (bin low edge, bin high edge, count).
    pub bins: Vec<(f64, f64, usize)>,
    /// Tests with |robust z| > 3.5.
    pub outliers: Vec<Outlier>,
    /// The values, in test order (for the plot).
    pub values: Vec<f64>,
}

/// A serial number tested in more than one run.
#[derive(Debug, Clone, PartialEq)]
pub struct Repeat {
    /// Serial number.
    pub serial: String,
    /// Number of tests.
    pub tests: usize,
    /// k2_max of each test, oldest first [µg/g²].
    pub k2_max_ug_per_g2: Vec<f64>,
    /// Largest − smallest k2_max [µg/g²].
    pub k2_max_spread: Option<f64>,
    /// Scale-factor repeatability of K1 (method.md §3.4) [ppm].
    pub k1_repeatability_ppm: Option<f64>,
}

/// Everything the batch report shows.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchReport {
    /// The runs, oldest first.
    pub runs: Vec<RunRow>,
    /// Every instrument test, in run order then slot order.
    pub tests: Vec<BatchTest>,
    /// One distribution per figure.
    pub distributions: Vec<Distribution>,
    /// Serial numbers tested more than once.
    pub repeats: Vec<Repeat>,
    /// Control charts and first-pass yields ([`BatchReport::rebaseline`]
    /// chooses their baseline; the first [`crate::control::DEFAULT_BASELINE_RUNS`] runs by default).
    pub control: crate::control::ControlReport,
}

impl BatchReport {
    /// Limits of the control charts from the first `runs` runs instead.
    pub fn rebaseline(&mut self, runs: usize) {
        self.control = crate::control::control_report(self, runs);
    }

    /// How many tests had each outcome: (pass, marginal, fail).
    pub fn outcomes(&self) -> (usize, usize, usize) {
        let count = |o: Outcome| self.tests.iter().filter(|t| t.outcome == o).count();
        (
            count(Outcome::Pass),
            count(Outcome::Marginal),
            count(Outcome::Fail),
        )
    }

    /// Tests whose run ended before they were measured whole (never graded).
    pub fn incomplete(&self) -> usize {
        self.tests
            .iter()
            .filter(|t| t.outcome == Outcome::Incomplete)
            .count()
    }

    /// ", N incomplete" when there are any, for the totals line.
    pub fn incomplete_note(&self) -> String {
        self.incomplete_note_in(crate::Lang::En)
    }

    /// [`BatchReport::incomplete_note`] in `lang`.
    pub fn incomplete_note_in(&self, lang: crate::Lang) -> String {
        let inconclusive = self
            .tests
            .iter()
            .filter(|t| t.outcome == Outcome::Inconclusive)
            .count();
        let mut note = match inconclusive {
            0 => String::new(),
            n => rust_i18n::t!("batch.inconclusive", n = n, locale = lang.code()).into_owned(),
        };
        if let n @ 1.. = self.incomplete() {
            note.push_str(&rust_i18n::t!(
                "batch.incomplete",
                n = n,
                locale = lang.code()
            ));
        }
        note
    }
}

/// Read the batch from the store: the runs named, or every run when none is.
pub fn gather_batch(store: &Store, run_ids: &[String]) -> Result<BatchReport, ReportError> {
    let mut runs = Vec::new();
    if run_ids.is_empty() {
        runs = store.runs()?;
    } else {
        for id in run_ids {
            runs.push(
                store
                    .run(id)?
                    .ok_or_else(|| ReportError::NoRun(id.clone()))?,
            );
        }
    }
    runs.sort_by(|a, b| a.started_at.cmp(&b.started_at).then(a.id.cmp(&b.id)));
    let mut tests = Vec::new();
    for run in &runs {
        for r in store.results(&run.id)? {
            let temperature_coefficients = r.record.temperature_coefficients;
            let a = r.record.analysis;
            tests.push(BatchTest {
                run_id: run.id.clone(),
                started_at: run.started_at,
                serial: r.serial,
                slot: r.record.slot,
                radius_m: r.record.radius_m.clone(),
                outcome: r.outcome,
                k2_max_ug_per_g2: r.k2_max_ug_per_g2,
                k2_ug_per_g2: a
                    .as_ref()
                    .and_then(|a| a.full_range.as_ref())
                    .and_then(|f| f.fit.k2_ug_per_g2),
                k1_hz_per_g: a
                    .as_ref()
                    .and_then(|a| a.full_range.as_ref())
                    .map(|f| f.fit.k1),
                sf_nonlinearity_ppm: a
                    .as_ref()
                    .and_then(|a| a.scale_factor.as_ref())
                    .map(|s| s.residual_max_ppm),
                asymmetry_ppm: a.as_ref().and_then(|a| a.figures.asymmetry_ppm),
                analysis: a,
                temperature_coefficients,
            });
        }
    }
    // An incomplete test (its run aborted or faulted before it was measured
    // whole) is listed, but its partial figures enter no statistics.
    let measured: Vec<BatchTest> = tests
        .iter()
        .filter(|t| t.outcome != Outcome::Incomplete)
        .cloned()
        .collect();
    let distributions = FIGURES
        .iter()
        .filter_map(|(name, unit, value)| distribution(name, unit, &measured, *value))
        .collect();
    let mut by_serial: BTreeMap<&str, Vec<&BatchTest>> = BTreeMap::new();
    for t in &measured {
        by_serial.entry(&t.serial).or_default().push(t);
    }
    let repeats = by_serial
        .into_iter()
        .filter(|(_, ts)| ts.len() > 1)
        .map(|(serial, ts)| {
            let k2: Vec<f64> = ts.iter().filter_map(|t| t.k2_max_ug_per_g2).collect();
            Repeat {
                serial: serial.to_string(),
                tests: ts.len(),
                k2_max_spread: (k2.len() > 1).then(|| {
                    k2.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                        - k2.iter().copied().fold(f64::INFINITY, f64::min)
                }),
                k2_max_ug_per_g2: k2,
                // The one definition, as `analyze` and `spinbench unit` give it.
                k1_repeatability_ppm: repeatability_of(
                    &ts.iter()
                        .filter_map(|t| t.analysis.as_ref())
                        .collect::<Vec<_>>(),
                )
                .map(|r| r.scale_factor_ppm),
            }
        })
        .collect();
    let mut report = BatchReport {
        runs,
        tests,
        distributions,
        repeats,
        control: crate::control::ControlReport::default(),
    };
    report.rebaseline(crate::control::DEFAULT_BASELINE_RUNS);
    Ok(report)
}

fn median(sorted: &[f64]) -> f64 {
    let n = sorted.len();
    if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    }
}

/// Statistics, histogram (Sturges' number of bins) and robust outliers of one figure.
fn distribution(
    name: &'static str,
    unit: &'static str,
    tests: &[BatchTest],
    value: fn(&BatchTest) -> Option<f64>,
) -> Option<Distribution> {
    let with: Vec<(&BatchTest, f64)> = tests
        .iter()
        .filter_map(|t| value(t).filter(|v| v.is_finite()).map(|v| (t, v)))
        .collect();
    if with.is_empty() {
        return None;
    }
    let values: Vec<f64> = with.iter().map(|(_, v)| *v).collect();
    let n = values.len();
    let mean = values.iter().sum::<f64>() / n as f64;
    let std = if n > 1 {
        (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        0.0
    };
    let mut sorted = values.clone();
    sorted.sort_by(f64::total_cmp);
    let (min, max) = (sorted[0], sorted[n - 1]);
    let med = median(&sorted);
    let mut deviations: Vec<f64> = sorted.iter().map(|v| (v - med).abs()).collect();
    deviations.sort_by(f64::total_cmp);
    let mad = median(&deviations);
    let outliers = if mad > 0.0 {
        with.iter()
            .map(|(t, v)| (t, *v, 0.6745 * (v - med) / mad))
            .filter(|(_, _, z)| z.abs() > 3.5)
            .map(|(t, v, z)| Outlier {
                serial: t.serial.clone(),
                run_id: t.run_id.clone(),
                value: v,
                robust_z: z,
            })
            .collect()
    } else {
        Vec::new()
    };
    let count = ((n as f64).log2().ceil() as usize + 1).clamp(1, 30);
    let width = if max > min {
        (max - min) / count as f64
    } else {
        1.0
    };
    let mut bins: Vec<(f64, f64, usize)> = (0..count)
        .map(|i| (min + i as f64 * width, min + (i + 1) as f64 * width, 0))
        .collect();
    for v in &values {
        let i = (((v - min) / width) as usize).min(count - 1);
        bins[i].2 += 1;
    }
    Some(Distribution {
        name,
        unit,
        n,
        mean,
        std,
        min,
        median: med,
        max,
        bins,
        outliers,
        values,
    })
}

/// Draw a distribution's histogram on any plotters backend.
pub(crate) fn draw_histogram<DB: DrawingBackend>(
    d: &Distribution,
    root: &DrawingArea<DB, Shift>,
) -> Option<()> {
    let (lo, hi) = (d.bins.first()?.0, d.bins.last()?.1);
    let top = d.bins.iter().map(|b| b.2).max().unwrap_or(1).max(1) as f64 * 1.15;
    let mut chart = ChartBuilder::on(root)
        .caption(
            format!(
                "{} [{}]: n {}, mean {:.4}, σ {:.4}",
                d.name, d.unit, d.n, d.mean, d.std
            ),
            ("sans-serif", 15),
        )
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(44)
        .build_cartesian_2d(lo..hi, 0.0..top)
        .ok()?;
    chart
        .configure_mesh()
        .x_desc(format!("{} [{}]", d.name, d.unit))
        .y_desc("tests")
        .draw()
        .ok()?;
    chart
        .draw_series(
            d.bins.iter().map(|&(a, b, c)| {
                Rectangle::new([(a, 0.0), (b, c as f64)], BLUE.mix(0.5).filled())
            }),
        )
        .ok()?;
    chart
        .draw_series(
            d.bins
                .iter()
                .map(|&(a, b, c)| Rectangle::new([(a, 0.0), (b, c as f64)], BLUE.stroke_width(1))),
        )
        .ok()?;
    Some(())
}

/// A distribution's histogram as SVG.
fn histogram_svg(d: &Distribution) -> Option<String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, crate::plots::SIZE).into_drawing_area();
        root.fill(&WHITE).ok()?;
        draw_histogram(d, &root)?;
        root.present().ok()?;
    }
    Some(out)
}

/// The statistics table's columns.
pub(crate) const STATISTICS_HEADERS: [&str; 9] = [
    "figure", "unit", "n", "mean", "σ", "min", "median", "max", "outliers",
];

/// One statistics row per figure, as shown.
pub(crate) fn statistics_rows(b: &BatchReport) -> Vec<Vec<String>> {
    b.distributions
        .iter()
        .map(|d| {
            vec![
                d.name.to_string(),
                d.unit.to_string(),
                d.n.to_string(),
                format!("{:.4}", d.mean),
                format!("{:.4}", d.std),
                format!("{:.4}", d.min),
                format!("{:.4}", d.median),
                format!("{:.4}", d.max),
                d.outliers.len().to_string(),
            ]
        })
        .collect()
}

/// The outliers table's columns.
pub(crate) const OUTLIER_HEADERS: [&str; 5] = ["figure", "serial", "run", "value", "robust z"];

/// One row per outlying test and figure.
pub(crate) fn outlier_rows(b: &BatchReport) -> Vec<Vec<String>> {
    b.distributions
        .iter()
        .flat_map(|d| {
            d.outliers.iter().map(move |o| {
                vec![
                    format!("{} [{}]", d.name, d.unit),
                    o.serial.clone(),
                    o.run_id.clone(),
                    format!("{:.4}", o.value),
                    format!("{:.1}", o.robust_z),
                ]
            })
        })
        .collect()
}

/// The repeatability table's columns.
pub(crate) const REPEAT_HEADERS: [&str; 5] = [
    "serial",
    "tests",
    "k2_max [µg/g²]",
    "k2_max spread [µg/g²]",
    "K1 repeatability [ppm]",
];

/// One row per serial tested more than once.
pub(crate) fn repeat_rows(b: &BatchReport) -> Vec<Vec<String>> {
    b.repeats
        .iter()
        .map(|r| {
            vec![
                r.serial.clone(),
                r.tests.to_string(),
                r.k2_max_ug_per_g2
                    .iter()
                    .map(|v| format!("{v:.3}"))
                    .collect::<Vec<_>>()
                    .join(" "),
                fmt(r.k2_max_spread, 3),
                fmt(r.k1_repeatability_ppm, 2),
            ]
        })
        .collect()
}

/// The tests table's columns (also the CSV's).
pub(crate) const TEST_HEADERS: [&str; 9] = [
    "run",
    "started",
    "serial",
    "outcome",
    "k2 [µg/g²]",
    "k2_max [µg/g²]",
    "K1 [Hz/g]",
    "SF nonlinearity [ppm]",
    "asymmetry [ppm]",
];

fn test_numbers(t: &BatchTest) -> [Option<f64>; 5] {
    [
        t.k2_ug_per_g2,
        t.k2_max_ug_per_g2,
        t.k1_hz_per_g,
        t.sf_nonlinearity_ppm,
        t.asymmetry_ppm,
    ]
}

/// One row per test, as shown (3–6 decimals).
pub(crate) fn test_rows(b: &BatchReport) -> Vec<Vec<String>> {
    b.tests
        .iter()
        .map(|t| {
            let mut row = vec![
                t.run_id.clone(),
                unix_date(t.started_at),
                t.serial.clone(),
                t.outcome.as_str().to_string(),
            ];
            row.extend(
                test_numbers(t)
                    .iter()
                    .zip([3, 3, 6, 1, 1])
                    .map(|(v, d)| fmt(*v, d)),
            );
            row
        })
        .collect()
}

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

pub(crate) fn html_table<S: AsRef<str>>(
    h: &mut String,
    id: &str,
    headers: &[S],
    rows: &[Vec<String>],
) {
    h.push_str(&format!("<table id=\"{id}\"><tr>"));
    for head in headers {
        h.push_str(&format!("<th>{}</th>", esc(head.as_ref())));
    }
    h.push_str("</tr>\n");
    for row in rows {
        h.push_str("<tr>");
        for cell in row {
            h.push_str(&format!("<td>{}</td>", esc(cell)));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
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
        "<!DOCTYPE html>\n<html lang=\"LANG\"><head><meta charset=\"utf-8\"><title>spinbench batch report</title>\
         <style>body{font-family:'Noto Sans','Noto Sans CJK SC','Microsoft YaHei','PingFang SC',sans-serif;margin:2em;color:#111}\
         table{border-collapse:collapse;font-size:0.85em;margin-bottom:1em}td,th{border:1px solid #999;padding:2px 6px}\
         th{background:#eee}figure{display:inline-block;margin:0.5em}</style></head><body>\n",
    )
    .replacen("LANG", lang.code(), 1);
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
    html_table(
        &mut h,
        "statistics",
        &heads(&STATISTICS_HEADERS),
        &statistics_rows(b),
    );
    for svg in b.distributions.iter().filter_map(histogram_svg) {
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
            outlier_rows(b),
        ),
        (
            "batch.repeats",
            "repeats",
            &REPEAT_HEADERS[..],
            repeat_rows(b),
        ),
        ("batch.tests", "tests", &TEST_HEADERS[..], test_rows(b)),
    ] {
        h.push_str(&format!("<h2>{}</h2>\n", esc(&tr(lang, title))));
        html_table(&mut h, id, &heads(list), &rows);
    }
    h.push_str("</body></html>\n");
    h
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
        ReportFormat::Pdf => crate::pdf::batch_pdf_in(b, lang),
        ReportFormat::Html => Ok(batch_html_in(b, lang).into_bytes()),
        ReportFormat::Csv => Ok(batch_csv(b).into_bytes()),
        ReportFormat::Xlsx => batch_xlsx(b, lang).map_err(|e| ReportError::Xlsx(e.to_string())),
    }
}

/// The batch report as an XLSX workbook: `tests`, `statistics`, `repeatability`
/// (the sheets keep their machine names; headers and outcomes in `lang`).
fn batch_xlsx(b: &BatchReport, lang: crate::Lang) -> Result<Vec<u8>, rust_xlsxwriter::XlsxError> {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn test(serial: &str, k2: f64) -> BatchTest {
        BatchTest {
            run_id: "r".into(),
            started_at: 0,
            serial: serial.into(),
            slot: 0,
            radius_m: BTreeMap::new(),
            outcome: Outcome::Pass,
            k2_max_ug_per_g2: Some(k2.abs()),
            k2_ug_per_g2: Some(k2),
            k1_hz_per_g: Some(100.0),
            sf_nonlinearity_ppm: None,
            asymmetry_ppm: None,
            analysis: None,
            temperature_coefficients: None,
        }
    }

    #[test]
    fn statistics_histogram_and_a_robust_outlier() {
        let mut tests: Vec<BatchTest> = (0..20)
            .map(|i| test(&format!("S{i}"), 10.0 + f64::from(i % 5) * 0.1))
            .collect();
        tests.push(test("WILD", 25.0));
        let d = distribution("k2", "µg/g²", &tests, |t| t.k2_ug_per_g2).expect("d");
        assert_eq!(d.n, 21);
        let mean = (20.0 * 10.2 + 25.0) / 21.0;
        assert!((d.mean - mean).abs() < 1e-12);
        assert_eq!((d.min, d.max), (10.0, 25.0));
        assert_eq!(d.bins.iter().map(|b| b.2).sum::<usize>(), 21);
        assert_eq!(d.bins.len(), 6, "Sturges: ⌈log2 21⌉ + 1");
        assert_eq!(d.outliers.len(), 1);
        assert_eq!(d.outliers[0].serial, "WILD");
        // No figure at all: no distribution.
        assert!(distribution("x", "", &tests, |t| t.asymmetry_ppm).is_none());
    }

    #[test]
    fn temperature_coefficients_get_their_distributions_only_when_measured() {
        let (name, _, value) = FIGURES[5];
        let tests: Vec<BatchTest> = (0..10).map(|i| test(&format!("S{i}"), 10.0)).collect();
        assert!(
            distribution(name, "", &tests, value).is_none(),
            "none measured"
        );
        let with: Vec<BatchTest> = (0..10)
            .map(|i| BatchTest {
                temperature_coefficients: Some(
                    spinbench_analysis::temperature::TemperatureCoefficients {
                        k0_ug_per_c: f64::from(i),
                        k0_ug_per_c_u95: 1.0,
                        k1_ppm_per_c: 0.0,
                        k1_ppm_per_c_u95: 1.0,
                        k2_ug_per_g2_per_c: None,
                        k2_ug_per_g2_per_c_u95: None,
                        temperatures: 3,
                        u: Default::default(),
                        chi2: Default::default(),
                        batch: None,
                    },
                ),
                ..test(&format!("S{i}"), 10.0)
            })
            .collect();
        let d = distribution(name, "µg/°C", &with, value).expect("k0 coefficients");
        assert_eq!((d.n, d.mean), (10, 4.5));
        let (k2_name, _, k2_value) = FIGURES[7];
        assert!(
            distribution(k2_name, "", &with, k2_value).is_none(),
            "no K2 coefficient"
        );
    }
}
