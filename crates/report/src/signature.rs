//! The centrifuge's signature a run learned from its instruments
//! (analysis::table_signature): one line that says what it rests on and
//! what it corrected, and its plot, in the run's report and on the web's
//! station page.

use plotters::coord::Shift;
use plotters::prelude::*;
use spinbench_analysis::table_signature::TableSignature;

/// The run's signature: every record that was corrected carries the same
/// one; the first found.
pub fn of_run(report: &crate::RunReport) -> Option<&TableSignature> {
    report
        .units
        .iter()
        .find_map(|u| u.record().table_signature.as_ref())
}

/// The signature as an SVG document.
pub fn svg(signature: &TableSignature, lang: crate::Lang) -> Option<String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, crate::plots::SIZE).into_drawing_area();
        root.fill(&WHITE).ok()?;
        draw(signature, &root, lang)?;
        root.present().ok()?;
    }
    Some(out)
}

/// Draw it: the median residual of the mountings at each level with ±2
/// standard errors, and the correction made there (the spike, whole, and
/// the seen remainder).
pub(crate) fn draw<DB: DrawingBackend>(
    signature: &TableSignature,
    root: &DrawingArea<DB, Shift>,
    lang: crate::Lang,
) -> Option<()> {
    let levels = &signature.levels;
    if levels.is_empty() {
        return None;
    }
    let x_top = levels.iter().map(|l| l.g).fold(1.0_f64, f64::max) * 1.05;
    let values = levels.iter().flat_map(|l| {
        [
            l.residual_ug - 2.0 * l.se_ug,
            l.residual_ug + 2.0 * l.se_ug,
            l.spike_ug + l.remainder_ug,
        ]
    });
    let (lo, hi) = values.fold((0.0_f64, 0.0_f64), |(a, b), v| (a.min(v), b.max(v)));
    let pad = 0.08 * (hi - lo).max(1.0);
    let tr = |key: &str| crate::lang::tr(lang, key);
    let mut chart = ChartBuilder::on(root)
        .caption(tr("signature.plot_title"), ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(64)
        .build_cartesian_2d(-1.0..x_top, (lo - pad)..(hi + pad))
        .ok()?;
    chart
        .configure_mesh()
        .x_desc(tr("signature.plot_x"))
        .y_desc(tr("signature.plot_y"))
        .draw()
        .ok()?;
    chart
        .draw_series(levels.iter().map(|l| {
            PathElement::new(
                vec![
                    (l.g, l.residual_ug - 2.0 * l.se_ug),
                    (l.g, l.residual_ug + 2.0 * l.se_ug),
                ],
                BLUE,
            )
        }))
        .ok()?;
    chart
        .draw_series(
            levels
                .iter()
                .map(|l| Circle::new((l.g, l.residual_ug), 3, BLUE.filled())),
        )
        .ok()?
        .label(tr("signature.plot_measured"))
        .legend(|(x, y)| Circle::new((x, y), 3, BLUE.filled()));
    chart
        .draw_series(
            levels
                .iter()
                .map(|l| Cross::new((l.g, l.spike_ug + l.remainder_ug), 5, RED)),
        )
        .ok()?
        .label(tr("signature.plot_correction"))
        .legend(|(x, y)| Cross::new((x, y), 5, RED));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .ok()?;
    Some(())
}

/// What it rests on and what it corrected, in `lang`.
pub fn describe(signature: &TableSignature, lang: crate::Lang) -> String {
    let spikes = if signature.correction.spikes.is_empty() {
        crate::lang::tr(lang, "signature.no_spike")
    } else {
        signature
            .correction
            .spikes
            .iter()
            .map(|s| format!("{:+.0} µg @ {} g", s.height_ug, s.g))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let broad = signature
        .correction
        .remainder
        .iter()
        .fold(0.0_f64, |m, (_, r)| m.max(r.abs()));
    let text = rust_i18n::t!(
        "signature.describe",
        instruments = signature.instruments,
        mountings = signature.mountings,
        runs = signature.runs,
        spikes = spikes,
        broad = format!("{broad:.0}"),
        detection = format!("{:.0}", signature.detection_ug),
        locale = lang.code()
    )
    .into_owned();
    match &signature.change {
        Some(change) => format!(
            "{text} {}",
            rust_i18n::t!(
                "signature.changed",
                levels = change.levels_shown(),
                runs = change.earlier_runs,
                z = format!("{:.0}", change.largest_z),
                locale = lang.code()
            )
        ),
        None => text,
    }
}
