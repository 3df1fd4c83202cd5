//! Runs: start one, answer its prompts, pause, resume, abort; the history,
//! one run's results, its reports, every run of one serial number.

use super::plans::plan_name_ok;
use super::schema::{
    ErrorBody, ExcludeLevel, Excluded, PromptAnswer, ResultRow, RetestRequest, RetestStarted,
    RunDetail, RunEntry, RunId, StartRun, UnitHistory, UnitTest,
};
use super::*;
use spinbench_engine::event::Wording;

/// Start a run of a plan; serials per slot replace the plan's.
#[utoipa::path(post, path = "/api/runs", tag = "runs",
    security(("session" = [], "csrf" = [])),
    request_body(content = StartRun, description = "At most 2 MiB (413 beyond)."),
    responses(
        (status = 201, description = "started", body = RunId),
        (status = 400, description = "not a start body, bad serials, or a plan that cannot run", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token; an override by someone not an admin", body = ErrorBody),
        (status = 404, description = "no plan of that name", body = ErrorBody),
        (status = 409, description = "a run is active, or a device is overdue for calibration", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
        (status = 503, description = "the hardware cannot be reached", body = ErrorBody),
    ))]
pub(super) async fn start_run(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<(StatusCode, Json<RunId>)> {
    let session = authorize(&app, &headers, Role::Operator, true).await?;
    let start: StartRun = parse_json(&body)?;
    if !plan_name_ok(&start.plan) {
        return Err(ApiError::bad(format!(
            "plan '{}': 1 to 64 letters, digits, - or _",
            spinbench_engine::bounds::shown(&start.plan)
        )));
    }
    let path = app.plans_dir.join(format!("{}.toml", start.plan));
    let text = std::fs::read_to_string(&path).map_err(|_| {
        ApiError::not_found(format!("no plan named '{}' (GET /api/plans)", start.plan))
    })?;
    let mut plan = TestPlan::from_toml(&text).map_err(|e| ApiError::bad(e.to_string()))?;
    let serials: BTreeMap<String, String> = start
        .serials
        .into_iter()
        .filter(|(_, s)| !s.trim().is_empty())
        .collect();
    if !serials.is_empty() {
        plan.serials = serials;
    }
    plan.operator = session.user.clone();
    if plan.retest_of.is_some() {
        let checked = plan.clone();
        blocking(&app, move |app| {
            crate::retest::check_retest_of(&store(app), &checked).map_err(|e| match e {
                crate::retest::RetestFromStoreError::Store(e) => ApiError::from(e),
                e => ApiError::bad(e.to_string()),
            })
        })
        .await?;
    }
    let overridden = check_equipment(&app, &session, start.override_overdue.as_deref()).await?;
    let run_id = start_plan(&app, &plan, &session.user).await?;
    if let Some(devices) = overridden {
        audit(
            &app,
            &session.user,
            "override overdue calibration",
            &format!(
                "{run_id} started with {devices} overdue: {}",
                start.override_overdue.as_deref().unwrap_or_default()
            ),
        )
        .await?;
    }
    let serial_list: Vec<String> = plan
        .serials
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    audit(
        &app,
        &session.user,
        "start run",
        &format!(
            "{run_id} plan {} serials {}",
            start.plan,
            serial_list.join(" ")
        ),
    )
    .await?;
    Ok((StatusCode::CREATED, Json(RunId { run_id })))
}

/// Refuse a run while a device is overdue for calibration, unless an admin
/// gives a reason to override (then the overdue devices, for the audit log).
async fn check_equipment(
    app: &App,
    session: &Session,
    override_reason: Option<&str>,
) -> ApiResult<Option<String>> {
    let station = app.runner.station().0;
    let required = station.equipment.require_registered;
    let list = blocking(app, move |app| {
        Ok(crate::equipment::station_equipment(&store(app), &station)?)
    })
    .await?;
    let Some(late) = crate::equipment::overdue(&list, required) else {
        return Ok(None);
    };
    match override_reason.map(str::trim) {
        Some(reason) if !reason.is_empty() && session.role >= Role::Admin => {
            if reason.chars().count() > 500 || reason.chars().any(char::is_control) {
                return Err(ApiError::bad(
                    "override_overdue: at most 500 characters, no control characters",
                ));
            }
            Ok(Some(late))
        }
        Some(_) if session.role < Role::Admin => Err(ApiError::new(
            StatusCode::FORBIDDEN,
            format!("{late} overdue for calibration: only an admin may start a run anyway"),
        )
        .worded(Wording::new("error.overdue_admin_only").with("devices", &late))),
        _ => Err(ApiError::conflict(format!(
            "{late} overdue for calibration: calibrate it and update the equipment register, or an admin starts the run with a reason (override_overdue)"
        ))
        .worded(Wording::new("error.overdue").with("devices", &late))),
    }
}

/// Start `plan` on the station for `user`; the run's id. Off the runtime:
/// starting opens the store, the run's files and the devices' ports.
async fn start_plan(app: &App, plan: &TestPlan, user: &str) -> ApiResult<String> {
    let plan_text = toml::to_string(plan).map_err(|e| ApiError::internal(e.to_string()))?;
    let (plan, user) = (plan.clone(), user.to_string());
    blocking(app, move |app| {
        Ok(app.runner.start(plan, &plan_text, &user))
    })
    .await?
    .map_err(|e| match e {
        StartError::Busy(id) => ApiError::conflict(format!(
            "run {id} is active; wait for it to end or abort it"
        ))
        .worded(Wording::new("error.busy").with("run", id)),
        StartError::Invalid(why) => ApiError::bad(why),
        StartError::Hardware(why) => ApiError::new(StatusCode::SERVICE_UNAVAILABLE, why),
        StartError::Files(why) => ApiError::internal(why),
    })
}

/// `POST /api/runs/{id}/retest`: a run of the finished run's failed,
/// inconclusive, incomplete and flagged instruments, same serials and plan,
/// linked to it (`retest_of`).
#[utoipa::path(post, path = "/api/runs/{id}/retest", tag = "runs",
    security(("session" = [], "csrf" = [])),
    params(("id" = String, Path, description = "the finished run")),
    request_body(content = Option<RetestRequest>, description = "Optional. At most 2 MiB (413 beyond)."),
    responses(
        (status = 201, description = "the retest started", body = RetestStarted),
        (status = 400, description = "not a run id, or a bad body", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token", body = ErrorBody),
        (status = 404, description = "no such run", body = ErrorBody),
        (status = 409, description = "the run has not ended, has nothing to retest, was recorded by another station, or a run is active", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
        (status = 503, description = "the hardware cannot be reached", body = ErrorBody),
    ))]
pub(super) async fn retest(
    State(app): State<App>,
    headers: HeaderMap,
    Path(id): Path<String>,
    body: Bytes,
) -> ApiResult<(StatusCode, Json<RetestStarted>)> {
    use crate::retest::{RetestFromStoreError as E, retest_plan_from_store};
    use spinbench_engine::retest::RetestError;
    let session = authorize(&app, &headers, Role::Operator, true).await?;
    // No body, or JSON null: no options.
    let ask: RetestRequest = if body.iter().all(u8::is_ascii_whitespace) {
        RetestRequest::default()
    } else {
        parse_json::<Option<RetestRequest>>(&body)?.unwrap_or_default()
    };
    let asked = id.clone();
    let (found, recorded_by) = blocking(&app, move |app| {
        let store = store(app);
        let recorded_by = store.run(&asked).ok().flatten().map(|r| r.station);
        Ok((retest_plan_from_store(&store, &asked), recorded_by))
    })
    .await?;
    // The instruments go back to the centrifuge and fixtures they were
    // measured on (issue 27 item 27): a run of another station is retested
    // there.
    let here = app.runner.station().0.station;
    if let Some(there) = recorded_by.filter(|s| *s != here) {
        return Err(ApiError::conflict(format!(
            "run {id} was recorded by station '{there}'; this is station '{here}': retest it on '{there}' (its Fleet page entry), so its instruments are measured again on the centrifuge they were tested on"
        )));
    }
    let (mut plan, serials, _) = found.map_err(|e| match e {
        E::NotFound(_) => ApiError::new(StatusCode::NOT_FOUND, e.to_string()),
        E::NotEnded(..)
        | E::Retest(RetestError::NothingToRetest(_) | RetestError::NotGraded(_)) => {
            ApiError::conflict(e.to_string())
        }
        // No run has such an id.
        E::Retest(RetestError::BadRunId(_)) => ApiError::not_found(e.to_string()),
        E::Plan(..) => ApiError::internal(e.to_string()),
        // Not made by retest_plan_from_store (a plan's own retest_of only).
        E::NotToRetest { .. } => ApiError::conflict(e.to_string()),
        E::Store(s) => ApiError::from(s),
    })?;
    plan.operator = session.user.clone();
    // As a new run: an admin may override an overdue device, with a reason
    // (issue 27, item 22: the 409 told them to).
    let overridden = check_equipment(&app, &session, ask.override_overdue.as_deref()).await?;
    let run_id = start_plan(&app, &plan, &session.user).await?;
    if let Some(devices) = overridden {
        audit(
            &app,
            &session.user,
            "override overdue calibration",
            &format!(
                "{run_id} (retest of {id}) started with {devices} overdue: {}",
                ask.override_overdue.as_deref().unwrap_or_default()
            ),
        )
        .await?;
    }
    audit(
        &app,
        &session.user,
        "retest run",
        &format!("{run_id} retests {id}: {}", serials.join(" ")),
    )
    .await?;
    Ok((
        StatusCode::CREATED,
        Json(RetestStarted {
            run_id,
            retest_of: id,
            serials,
        }),
    ))
}

/// Answer the operator prompt waiting now: done as asked, or abort.
#[utoipa::path(post, path = "/api/run/prompt", tag = "runs",
    security(("session" = [], "csrf" = [])),
    request_body(content = PromptAnswer, description = "At most 2 MiB (413 beyond)."),
    responses(
        (status = 200, description = "answered", body = RunId),
        (status = 400, description = "not an answer body", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token", body = ErrorBody),
        (status = 409, description = "no prompt is waiting", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
    ))]
pub(super) async fn answer_prompt(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Json<RunId>> {
    let session = authorize(&app, &headers, Role::Operator, true).await?;
    let answer: PromptAnswer = parse_json(&body)?;
    let prompt = app.runner.prompt().unwrap_or_default();
    let run_id = app
        .runner
        .answer(answer.proceed, &session.user)
        .map_err(ApiError::conflict)?;
    audit(
        &app,
        &session.user,
        if answer.proceed {
            "answer prompt: done"
        } else {
            "answer prompt: abort"
        },
        &format!("{run_id}: {prompt}"),
    )
    .await?;
    Ok(Json(RunId { run_id }))
}

pub(super) async fn control(
    app: &App,
    headers: &HeaderMap,
    action: &str,
    act: impl FnOnce(&crate::web::runner::Runner, &str) -> Result<String, String>,
) -> ApiResult<Json<RunId>> {
    let session = authorize(app, headers, Role::Operator, true).await?;
    let run_id = act(&app.runner, &session.user).map_err(ApiError::conflict)?;
    audit(app, &session.user, action, &run_id).await?;
    Ok(Json(RunId { run_id }))
}

/// Hold the active run between steps (the ports are still read).
#[utoipa::path(post, path = "/api/run/pause", tag = "runs",
    security(("session" = [], "csrf" = [])),
    responses(
        (status = 200, description = "held", body = RunId),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token", body = ErrorBody),
        (status = 409, description = "no active run", body = ErrorBody),
    ))]
pub(super) async fn pause(
    State(app): State<App>,
    headers: HeaderMap,
    _body: Bytes,
) -> ApiResult<Json<RunId>> {
    control(&app, &headers, "pause", |r, _| r.pause(true)).await
}

/// Let a held run go on.
#[utoipa::path(post, path = "/api/run/resume", tag = "runs",
    security(("session" = [], "csrf" = [])),
    responses(
        (status = 200, description = "going on", body = RunId),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token", body = ErrorBody),
        (status = 409, description = "no active run", body = ErrorBody),
    ))]
pub(super) async fn resume(
    State(app): State<App>,
    headers: HeaderMap,
    _body: Bytes,
) -> ApiResult<Json<RunId>> {
    control(&app, &headers, "resume", |r, _| r.pause(false)).await
}

/// Abort the active run: the station goes to its safe state, the run is recorded.
#[utoipa::path(post, path = "/api/run/abort", tag = "runs",
    security(("session" = [], "csrf" = [])),
    responses(
        (status = 200, description = "aborting", body = RunId),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token", body = ErrorBody),
        (status = 409, description = "no active run", body = ErrorBody),
    ))]
pub(super) async fn abort(
    State(app): State<App>,
    headers: HeaderMap,
    _body: Bytes,
) -> ApiResult<Json<RunId>> {
    control(&app, &headers, "abort", |r, user| {
        r.abort(&format!("the web UI (user {user})"))
    })
    .await
}

/// Which station's runs (`GET /api/runs`).
#[derive(Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct StationFilter {
    /// Only this station's runs (its id; every station's without it).
    #[param(max_length = 64)]
    station: Option<String>,
}

/// Every run of the fleet (or of one station), newest first.
#[utoipa::path(get, path = "/api/runs", tag = "runs",
    security(("session" = [])),
    params(StationFilter),
    responses(
        (status = 200, description = "the runs", body = Vec<RunEntry>),
        (status = 400, description = "a bad query string", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn runs(
    State(app): State<App>,
    headers: HeaderMap,
    q: Result<Query<StationFilter>, QueryRejection>,
) -> ApiResult<Json<Vec<RunEntry>>> {
    authorize(&app, &headers, Role::Operator, false).await?;
    let Query(q) = q.map_err(query_error)?;
    let runs = blocking(&app, |app| Ok(store(app).runs()?)).await?;
    Ok(Json(
        runs.iter()
            .filter(|r| q.station.as_ref().is_none_or(|s| &r.station == s))
            .map(RunEntry::from)
            .collect(),
    ))
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
        Ok(spinbench_report::gather(&store(app), &asked))
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
            (Vec<u8> = "application/pdf"),
            (String = "text/html; charset=utf-8"),
            (Vec<u8> = "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet"),
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
    let bytes = tokio::task::spawn_blocking(move || {
        let store = spinbench_store::Store::connect(&db)?;
        let report = spinbench_report::gather(&store, &run_id)?;
        spinbench_report::render_in(&report, format, lang)
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
                format!("attachment; filename=\"report-{id}.{}\"", format.ext()),
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
    let history = blocking(&app, move |app| Ok(store(app).unit_history(&asked)?)).await?;
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
            })
            .collect(),
    }))
}

/// Leave a level of one instrument of a finished run out of its reduction
/// (an engineer, with a reason): the record is reduced and graded again by
/// the run's own plan and station config, its exclusions list who, why and
/// how many readings, and the audit log keeps the figures before and after.
/// The readings themselves stay.
#[utoipa::path(post, path = "/api/runs/{id}/exclusions", tag = "runs",
    security(("session" = [], "csrf" = [])),
    params(("id" = String, Path, description = "the finished run")),
    request_body(content = ExcludeLevel, description = "At most 2 MiB (413 beyond)."),
    responses(
        (status = 200, description = "reduced and graded again", body = Excluded),
        (status = 400, description = "not an exclusion body", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an engineer", body = ErrorBody),
        (status = 404, description = "no such run or instrument", body = ErrorBody),
        (status = 409, description = "the run is still going or did not record its station config; the level is not the run's, is already left out, or would leave too few levels to reduce", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
    ))]
pub(super) async fn exclude_level(
    State(app): State<App>,
    headers: HeaderMap,
    Path(id): Path<String>,
    body: Bytes,
) -> ApiResult<Json<Excluded>> {
    let session = authorize(&app, &headers, Role::Engineer, true).await?;
    let ask: ExcludeLevel = parse_json(&body)?;
    check_exclusion_ask(&app, &id, &ask)?;
    blocking(&app, move |app| {
        let store = store(app);
        let exclusion = spinbench_analysis::exclusion::LevelExclusion {
            unit: Some(ask.serial.clone()),
            mount: ask.mount,
            g: ask.g,
            reason: ask.reason.trim().to_string(),
            by: session.user.clone(),
            points_removed: 0,
        };
        let (before, after) = change_record(&store, &id, &ask.serial, |record, plan, station| {
            spinbench_engine::executor::exclude_after_run(record, plan, station, exclusion)
        })?;
        let detail = format!(
            "{id} {} {}:{} g ({}): k2_max {} → {} µg/g², outcome {} → {}",
            ask.serial,
            ask.mount,
            ask.g,
            ask.reason.trim(),
            k2_shown(&before),
            k2_shown(&after),
            before.outcome,
            after.outcome
        );
        store.replace_result(&id, &after, &session.user, "exclude level", &detail)?;
        Ok(Json(Excluded {
            run_id: id,
            exclusions: json!(after.exclusions),
            outcome: after.outcome.to_string(),
            k2_max_ug_per_g2: after.k2_max_ug_per_g2,
            serial: after.serial,
        }))
    })
    .await
}

/// Withdraw an engineer's exclusion of a level of one instrument of a
/// finished run (an engineer, with a reason; issue 27 item 9): the record is
/// reduced and graded again with its other exclusions, and the audit log
/// keeps the figures before and after.
#[utoipa::path(post, path = "/api/runs/{id}/exclusions/withdraw", tag = "runs",
    security(("session" = [], "csrf" = [])),
    params(("id" = String, Path, description = "the finished run")),
    request_body(content = ExcludeLevel, description = "The exclusion to withdraw (serial, mount, g) and why. At most 2 MiB (413 beyond)."),
    responses(
        (status = 200, description = "reduced and graded again", body = Excluded),
        (status = 400, description = "not a body", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an engineer", body = ErrorBody),
        (status = 404, description = "no such run or instrument", body = ErrorBody),
        (status = 409, description = "the run is still going or did not record its station config, or the level is not left out", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
    ))]
pub(super) async fn withdraw_exclusion(
    State(app): State<App>,
    headers: HeaderMap,
    Path(id): Path<String>,
    body: Bytes,
) -> ApiResult<Json<Excluded>> {
    let session = authorize(&app, &headers, Role::Engineer, true).await?;
    let ask: ExcludeLevel = parse_json(&body)?;
    check_exclusion_ask(&app, &id, &ask)?;
    blocking(&app, move |app| {
        let store = store(app);
        let (before, after) = change_record(&store, &id, &ask.serial, |record, plan, station| {
            spinbench_engine::executor::withdraw_exclusion_after_run(
                record, plan, station, ask.mount, ask.g,
            )
        })?;
        let detail = format!(
            "{id} {} {}:{} g back in ({}): k2_max {} → {} µg/g², outcome {} → {}",
            ask.serial,
            ask.mount,
            ask.g,
            ask.reason.trim(),
            k2_shown(&before),
            k2_shown(&after),
            before.outcome,
            after.outcome
        );
        store.replace_result(&id, &after, &session.user, "withdraw exclusion", &detail)?;
        Ok(Json(Excluded {
            run_id: id,
            exclusions: json!(after.exclusions),
            outcome: after.outcome.to_string(),
            k2_max_ug_per_g2: after.k2_max_ug_per_g2,
            serial: after.serial,
        }))
    })
    .await
}

/// An instrument's k2_max as the audit log shows it.
fn k2_shown(r: &spinbench_engine::UnitRecord) -> String {
    r.k2_max_ug_per_g2
        .map_or("—".to_string(), |k| format!("{k:.3}"))
}

/// The checks of an exclusion's (or a withdrawal's) body that need no
/// store: a level in g, a reason of 1 to 500 characters with no control
/// characters, and a run that has ended.
fn check_exclusion_ask(app: &App, id: &str, ask: &ExcludeLevel) -> ApiResult<()> {
    if !(ask.g.is_finite() && (0.0..=spinbench_engine::bounds::MAX_LEVEL_G).contains(&ask.g)) {
        return Err(ApiError::bad(format!(
            "g = {}: give one of the run's levels in g",
            ask.g
        )));
    }
    // Characters, not bytes (200 Chinese characters are 600 bytes); no
    // control characters into the record and the audit log.
    if ask.reason.trim().is_empty()
        || ask.reason.chars().count() > 500
        || ask.reason.chars().any(char::is_control)
    {
        return Err(ApiError::bad(
            "reason: say why (1 to 500 characters, no control characters)",
        ));
    }
    if app.runner.active().as_deref() == Some(id) {
        return Err(ApiError::conflict(format!(
            "run {id} is still going; change its records once it has ended"
        )));
    }
    Ok(())
}

/// Instrument `serial` of finished run `id` changed by `change` under the
/// run's own plan and station config: its record before and after (a
/// refusal of `change` is a 400).
fn change_record(
    store: &spinbench_store::Store,
    id: &str,
    serial: &str,
    change: impl FnOnce(
        &spinbench_engine::UnitRecord,
        &spinbench_engine::CompiledPlan,
        &spinbench_engine::StationConfig,
    ) -> Result<spinbench_engine::UnitRecord, String>,
) -> ApiResult<(spinbench_engine::UnitRecord, spinbench_engine::UnitRecord)> {
    let run = store
        .run(id)?
        .ok_or_else(|| ApiError::not_found(format!("no run '{id}' (GET /api/runs)")))?;
    let context = store
        .run_context(id)?
        .ok_or_else(|| ApiError::not_found(format!("no run '{id}'")))?;
    let station_toml = context.station_config.ok_or_else(|| {
        ApiError::conflict(format!(
            "run {id} did not record its station config, so it cannot be reduced again here; use `spinbench analyze --exclude-level`"
        ))
    })?;
    let station = spinbench_engine::StationConfig::from_toml(&station_toml)
        .map_err(|e| ApiError::internal(format!("run {id}'s station config: {e}")))?;
    let plan: TestPlan = serde_json::from_str(&context.plan_json)
        .map_err(|e| ApiError::internal(format!("run {id}'s plan: {e}")))?;
    let compiled = plan
        .compile(&station)
        .map_err(|e| ApiError::internal(format!("run {id}'s plan: {e}")))?;
    let result = store
        .results(id)?
        .into_iter()
        .find(|r| r.serial == serial)
        .ok_or_else(|| {
            ApiError::not_found(format!(
                "run {id} ({}) has no instrument '{serial}'",
                run.state
            ))
        })?;
    // The body was well formed; the record's state refuses it (a level the
    // run does not have, one already out or not out, too few levels left).
    let after = change(&result.record, &compiled, &station).map_err(ApiError::conflict)?;
    Ok((result.record, after))
}
