//! [`PdfPlotBackend`]: a plotters backend that emits PDF path and text
//! operators (written by hand: no crate draws plotters charts into printpdf
//! operators), so the PDF's plots are the very same charts as the HTML's SVG.

use super::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, Canvas, DrawingBackend,
    DrawingErrorKind, FontTransform, HPos, Infallible, LinePoint, VPos, plots, point,
};

/// A plotters backend that draws into a [`Canvas`] page as PDF vector
/// operators: plotters lays the chart out in its pixel grid, and each pixel
/// becomes `pt_per_px` points on the page.
pub(super) struct PdfPlotBackend<'a> {
    pub(super) canvas: &'a mut Canvas,
    /// Page x of the plot's left edge [pt].
    pub(super) left_pt: f32,
    /// Page y of the plot's top edge [pt].
    pub(super) top_pt: f32,
    pub(super) pt_per_px: f32,
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
