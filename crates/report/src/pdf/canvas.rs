//! The page canvas: A4 pages of PDF operators being laid out (text in the
//! embedded font, tables, lines), and the characters used on them.

use super::{
    BLACK, BTreeSet, Color, DrawingArea, FONT_ID, FOOTER_MM, FontId, GREY, Lang, Line, LinePoint,
    MARGIN_MM, OnceLock, Op, Outcome, PAGE_H_MM, PAGE_W_MM, PT_PER_MM, PaintMode, ParsedFont,
    PdfFontHandle, PdfPlotBackend, Point, Polygon, PolygonRing, Pt, Rgb, Shift, TextItem,
    TextMatrix, WHITE, WindingOrder, lang, plots,
};
use plotters::drawing::IntoDrawingArea;

/// Text alignment in a table cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Align {
    Left,
    Right,
}

/// Pages of PDF operators being laid out, and the characters used on them.
pub(super) struct Canvas {
    pub(super) font: &'static ParsedFont,
    pub(super) pages: Vec<Vec<Op>>,
    pub(super) used: BTreeSet<char>,
}

pub(super) fn rgb((r, g, b): (f32, f32, f32)) -> Color {
    Color::Rgb(Rgb::new(r, g, b, None))
}

pub(super) fn point(x_pt: f32, y_pt: f32) -> LinePoint {
    LinePoint {
        p: Point {
            x: Pt(x_pt),
            y: Pt(y_pt),
        },
        bezier: false,
    }
}

/// PDF y [pt] of a distance from the page's top [mm].
pub(super) fn from_top(y_mm: f32) -> f32 {
    (PAGE_H_MM - y_mm) * PT_PER_MM
}

/// An RGB colour, each part from 0 to 1.
type Colour = (f32, f32, f32);

/// The colour of a cell that is an outcome's word in any language (black
/// for any other cell); the words are looked up once per process.
fn outcome_color(cell: &str) -> Colour {
    static WORDS: OnceLock<Vec<(String, Colour)>> = OnceLock::new();
    let words = WORDS.get_or_init(|| {
        [
            (Outcome::Fail, (0.7, 0.0, 0.0)),
            (Outcome::Marginal, (0.65, 0.4, 0.0)),
            (Outcome::Inconclusive, (0.1, 0.25, 0.7)),
            (Outcome::Pass, (0.0, 0.4, 0.0)),
        ]
        .into_iter()
        .flat_map(|(o, colour)| {
            Lang::ALL
                .iter()
                .map(move |&l| (lang::outcome(l, o.as_str()), colour))
        })
        .collect()
    });
    words
        .iter()
        .find(|(w, _)| w == cell)
        .map_or(BLACK, |(_, colour)| *colour)
}

impl Canvas {
    pub(super) fn new(font: &'static ParsedFont) -> Canvas {
        Canvas {
            font,
            pages: Vec::new(),
            used: BTreeSet::new(),
        }
    }

    pub(super) fn new_page(&mut self) {
        self.pages.push(Vec::new());
    }

    pub(super) fn ops(&mut self) -> &mut Vec<Op> {
        if self.pages.is_empty() {
            self.new_page();
        }
        let last = self.pages.len() - 1;
        &mut self.pages[last]
    }

    /// Advance width of `text` at `size` (in the units of `size`).
    pub(super) fn width(&self, text: &str, size: f32) -> f32 {
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

    pub(super) fn width_mm(&self, text: &str, size_pt: f32) -> f32 {
        self.width(text, size_pt) / PT_PER_MM
    }

    /// `text` in lines at most `max_mm` wide, broken at spaces (within a
    /// word too long for a line, and in Chinese text, between characters):
    /// nothing a signer must read is cut. Every line after
    /// the first is indented by two spaces.
    pub(super) fn wrap(&self, text: &str, size_pt: f32, max_mm: f32) -> Vec<String> {
        let mut lines = Vec::new();
        let mut line = String::new();
        let fits = |s: &str| self.width_mm(s, size_pt) <= max_mm;
        for word in text.split(' ') {
            let candidate = if line.is_empty() {
                word.to_string()
            } else {
                format!("{line} {word}")
            };
            if fits(&candidate) {
                line = candidate;
                continue;
            }
            if !line.trim().is_empty() {
                lines.push(std::mem::take(&mut line));
                line = "  ".to_string();
            }
            // The word alone: character by character where it is too long.
            for c in word.chars() {
                line.push(c);
                if !fits(&line) && line.trim().chars().count() > 1 {
                    line.pop();
                    lines.push(std::mem::take(&mut line));
                    line = format!("  {c}");
                }
            }
        }
        if !line.trim().is_empty() {
            lines.push(line);
        }
        lines
    }

    /// Text with its baseline starting at (`x_pt`, `y_pt`), turned
    /// counter-clockwise by `angle_deg`, on the current page.
    pub(super) fn text_pt(
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
    pub(super) fn text_ops(
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
    pub(super) fn text(&mut self, x_mm: f32, y_mm: f32, size_pt: f32, text: &str, align: Align) {
        self.text_colored(x_mm, y_mm, size_pt, text, align, BLACK);
    }

    pub(super) fn text_colored(
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
    pub(super) fn rule(&mut self, x1_mm: f32, x2_mm: f32, y_mm: f32, width_pt: f32) {
        let y = from_top(y_mm);
        self.stroke(
            &[point(x1_mm * PT_PER_MM, y), point(x2_mm * PT_PER_MM, y)],
            GREY,
            width_pt,
            false,
        );
    }

    pub(super) fn stroke(
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

    pub(super) fn fill(&mut self, points: Vec<LinePoint>, color: (f32, f32, f32)) {
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
    pub(super) fn table<S: AsRef<str>>(
        &mut self,
        mut y_mm: f32,
        headers: &[S],
        rows: &[Vec<String>],
        size_pt: f32,
        across: usize,
    ) -> f32 {
        let line_mm = size_pt / PT_PER_MM * 1.4;
        let pad_mm = 2.0;
        // Headers "name [unit]" on two lines.
        let heads: Vec<(String, String)> = headers
            .iter()
            .map(|h| match h.as_ref().split_once(" [") {
                Some((name, unit)) => (name.to_string(), format!("[{unit}")),
                None => (h.as_ref().to_string(), String::new()),
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
            // The last column wraps (its reasons), never cut.
            let last_lines = row
                .get(n.saturating_sub(1))
                .filter(|_| n > 0 && row.len() >= n)
                .map(|cell| self.wrap(cell, size_pt, widths[n - 1]))
                .unwrap_or_default();
            let row_mm = line_mm * last_lines.len().max(1) as f32;
            if y_mm + row_mm > last_y {
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
                let color = outcome_color(cell);
                if c + 1 == n && !numeric[c] {
                    for (k, text) in last_lines.iter().enumerate() {
                        let y = y_mm + line_mm * (0.8 + k as f32);
                        self.text_colored(x, y, size_pt, text, Align::Left, color);
                    }
                    continue;
                }
                let text = cell.clone();
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
            y_mm += row_mm;
        }
        y_mm
    }

    /// Draw a plot with `draw` (a plotters chart on any backend) with its
    /// top-left corner at (`x_mm`, `y_mm`), `width_mm` wide. Returns
    /// whether anything was drawn.
    pub(super) fn plot(
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
