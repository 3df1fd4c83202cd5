//! Runs: start one (or a retest of one), answer its prompts, pause,
//! resume, abort. The history is in `history`, changes to a finished run's
//! records in `exclusions`.

use super::plans::{plan_name_ok, plan_with_serials};
use super::schema::{ErrorBody, PromptAnswer, RetestRequest, RetestStarted, RunId, StartRun};
use super::{
    ApiError, ApiResult, App, Arc, Bytes, Duration, HeaderMap, Instant, Json, Path, Role, Session,
    StartError, State, StatusCode, TestPlan, audit, audit_all, authorize, authorize_control,
    blocking, blocking_to_the_end, parse_json, store,
};
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
    let (mut plan, _) = plan_with_serials(&app, &start.plan, start.serials)?;
    plan.operator = session.user.clone();
    if let Some(target) = start.target_k2_u95_ug_per_g2 {
        plan.set_target(target)
            .map_err(|e| ApiError::bad(e.to_string()))?;
    }
    // Serials like an earlier run's, and a plan's retest_of, checked
    // against the store.
    let checked = plan.clone();
    blocking(&app, move |app| {
        crate::retest::check_retest_of(&*store(app)?, &checked).map_err(|e| match e {
            crate::retest::RetestFromStoreError::Store(e) => ApiError::from(e),
            e => ApiError::bad(e.to_string()),
        })
    })
    .await?;
    let overridden = check_equipment(&app, &session, start.override_overdue.as_deref()).await?;
    let serial_list: Vec<String> = plan
        .serials
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    let (plan_name, reason) = (start.plan.clone(), start.override_overdue.clone());
    let run_id = start_plan(&app, &plan, &session.user, move |run_id| {
        run_entries(
            (&overridden, &reason),
            format!("{run_id} started"),
            (
                "start run",
                format!(
                    "{run_id} plan {plan_name} serials {}",
                    serial_list.join(" ")
                ),
            ),
        )
    })
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
        Ok(crate::equipment::station_equipment(
            &*store(app)?,
            &station,
        )?)
    })
    .await?;
    // The one admission gate: an admin may override.
    use crate::equipment::Refusal;
    match crate::equipment::admit(&list, required, override_reason, session.role >= Role::Admin) {
        Ok(crate::equipment::Admission::Clear) => Ok(None),
        Ok(crate::equipment::Admission::Overridden { devices, .. }) => Ok(Some(devices)),
        Err(Refusal::BadReason { why }) => Err(ApiError::bad(format!("override_overdue: {why}"))),
        Err(Refusal::NotAllowed { devices }) => Err(ApiError::new(
            StatusCode::FORBIDDEN,
            format!("{devices}: calibration not cleared; only an admin may start a run anyway"),
        )
        .worded(Wording::new("error.overdue_admin_only").with("devices", &devices))),
        Err(Refusal::Overdue { devices }) => Err(ApiError::conflict(format!(
            "{devices}: calibration not cleared; calibrate it and update the equipment register, or an admin starts the run with a reason (override_overdue)"
        ))
        .worded(Wording::new("error.overdue").with("devices", &devices))),
    }
}

/// A run's audit entries: the override of its calibration check (the
/// devices and the reason), if one was made, after `started` ("RUN
/// started"), then its own entry (action, detail).
fn run_entries(
    (overridden, reason): (&Option<String>, &Option<String>),
    started: String,
    (action, detail): (&str, String),
) -> Vec<(String, String)> {
    let mut entries = Vec::new();
    if let Some(devices) = overridden {
        entries.push((
            crate::equipment::OVERRIDE_ACTION.to_string(),
            format!(
                "{started} with {devices}: {}",
                reason.as_deref().unwrap_or_default()
            ),
        ));
    }
    entries.push((action.to_string(), detail));
    entries
}

/// Start `plan` on the station for `user`; the run's id. Off the runtime:
/// starting opens the store, the run's files and the devices' ports. The
/// audit entries `entries` makes of the run's id are written in one
/// transaction before anything is switched on; if they cannot be, nothing
/// starts.
async fn start_plan(
    app: &App,
    plan: &TestPlan,
    user: &str,
    entries: impl Fn(&str) -> Vec<(String, String)> + Send + 'static,
) -> ApiResult<String> {
    let plan_text = toml::to_string(plan).map_err(|e| ApiError::internal(e.to_string()))?;
    let (plan, user) = (plan.clone(), user.to_string());
    let run_id = blocking_to_the_end(app, move |app| {
        let admit = |run_id: &str| audit_all(app, &user, &entries(run_id));
        Ok(app.runner.start(plan, &plan_text, &user, &admit))
    })
    .await?
    .map_err(start_error)?;
    readable(app, &run_id).await;
    Ok(run_id)
}

/// How long a start's answer waits for the store to have the run, so that
/// the run's own link (`GET /api/runs/{id}`) answers at once.
const READABLE_WAIT: Duration = Duration::from_secs(5);

/// Wait (at most [`READABLE_WAIT`]) until the store has run `id` (its
/// outbox writes the start first); a store that is down is not waited for
/// longer: the run goes on and its record follows.
async fn readable(app: &App, id: &str) {
    let until = Instant::now() + READABLE_WAIT;
    while Instant::now() < until {
        let asked = id.to_string();
        let found = blocking(app, move |app| Ok(store(app)?.run(&asked)?.is_some())).await;
        if matches!(found, Ok(true)) {
            return;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// A run that could not start, as the API says it.
fn start_error(e: StartError) -> ApiError {
    match e {
        StartError::Busy(id) => ApiError::conflict(format!(
            "run {id} is active; wait for it to end or abort it"
        ))
        .worded(Wording::new("error.busy").with("run", id)),
        StartError::Invalid(why) => ApiError::bad(why),
        StartError::Hardware(why) => ApiError::new(StatusCode::SERVICE_UNAVAILABLE, why),
        StartError::Files(why) => ApiError::internal(why),
        StartError::NotHere(why) => ApiError::not_found(why),
        StartError::Refused(why) => ApiError::conflict(why),
        StartError::NotAudited(why) => ApiError::store_unavailable(format!(
            "nothing was started: its audit entry could not be written ({why})"
        )),
    }
}

/// `POST /api/runs/{id}/resume`: continue a run of this station that a
/// crash left interrupted, or that ended aborted or faulted, with its own
/// plan from its journal (the steps it completed are kept).
#[utoipa::path(post, path = "/api/runs/{id}/resume", tag = "runs",
    security(("session" = [], "csrf" = [])),
    params(("id" = String, Path, description = "the run to continue")),
    request_body(content = Option<RetestRequest>, description = "Optional: an admin's reason to go on with a device overdue for calibration. At most 2 MiB (413 beyond)."),
    responses(
        (status = 201, description = "the run goes on", body = RunId),
        (status = 400, description = "a bad body", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token; an override by someone not an admin", body = ErrorBody),
        (status = 404, description = "no such run in this station's data directory", body = ErrorBody),
        (status = 409, description = "a run is active, this one completed or is being run by another process, or a device is overdue for calibration", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
        (status = 503, description = "the hardware cannot be reached", body = ErrorBody),
    ))]
pub(super) async fn resume_run(
    State(app): State<App>,
    headers: HeaderMap,
    Path(id): Path<String>,
    body: Bytes,
) -> ApiResult<(StatusCode, Json<RunId>)> {
    let session = authorize(&app, &headers, Role::Operator, true).await?;
    let ask = override_request(&body)?;
    let checked = id.clone();
    // The run's journal is read: off the server's threads.
    blocking(&app, move |app| {
        app.runner.check_resumable(&checked).map_err(start_error)
    })
    .await?;
    // A resume moves the table as a new run does: the same gate.
    let overridden = check_equipment(&app, &session, ask.override_overdue.as_deref()).await?;
    let (asked, user, reason) = (id.clone(), session.user.clone(), ask.override_overdue);
    let run_id = blocking_to_the_end(&app, move |app| {
        let admit = |run_id: &str| {
            audit_all(
                app,
                &user,
                &run_entries(
                    (&overridden, &reason),
                    format!("{run_id} resumed"),
                    ("resume run", run_id.to_string()),
                ),
            )
        };
        Ok(app.runner.resume(&asked, &user, &admit))
    })
    .await?
    .map_err(start_error)?;
    readable(&app, &run_id).await;
    Ok((StatusCode::CREATED, Json(RunId { run_id })))
}

/// The optional body of a retest or a resume: empty, JSON null or an object.
fn override_request(body: &[u8]) -> ApiResult<RetestRequest> {
    if body.iter().all(u8::is_ascii_whitespace) {
        Ok(RetestRequest::default())
    } else {
        Ok(parse_json::<Option<RetestRequest>>(body)?.unwrap_or_default())
    }
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
    let ask = override_request(&body)?;
    let asked = id.clone();
    let (found, recorded_by) = blocking(&app, move |app| {
        // A run that ended with the store down has its end in its left-over file.
        app.runner.catch_up_left_over();
        let store = store(app)?;
        let recorded_by = store.run(&asked).ok().flatten().map(|r| r.station);
        // The web's Retest takes what needs one; a clear fail is set aside
        // (the board says so), retested on purpose from the command line.
        let choice = spinbench_engine::retest::RetestChoice::default();
        Ok((retest_plan_from_store(&store, &asked, choice), recorded_by))
    })
    .await?;
    // The instruments go back to the centrifuge and fixtures they were
    // measured on: a run of another station is retested
    // there.
    let here = app.runner.station().0.station;
    if let Some(there) = recorded_by.filter(|s| *s != here) {
        return Err(ApiError::conflict(format!(
            "run {id} was recorded by station '{there}'; this is station '{here}': retest it on '{there}' (its Fleet page entry), so its instruments are measured again on the centrifuge they were tested on"
        )));
    }
    let crate::retest::Retest {
        mut plan, serials, ..
    } = found.map_err(|e| match e {
        E::NotFound(_) => ApiError::new(StatusCode::NOT_FOUND, e.to_string()),
        E::NotEnded(..)
        | E::Retest(RetestError::NothingToRetest(_) | RetestError::NotGraded(_)) => {
            ApiError::conflict(e.to_string())
        }
        // No run has such an id.
        E::Retest(RetestError::BadRunId(_)) => ApiError::not_found(e.to_string()),
        E::Plan(..) => ApiError::internal(e.to_string()),
        // Not made by retest_plan_from_store (a plan's own retest_of only).
        E::NotToRetest { .. } | E::LookAlikeSerial { .. } => ApiError::conflict(e.to_string()),
        E::Store(s) => ApiError::from(s),
    })?;
    plan.operator = session.user.clone();
    // As a new run: an admin may override an overdue device, with a reason
    // (the 409 told them to).
    let overridden = check_equipment(&app, &session, ask.override_overdue.as_deref()).await?;
    let (retested, reason, listed) = (id.clone(), ask.override_overdue.clone(), serials.join(" "));
    let run_id = start_plan(&app, &plan, &session.user, move |run_id| {
        run_entries(
            (&overridden, &reason),
            format!("{run_id} (retest of {retested}) started"),
            (
                "retest run",
                format!("{run_id} retests {retested}: {listed}"),
            ),
        )
    })
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
    // Audited first: while the audit log cannot be
    // written the run waits at its prompt (the table at rest), and the
    // answer says so; abort and pause need no audit entry first.
    let Some(prompt) = app.runner.prompt() else {
        return Err(ApiError::conflict(if app.runner.active().is_none() {
            "no run is active"
        } else {
            "no prompt is waiting for an answer"
        }));
    };
    let run = app.runner.active().unwrap_or_default();
    let action = if answer.proceed {
        "answer prompt: done"
    } else {
        "answer prompt: abort"
    };
    audit(&app, &session.user, action, &format!("{run}: {prompt}"))
        .await
        .map_err(|e| e.prefixed("the prompt was not answered"))?;
    let run_id = match app.runner.answer(answer.proceed, &session.user) {
        Ok(id) => id,
        Err(why) => {
            let _ = audit(
                &app,
                &session.user,
                "answer prompt not taken",
                &format!("{run}: {why}"),
            )
            .await;
            return Err(why.into());
        }
    };
    Ok(Json(RunId { run_id }))
}

/// How long a control's answer waits for its audit entry (a store that
/// does not answer: the entry is written when it does).
const AUDIT_WAIT: Duration = Duration::from_secs(2);

/// How long a control's audit entry is tried again while the store does
/// not take it.
const CONTROL_AUDIT_RETRY: Duration = Duration::from_secs(600);

pub(super) async fn control(
    app: &App,
    headers: &HeaderMap,
    action: &str,
    act: impl FnOnce(
        &crate::web::runner::Runner,
        &str,
    ) -> Result<String, crate::web::runner::ControlError>,
) -> ApiResult<Json<RunId>> {
    // Whatever the database does: a known session from the cache, the
    // action at once, the audit entry written when the store answers.
    let session = authorize_control(app, headers).await?;
    let run_id = act(&app.runner, &session.user)?;
    let done_at_unix_s = spinbench_store::now_s();
    let (app, action, id) = (Arc::clone(app), action.to_string(), run_id.clone());
    // A safety control is never held back by the audit log: its entry is
    // written until the store takes it, dated when it was done (the run's
    // own record names who aborted or held it in any case).
    let written = tokio::spawn(async move {
        let until = tokio::time::Instant::now() + CONTROL_AUDIT_RETRY;
        let mut warned = false;
        let write = || {
            let (who, action, id) = (session.user.clone(), action.clone(), id.clone());
            blocking(&app, move |app| {
                store(app)?
                    .audit_at(&who, &action, &id, done_at_unix_s)
                    .map_err(ApiError::from)
            })
        };
        while let Err(e) = write().await {
            if !warned {
                eprintln!(
                    "warning: the audit entry of {} by {} on run {id} is not written yet ({}); tried again every 2 s",
                    action, session.user, e.message
                );
                warned = true;
            }
            if tokio::time::Instant::now() >= until {
                eprintln!(
                    "error: the audit entry of {action} by {} on run {id} could not be written in {} s; the run's record names who did it",
                    session.user,
                    CONTROL_AUDIT_RETRY.as_secs()
                );
                break;
            }
            tokio::time::sleep(Duration::from_secs(2)).await;
        }
    });
    // Answered once the entry is written, or after AUDIT_WAIT (it goes on).
    let _ = tokio::time::timeout(AUDIT_WAIT, written).await;
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
    control(&app, &headers, "abort", |r, user| r.abort_by_user(user)).await
}

/// Acknowledge the fault that stopped the station's run: its banner goes,
/// and who acknowledged it, and when, goes into the audit log.
#[utoipa::path(post, path = "/api/run/acknowledge", tag = "runs",
    security(("session" = [], "csrf" = [])),
    responses(
        (status = 200, description = "acknowledged", body = RunId),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token", body = ErrorBody),
        (status = 409, description = "no fault waits for acknowledgement", body = ErrorBody),
    ))]
pub(super) async fn acknowledge_fault(
    State(app): State<App>,
    headers: HeaderMap,
    _body: Bytes,
) -> ApiResult<Json<RunId>> {
    let session = authorize(&app, &headers, Role::Operator, true).await?;
    let (run_id, reason) = app
        .hub
        .acknowledge_fault(&session.user)
        .map_err(|e| ApiError::conflict(e.to_string()))?;
    audit(
        &app,
        &session.user,
        "acknowledge fault",
        &format!("{run_id}: {reason}"),
    )
    .await?;
    Ok(Json(RunId { run_id }))
}
