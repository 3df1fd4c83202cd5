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
use crate::plots::{self, UNIT_PLOTS};
use crate::{
    POINT_HEADERS, ReportError, RunReport, SUMMARY_DECIMALS, SUMMARY_HEADERS, UnitReport,
    meta_rows, numbers, point_cells, summary,
};
use plotters::coord::Shift;
use plotters::prelude::{DrawingArea, IntoDrawingArea, WHITE};
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
use std::collections::BTreeSet;
use std::convert::Infallible;
use std::sync::OnceLock;

/// WenQuanYi Micro Hei: Latin, Greek, symbols (µ ± ² σ) and CJK in one face.
const FONT_TTC: &[u8] = include_bytes!("../fonts/wqy-microhei.ttc");
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

/// The embedded font, parsed once per process (metrics for the layout).
fn full_font() -> Result<&'static ParsedFont, ReportError> {
    static FONT: OnceLock<Option<ParsedFont>> = OnceLock::new();
    FONT.get_or_init(|| ParsedFont::from_bytes(FONT_TTC, 0, &mut Vec::new()))
        .as_ref()
        .ok_or_else(|| ReportError::Pdf("the embedded font cannot be read".into()))
}

/// Text alignment in a table cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Align {
    Left,
    Right,
}

/// Pages of PDF operators being laid out, and the characters used on them.
struct Canvas {
    font: &'static ParsedFont,
    pages: Vec<Vec<Op>>,
    used: BTreeSet<char>,
}

fn rgb((r, g, b): (f32, f32, f32)) -> Color {
    Color::Rgb(Rgb::new(r, g, b, None))
}

fn point(x_pt: f32, y_pt: f32) -> LinePoint {
    LinePoint {
        p: Point {
            x: Pt(x_pt),
            y: Pt(y_pt),
        },
        bezier: false,
    }
}

/// PDF y [pt] of a distance from the page's top [mm].
fn from_top(y_mm: f32) -> f32 {
    (PAGE_H_MM - y_mm) * PT_PER_MM
}

impl Canvas {
    fn new(font: &'static ParsedFont) -> Canvas {
        Canvas {
            font,
            pages: Vec::new(),
            used: BTreeSet::new(),
        }
    }

    fn new_page(&mut self) {
        self.pages.push(Vec::new());
    }

    fn ops(&mut self) -> &mut Vec<Op> {
        if self.pages.is_empty() {
            self.new_page();
        }
        let last = self.pages.len() - 1;
        &mut self.pages[last]
    }

    /// Advance width of `text` at `size` (in the units of `size`).
    fn width(&self, text: &str, size: f32) -> f32 {
        let per_em = f32::from(self.font.units_per_em.max(1));
        let units: f32 = text
            .chars()
            .map(|c| {
                self.font
                    .lookup_glyph_index(c as u32)
                    .and_then(|g| self.font.get_glyph_width(g))
                    .map_or(per_em * 0.5, f32::from)
            })
            .sum();
        units / per_em * size
    }

    fn width_mm(&self, text: &str, size_pt: f32) -> f32 {
        self.width(text, size_pt) / PT_PER_MM
    }

    /// `text` cut to `max_mm` wide, with an ellipsis when cut.
    fn fit(&self, text: &str, size_pt: f32, max_mm: f32) -> String {
        if self.width_mm(text, size_pt) <= max_mm {
            return text.to_string();
        }
        let mut out = String::new();
        for c in text.chars() {
            out.push(c);
            if self.width_mm(&out, size_pt) + self.width_mm("…", size_pt) > max_mm {
                out.pop();
                break;
            }
        }
        out.push('…');
        out
    }

    /// Text with its baseline starting at (`x_pt`, `y_pt`), turned
    /// counter-clockwise by `angle_deg`, on the current page.
    fn text_pt(
        &mut self,
        x_pt: f32,
        y_pt: f32,
        angle_deg: f32,
        size_pt: f32,
        color: (f32, f32, f32),
        text: &str,
    ) {
        let ops = self.text_ops(x_pt, y_pt, angle_deg, size_pt, 1.0, color, text);
        self.ops().extend(ops);
    }

    /// The operators that draw `text` (see [`Canvas::text_pt`]), its width
    /// scaled by `stretch`; notes its characters.
    #[allow(clippy::too_many_arguments)]
    fn text_ops(
        &mut self,
        x_pt: f32,
        y_pt: f32,
        angle_deg: f32,
        size_pt: f32,
        stretch: f32,
        color: (f32, f32, f32),
        text: &str,
    ) -> Vec<Op> {
        if text.is_empty() {
            return Vec::new();
        }
        self.used.extend(text.chars());
        let (sin, cos) = angle_deg.to_radians().sin_cos();
        vec![
            Op::StartTextSection,
            Op::SetFont {
                font: PdfFontHandle::External(FontId(FONT_ID.into())),
                size: Pt(size_pt),
            },
            Op::SetFillColor { col: rgb(color) },
            Op::SetTextMatrix {
                matrix: TextMatrix::Raw([cos * stretch, sin * stretch, -sin, cos, x_pt, y_pt]),
            },
            Op::ShowText {
                items: vec![TextItem::Text(text.to_string())],
            },
            Op::EndTextSection,
        ]
    }

    /// Text on a baseline `y_mm` from the top; `x_mm` is its left or right end.
    fn text(&mut self, x_mm: f32, y_mm: f32, size_pt: f32, text: &str, align: Align) {
        self.text_colored(x_mm, y_mm, size_pt, text, align, BLACK);
    }

    fn text_colored(
        &mut self,
        x_mm: f32,
        y_mm: f32,
        size_pt: f32,
        text: &str,
        align: Align,
        color: (f32, f32, f32),
    ) {
        let x = match align {
            Align::Left => x_mm * PT_PER_MM,
            Align::Right => x_mm * PT_PER_MM - self.width(text, size_pt),
        };
        self.text_pt(x, from_top(y_mm), 0.0, size_pt, color, text);
    }

    /// A horizontal rule `y_mm` from the top.
    fn rule(&mut self, x1_mm: f32, x2_mm: f32, y_mm: f32, width_pt: f32) {
        let y = from_top(y_mm);
        self.stroke(
            &[point(x1_mm * PT_PER_MM, y), point(x2_mm * PT_PER_MM, y)],
            GREY,
            width_pt,
            false,
        );
    }

    fn stroke(
        &mut self,
        points: &[LinePoint],
        color: (f32, f32, f32),
        width_pt: f32,
        closed: bool,
    ) {
        if points.len() < 2 {
            return;
        }
        self.ops().extend([
            Op::SetOutlineColor { col: rgb(color) },
            Op::SetOutlineThickness { pt: Pt(width_pt) },
            Op::DrawLine {
                line: Line {
                    points: points.to_vec(),
                    is_closed: closed,
                },
            },
        ]);
    }

    fn fill(&mut self, points: Vec<LinePoint>, color: (f32, f32, f32)) {
        if points.len() < 3 {
            return;
        }
        self.ops().extend([
            Op::SetFillColor { col: rgb(color) },
            Op::DrawPolygon {
                polygon: Polygon {
                    rings: vec![PolygonRing { points }],
                    mode: PaintMode::Fill,
                    winding_order: WindingOrder::NonZero,
                },
            },
        ]);
    }

    /// A table from `y_mm` down, over as many pages as it needs (the header
    /// again on each), in up to `across` blocks side by side when it is
    /// narrow enough; columns as wide as their widest cell, the last one
    /// taking at most what is left (cut with an ellipsis). Returns the y
    /// below its last row.
    fn table(
        &mut self,
        mut y_mm: f32,
        headers: &[&str],
        rows: &[Vec<String>],
        size_pt: f32,
        across: usize,
    ) -> f32 {
        let line_mm = size_pt / PT_PER_MM * 1.4;
        let pad_mm = 2.0;
        // Headers "name [unit]" on two lines.
        let heads: Vec<(String, String)> = headers
            .iter()
            .map(|h| match h.split_once(" [") {
                Some((name, unit)) => (name.to_string(), format!("[{unit}")),
                None => (h.to_string(), String::new()),
            })
            .collect();
        let mut widths: Vec<f32> = heads
            .iter()
            .map(|(a, b)| self.width_mm(a, size_pt).max(self.width_mm(b, size_pt)))
            .collect();
        for row in rows {
            for (w, cell) in widths.iter_mut().zip(row) {
                *w = w.max(self.width_mm(cell, size_pt));
            }
        }
        let available = PAGE_W_MM - 2.0 * MARGIN_MM;
        let n = widths.len();
        let fixed: f32 = widths
            .iter()
            .take(n.saturating_sub(1))
            .map(|w| w + pad_mm)
            .sum();
        if let Some(last) = widths.last_mut() {
            *last = last.min((available - fixed - pad_mm).max(10.0));
        }
        // Numbers right-aligned: a column is numeric when its cells parse.
        let numeric: Vec<bool> = (0..n)
            .map(|c| {
                rows.iter()
                    .filter_map(|r| r.get(c))
                    .filter(|s| !s.is_empty() && s.as_str() != "—")
                    .all(|s| s.parse::<f64>().is_ok())
                    && rows
                        .iter()
                        .any(|r| r.get(c).is_some_and(|s| s.parse::<f64>().is_ok()))
            })
            .collect();
        let gap_mm = 8.0;
        let block_mm: f32 = widths.iter().map(|w| w + pad_mm).sum();
        let across = (1..=across.max(1))
            .rev()
            .find(|&k| k as f32 * block_mm + (k - 1) as f32 * gap_mm <= available)
            .unwrap_or(1);
        let header = |canvas: &mut Canvas, x0: f32, y: f32| -> f32 {
            let mut x = x0;
            for (c, (a, b)) in heads.iter().enumerate() {
                let (xa, align) = if numeric[c] {
                    (x + widths[c], Align::Right)
                } else {
                    (x, Align::Left)
                };
                canvas.text(xa, y + line_mm * 0.8, size_pt, a, align);
                canvas.text(xa, y + line_mm * 1.8, size_pt, b, align);
                x += widths[c] + pad_mm;
            }
            let bottom = y + line_mm * 2.2;
            canvas.rule(x0, x - pad_mm, bottom, 0.6);
            bottom
        };
        let (mut top, mut block, mut x0) = (y_mm, 0, MARGIN_MM);
        y_mm = header(self, x0, top);
        let last_y = PAGE_H_MM - MARGIN_MM - FOOTER_MM;
        for row in rows {
            if y_mm + line_mm > last_y {
                block += 1;
                if block == across {
                    self.new_page();
                    (top, block) = (MARGIN_MM, 0);
                }
                x0 = MARGIN_MM + block as f32 * (block_mm + gap_mm);
                y_mm = header(self, x0, top);
            }
            let mut x = x0;
            for (c, cell) in row.iter().enumerate().take(n) {
                let text = if c + 1 == n {
                    self.fit(cell, size_pt, widths[c])
                } else {
                    cell.clone()
                };
                let color = match cell.as_str() {
                    "fail" => (0.7, 0.0, 0.0),
                    "marginal" => (0.65, 0.4, 0.0),
                    "pass" => (0.0, 0.4, 0.0),
                    _ => BLACK,
                };
                if numeric[c] {
                    self.text_colored(
                        x + widths[c],
                        y_mm + line_mm * 0.8,
                        size_pt,
                        &text,
                        Align::Right,
                        color,
                    );
                } else {
                    self.text_colored(x, y_mm + line_mm * 0.8, size_pt, &text, Align::Left, color);
                }
                x += widths[c] + pad_mm;
            }
            y_mm += line_mm;
        }
        y_mm
    }

    /// Draw a plot with `draw` (a plotters chart on any backend) with its
    /// top-left corner at (`x_mm`, `y_mm`), `width_mm` wide. Returns
    /// whether anything was drawn.
    fn plot(
        &mut self,
        x_mm: f32,
        y_mm: f32,
        width_mm: f32,
        draw: impl FnOnce(&DrawingArea<PdfPlotBackend<'_>, Shift>) -> Option<()>,
    ) -> bool {
        let pt_per_px = width_mm * PT_PER_MM / plots::SIZE.0 as f32;
        let backend = PdfPlotBackend {
            canvas: self,
            left_pt: x_mm * PT_PER_MM,
            top_pt: from_top(y_mm),
            pt_per_px,
        };
        let root = backend.into_drawing_area();
        if root.fill(&WHITE).is_err() {
            return false;
        }
        draw(&root).is_some()
    }
}

/// A plotters backend that draws into a [`Canvas`] page as PDF vector
/// operators: plotters lays the chart out in its pixel grid, and each pixel
/// becomes `pt_per_px` points on the page.
struct PdfPlotBackend<'a> {
    canvas: &'a mut Canvas,
    /// Page x of the plot's left edge [pt].
    left_pt: f32,
    /// Page y of the plot's top edge [pt].
    top_pt: f32,
    pt_per_px: f32,
}

impl PdfPlotBackend<'_> {
    fn at(&self, (x, y): BackendCoord) -> LinePoint {
        point(
            self.left_pt + x as f32 * self.pt_per_px,
            self.top_pt - y as f32 * self.pt_per_px,
        )
    }

    /// The colour as drawn over the white plot background (a translucent
    /// mesh line becomes a light one); `None` when fully transparent.
    fn color(c: BackendColor) -> Option<(f32, f32, f32)> {
        (c.alpha > 0.0).then(|| {
            let a = c.alpha.clamp(0.0, 1.0) as f32;
            let over_white = |v: u8| a * f32::from(v) / 255.0 + (1.0 - a);
            let (r, g, b) = c.rgb;
            (over_white(r), over_white(g), over_white(b))
        })
    }

    fn shape<S: BackendStyle>(
        &mut self,
        corners: &[BackendCoord],
        style: &S,
        fill: bool,
        closed: bool,
    ) {
        let Some(color) = Self::color(style.color()) else {
            return;
        };
        let points: Vec<LinePoint> = corners.iter().map(|&c| self.at(c)).collect();
        if fill {
            self.canvas.fill(points, color);
        } else {
            let width = style.stroke_width().max(1) as f32 * self.pt_per_px;
            self.canvas.stroke(&points, color, width, closed);
        }
    }
}

type Drawn = Result<(), DrawingErrorKind<Infallible>>;

impl DrawingBackend for PdfPlotBackend<'_> {
    type ErrorType = Infallible;

    fn get_size(&self) -> (u32, u32) {
        plots::SIZE
    }

    fn ensure_prepared(&mut self) -> Drawn {
        Ok(())
    }

    fn present(&mut self) -> Drawn {
        Ok(())
    }

    fn draw_pixel(&mut self, p: BackendCoord, color: BackendColor) -> Drawn {
        let square = [p, (p.0 + 1, p.1), (p.0 + 1, p.1 + 1), (p.0, p.1 + 1)];
        self.shape(&square, &color, true, true);
        Ok(())
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Drawn {
        self.shape(&[from, to], style, false, false);
        Ok(())
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        ul: BackendCoord,
        br: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Drawn {
        self.shape(&[ul, (br.0, ul.1), br, (ul.0, br.1)], style, fill, true);
        Ok(())
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Drawn {
        let path: Vec<BackendCoord> = path.into_iter().collect();
        self.shape(&path, style, false, false);
        Ok(())
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Drawn {
        // A 16-gon: at a marker's size it is a circle on paper.
        let Some(color) = Self::color(style.color()) else {
            return Ok(());
        };
        let c = self.at(center).p;
        let r = radius as f32 * self.pt_per_px;
        let points: Vec<LinePoint> = (0..16)
            .map(|k| {
                let (s, co) = (k as f32 * std::f32::consts::TAU / 16.0).sin_cos();
                point(c.x.0 + r * co, c.y.0 + r * s)
            })
            .collect();
        if fill {
            self.canvas.fill(points, color);
        } else {
            let width = style.stroke_width().max(1) as f32 * self.pt_per_px;
            self.canvas.stroke(&points, color, width, true);
        }
        Ok(())
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Drawn {
        let vert: Vec<BackendCoord> = vert.into_iter().collect();
        self.shape(&vert, style, true, true);
        Ok(())
    }

    fn draw_text<T: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &T,
        pos: BackendCoord,
    ) -> Drawn {
        let Some(color) = Self::color(style.color()) else {
            return Ok(());
        };
        let size = style.size() as f32;
        // Plotters sizes legend boxes with its own estimate of text width
        // (0.7 em of size/1.24² per byte); text wider than that is condensed
        // to it so it stays inside its box.
        let estimate = size / 1.24 / 1.24 * 0.7 * text.len() as f32;
        let real = self.canvas.width(text, size);
        let stretch = if real > estimate && real > 0.0 {
            estimate / real
        } else {
            1.0
        };
        let width = real * stretch;
        let anchor = style.anchor();
        let dx = match anchor.h_pos {
            HPos::Left => 0.0,
            HPos::Center => -width / 2.0,
            HPos::Right => -width,
        };
        let dy = match anchor.v_pos {
            VPos::Top => 0.0,
            VPos::Center => -size / 2.0,
            VPos::Bottom => -size,
        };
        // The baseline's start in the text's own frame (ascent ≈ 0.8 em),
        // turned as plotters turns it (clockwise on the page).
        let transform = style.transform();
        let (bx, by) = transform.transform(dx.round() as i32, (dy + 0.8 * size).round() as i32);
        let angle = match transform {
            FontTransform::None => 0.0,
            FontTransform::Rotate90 => -90.0,
            FontTransform::Rotate180 => 180.0,
            FontTransform::Rotate270 => 90.0,
        };
        let at = self.at((pos.0 + bx, pos.1 + by)).p;
        let ops = self.canvas.text_ops(
            at.x.0,
            at.y.0,
            angle,
            size * self.pt_per_px,
            stretch,
            color,
            text,
        );
        self.canvas.ops().extend(ops);
        Ok(())
    }

    fn estimate_text_size<T: BackendTextStyle>(
        &self,
        text: &str,
        style: &T,
    ) -> Result<(u32, u32), DrawingErrorKind<Infallible>> {
        let size = style.size() as f32;
        Ok((
            self.canvas.width(text, size).ceil() as u32,
            size.ceil() as u32,
        ))
    }
}

/// The embedded font cut down to the glyphs of `used` (a whole CJK font is
/// 5 MB; a report uses a few hundred glyphs).
fn subset_font(full: &ParsedFont, used: &BTreeSet<char>) -> Result<ParsedFont, ReportError> {
    use allsorts::binary::read::ReadScope;
    use allsorts::font_data::FontData;
    use allsorts::subset::{CmapTarget, SubsetProfile, subset};
    let fail =
        |what: &str, e: String| ReportError::Pdf(format!("subsetting the font: {what}: {e}"));
    let mut glyphs: Vec<u16> = used
        .iter()
        .filter_map(|&c| full.lookup_glyph_index(c as u32))
        .filter(|&g| g != 0)
        .collect();
    glyphs.sort_unstable();
    glyphs.dedup();
    // Glyph 0 (.notdef) first, as the subsetter requires.
    let ids: Vec<u16> = std::iter::once(0).chain(glyphs).collect();
    let data = ReadScope::new(FONT_TTC)
        .read::<FontData<'_>>()
        .map_err(|e| fail("reading", e.to_string()))?;
    let provider = data
        .table_provider(0)
        .map_err(|e| fail("face 0", e.to_string()))?;
    let bytes = subset(&provider, &ids, &SubsetProfile::Pdf, CmapTarget::Unicode)
        .map_err(|e| fail("subset", e.to_string()))?;
    let font = ParsedFont::from_bytes(&bytes, 0, &mut Vec::new())
        .ok_or_else(|| fail("reading the subset", "not a font".into()))?;
    // Every character the full font draws must still map to a glyph.
    if let Some(lost) = used.iter().find(|&&c| {
        full.lookup_glyph_index(c as u32).is_some_and(|g| g != 0)
            && font.lookup_glyph_index(c as u32).is_none_or(|g| g == 0)
    }) {
        return Err(fail("lost a glyph", format!("{lost:?}")));
    }
    Ok(font)
}

/// Number each page and write the document.
fn finish(mut canvas: Canvas, title: &str, footer: &str) -> Result<Vec<u8>, ReportError> {
    let total = canvas.pages.len();
    for i in 0..total {
        let text = format!("{footer} · page {} of {total}", i + 1);
        let y = from_top(PAGE_H_MM - MARGIN_MM + 2.0);
        let ops = canvas.text_ops(MARGIN_MM * PT_PER_MM, y, 0.0, 7.0, 1.0, GREY, &text);
        canvas.pages[i].extend(ops);
    }
    let font = subset_font(canvas.font, &canvas.used)?;
    let mut doc = PdfDocument::new(title);
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
    let mut c = Canvas::new(full_font()?);
    let run = &report.run;
    c.new_page();
    let mut y = MARGIN_MM + 6.0;
    c.text(
        MARGIN_MM,
        y,
        16.0,
        &format!("Centrifuge test report — run {}", run.id),
        Align::Left,
    );
    y += 8.0;
    for (label, value) in meta_rows(report) {
        c.text(MARGIN_MM, y, 9.0, label, Align::Left);
        c.text(MARGIN_MM + 28.0, y, 9.0, &value, Align::Left);
        y += 4.6;
    }
    if let Some(devices) = crate::devices(report) {
        y += 2.0;
        c.text(
            MARGIN_MM,
            y,
            11.0,
            "Instruments of the station",
            Align::Left,
        );
        y += 5.0;
        for (role, identity) in devices {
            c.text(MARGIN_MM, y, 8.0, &role, Align::Left);
            c.text(MARGIN_MM + 28.0, y, 8.0, &identity, Align::Left);
            y += 4.0;
        }
    }
    y += 3.0;
    c.text(MARGIN_MM, y, 11.0, "Summary", Align::Left);
    y += 2.0;
    let rows: Vec<Vec<String>> = summary(report)
        .iter()
        .map(|row| {
            let mut cells = vec![row.serial.clone(), row.slot.to_string(), row.mount.clone()];
            cells.extend(
                numbers(row)
                    .iter()
                    .zip(SUMMARY_DECIMALS)
                    .map(|(v, d)| crate::fmt(*v, d)),
            );
            cells.push(row.outcome.clone());
            cells.push(row.reasons.clone());
            cells
        })
        .collect();
    c.table(y, &SUMMARY_HEADERS, &rows, 7.0, 1);
    for u in &report.units {
        unit_page(&mut c, u);
    }
    finish(
        c,
        &format!("spinbench report {}", run.id),
        &format!(
            "spinbench {} · run {}",
            report.context.software_version, run.id
        ),
    )
}

/// One instrument: title, fit figures, the three plots, the points.
fn unit_page(c: &mut Canvas, u: &UnitReport) {
    c.new_page();
    let mut y = MARGIN_MM + 5.0;
    let title = format!("{} (slot {})", u.result.serial, u.result.slot + 1);
    c.text(MARGIN_MM, y, 14.0, &title, Align::Left);
    let x = MARGIN_MM + c.width_mm(&title, 14.0) + 4.0;
    let color = match u.result.outcome.as_str() {
        "fail" => (0.7, 0.0, 0.0),
        "marginal" => (0.65, 0.4, 0.0),
        _ => (0.0, 0.4, 0.0),
    };
    c.text_colored(x, y, 14.0, &u.result.outcome, Align::Left, color);
    y += 6.0;
    if let Some(fits) = u.record["analysis"]["fits"].as_object() {
        for (mount, fit) in fits {
            let ci = &fit["ci95"]["k2_ug_per_g2"];
            let half = match (ci[0].as_f64(), ci[1].as_f64()) {
                (Some(a), Some(b)) => Some((b - a) / 2.0),
                _ => None,
            };
            let line = format!(
                "mounting {mount}: k0 {} g · k1 {} Hz/g · k2 {} ± {} µg/g² (95 %) · k3 {} µg/g³ · residual RMS {} µg",
                crate::fmt(fit["k0_g"].as_f64(), 6),
                crate::fmt(fit["k1"].as_f64(), 6),
                crate::fmt(fit["k2_ug_per_g2"].as_f64(), 3),
                crate::fmt(half, 3),
                crate::fmt(fit["k3_ug_per_g3"].as_f64(), 3),
                crate::fmt(fit["residual_rms_ug"].as_f64(), 2),
            );
            c.text(MARGIN_MM, y, 8.5, &line, Align::Left);
            y += 4.2;
        }
    }
    let reasons: Vec<&str> = u.record["reasons"]
        .as_array()
        .map(|v| v.iter().filter_map(|r| r.as_str()).collect())
        .unwrap_or_default();
    if !reasons.is_empty() {
        let text = c.fit(&reasons.join("; "), 8.5, PAGE_W_MM - 2.0 * MARGIN_MM);
        c.text_colored(MARGIN_MM, y, 8.5, &text, Align::Left, (0.7, 0.0, 0.0));
        y += 4.2;
    }
    y += 1.0;
    let gap = 4.0;
    let width = (PAGE_W_MM - 2.0 * MARGIN_MM - 2.0 * gap) / 3.0;
    let height = width * plots::SIZE.1 as f32 / plots::SIZE.0 as f32;
    for (k, plot) in UNIT_PLOTS.iter().enumerate() {
        c.plot(MARGIN_MM + k as f32 * (width + gap), y, width, |root| {
            plot.draw(u, root)
        });
    }
    y += height + 3.0;
    let rows: Vec<Vec<String>> = u.points.iter().map(|p| point_cells(p).to_vec()).collect();
    c.table(y, &POINT_HEADERS, &rows, 6.5, 2);
}

/// The batch report as PDF bytes: totals and statistics, the histograms,
/// outliers, repeatability, then every test.
pub fn batch_pdf(b: &BatchReport) -> Result<Vec<u8>, ReportError> {
    let mut c = Canvas::new(full_font()?);
    c.new_page();
    let mut y = MARGIN_MM + 6.0;
    c.text(MARGIN_MM, y, 16.0, "Batch report", Align::Left);
    y += 7.0;
    let (pass, marginal, fail) = b.outcomes();
    let serials: BTreeSet<&str> = b.tests.iter().map(|t| t.serial.as_str()).collect();
    let totals = format!(
        "{} runs, {} instrument tests, {} serial numbers: {pass} pass, {marginal} marginal, {fail} fail{}",
        b.runs.len(),
        b.tests.len(),
        serials.len(),
        b.incomplete_note()
    );
    c.text(MARGIN_MM, y, 9.0, &totals, Align::Left);
    if let (Some(first), Some(last)) = (b.runs.first(), b.runs.last()) {
        y += 4.6;
        let span = format!(
            "runs from {} to {}",
            crate::unix_date(first.started_at),
            crate::unix_date(last.started_at)
        );
        c.text(MARGIN_MM, y, 9.0, &span, Align::Left);
    }
    y += 4.0;
    let rows = batch::statistics_rows(b);
    let bottom = c.table(y, &batch::STATISTICS_HEADERS, &rows, 7.5, 1);
    let gap = 4.0;
    let width = (PAGE_W_MM - 2.0 * MARGIN_MM - 2.0 * gap) / 3.0;
    let height = width * plots::SIZE.1 as f32 / plots::SIZE.0 as f32;
    let mut top = bottom + 2.0;
    for (k, d) in b.distributions.iter().enumerate() {
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
            |root| batch::draw_histogram(d, root),
        );
    }
    for (title, headers, rows) in [
        (
            "Outliers (|robust z| > 3.5)",
            &batch::OUTLIER_HEADERS[..],
            batch::outlier_rows(b),
        ),
        (
            "Repeatability of serial numbers tested more than once",
            &batch::REPEAT_HEADERS[..],
            batch::repeat_rows(b),
        ),
        ("Every test", &batch::TEST_HEADERS[..], batch::test_rows(b)),
    ] {
        c.new_page();
        c.text(MARGIN_MM, MARGIN_MM + 5.0, 12.0, title, Align::Left);
        if rows.is_empty() {
            c.text(MARGIN_MM, MARGIN_MM + 12.0, 9.0, "none", Align::Left);
        } else {
            c.table(MARGIN_MM + 8.0, headers, &rows, 7.0, 1);
        }
    }
    finish(c, "spinbench batch report", "spinbench batch report")
}
