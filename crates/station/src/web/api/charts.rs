//! Control charts across the stored runs: every chart
//! with its limits, the Western Electric rules broken, its SVG, and the
//! first-pass yields — the batch report's section, for the web UI; one
//! station (centrifuge) at a time, this server's unless another is asked.

use super::{
    ApiError, ApiResult, App, Deserialize, HeaderMap, Json, Query, QueryRejection, Role, State,
    authorize, blocking, query_error, store,
};

use super::schema::{ChartPoint, ChartReply, ChartViolation, ChartsReply, ErrorBody, YieldRow};

#[derive(Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct Baseline {
    /// Limits from the first this many runs (default 10, 1 to 100,000).
    #[param(minimum = 1, maximum = 100000)]
    baseline_runs: Option<usize>,
    /// The station (centrifuge) whose runs are charted: its fixture
    /// positions are its own (default: this server's station).
    #[param(max_length = 64)]
    station: Option<String>,
    /// Chart its newest this many runs (default 200, 1 to 1000): what a
    /// chart reads does not grow with the station's history.
    #[param(minimum = 1, maximum = 1000)]
    runs: Option<usize>,
}

/// Runs charted unless `runs` says.
const DEFAULT_CHARTED_RUNS: usize = 200;

/// Most runs a baseline may name.
const MAX_BASELINE_RUNS: usize = 100_000;

/// Control charts across the stored runs, with the rules broken and the yields.
#[utoipa::path(get, path = "/api/control-charts", tag = "charts",
    security(("session" = [])),
    params(Baseline),
    responses(
        (status = 200, description = "the charts", body = ChartsReply),
        (status = 400, description = "a baseline outside 1 to 100,000 runs", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn control_charts(
    State(app): State<App>,
    headers: HeaderMap,
    q: Result<Query<Baseline>, QueryRejection>,
) -> ApiResult<Json<ChartsReply>> {
    use spinbench_report::control::{DEFAULT_BASELINE_RUNS, control_chart_svg};
    let session = authorize(&app, &headers, Role::Operator, false).await?;
    let Query(q) = q.map_err(query_error)?;
    // The rules' texts in the user's language (`rule` is the stable name).
    let lang = super::session::language_of(&app, &headers, Some(&session)).await;
    let baseline = q.baseline_runs.unwrap_or(DEFAULT_BASELINE_RUNS);
    if !(1..=MAX_BASELINE_RUNS).contains(&baseline) {
        return Err(ApiError::bad(format!(
            "baseline_runs = {baseline}: from 1 to {MAX_BASELINE_RUNS} runs"
        )));
    }
    // One centrifuge's runs: a fixture position's radius is its own.
    let station = q
        .station
        .clone()
        .unwrap_or_else(|| app.runner.station().0.station);
    let window = q.runs.unwrap_or(DEFAULT_CHARTED_RUNS);
    if !(1..=spinbench_store::MAX_RUNS_PAGE).contains(&window) {
        return Err(ApiError::bad(format!(
            "runs = {window}: from 1 to {} runs",
            spinbench_store::MAX_RUNS_PAGE
        )));
    }
    // The newest runs and their results, filtered, windowed and ordered by
    // the database: two statements, whatever the history.
    let mut batch = blocking(&app, move |app| {
        Ok(spinbench_report::newest_batch(
            &*store(app)?,
            &station,
            window,
        ))
    })
    .await?
    .map_err(|e| ApiError::internal(e.to_string()))?;
    if batch.runs.is_empty() {
        // No run of that station: nothing to chart.
        return Ok(Json(ChartsReply {
            baseline_runs: baseline,
            runs: 0,
            charts: Vec::new(),
            yield_by_run: Vec::new(),
            yield_by_day: Vec::new(),
        }));
    }
    batch.rebaseline(baseline);
    let c = &batch.control;
    let charts: Vec<ChartReply> = c
        .charts
        .iter()
        .map(|chart| ChartReply {
            quantity: chart.quantity.clone(),
            unit: chart.unit.to_string(),
            slot: chart.position.map(|p| p.0),
            baseline: chart.baseline,
            centre: chart.limits.map(|l| l.centre),
            sigma: chart.limits.map(|l| l.sigma),
            flagged: chart.flagged(),
            points: chart
                .points
                .iter()
                .map(|p| ChartPoint {
                    run_id: p.run_id.clone(),
                    serial: p.serial.clone(),
                    value: p.value,
                })
                .collect(),
            violations: chart
                .violations
                .iter()
                .map(|v| ChartViolation {
                    point: v.index + 1,
                    run_id: chart.points[v.index].run_id.clone(),
                    run_label: batch
                        .runs
                        .iter()
                        .find(|r| r.id == chart.points[v.index].run_id)
                        .map_or_else(|| chart.points[v.index].run_id.clone(), |r| r.label()),
                    serial: chart.points[v.index].serial.clone(),
                    rule: spinbench_report::lang::serde_name(v.rule),
                    says: spinbench_report::control::rule_text(lang, v.rule),
                })
                .collect(),
            svg: control_chart_svg(chart, lang),
        })
        .collect();
    let yields = |list: &[spinbench_report::control::Yield]| -> Vec<YieldRow> {
        list.iter()
            .map(|y| YieldRow {
                label: y.label.clone(),
                first_tests: y.first_tests,
                first_passes: y.first_passes,
                fraction: y.fraction(),
            })
            .collect()
    };
    Ok(Json(ChartsReply {
        baseline_runs: baseline,
        runs: batch.runs.len(),
        charts,
        yield_by_run: yields(&c.yield_by_run),
        yield_by_day: yields(&c.yield_by_day),
    }))
}
