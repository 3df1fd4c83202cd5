//! Control charts across the stored runs (issue 16, part 3): every chart
//! with its limits, the Western Electric rules broken, its SVG, and the
//! first-pass yields — the batch report's section, for the web UI.

use super::*;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Baseline {
    /// Limits from the first this many runs (default 10, 1 to 100,000).
    baseline_runs: Option<usize>,
}

/// Most runs a baseline may name.
const MAX_BASELINE_RUNS: usize = 100_000;

pub(super) async fn control_charts(
    State(app): State<App>,
    headers: HeaderMap,
    Query(q): Query<Baseline>,
) -> ApiResult<axum::Json<Value>> {
    use spinbench_report::control::{DEFAULT_BASELINE_RUNS, control_chart_svg};
    let session = authorize(&app, &headers, Role::Operator, false)?;
    // The rules' texts in the user's language (`rule` is the stable name).
    let lang = super::session::language_of(&app, &headers, Some(&session));
    let baseline = q.baseline_runs.unwrap_or(DEFAULT_BASELINE_RUNS);
    if !(1..=MAX_BASELINE_RUNS).contains(&baseline) {
        return Err(ApiError::bad(format!(
            "baseline_runs = {baseline}: from 1 to {MAX_BASELINE_RUNS} runs"
        )));
    }
    let mut batch = {
        let store = store(&app);
        spinbench_report::gather_batch(&store, &[])
    }
    .map_err(|e| ApiError::internal(e.to_string()))?;
    batch.rebaseline(baseline);
    let c = &batch.control;
    let charts: Vec<Value> = c
        .charts
        .iter()
        .map(|chart| {
            json!({
                "quantity": chart.quantity,
                "unit": chart.unit,
                "slot": chart.position.map(|p| p.0),
                "baseline": chart.baseline,
                "centre": chart.limits.map(|l| l.centre),
                "sigma": chart.limits.map(|l| l.sigma),
                "flagged": chart.flagged(),
                "points": chart.points.iter().map(|p| json!({
                    "run_id": p.run_id, "serial": p.serial, "value": p.value,
                })).collect::<Vec<_>>(),
                "violations": chart.violations.iter().map(|v| json!({
                    "point": v.index + 1, "run_id": chart.points[v.index].run_id,
                    "rule": v.rule, "says": spinbench_report::control::rule_text(lang, v.rule),
                })).collect::<Vec<_>>(),
                "svg": control_chart_svg(chart, lang),
            })
        })
        .collect();
    let yields = |list: &[spinbench_report::control::Yield]| -> Vec<Value> {
        list.iter()
            .map(|y| {
                json!({
                    "label": y.label, "first_tests": y.first_tests,
                    "first_passes": y.first_passes, "yield": y.fraction(),
                })
            })
            .collect()
    };
    Ok(axum::Json(json!({
        "baseline_runs": baseline,
        "runs": batch.runs.len(),
        "charts": charts,
        "yield_by_run": yields(&c.yield_by_run),
        "yield_by_day": yields(&c.yield_by_day),
    })))
}
