//! The per-instrument plots, drawn with plotters into SVG (vector; text as
//! SVG text, so the browser's fonts render any script).

use crate::UnitReport;
use crate::lang::{Lang, tr};

/// The catalogue's `key` in `lang` filled with `args`; the key's English
/// template unfilled when a value is missing (never the case here).
fn fill(lang: Lang, key: &str, args: &[(&str, &str)]) -> String {
    let args = args
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    crate::lang::fill(lang, key, &args).unwrap_or_else(|| tr(lang, key))
}
use plotters::coord::Shift;
use plotters::prelude::*;
use spinbench_analysis::{Direction, Mount};

/// Size of every plot [px]; the PDF maps it onto its page.
pub(crate) const SIZE: (u32, u32) = (460, 320);

/// One residual of a stored fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ResidualPoint {
    /// P or N.
    pub mount: Mount,
    /// Level [g].
    pub g_nominal: f64,
    /// Fit input [g] (signed by the mounting in the plots).
    pub g_input: f64,
    /// Up, down, or not known.
    pub direction: Option<Direction>,
    /// Observed output [Hz].
    pub output: f64,
    /// Residual [µg].
    pub residual_ug: f64,
}

/// Every residual of the instrument's per-mounting fits.
pub fn residuals(u: &UnitReport) -> Vec<ResidualPoint> {
    let mut out = Vec::new();
    let fits = u.record().analysis.as_ref().map(|a| &a.fits);
    for (mount, fit) in fits.into_iter().flatten() {
        for r in &fit.fit.residuals {
            out.push(ResidualPoint {
                mount: *mount,
                g_nominal: r.g_nominal,
                g_input: r.g_input,
                direction: r.direction,
                output: r.output,
                residual_ug: r.residual_ug,
            });
        }
    }
    out
}

fn sign(mount: &Mount) -> f64 {
    mount.input_sign()
}

fn range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return None;
    }
    let pad = ((hi - lo) * 0.08).max(1e-9 * hi.abs().max(1.0));
    Some((lo - pad, hi + pad))
}

/// The three plots of an instrument's page, in order.
pub(crate) const UNIT_PLOTS: [UnitPlot; 3] =
    [UnitPlot::OutputVsG, UnitPlot::ResidualsVsG, UnitPlot::K1VsG];

/// One of the per-instrument plots.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum UnitPlot {
    /// Output vs applied acceleration.
    OutputVsG,
    /// Fit residuals vs level.
    ResidualsVsG,
    /// K1(a) with its fit.
    K1VsG,
}

impl UnitPlot {
    /// Draw the plot on any plotters backend (SVG for HTML, PDF operators
    /// for the PDF); `None` if there is nothing to draw or drawing failed.
    pub(crate) fn draw<DB: DrawingBackend>(
        self,
        u: &UnitReport,
        root: &DrawingArea<DB, Shift>,
        lang: Lang,
    ) -> Option<()> {
        match self {
            UnitPlot::OutputVsG => draw_output_vs_g(u, root, lang),
            UnitPlot::ResidualsVsG => draw_residuals_vs_g(u, root, lang),
            UnitPlot::K1VsG => draw_k1_vs_g(u, root, lang),
        }
    }

    /// The plot as an SVG document, its words in `lang`.
    pub(crate) fn svg(self, u: &UnitReport, lang: Lang) -> Option<String> {
        let mut out = String::new();
        {
            let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
            root.fill(&WHITE).ok()?;
            self.draw(u, &root, lang)?;
            root.present().ok()?;
        }
        Some(out)
    }
}

/// Output [Hz] vs applied acceleration [g], both mountings (N drawn at −g).
fn draw_output_vs_g<DB: DrawingBackend>(
    u: &UnitReport,
    root: &DrawingArea<DB, Shift>,
    lang: Lang,
) -> Option<()> {
    let pts: Vec<(f64, f64, &str)> = u
        .points
        .iter()
        .map(|p| {
            (
                sign(&p.mount) * p.g_applied.abs(),
                p.output_hz,
                if p.mount == Mount::N { "N" } else { "P" },
            )
        })
        .collect();
    let x = range(pts.iter().map(|p| p.0))?;
    let y = range(pts.iter().map(|p| p.1))?;
    {
        let mut chart = ChartBuilder::on(root)
            .caption(tr(lang, "plot.output_title"), ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(64)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)
            .ok()?;
        chart
            .configure_mesh()
            .x_desc(tr(lang, "plot.output_x"))
            .y_desc(tr(lang, "plot.output_y"))
            .draw()
            .ok()?;
        for (mount, color) in [("P", BLUE), ("N", RED)] {
            chart
                .draw_series(
                    pts.iter()
                        .filter(|p| p.2 == mount)
                        .map(|p| Circle::new((p.0, p.1), 3, color.filled())),
                )
                .ok()?
                .label(fill(lang, "plot.mounting", &[("mount", mount)]))
                .legend(move |(x, y)| Circle::new((x, y), 3, color.filled()));
        }
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .ok()
    }
}

/// Where to ring each outlier level on the residual plot: (signed level,
/// mean residual of its readings [µg]).
pub fn outlier_marks(u: &UnitReport, res: &[ResidualPoint]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let fits = u.record().analysis.as_ref().map(|a| &a.fits);
    for (mount, fit) in fits.into_iter().flatten() {
        let m = *mount;
        for o in fit.diagnostics.iter().flat_map(|d| &d.outlier_levels) {
            let at: Vec<f64> = res
                .iter()
                .filter(|r| r.mount == m && r.g_nominal.abs() == o.g)
                .map(|r| r.residual_ug)
                .collect();
            if !at.is_empty() {
                let mean = at.iter().sum::<f64>() / at.len() as f64;
                out.push((sign(&m) * o.g, mean));
            }
        }
    }
    out
}

/// Fit residuals [µg] vs level [g]: up as circles, down as crosses, the
/// diagnostics' outlier levels ringed.
fn draw_residuals_vs_g<DB: DrawingBackend>(
    u: &UnitReport,
    root: &DrawingArea<DB, Shift>,
    lang: Lang,
) -> Option<()> {
    let res = residuals(u);
    let x = range(res.iter().map(|r| sign(&r.mount) * r.g_nominal.abs()))?;
    let y = range(res.iter().map(|r| r.residual_ug))?;
    {
        let mut chart = ChartBuilder::on(root)
            .caption(tr(lang, "plot.residuals_title"), ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(64)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)
            .ok()?;
        chart
            .configure_mesh()
            .x_desc(tr(lang, "plot.residuals_x"))
            .y_desc(tr(lang, "plot.residuals_y"))
            .draw()
            .ok()?;
        chart
            .draw_series(
                res.iter()
                    .filter(|r| r.direction != Some(Direction::Down))
                    .map(|r| {
                        Circle::new(
                            (sign(&r.mount) * r.g_nominal.abs(), r.residual_ug),
                            3,
                            BLUE.filled(),
                        )
                    }),
            )
            .ok()?
            .label(tr(lang, "arg.direction.up"))
            .legend(|(x, y)| Circle::new((x, y), 3, BLUE.filled()));
        chart
            .draw_series(
                res.iter()
                    .filter(|r| r.direction == Some(Direction::Down))
                    .map(|r| {
                        Cross::new((sign(&r.mount) * r.g_nominal.abs(), r.residual_ug), 4, RED)
                    }),
            )
            .ok()?
            .label(tr(lang, "arg.direction.down"))
            .legend(|(x, y)| Cross::new((x, y), 4, RED));
        // The levels the diagnostics flag as off the curve, ringed.
        let flagged = outlier_marks(u, &res);
        if !flagged.is_empty() {
            chart
                .draw_series(
                    flagged
                        .iter()
                        .map(|&(x, y)| Circle::new((x, y), 9, MAGENTA.stroke_width(2))),
                )
                .ok()?
                .label(tr(lang, "plot.outlier_level"))
                .legend(|(x, y)| Circle::new((x, y), 5, MAGENTA.stroke_width(2)));
        }
        // Upper left: the residuals of the top levels sit upper right.
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .ok()
    }
}

/// K1(a) (10) with its fit KA + KB·a + KC·a² (11).
fn draw_k1_vs_g<DB: DrawingBackend>(
    u: &UnitReport,
    root: &DrawingArea<DB, Shift>,
    lang: Lang,
) -> Option<()> {
    let sf = u.record().analysis.as_ref()?.scale_factor.as_ref()?;
    let pts: Vec<(f64, f64)> = sf.points.iter().map(|p| (p.g_input, p.k1)).collect();
    let (ka, kb, kc) = (sf.ka, sf.kb, sf.kc);
    let x = range(pts.iter().map(|p| p.0))?;
    let curve: Vec<(f64, f64)> = (0..=100)
        .map(|i| {
            let a = x.0 + (x.1 - x.0) * f64::from(i) / 100.0;
            (a, ka + kb * a + kc * a * a)
        })
        .collect();
    let y = range(pts.iter().map(|p| p.1).chain(curve.iter().map(|c| c.1)))?;
    {
        let mut chart = ChartBuilder::on(root)
            .caption(tr(lang, "plot.k1_title"), ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(72)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)
            .ok()?;
        chart
            .configure_mesh()
            .x_desc(tr(lang, "plot.k1_x"))
            .y_desc(tr(lang, "plot.k1_y"))
            .draw()
            .ok()?;
        chart
            .draw_series(pts.iter().map(|p| Circle::new(*p, 3, BLUE.filled())))
            .ok()?
            .label("K1(a)")
            .legend(|(x, y)| Circle::new((x, y), 3, BLUE.filled()));
        chart
            .draw_series(LineSeries::new(curve, RED))
            .ok()?
            .label("KA + KB·a + KC·a²")
            .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], RED));
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .ok()
    }
}
