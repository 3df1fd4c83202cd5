//! What every format of the batch report shows: the histograms' drawing and
//! the tables' headers and rows.

use super::{
    BLUE, BatchReport, BatchTest, ChartBuilder, Distribution, DrawingArea, DrawingBackend,
    Rectangle, SVGBackend, Shift, WHITE, fmt,
};
use plotters::drawing::IntoDrawingArea;
use plotters::style::Color;

/// Draw a distribution's histogram on any plotters backend.
pub(crate) fn draw_histogram<DB: DrawingBackend>(
    d: &Distribution,
    root: &DrawingArea<DB, Shift>,
    lang: crate::Lang,
) -> Option<()> {
    let (lo, hi) = (d.bins.first()?.0, d.bins.last()?.1);
    let top = d.bins.iter().map(|b| b.2).max().unwrap_or(1).max(1) as f64 * 1.15;
    let name = figure_name(lang, d.name);
    let mut chart = ChartBuilder::on(root)
        .caption(
            rust_i18n::t!(
                "batch.histogram_caption",
                name = name,
                unit = d.unit,
                n = d.n,
                mean = format!("{:.4}", d.mean),
                std = format!("{:.4}", d.std),
                locale = lang.code()
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
        .x_desc(format!("{name} [{}]", d.unit))
        .y_desc(crate::lang::tr(lang, "batch.axis_tests"))
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
pub(crate) fn histogram_svg(d: &Distribution, lang: crate::Lang) -> Option<String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, crate::plots::SIZE).into_drawing_area();
        root.fill(&WHITE).ok()?;
        draw_histogram(d, &root, lang)?;
        root.present().ok()?;
    }
    Some(out)
}

/// The statistics table's columns.
pub(crate) const STATISTICS_HEADERS: [&str; 9] = [
    "figure", "unit", "n", "mean", "σ", "min", "median", "max", "outliers",
];

/// A figure's name in `lang` (`asymmetry` → 不对称度); symbols (k2,
/// K1) are the same in every language.
pub(crate) fn figure_name(lang: crate::Lang, name: &str) -> String {
    crate::lang::tr_or(lang, &format!("figure.{name}"), name)
}

/// One statistics row per figure, as shown.
pub(crate) fn statistics_rows(b: &BatchReport, lang: crate::Lang) -> Vec<Vec<String>> {
    b.distributions
        .iter()
        .map(|d| {
            vec![
                figure_name(lang, d.name),
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
pub(crate) fn outlier_rows(b: &BatchReport, lang: crate::Lang) -> Vec<Vec<String>> {
    b.distributions
        .iter()
        .flat_map(|d| {
            d.outliers.iter().map(move |o| {
                vec![
                    format!("{} [{}]", figure_name(lang, d.name), d.unit),
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

pub(crate) fn test_numbers(t: &BatchTest) -> [Option<f64>; 5] {
    [
        t.k2_ug_per_g2,
        t.k2_max_ug_per_g2,
        t.k1_hz_per_g,
        t.sf_nonlinearity_ppm,
        t.asymmetry_ppm,
    ]
}

/// One row per test, as shown (3–6 decimals).
pub(crate) fn test_rows(b: &BatchReport, lang: crate::Lang) -> Vec<Vec<String>> {
    b.tests
        .iter()
        .map(|t| {
            let mut row = vec![
                t.run_id.clone(),
                crate::lang::date_time(lang, t.started_at),
                t.serial.clone(),
                crate::lang::outcome(lang, t.outcome.as_str()),
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
