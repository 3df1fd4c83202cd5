//! The runs' history: every run of the fleet or one station, one run's
//! results with its links, its reports, every test of one serial number.

use super::schema::{
    ErrorBody, JudgedValue, ResultRow, RunDetail, RunEntry, UnitHistory, UnitTest,
};
use super::{
    ApiError, ApiResult, App, Deserialize, HeaderMap, Json, Path, Query, QueryRejection,
    ReportFormat, Response, Role, State, authorize, blocking, header, query_error, store,
};
use axum::response::IntoResponse;

/// Which runs, one page at a time (`GET /api/runs`).
#[derive(Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct StationFilter {
    /// Only this station's runs (its id; every station's without it).
    #[param(max_length = 64)]
    station: Option<String>,
    /// The most runs in the page (1 to 1000; default 200).
    #[param(minimum = 1, maximum = 1000)]
    limit: Option<usize>,
    /// The page after this one's last run: the `next` cursor of the
    /// previous page's `Link` header (`STARTED.ID`, the run's start [Unix
    /// s] and id).
    #[param(
        max_length = 80,
        pattern = r"^(0|[1-9][0-9]{0,10})\.[A-Za-z0-9_-]{1,64}$"
    )]
    after: Option<String>,
}

/// The latest start a cursor may name [Unix s] (year 9999).
const MAX_CURSOR_UNIX_S: i64 = 253_402_300_799;

/// Runs in a page unless `limit` says.
const DEFAULT_RUNS_PAGE: usize = 200;

/// `STARTED.ID` as a cursor, refused in words when it is not one.
fn cursor(text: &str) -> Result<(i64, String), ApiError> {
    let bad = || {
        ApiError::bad(format!(
            "after '{}': a cursor is STARTED.ID, as the previous page's Link header gives it",
            spinbench_engine::bounds::shown(text)
        ))
    };
    let (t, id) = text.split_once('.').ok_or_else(bad)?;
    let t: i64 = t.parse().map_err(|_| bad())?;
    let id_ok = !id.is_empty()
        && id.len() <= 64
        && id
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if !id_ok || !(0..=MAX_CURSOR_UNIX_S).contains(&t) {
        return Err(bad());
    }
    Ok((t, id.to_string()))
}

/// The runs of the fleet (or of one station), newest first, one page at a
/// time: the filter and the page are the database's, and a `Link` header
/// (`rel="next"`) gives the next page while there is one.
#[utoipa::path(get, path = "/api/runs", tag = "runs",
    security(("session" = [])),
    params(StationFilter),
    responses(
        (status = 200, description = "a page of the runs; the header `Link: </api/runs?…&after=CURSOR>; rel=\"next\"` while more follow", body = Vec<RunEntry>),
        (status = 400, description = "a bad query string", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn runs(
    State(app): State<App>,
    headers: HeaderMap,
    q: Result<Query<StationFilter>, QueryRejection>,
) -> ApiResult<Response> {
    authorize(&app, &headers, Role::Operator, false).await?;
    let Query(q) = q.map_err(query_error)?;
    let limit = q.limit.unwrap_or(DEFAULT_RUNS_PAGE);
    if !(1..=spinbench_store::MAX_RUNS_PAGE).contains(&limit) {
        return Err(ApiError::bad(format!(
            "limit {limit}: from 1 to {} runs a page",
            spinbench_store::MAX_RUNS_PAGE
        )));
    }
    let after = q.after.as_deref().map(cursor).transpose()?;
    let station = q.station.clone();
    let (runs, more) = blocking(&app, move |app| {
        Ok(store(app)?.runs_page(
            station.as_deref(),
            after.as_ref().map(|(t, id)| (*t, id.as_str())),
            limit,
        )?)
    })
    .await?;
    let next = runs.last().filter(|_| more).map(|last| {
        let mut query = format!("limit={limit}&after={}.{}", last.started_at, last.id);
        if let Some(s) = &q.station {
            query = format!("station={}&{query}", url_encoded(s));
        }
        format!("</api/runs?{query}>; rel=\"next\"")
    });
    let entries: Vec<RunEntry> = runs.iter().map(RunEntry::from).collect();
    let mut response = Json(entries).into_response();
    if let Some(link) = next.and_then(|l| l.parse().ok()) {
        response.headers_mut().insert(header::LINK, link);
    }
    Ok(response)
}

/// `text` with everything but unreserved characters percent-encoded.
fn url_encoded(text: &str) -> String {
    text.bytes()
        .map(|b| {
            if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
                (b as char).to_string()
            } else {
                format!("%{b:02X}")
            }
        })
        .collect()
}

/// One run: its results (reasons in the user's language), links and reports.
#[utoipa::path(get, path = "/api/runs/{id}", tag = "runs",
    security(("session" = [])),
    params(("id" = String, Path, description = "the run")),
    responses(
        (status = 200, description = "the run", body = RunDetail),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 404, description = "no such run", body = ErrorBody),
    ))]
pub(super) async fn run(
    State(app): State<App>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> ApiResult<Json<RunDetail>> {
    let session = authorize(&app, &headers, Role::Operator, false).await?;
    // The results' reasons in the user's language (the records keep codes).
    let lang = super::session::language_of(&app, &headers, Some(&session)).await;
    let asked = id.clone();
    let report = blocking(&app, move |app| {
        Ok(spinbench_report::gather(&*store(app)?, &asked))
    })
    .await?
    .map_err(|e| match e {
        spinbench_report::ReportError::NoRun(_) => ApiError::not_found(e.to_string()),
        other => ApiError::internal(other.to_string()),
    })?;
    let rows: Vec<ResultRow> = spinbench_report::summary_in(&report, lang)
        .into_iter()
        .map(|r| ResultRow {
            serial: r.serial,
            slot: r.slot,
            mount: r.mount,
            radius_m: r.radius_m,
            drawing_radius_m: r.drawing_radius_m,
            k0_g: r.k0_g,
            k1_hz_per_g: r.k1_hz_per_g,
            k2_ug_per_g2: r.k2_ug_per_g2,
            k2_ci95_half_ug_per_g2: r.k2_ci95_half_ug_per_g2,
            k2_u95_ug_per_g2: r.k2_u95_ug_per_g2,
            k3_ug_per_g3: r.k3_ug_per_g3,
            k2_max_ug_per_g2: r.k2_max_ug_per_g2,
            sf_nonlinearity_ppm: r.sf_nonlinearity_ppm,
            asymmetry_ppm: r.asymmetry_ppm,
            hysteresis_ug: r.hysteresis_ug,
            outcome: r.outcome,
            reasons: r.reasons,
            reason_codes: r.reason_codes,
            judged: r.verdict.map(JudgedValue::from),
            instrument_k2_ug_per_g2: r.instrument_k2_ug_per_g2,
            instrument_k2_u95_ug_per_g2: r.instrument_k2_u95_ug_per_g2,
        })
        .collect();
    let run = &report.run;
    let to_retest: Vec<String> = report
        .units
        .iter()
        .filter(|u| spinbench_engine::retest::needs_retest(u.record()))
        .map(|u| u.result.serial.clone())
        .collect();
    Ok(Json(RunDetail {
        run: RunEntry::from(run),
        retested_by: report.retested_by.clone(),
        to_retest,
        results: rows,
        reports: ReportFormat::ALL
            .iter()
            .map(|f| format!("/api/runs/{}/report/{}", run.id, f.ext()))
            .collect(),
    }))
}

#[derive(Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct ReportQuery {
    /// `en` or `zh-CN` (default: the user's language, else the browser's).
    #[param(value_type = Option<super::schema::LanguageTag>)]
    lang: Option<String>,
}

/// A run's report as a file.
#[utoipa::path(get, path = "/api/runs/{id}/report/{format}", tag = "runs",
    security(("session" = [])),
    params(
        ("id" = String, Path, description = "the run"),
        ("format" = super::schema::ReportFormatName, Path, description = "the file's format"),
        ReportQuery,
    ),
    responses(
        (status = 200, description = "the report", content(
            (super::schema::BinaryFile = "application/pdf"),
            (String = "text/html; charset=utf-8"),
            (super::schema::BinaryFile = "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet"),
            (String = "text/csv; charset=utf-8"),
        )),
        (status = 400, description = "an unknown format or language", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 404, description = "no such run", body = ErrorBody),
    ))]
pub(super) async fn report(
    State(app): State<App>,
    headers: HeaderMap,
    Path((id, format)): Path<(String, String)>,
    q: Result<Query<ReportQuery>, QueryRejection>,
) -> ApiResult<Response> {
    let session = authorize(&app, &headers, Role::Operator, false).await?;
    let Query(q) = q.map_err(query_error)?;
    let format = ReportFormat::parse(&format).ok_or_else(|| {
        ApiError::bad(format!(
            "report format '{format}': use pdf, html, xlsx or csv"
        ))
    })?;
    let lang = match q.lang.as_deref() {
        Some(tag) => spinbench_report::Lang::parse(tag).ok_or_else(|| {
            ApiError::bad(format!(
                "lang '{}': en or zh-CN",
                tag.chars().take(40).collect::<String>()
            ))
        })?,
        None => super::session::language_of(&app, &headers, Some(&session)).await,
    };
    let db = app.db.clone();
    let run_id = id.clone();
    // A 96-instrument PDF takes a moment: off the async workers, on its own connection.
    let (stem, bytes) = tokio::task::spawn_blocking(move || {
        let store = spinbench_store::Store::connect(&db)?;
        let report = spinbench_report::gather(&store, &run_id)?;
        let stem = spinbench_report::report_file_stem_in(&report.run, lang);
        spinbench_report::render_in(&report, format, lang).map(|bytes| (stem, bytes))
    })
    .await
    .map_err(|e| ApiError::internal(e.to_string()))?
    .map_err(|e| match e {
        spinbench_report::ReportError::NoRun(_) => ApiError::not_found(e.to_string()),
        other => ApiError::internal(other.to_string()),
    })?;
    Ok((
        [
            (header::CONTENT_TYPE, format.mime().to_string()),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{stem}.{}\"", format.ext()),
            ),
        ],
        bytes,
    )
        .into_response())
}

/// Every test of one serial number.
#[utoipa::path(get, path = "/api/units/{serial}", tag = "runs",
    security(("session" = [])),
    params(("serial" = String, Path, description = "the serial number")),
    responses(
        (status = 200, description = "its tests", body = UnitHistory),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 404, description = "no run holds it", body = ErrorBody),
    ))]
pub(super) async fn unit(
    State(app): State<App>,
    headers: HeaderMap,
    Path(serial): Path<String>,
) -> ApiResult<Json<UnitHistory>> {
    authorize(&app, &headers, Role::Operator, false).await?;
    let asked = serial.clone();
    let history = blocking(&app, move |app| Ok(store(app)?.unit_history(&asked)?)).await?;
    if history.is_empty() {
        return Err(ApiError::not_found(format!(
            "no run holds serial '{serial}'"
        )));
    }
    Ok(Json(UnitHistory {
        serial,
        tests: history
            .iter()
            .map(|h| UnitTest {
                run_id: h.run_id.clone(),
                slot: h.slot + 1,
                outcome: h.outcome.to_string(),
                k2_max_ug_per_g2: h.k2_max_ug_per_g2,
                judged: h.record.judged().map(JudgedValue::from),
                reason_codes: h.record.reason_codes(),
            })
            .collect(),
    }))
}
