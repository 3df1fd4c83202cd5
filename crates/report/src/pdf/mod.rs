//! The report as a PDF, rendered from Rust with printpdf: A4 landscape pages,
//! text in an embedded font that covers Chinese as well as Latin
//! (WenQuanYi Micro Hei, Apache-2.0, see `fonts/wqy-microhei.COPYRIGHT`),
//! subset to the glyphs the report uses, and the plots as vector paths drawn
//! by the same plotters code as the HTML's SVG through [`PdfPlotBackend`].
//!
//! Written by hand here: the plotters backend (no crate draws plotters
//! charts into printpdf operators; printpdf's own SVG import needs its HTML
//! layout engine, a large build) and the table layout (a few fixed columns).

use crate::batch::{self, BatchReport};
use crate::lang::{self, Lang, tr};
use crate::plots::{self, UNIT_PLOTS};
use crate::{
    POINT_HEADERS, ReportError, RunReport, SUMMARY_DECIMALS, SUMMARY_HEADERS, UnitReport,
    meta_rows_in, numbers, point_cells, summary_in,
};
use plotters::coord::Shift;
use plotters::prelude::{DrawingArea, WHITE};
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
    FontTransform,
};
use printpdf::{
    Color, FontId, Line, LinePoint, Mm, Op, PaintMode, ParsedFont, PdfDocument, PdfFont,
    PdfFontHandle, PdfPage, PdfSaveOptions, Point, Polygon, PolygonRing, Pt, Rgb, TextItem,
    TextMatrix, WindingOrder,
};
use spinbench_engine::Outcome;
use std::collections::BTreeSet;
use std::convert::Infallible;
use std::sync::OnceLock;

mod backend;
mod canvas;
mod font;
mod signer;

use backend::PdfPlotBackend;
use canvas::{Align, Canvas, from_top, point};
pub use font::web_font;
use font::{full_font, subset_font};

/// WenQuanYi Micro Hei: Latin, Greek, symbols (µ ± ² σ) and CJK in one face.
const FONT_TTC: &[u8] = include_bytes!("../../fonts/wqy-microhei.ttc");
/// The font's resource name in every page.
const FONT_ID: &str = "F1";
const PAGE_W_MM: f32 = 297.0;
const PAGE_H_MM: f32 = 210.0;
const MARGIN_MM: f32 = 12.0;
/// Room kept at the foot of each page for the footer [mm].
const FOOTER_MM: f32 = 8.0;
const PT_PER_MM: f32 = 72.0 / 25.4;
const BLACK: (f32, f32, f32) = (0.0, 0.0, 0.0);
const GREY: (f32, f32, f32) = (0.45, 0.45, 0.45);

/// What the document says of itself (its Info dictionary).
struct Metadata<'a> {
    /// Title.
    title: &'a str,
    /// Author: the station that measured.
    author: &'a str,
    /// Subject.
    subject: &'a str,
    /// The software version, for Creator and Producer.
    version: &'a str,
}

/// Number each page and write the document, dated now.
fn finish(
    mut canvas: Canvas,
    meta: Metadata,
    footer: &str,
    lang: Lang,
) -> Result<Vec<u8>, ReportError> {
    let title = meta.title;
    let total = canvas.pages.len();
    for i in 0..total {
        let page = rust_i18n::t!(
            "report.page",
            n = i + 1,
            total = total,
            locale = lang.code()
        );
        let text = format!("{footer} · {page}");
        let y = from_top(PAGE_H_MM - MARGIN_MM + 2.0);
        let ops = canvas.text_ops(MARGIN_MM * PT_PER_MM, y, 0.0, 7.0, 1.0, GREY, &text);
        canvas.pages[i].extend(ops);
    }
    let font = subset_font(canvas.font, &canvas.used)?;
    let mut doc = PdfDocument::new(title);
    let info = &mut doc.metadata.info;
    let now = printpdf::DateTime::now();
    info.creation_date = now;
    info.modification_date = now;
    info.metadata_date = now;
    info.author = meta.author.to_string();
    info.subject = meta.subject.to_string();
    info.creator = format!("spinbench {}", meta.version);
    info.producer = format!("spinbench {} (printpdf)", meta.version);
    doc.resources
        .fonts
        .map
        .insert(FontId(FONT_ID.into()), PdfFont::new(font));
    let pages = canvas
        .pages
        .into_iter()
        .map(|ops| PdfPage::new(Mm(PAGE_W_MM), Mm(PAGE_H_MM), ops))
        .collect();
    doc.with_pages(pages);
    let options = PdfSaveOptions {
        // Subset above already.
        subset_fonts: false,
        ..PdfSaveOptions::default()
    };
    Ok(doc.save(&options, &mut Vec::new()))
}

/// The run's report as PDF bytes: a cover with the run, the station's
/// devices and the summary table, then a page per instrument with its three
/// plots and its points.
pub fn pdf(report: &RunReport) -> Result<Vec<u8>, ReportError> {
    pdf_in(report, Lang::En)
}

/// The run's report as PDF bytes in `lang`.
pub fn pdf_in(report: &RunReport, lang: Lang) -> Result<Vec<u8>, ReportError> {
    let mut c = Canvas::new(full_font()?);
    let run = &report.run;
    // Page 1: what a signer signs; then the run's whole header and the
    // figures per mounting; the instruments' pages; every action and notice.
    let left_over = signer::signer_page(&mut c, report, lang);
    c.new_page();
    let mut y = MARGIN_MM + 6.0;
    c.text(MARGIN_MM, y, 12.0, &tr(lang, "report.details"), Align::Left);
    y += 6.0;
    for (label, value) in meta_rows_in(report, lang) {
        c.text(
            MARGIN_MM,
            y,
            8.5,
            &tr(lang, &format!("meta.{label}")),
            Align::Left,
        );
        for line in c.wrap(&value, 8.5, PAGE_W_MM - 2.0 * MARGIN_MM - 28.0) {
            c.text(MARGIN_MM + 28.0, y, 8.5, &line, Align::Left);
            y += 4.2;
        }
    }
    y += 3.0;
    c.text(MARGIN_MM, y, 11.0, &tr(lang, "report.summary"), Align::Left);
    y += 2.0;
    let rows: Vec<Vec<String>> = summary_in(report, lang)
        .iter()
        .map(|row| {
            let mut cells = vec![row.serial.clone(), row.slot.to_string(), row.mount.clone()];
            cells.extend(
                numbers(row)
                    .iter()
                    .zip(SUMMARY_DECIMALS)
                    .map(|(v, d)| crate::fmt(*v, d)),
            );
            cells.push(lang::outcome(lang, &row.outcome));
            cells.push(row.reasons.clone());
            cells
        })
        .collect();
    let headers: Vec<String> = SUMMARY_HEADERS
        .iter()
        .map(|h| lang::header(lang, h))
        .collect();
    let headers: Vec<&str> = headers.iter().map(String::as_str).collect();
    c.table(y, &headers, &rows, 7.0, 1);
    if let Some(signature) = crate::signature::of_run(report) {
        signature_page(&mut c, signature, lang);
    }
    for u in &report.units {
        unit_page(&mut c, u, lang);
    }
    if left_over {
        signer::actions_page(&mut c, report, lang);
    }
    finish(
        c,
        Metadata {
            title: &format!("spinbench report {}", run.id),
            author: &format!("spinbench station {}", run.station),
            subject: "centrifuge test of vibrating-beam accelerometers: k2 and nonlinearity",
            version: &report.record.start.software_version,
        },
        &format!(
            "spinbench {} · {} {}",
            report.record.start.software_version,
            tr(lang, "meta.label"),
            run.id
        ),
        lang,
    )
}

/// The centrifuge's signature the run learned: what it rests on and its plot.
fn signature_page(
    c: &mut Canvas,
    signature: &spinbench_analysis::table_signature::TableSignature,
    lang: Lang,
) {
    c.new_page();
    let mut y = MARGIN_MM + 6.0;
    c.text(
        MARGIN_MM,
        y,
        13.0,
        &tr(lang, "signature.heading"),
        Align::Left,
    );
    y += 6.0;
    let text = crate::signature::describe(signature, lang);
    for line in c.wrap(&text, 8.5, PAGE_W_MM - 2.0 * MARGIN_MM) {
        c.text(MARGIN_MM, y, 8.5, &line, Align::Left);
        y += 4.2;
    }
    y += 2.0;
    let width = (PAGE_W_MM - 2.0 * MARGIN_MM) * 0.6;
    c.plot(MARGIN_MM, y, width, |root| {
        crate::signature::draw(signature, root, lang)
    });
}

/// One instrument: title, fit figures, the three plots, the points.
fn unit_page(c: &mut Canvas, u: &UnitReport, lang: Lang) {
    c.new_page();
    let mut y = MARGIN_MM + 5.0;
    let title = rust_i18n::t!(
        "report.slot_heading",
        serial = u.result.serial,
        slot = u.result.slot + 1,
        locale = lang.code()
    )
    .into_owned();
    c.text(MARGIN_MM, y, 14.0, &title, Align::Left);
    let x = MARGIN_MM + c.width_mm(&title, 14.0) + 4.0;
    let color = match u.result.outcome {
        Outcome::Fail => (0.7, 0.0, 0.0),
        Outcome::Marginal => (0.65, 0.4, 0.0),
        Outcome::Incomplete => (0.35, 0.35, 0.35),
        Outcome::Inconclusive => (0.1, 0.25, 0.7),
        Outcome::Pass => (0.0, 0.4, 0.0),
    };
    let word = lang::outcome(lang, u.result.outcome.as_str());
    c.text_colored(x, y, 14.0, &word, Align::Left, color);
    y += 6.0;
    let fits = u.record().analysis.as_ref().map(|a| &a.fits);
    for (mount, mounting) in fits.into_iter().flatten() {
        let fit = &mounting.fit;
        // The one interval: the budget's U95 (the decision's), else the fit's.
        let half = mounting
            .uncertainty
            .as_ref()
            .and_then(|u| u.k2_ug_per_g2.as_ref())
            .map(|u| u.u95)
            .or_else(|| fit.ci95.k2_ug_per_g2.map(|[a, b]| (b - a) / 2.0));
        let line = rust_i18n::t!(
            "report.mounting_line",
            mount = mount,
            k0 = crate::fmt(Some(fit.k0_g), 6),
            k1 = crate::fmt(Some(fit.k1), 6),
            k2 = crate::fmt(fit.k2_ug_per_g2, 3),
            u95 = crate::fmt(half, 3),
            k3 = crate::fmt(fit.k3_ug_per_g3, 3),
            rms = crate::fmt(Some(fit.residual_rms_ug), 2),
            locale = lang.code()
        )
        .into_owned();
        for text in c.wrap(&line, 8.5, PAGE_W_MM - 2.0 * MARGIN_MM) {
            c.text(MARGIN_MM, y, 8.5, &text, Align::Left);
            y += 4.2;
        }
    }
    // Wrapped, never cut: a signer reads every figure.
    for line in crate::diagnostic_lines_in(u, lang) {
        for text in c.wrap(&line, 8.0, PAGE_W_MM - 2.0 * MARGIN_MM) {
            c.text(MARGIN_MM, y, 8.0, &text, Align::Left);
            y += 4.0;
        }
    }
    if !u.record().reasons.is_empty() {
        for text in c.wrap(&u.reasons_text_in(lang), 8.5, PAGE_W_MM - 2.0 * MARGIN_MM) {
            c.text_colored(MARGIN_MM, y, 8.5, &text, Align::Left, (0.7, 0.0, 0.0));
            y += 4.2;
        }
    }
    y += 1.0;
    let gap = 4.0;
    let width = (PAGE_W_MM - 2.0 * MARGIN_MM - 2.0 * gap) / 3.0;
    let height = width * plots::SIZE.1 as f32 / plots::SIZE.0 as f32;
    for (k, plot) in UNIT_PLOTS.iter().enumerate() {
        c.plot(MARGIN_MM + k as f32 * (width + gap), y, width, |root| {
            plot.draw(u, root, lang)
        });
    }
    y += height + 3.0;
    let rows: Vec<Vec<String>> = u
        .points
        .iter()
        .map(|p| point_cells(p, lang).to_vec())
        .collect();
    let headers: Vec<String> = POINT_HEADERS
        .iter()
        .map(|h| lang::header(lang, h))
        .collect();
    let headers: Vec<&str> = headers.iter().map(String::as_str).collect();
    c.table(y, &headers, &rows, 6.5, 2);
}

/// Charts three to a row from `top`, a new page when a row would not fit.
fn plot_grid<T>(
    c: &mut Canvas,
    mut top: f32,
    items: impl Iterator<Item = T>,
    draw: impl Fn(&T, &DrawingArea<PdfPlotBackend<'_>, Shift>) -> Option<()>,
) {
    let gap = 4.0;
    let width = (PAGE_W_MM - 2.0 * MARGIN_MM - 2.0 * gap) / 3.0;
    let height = width * plots::SIZE.1 as f32 / plots::SIZE.0 as f32;
    for (k, item) in items.enumerate() {
        let column = k % 3;
        if column == 0 && k > 0 {
            top += height + 2.0;
        }
        if top + height > PAGE_H_MM - MARGIN_MM - FOOTER_MM {
            c.new_page();
            top = MARGIN_MM;
        }
        c.plot(
            MARGIN_MM + column as f32 * (width + gap),
            top,
            width,
            |root| draw(&item, root),
        );
    }
}

/// Table headers in `lang` (`lang::header`), as the canvas takes them.
fn headers_in(lang: Lang, english: &[&str]) -> Vec<String> {
    english
        .iter()
        .map(|h| crate::lang::header(lang, h))
        .collect()
}

/// The control charts' pages: the flags, the charts shown, the yields.
fn control_pages(c: &mut Canvas, control: &crate::control::ControlReport, lang: Lang) {
    use crate::control::{FLAG_HEADERS, YIELD_HEADERS, flag_rows, shown, yield_rows};
    c.new_page();
    let title = rust_i18n::t!(
        "batch.control",
        runs = control.baseline_runs,
        locale = lang.code()
    );
    c.text(MARGIN_MM, MARGIN_MM + 5.0, 12.0, &title, Align::Left);
    let flags = flag_rows(control, lang);
    let top = if flags.is_empty() {
        c.text(
            MARGIN_MM,
            MARGIN_MM + 12.0,
            9.0,
            &tr(lang, "batch.no_rule_broken"),
            Align::Left,
        );
        MARGIN_MM + 16.0
    } else {
        c.table(
            MARGIN_MM + 8.0,
            &headers_in(lang, &FLAG_HEADERS),
            &flags,
            7.0,
            1,
        ) + 2.0
    };
    plot_grid(c, top, shown(control), |chart, root| {
        crate::control::draw_control_chart(chart, root, lang)
    });
    c.new_page();
    c.text(
        MARGIN_MM,
        MARGIN_MM + 5.0,
        12.0,
        &tr(lang, "batch.yield"),
        Align::Left,
    );
    c.table(
        MARGIN_MM + 8.0,
        &headers_in(lang, &YIELD_HEADERS),
        &yield_rows(control),
        7.0,
        1,
    );
}

/// The batch report as PDF bytes: totals and statistics, the histograms,
/// outliers, repeatability, then every test.
pub fn batch_pdf(b: &BatchReport) -> Result<Vec<u8>, ReportError> {
    batch_pdf_in(b, Lang::En)
}

/// [`batch_pdf`] in `lang`.
pub fn batch_pdf_in(b: &BatchReport, lang: Lang) -> Result<Vec<u8>, ReportError> {
    let mut c = Canvas::new(full_font()?);
    c.new_page();
    let mut y = MARGIN_MM + 6.0;
    c.text(MARGIN_MM, y, 16.0, &tr(lang, "batch.title"), Align::Left);
    y += 7.0;
    let (pass, marginal, fail) = b.outcomes();
    let serials: BTreeSet<&str> = b.tests.iter().map(|t| t.serial.as_str()).collect();
    let totals = rust_i18n::t!(
        "batch.totals",
        runs = b.runs.len(),
        tests = b.tests.len(),
        serials = serials.len(),
        pass = pass,
        marginal = marginal,
        fail = fail,
        locale = lang.code()
    );
    let totals = format!("{totals}{}", b.incomplete_note_in(lang));
    c.text(MARGIN_MM, y, 9.0, &totals, Align::Left);
    if let (Some(first), Some(last)) = (b.runs.first(), b.runs.last()) {
        y += 4.6;
        let span = rust_i18n::t!(
            "batch.span",
            first = crate::lang::date_time(lang, first.started_at),
            last = crate::lang::date_time(lang, last.started_at),
            locale = lang.code()
        );
        c.text(MARGIN_MM, y, 9.0, &span, Align::Left);
    }
    y += 4.0;
    let rows = batch::statistics_rows(b, lang);
    let bottom = c.table(
        y,
        &headers_in(lang, &batch::STATISTICS_HEADERS),
        &rows,
        7.5,
        1,
    );
    plot_grid(&mut c, bottom + 2.0, b.distributions.iter(), |d, root| {
        batch::draw_histogram(d, root, lang)
    });
    control_pages(&mut c, &b.control, lang);
    for (title, headers, rows) in [
        (
            "batch.outliers",
            &batch::OUTLIER_HEADERS[..],
            batch::outlier_rows(b, lang),
        ),
        (
            "batch.repeats",
            &batch::REPEAT_HEADERS[..],
            batch::repeat_rows(b),
        ),
        (
            "batch.tests",
            &batch::TEST_HEADERS[..],
            batch::test_rows(b, lang),
        ),
    ] {
        c.new_page();
        c.text(
            MARGIN_MM,
            MARGIN_MM + 5.0,
            12.0,
            &tr(lang, title),
            Align::Left,
        );
        if rows.is_empty() {
            c.text(
                MARGIN_MM,
                MARGIN_MM + 12.0,
                9.0,
                &tr(lang, "batch.none"),
                Align::Left,
            );
        } else {
            c.table(MARGIN_MM + 8.0, &headers_in(lang, headers), &rows, 7.0, 1);
        }
    }
    let mut stations: Vec<&str> = b.runs.iter().map(|r| r.station.as_str()).collect();
    stations.sort_unstable();
    stations.dedup();
    finish(
        c,
        Metadata {
            title: "spinbench batch report",
            author: &format!("spinbench station {}", stations.join(", ")),
            subject: "batch of centrifuge tests of vibrating-beam accelerometers",
            version: env!("CARGO_PKG_VERSION"),
        },
        &tr(lang, "batch.title"),
        lang,
    )
}
