//! The rows and cells every format of a run's report shares: one summary
//! row per instrument-mounting, the points' cells, the run's meta rows.

use super::PointRow;
use crate::{Lang, RunReport, lang, tr};

/// One row of the summary table.
#[derive(Debug, Clone, PartialEq)]
pub struct SummaryRow {
    /// Serial number.
    pub serial: String,
    /// Slot (1-based).
    pub slot: i64,
    /// P or N.
    pub mount: String,
    /// Radius found [m].
    pub radius_m: Option<f64>,
    /// Drawing radius R0 [m].
    pub drawing_radius_m: Option<f64>,
    /// k0 [g].
    pub k0_g: Option<f64>,
    /// k1 [Hz/g].
    pub k1_hz_per_g: Option<f64>,
    /// k2 [µg/g²].
    pub k2_ug_per_g2: Option<f64>,
    /// Half-width of k2's 95 % interval from the fit alone (Type A) [µg/g²].
    pub k2_ci95_half_ug_per_g2: Option<f64>,
    /// k2's expanded uncertainty at 95 % from its GUM budget (Type A and B),
    /// the one the guarded decision uses [µg/g²].
    pub k2_u95_ug_per_g2: Option<f64>,
    /// k3 [µg/g³].
    pub k3_ug_per_g3: Option<f64>,
    /// k2_max of the instrument [µg/g²].
    pub k2_max_ug_per_g2: Option<f64>,
    /// Scale-factor nonlinearity: the largest residual of (11) [ppm].
    pub sf_nonlinearity_ppm: Option<f64>,
    /// Asymmetry [ppm].
    pub asymmetry_ppm: Option<f64>,
    /// Hysteresis [µg].
    pub hysteresis_ug: Option<f64>,
    /// The instrument's own K2 (both mountings; the same on each of its rows) [µg/g²].
    pub instrument_k2_ug_per_g2: Option<f64>,
    /// Its U95 [µg/g²].
    pub instrument_k2_u95_ug_per_g2: Option<f64>,
    /// The quantity the verdict judged (`K2`, `k2_max`; empty when the
    /// record does not say).
    pub judged: String,
    /// What the verdict judged, whole (`None` for a record made before
    /// the decision was recorded).
    pub verdict: Option<spinbench_engine::Judged>,
    /// Its limit [µg/g²].
    pub limit_ug_per_g2: Option<f64>,
    /// The decision rule (`guarded`, `simple`; empty when not recorded).
    pub rule: String,
    /// pass, marginal or fail.
    pub outcome: String,
    /// Why, when not a plain pass.
    pub reasons: String,
    /// The reasons' stable codes, in order (for a line's MES).
    pub reason_codes: Vec<String>,
}

/// The summary rows: one per instrument and mounting measured.
pub fn summary(report: &RunReport) -> Vec<SummaryRow> {
    summary_in(report, Lang::En)
}

/// The summary rows with their reasons in `lang`.
pub fn summary_in(report: &RunReport, lang: Lang) -> Vec<SummaryRow> {
    let mut rows = Vec::new();
    for u in &report.units {
        let r = u.record();
        let analysis = r.analysis.as_ref();
        let fits: Vec<Option<(&spinbench_analysis::Mount, &spinbench_analysis::MountingFit)>> =
            match analysis.map(|a| &a.fits) {
                Some(fits) if !fits.is_empty() => fits.iter().map(Some).collect(),
                _ => vec![None],
            };
        let figures = spinbench_store::ResultFigures::of(r);
        for entry in fits {
            let mount = entry.map(|(m, _)| *m);
            let fit = entry.map(|(_, f)| &f.fit);
            rows.push(SummaryRow {
                serial: u.result.serial.clone(),
                slot: u.result.slot + 1,
                mount: mount.map(|m| m.to_string()).unwrap_or_default(),
                radius_m: mount.and_then(|m| r.radius_m.get(&m).copied()),
                drawing_radius_m: Some(r.drawing_radius_m),
                k0_g: fit.map(|f| f.k0_g),
                k1_hz_per_g: fit.map(|f| f.k1),
                k2_ug_per_g2: fit.and_then(|f| f.k2_ug_per_g2),
                k2_ci95_half_ug_per_g2: fit
                    .and_then(|f| f.ci95.k2_ug_per_g2)
                    .map(|[a, b]| (b - a) / 2.0),
                k2_u95_ug_per_g2: entry
                    .and_then(|(_, f)| f.uncertainty.as_ref())
                    .and_then(|u| u.k2_ug_per_g2.as_ref())
                    .map(|u| u.u95),
                k3_ug_per_g3: fit.and_then(|f| f.k3_ug_per_g3),
                k2_max_ug_per_g2: u.result.k2_max_ug_per_g2,
                sf_nonlinearity_ppm: analysis
                    .and_then(|a| a.scale_factor.as_ref())
                    .map(|s| s.residual_max_ppm),
                asymmetry_ppm: analysis.and_then(|a| a.figures.asymmetry_ppm),
                hysteresis_ug: analysis.and_then(|a| a.figures.hysteresis_ug),
                instrument_k2_ug_per_g2: figures.instrument_k2,
                instrument_k2_u95_ug_per_g2: figures.instrument_k2_u95,
                judged: r
                    .decision
                    .map_or_else(String::new, |d| d.measurand.name().to_string()),
                verdict: r.judged(),
                limit_ug_per_g2: r.decision.map(|d| d.limit_ug_per_g2),
                rule: r
                    .decision
                    .map(|d| d.rule)
                    .or(r.decision_rule)
                    .map_or_else(String::new, |rule| rule.name().to_string()),
                outcome: u.result.outcome.to_string(),
                reasons: u.reasons_text_in(lang),
                reason_codes: r.reason_codes(),
            });
        }
    }
    rows
}

/// The summary table's columns, with units.
pub const SUMMARY_HEADERS: [&str; 16] = [
    "serial",
    "slot",
    "mount",
    "radius [m]",
    "R0 [m]",
    "k0 [g]",
    "k1 [Hz/g]",
    "k2 [µg/g²]",
    "k2 ±95% [µg/g²]",
    "k3 [µg/g³]",
    "k2_max [µg/g²]",
    "SF nonlinearity [ppm]",
    "asymmetry [ppm]",
    "hysteresis [µg]",
    "outcome",
    "reasons",
];

/// The CSV's columns after [`SUMMARY_HEADERS`]: what the verdict judged
/// (appended, so a reader of the earlier columns reads them where they were).
pub const DECISION_HEADERS: [&str; 5] = [
    "K2 [µg/g²]",
    "K2 U95 [µg/g²]",
    "judged",
    "limit [µg/g²]",
    "rule",
];

/// Decimals shown for the summary's numbers (HTML and PDF), in [`numbers`] order.
pub(crate) const SUMMARY_DECIMALS: [usize; 11] = [6, 3, 6, 6, 3, 3, 3, 3, 1, 1, 1];

/// The point table's columns (HTML and PDF).
pub(crate) const POINT_HEADERS: [&str; 10] = [
    "step",
    "mount",
    "level [g]",
    "direction",
    "applied [g]",
    "rate [deg/s]",
    "output [Hz]",
    "σ [Hz]",
    "n",
    "T [°C]",
];

/// One row of the point table, as shown.
pub(crate) fn point_cells(p: &PointRow, lang: Lang) -> [String; 10] {
    let direction = lang::tr_or(
        lang,
        &format!("arg.direction.{}", p.direction.as_str()),
        p.direction.as_str(),
    );
    [
        p.step.to_string(),
        p.mount.to_string(),
        p.g_nominal.to_string(),
        direction,
        format!("{:.6}", p.g_applied),
        format!("{:.4}", p.rate_deg_s),
        format!("{:.6}", p.output_hz),
        format!("{:.6}", p.std_hz),
        p.n.to_string(),
        p.temperature_c
            .map_or("—".to_string(), |t| format!("{t:.2}")),
    ]
}

/// The run's header block: (label — the catalogue's `meta.` key — and its
/// value, dates as `lang` writes them).
pub(crate) fn meta_rows_in(report: &RunReport, lang: Lang) -> Vec<(&'static str, String)> {
    let run = &report.run;
    let plan = &report.record.start.plan;
    let mut rows = Vec::new();
    if run.seq.is_some() {
        rows.push(("label", run.label()));
    }
    rows.push(("station", run.station.clone()));
    if let Some(original) = &run.retest_of {
        rows.push((
            "retest of",
            rust_i18n::t!("report.retest_of", run = original, locale = lang.code()).into_owned(),
        ));
    }
    if !report.retested_by.is_empty() {
        let runs: Vec<String> = report
            .retested_by
            .iter()
            .map(|id| rust_i18n::t!("report.run", run = id, locale = lang.code()).into_owned())
            .collect();
        rows.push(("retested by", runs.join(&tr(lang, "report.list_separator"))));
    }
    rows.extend([
        ("operator", plan.operator()),
        ("started", report.time(lang, run.started_at)),
        (
            "state",
            match (lang, &run.reason) {
                // English: the state and the reason as recorded.
                (Lang::En, Some(r)) => format!("{}: {r}", run.state),
                (Lang::En, None) => run.state.to_string(),
                (_, Some(r)) => format!(
                    "{}：{}",
                    lang::state(lang, run.state),
                    run.reason_wording
                        .as_ref()
                        .and_then(|w| lang::say(lang, w))
                        .unwrap_or_else(|| r.clone())
                ),
                (_, None) => lang::state(lang, run.state),
            },
        ),
        ("plan", plan.name()),
        (
            "decision rule",
            // Plans made before the rule was recorded (or that this release
            // cannot read) were judged by value alone.
            lang::decision_rule(lang, plan.decision_rule()),
        ),
        (
            "software",
            format!("spinbench {}", report.record.start.software_version),
        ),
    ]);
    if let Some(spans) = temperature_spans(report, lang) {
        rows.push(("instrument temperature", spans));
    }
    if let Some(p) = plan.plan.as_ref().and_then(|p| p.prediction.clone()) {
        let a = spinbench_engine::planning::achieved(report.units.iter().map(|u| u.record()));
        let shown = |v: Option<f64>, digits: usize| {
            v.map_or_else(|| "—".into(), |v| format!("{v:.digits$}"))
        };
        let range = p
            .k2_u95_run_range_ug_per_g2
            .map_or_else(String::new, |[low, high]| {
                rust_i18n::t!(
                    "report.prediction_range",
                    low = format!("{low:.3}"),
                    high = format!("{high:.3}"),
                    locale = lang.code()
                )
                .into_owned()
            });
        rows.push((
            "prediction",
            rust_i18n::t!(
                "report.prediction",
                u95 = format!("{:.3}", p.k2_u95_ug_per_g2),
                achieved_u95 = shown(a.k2_u95_ug_per_g2, 3),
                time = format!("{:.0}", p.centrifuge_time_s),
                achieved_time = shown(a.centrifuge_time_s, 0),
                published_u95 = shown(p.published_k2_u95_ug_per_g2, 3),
                published_time = shown(p.published_centrifuge_time_s, 0),
                runs = p.model_runs,
                locale = lang.code()
            )
            .into_owned()
                + &range
                + &p.sequential_centrifuge_time_max_s
                    .map_or_else(String::new, |t| {
                        rust_i18n::t!(
                            "report.prediction_sequential",
                            time = format!("{t:.0}"),
                            locale = lang.code()
                        )
                        .into_owned()
                    }),
        ));
    }
    rows
}

/// Each mounting's span of the instruments' temperatures over the run's
/// points, `P 26.98–26.99 °C; N 23.95–26.05 °C`: a signer sees whether the
/// mountings were measured in one thermal state (`None`: no point has a
/// temperature).
fn temperature_spans(report: &RunReport, lang: Lang) -> Option<String> {
    let mut spans: std::collections::BTreeMap<spinbench_analysis::Mount, (f64, f64)> =
        std::collections::BTreeMap::new();
    for u in &report.units {
        for p in &u.record().points {
            if let Some(t) = p.temperature_c.filter(|t| t.is_finite()) {
                let span = spans.entry(p.mount).or_insert((t, t));
                *span = (span.0.min(t), span.1.max(t));
            }
        }
    }
    (!spans.is_empty()).then(|| {
        spans
            .iter()
            .map(|(m, (low, high))| format!("{m} {low:.2}–{high:.2} °C"))
            .collect::<Vec<_>>()
            .join(&tr(lang, "report.list_separator"))
    })
}

pub(crate) fn numbers(row: &SummaryRow) -> [Option<f64>; 11] {
    [
        row.radius_m,
        row.drawing_radius_m,
        row.k0_g,
        row.k1_hz_per_g,
        row.k2_ug_per_g2,
        // The ±95 % shown is the one the decision uses: the GUM U95 where
        // there is a budget, else the fit's interval.
        row.k2_u95_ug_per_g2.or(row.k2_ci95_half_ug_per_g2),
        row.k3_ug_per_g3,
        row.k2_max_ug_per_g2,
        row.sf_nonlinearity_ppm,
        row.asymmetry_ppm,
        row.hysteresis_ug,
    ]
}
