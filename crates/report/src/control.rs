//! Control charts across the runs of a batch: the
//! product's k2_max, K2, K1, k0 and asymmetry test by test, and each
//! fixture position's found radius run by run (a drifting radius is a
//! fixture coming loose), each against limits from a baseline period with
//! the Western Electric rules flagged ([`spinbench_analysis::control`]);
//! and the first-pass yield per run and per day.

use crate::batch::{BatchReport, BatchTest};
use plotters::coord::Shift;
use plotters::prelude::*;
use spinbench_analysis::Mount;
use spinbench_analysis::control::{ControlLimits, Violation, western_electric};
use spinbench_engine::Outcome;
use std::collections::BTreeMap;

/// Baseline points from which a chart's limits count as settled (the usual
/// 20–25 of an individuals chart); below, they are said to be provisional.
pub const SETTLED_BASELINE_POINTS: usize = 20;

/// "limits from n = 24", or "provisional limits (n = 6)" on a short
/// baseline, in `lang`.
pub fn limits_caption(chart: &ControlChart, lang: crate::Lang) -> String {
    let key = if chart.baseline < SETTLED_BASELINE_POINTS {
        "chart.provisional_limits"
    } else {
        "chart.limits_from"
    };
    rust_i18n::t!(key, n = chart.baseline, locale = lang.code()).into_owned()
}

/// The baseline period when none is chosen: the first this many runs.
pub const DEFAULT_BASELINE_RUNS: usize = 10;

/// One point of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartPoint {
    /// The run.
    pub run_id: String,
    /// When it started [Unix s].
    pub started_at: i64,
    /// The instrument (product charts) or empty (radius charts).
    pub serial: String,
    /// The value.
    pub value: f64,
}

/// One control chart.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlChart {
    /// What it charts, e.g. "K2" or "radius slot 3 P".
    pub quantity: String,
    /// Its unit.
    pub unit: &'static str,
    /// The fixture position for a radius chart: the slot (1-based) and the
    /// mounting (absent: the mean of both, the fixture's centre).
    pub position: Option<(usize, Option<Mount>)>,
    /// Its points in time order.
    pub points: Vec<ChartPoint>,
    /// How many of the first points are the baseline.
    pub baseline: usize,
    /// Centre and σ̂ from the baseline (absent: too short a baseline).
    pub limits: Option<ControlLimits>,
    /// The Western Electric rules broken.
    pub violations: Vec<Violation>,
}

impl ControlChart {
    /// A chart of `points` whose first `baseline` give its limits; with
    /// `sigma`, that σ̂ instead of the chart's own (the centre stays its own).
    fn new(
        quantity: String,
        unit: &'static str,
        position: Option<(usize, Option<Mount>)>,
        points: Vec<ChartPoint>,
        baseline: usize,
        sigma: Option<f64>,
    ) -> ControlChart {
        let values: Vec<f64> = points.iter().map(|p| p.value).collect();
        let limits = ControlLimits::from_baseline(&values[..baseline.min(values.len())]).map(|l| {
            ControlLimits {
                sigma: sigma.filter(|s| *s > 0.0).unwrap_or(l.sigma),
                ..l
            }
        });
        let violations = limits
            .map(|l| western_electric(&values, &l))
            .unwrap_or_default();
        ControlChart {
            quantity,
            unit,
            position,
            points,
            baseline,
            limits,
            violations,
        }
    }

    /// True when a rule is broken.
    pub fn flagged(&self) -> bool {
        !self.violations.is_empty()
    }
}

/// First-pass yield of a group (a run or a day).
#[derive(Debug, Clone, PartialEq)]
pub struct Yield {
    /// The run's id or the day (YYYY-MM-DD, UTC).
    pub label: String,
    /// Instruments tested for the first time.
    pub first_tests: usize,
    /// Of those, how many passed (pass or marginal) the first time.
    pub first_passes: usize,
}

impl Yield {
    /// The fraction, when any were tested.
    pub fn fraction(&self) -> Option<f64> {
        (self.first_tests > 0).then(|| self.first_passes as f64 / self.first_tests as f64)
    }
}

/// Every chart and the yields.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ControlReport {
    /// The baseline period: the first this many runs.
    pub baseline_runs: usize,
    /// Product charts, then one radius chart per fixture position.
    pub charts: Vec<ControlChart>,
    /// First-pass yield per run, in run order.
    pub yield_by_run: Vec<Yield>,
    /// First-pass yield per day.
    pub yield_by_day: Vec<Yield>,
}

type Figure = fn(&BatchTest) -> Option<f64>;

/// The product figures charted test by test: (name, unit, value).
const PRODUCT: [(&str, &str, Figure); 5] = [
    ("k2_max", "µg/g²", |t| t.k2_max_ug_per_g2),
    ("K2", "µg/g²", |t| {
        t.analysis
            .as_ref()
            .and_then(|a| a.joint.as_ref())
            .map(|j| j.k2_even_ug_per_g2)
    }),
    ("K1", "Hz/g", |t| t.k1_hz_per_g),
    ("k0", "µg", |t| {
        t.analysis
            .as_ref()
            .and_then(|a| a.full_range.as_ref())
            .map(|f| f.fit.k0_g * 1e6)
    }),
    ("asymmetry", "ppm", |t| t.asymmetry_ppm),
];

/// The charts of a batch with limits from its first `baseline_runs` runs.
/// Incomplete tests are left out (as from every statistic).
pub fn control_report(b: &BatchReport, baseline_runs: usize) -> ControlReport {
    let baseline_ids: Vec<&str> = b
        .runs
        .iter()
        .take(baseline_runs)
        .map(|r| r.id.as_str())
        .collect();
    let in_baseline = |run: &str| baseline_ids.contains(&run);
    let measured: Vec<&BatchTest> = b
        .tests
        .iter()
        .filter(|t| t.outcome != Outcome::Incomplete)
        .collect();
    let mut charts = Vec::new();
    for (name, unit, value) in PRODUCT {
        let points: Vec<ChartPoint> = measured
            .iter()
            .filter_map(|t| {
                value(t).filter(|v| v.is_finite()).map(|v| ChartPoint {
                    run_id: t.run_id.clone(),
                    started_at: t.started_at,
                    serial: t.serial.clone(),
                    value: v,
                })
            })
            .collect();
        if points.is_empty() {
            continue;
        }
        let baseline = points.iter().filter(|p| in_baseline(&p.run_id)).count();
        charts.push(ControlChart::new(
            name.into(),
            unit,
            None,
            points,
            baseline,
            None,
        ));
    }
    // Each fixture position's radius, one point per run that used it: with
    // both mountings their mean, the fixture's centre (the proof mass's
    // offset, which differs from instrument to instrument, is + in one and
    // − in the other and leaves it), else the one mounting's.
    let mut positions: BTreeMap<(usize, Option<Mount>), Vec<ChartPoint>> = BTreeMap::new();
    for t in &measured {
        let finite = |m| t.radius_m.get(&m).copied().filter(|r| r.is_finite());
        let (mount, radius_m) = match (finite(Mount::P), finite(Mount::N)) {
            (Some(p), Some(n)) => (None, 0.5 * (p + n)),
            (Some(p), None) => (Some(Mount::P), p),
            (None, Some(n)) => (Some(Mount::N), n),
            (None, None) => continue,
        };
        positions
            .entry((t.slot + 1, mount))
            .or_default()
            .push(ChartPoint {
                run_id: t.run_id.clone(),
                started_at: t.started_at,
                serial: t.serial.clone(),
                value: radius_m * 1e3,
            });
    }
    // One σ̂ for every position of a kind (centre, P or N): the radius's
    // repeatability is the method's, not the fixture's, and a baseline of a
    // few runs per position gives too uncertain a σ̂ alone (false alarms).
    let pooled_sigma = |kind: Option<Mount>| -> Option<f64> {
        let ranges: Vec<f64> = positions
            .iter()
            .filter(|((_, m), _)| *m == kind)
            .flat_map(|(_, points)| {
                let base: Vec<f64> = points
                    .iter()
                    .filter(|p| in_baseline(&p.run_id))
                    .map(|p| p.value)
                    .collect();
                base.windows(2)
                    .map(|w| (w[1] - w[0]).abs())
                    .collect::<Vec<_>>()
            })
            .collect();
        (ranges.len() >= spinbench_analysis::control::MIN_BASELINE - 1).then(|| {
            ranges.iter().sum::<f64>() / ranges.len() as f64 / spinbench_analysis::control::D2_N2
        })
    };
    let sigmas: BTreeMap<Option<Mount>, Option<f64>> = [None, Some(Mount::P), Some(Mount::N)]
        .into_iter()
        .map(|k| (k, pooled_sigma(k)))
        .collect();
    for ((slot, mount), points) in positions {
        let baseline = points.iter().filter(|p| in_baseline(&p.run_id)).count();
        let name = match mount {
            None => format!("radius slot {slot}"),
            Some(m) => format!("radius slot {slot} {m:?}"),
        };
        let sigma = sigmas.get(&mount).copied().flatten();
        charts.push(ControlChart::new(
            name,
            "mm",
            Some((slot, mount)),
            points,
            baseline,
            sigma,
        ));
    }
    let (yield_by_run, yield_by_day) = first_pass_yields(&measured);
    ControlReport {
        baseline_runs,
        charts,
        yield_by_run,
        yield_by_day,
    }
}

/// First-pass yield per run and per day: of the instruments tested for the
/// first time (in the batch), how many passed (pass or marginal).
fn first_pass_yields(tests: &[&BatchTest]) -> (Vec<Yield>, Vec<Yield>) {
    let mut seen = std::collections::BTreeSet::new();
    let mut by_run: Vec<Yield> = Vec::new();
    let mut by_day: Vec<Yield> = Vec::new();
    let add = |list: &mut Vec<Yield>, label: &str, passed: bool| {
        if list.last().is_none_or(|y| y.label != label) {
            list.push(Yield {
                label: label.to_string(),
                first_tests: 0,
                first_passes: 0,
            });
        }
        if let Some(y) = list.last_mut() {
            y.first_tests += 1;
            y.first_passes += usize::from(passed);
        }
    };
    for t in tests {
        if !seen.insert(t.serial.clone()) {
            continue;
        }
        let passed = matches!(t.outcome, Outcome::Pass | Outcome::Marginal);
        add(&mut by_run, &t.run_id, passed);
        let day: String = crate::unix_date(t.started_at).chars().take(10).collect();
        add(&mut by_day, &day, passed);
    }
    (by_run, by_day)
}

/// A chart's quantity as `lang` names it: a fixture position's radius
/// (`radius slot 2 P` → 半径 工位 2 P), a figure through the catalogue's
/// `figure.` names; symbols (k2_max, K2, K1, k0) stay as they are.
pub fn quantity_label(lang: crate::Lang, chart: &ControlChart) -> String {
    match chart.position {
        Some((slot, mount)) => {
            let radius =
                rust_i18n::t!("chart.radius_slot", slot = slot, locale = lang.code()).into_owned();
            match mount {
                Some(m) => format!("{radius} {m:?}"),
                None => radius,
            }
        }
        None => crate::lang::tr_or(lang, &format!("figure.{}", chart.quantity), &chart.quantity),
    }
}

/// The flags table's columns.
pub(crate) const FLAG_HEADERS: [&str; 6] = ["chart", "point", "run", "serial", "value", "rule"];

/// One row per rule broken.
pub(crate) fn flag_rows(c: &ControlReport, lang: crate::Lang) -> Vec<Vec<String>> {
    c.charts
        .iter()
        .flat_map(|chart| {
            chart.violations.iter().map(move |v| {
                let p = &chart.points[v.index];
                vec![
                    quantity_label(lang, chart),
                    (v.index + 1).to_string(),
                    p.run_id.clone(),
                    p.serial.clone(),
                    format!("{:.6} {}", p.value, chart.unit),
                    rule_text(lang, v.rule),
                ]
            })
        })
        .collect()
}

/// A Western Electric rule's text in `lang` (English: its own description).
pub fn rule_text(lang: crate::Lang, rule: spinbench_analysis::control::WesternElectric) -> String {
    match lang {
        crate::Lang::En => rule.describe().to_string(),
        _ => crate::lang::tr_or(
            lang,
            &format!("we.{}", crate::lang::serde_name(rule)),
            rule.describe(),
        ),
    }
}

/// The yield table's columns.
pub(crate) const YIELD_HEADERS: [&str; 4] =
    ["run or day", "first tests", "passed first time", "yield"];

/// One row per run, then one per day.
pub(crate) fn yield_rows(c: &ControlReport) -> Vec<Vec<String>> {
    c.yield_by_run
        .iter()
        .chain(&c.yield_by_day)
        .map(|y| {
            vec![
                y.label.clone(),
                y.first_tests.to_string(),
                y.first_passes.to_string(),
                y.fraction()
                    .map_or("—".into(), |f| format!("{:.1} %", 100.0 * f)),
            ]
        })
        .collect()
}

/// The charts worth drawing: every product chart, and the radius charts
/// that broke a rule (the rest are in the flags table as in control).
pub fn shown(c: &ControlReport) -> impl Iterator<Item = &ControlChart> {
    c.charts
        .iter()
        .filter(|chart| chart.position.is_none() || chart.flagged())
}

/// Draw a control chart on any plotters backend: the points in order, the
/// centre, ±1σ̂, ±2σ̂ and the ±3σ̂ limits, the baseline's end, and every
/// point that broke a rule in red. The caption gives the baseline's n, and
/// calls the limits provisional below [`SETTLED_BASELINE_POINTS`].
pub(crate) fn draw_control_chart<DB: DrawingBackend>(
    chart: &ControlChart,
    root: &DrawingArea<DB, Shift>,
    lang: crate::Lang,
) -> Option<()> {
    let values: Vec<f64> = chart.points.iter().map(|p| p.value).collect();
    let (mut lo, mut hi) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if let Some(l) = chart.limits {
        let (l3, u3) = l.limits();
        lo = lo.min(l3);
        hi = hi.max(u3);
    }
    // A margin around the values, also when they are one value (or equal).
    let scale = lo.abs().max(hi.abs());
    let pad = ((hi - lo) * 0.08).max(scale * 1e-6).max(1e-9);
    let n = values.len().max(2) as f64;
    // Tick labels with as many decimals as the span needs, no more.
    let span = hi - lo + 2.0 * pad;
    let decimals = (-(span / 5.0).log10()).ceil().clamp(0.0, 9.0) as usize;
    let mut c = ChartBuilder::on(root)
        .caption(
            format!(
                "{} [{}] — {}",
                quantity_label(lang, chart),
                chart.unit,
                limits_caption(chart, lang)
            ),
            ("sans-serif", 15),
        )
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(72)
        .build_cartesian_2d(0.5..n + 0.5, (lo - pad)..(hi + pad))
        .ok()?;
    c.configure_mesh()
        .x_desc(crate::tr(
            lang,
            if chart.position.is_some() {
                "chart.runs_in_order"
            } else {
                "chart.tests_in_order"
            },
        ))
        .x_labels(values.len().clamp(2, 12))
        .x_label_formatter(&|x| {
            if (x - x.round()).abs() < 1e-6 {
                format!("{x:.0}")
            } else {
                String::new()
            }
        })
        .y_label_formatter(&|y| format!("{y:.decimals$}"))
        .y_desc(format!("{} [{}]", quantity_label(lang, chart), chart.unit))
        .draw()
        .ok()?;
    let x_end = n + 0.5;
    if let Some(l) = chart.limits {
        for (k, colour, width) in [
            (0.0, BLACK, 2),
            (1.0, RGBColor(170, 170, 170), 1),
            (2.0, RGBColor(230, 150, 0), 1),
            (3.0, RED, 2),
        ] {
            for side in [-1.0, 1.0] {
                let y = l.centre + side * k * l.sigma;
                c.draw_series(LineSeries::new(
                    [(0.5, y), (x_end, y)],
                    colour.stroke_width(width),
                ))
                .ok()?;
            }
        }
        if chart.baseline > 0 && chart.baseline < values.len() {
            let x = chart.baseline as f64 + 0.5;
            c.draw_series(LineSeries::new(
                [(x, lo - pad), (x, hi + pad)],
                BLUE.mix(0.5).stroke_width(1),
            ))
            .ok()?;
        }
    }
    c.draw_series(LineSeries::new(
        values.iter().enumerate().map(|(i, &v)| (i as f64 + 1.0, v)),
        BLUE.stroke_width(1),
    ))
    .ok()?;
    let flagged: std::collections::BTreeSet<usize> =
        chart.violations.iter().map(|v| v.index).collect();
    c.draw_series(values.iter().enumerate().map(|(i, &v)| {
        let colour = if flagged.contains(&i) { RED } else { BLUE };
        Circle::new((i as f64 + 1.0, v), 3, colour.filled())
    }))
    .ok()?;
    Some(())
}

/// The batch report's HTML section: the flags, the charts, the yields.
pub(crate) fn html_section(h: &mut String, c: &ControlReport, lang: crate::Lang) {
    h.push_str(&format!(
        "<h2>{}</h2>\n",
        crate::esc(&rust_i18n::t!(
            "batch.control",
            runs = c.baseline_runs,
            locale = lang.code()
        ))
    ));
    let in_control: Vec<String> = c
        .charts
        .iter()
        .filter(|ch| !ch.flagged())
        .map(|ch| crate::esc(&quantity_label(lang, ch)))
        .collect();
    h.push_str(&format!(
        "<p id=\"in-control\">{}: {}.</p>\n",
        crate::esc(&crate::tr(lang, "batch.in_control")),
        if in_control.is_empty() {
            crate::tr(lang, "batch.none")
        } else {
            in_control.join(", ")
        }
    ));
    let heads = |list: &[&str]| -> Vec<String> {
        list.iter().map(|x| crate::lang::header(lang, x)).collect()
    };
    crate::text::html_table(
        h,
        "control-flags",
        &heads(&FLAG_HEADERS),
        &flag_rows(c, lang),
    );
    for chart in shown(c) {
        if let Some(svg) = control_chart_svg(chart, lang) {
            h.push_str("<figure class=\"control-chart\">");
            h.push_str(&svg);
            h.push_str("</figure>\n");
        }
    }
    h.push_str(&format!(
        "<h2>{}</h2>\n",
        crate::esc(&crate::tr(lang, "batch.yield"))
    ));
    crate::text::html_table(h, "yield", &heads(&YIELD_HEADERS), &yield_rows(c));
}

/// A control chart as SVG.
pub fn control_chart_svg(chart: &ControlChart, lang: crate::Lang) -> Option<String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, crate::plots::SIZE).into_drawing_area();
        root.fill(&WHITE).ok()?;
        draw_control_chart(chart, &root, lang)?;
        root.present().ok()?;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use spinbench_store::RunRow;

    fn run(i: usize) -> RunRow {
        RunRow {
            id: format!("r{i:02}"),
            station: "s".into(),
            state: spinbench_store::StoredState::Completed,
            reason: None,
            started_at: 1_700_000_000 + 3600 * i as i64,
            units: 2,
            points: 0,
            retest_of: None,
            reason_wording: None,
            seq: Some(i as i64 + 1),
            utc_offset_s: 0,
        }
    }

    fn test(run: &RunRow, slot: usize, serial: &str, radius_m: f64, outcome: Outcome) -> BatchTest {
        BatchTest {
            run_id: run.id.clone(),
            started_at: run.started_at,
            serial: serial.into(),
            slot,
            radius_m: [(Mount::P, radius_m)].into_iter().collect(),
            outcome,
            k2_max_ug_per_g2: Some(10.0 + slot as f64),
            k2_ug_per_g2: None,
            k1_hz_per_g: None,
            sf_nonlinearity_ppm: None,
            asymmetry_ppm: None,
            analysis: None,
            temperature_coefficients: None,
        }
    }

    #[test]
    fn a_drifting_position_is_flagged_and_the_yields_count_first_tests() {
        let runs: Vec<RunRow> = (0..24).map(run).collect();
        let mut tests = Vec::new();
        for (i, r) in runs.iter().enumerate() {
            // ±1 µm of scatter; slot 2 drifts 2 µm a run from run 12 on.
            let wobble = 1e-6 * ((i * 7 % 5) as f64 - 2.0) / 2.0;
            let drift = 2e-6 * i.saturating_sub(11) as f64;
            tests.push(test(r, 0, &format!("A{i}"), 0.8 + wobble, Outcome::Pass));
            tests.push(test(
                r,
                1,
                &format!("B{i}"),
                0.8 + wobble + drift,
                Outcome::Fail,
            ));
        }
        // A serial tested again later is not a first test.
        tests.push(test(&runs[23], 3, "A0", 0.8, Outcome::Pass));
        let b = BatchReport {
            runs,
            tests,
            distributions: Vec::new(),
            repeats: Vec::new(),
            control: ControlReport::default(),
        };
        let c = control_report(&b, 10);
        let flagged: Vec<&str> = c
            .charts
            .iter()
            .filter(|ch| ch.position.is_some() && ch.flagged())
            .map(|ch| ch.quantity.as_str())
            .collect();
        assert_eq!(flagged, ["radius slot 2 P"]);
        let chart = c
            .charts
            .iter()
            .find(|ch| ch.quantity == "radius slot 2 P")
            .expect("chart");
        assert_eq!(chart.baseline, 10);
        assert!(
            chart.violations.iter().all(|v| v.index >= 12),
            "{:?}",
            chart.violations
        );
        assert_eq!(c.yield_by_run.len(), 24);
        assert_eq!(c.yield_by_run[0].fraction(), Some(0.5));
        assert_eq!(
            c.yield_by_run[23].first_tests, 2,
            "A0 again is not a first test"
        );
        assert_eq!(
            c.yield_by_day.iter().map(|y| y.first_tests).sum::<usize>(),
            48
        );
        let svg = control_chart_svg(chart, crate::Lang::En).expect("svg");
        assert!(svg.contains("<svg") && svg.contains("radius slot 2 P"));
        // Ten baseline points are provisional limits, said
        // with n; twenty-five are settled, n still shown.
        assert!(svg.contains("provisional limits (n = 10)"), "{svg}");
        let zh = control_chart_svg(chart, crate::Lang::ZhCn).expect("svg");
        assert!(zh.contains("临时控制限（n = 10）"), "{zh}");
        let long = ControlChart::new(
            "k2".into(),
            "µg/g²",
            None,
            chart.points.iter().cycle().take(30).cloned().collect(),
            25,
            None,
        );
        let settled = control_chart_svg(&long, crate::Lang::En).expect("svg");
        assert!(
            settled.contains("limits from n = 25") && !settled.contains("provisional"),
            "{settled}"
        );
        assert!(
            flag_rows(&c, crate::Lang::En)
                .iter()
                .all(|r| r[0] == "radius slot 2 P")
        );
    }
}
