//! The HTTP API and the page's files. Every `/api` route but login, the
//! session check and the OpenAPI document needs a session; every request
//! that changes something also needs the session's CSRF token in
//! `X-CSRF-Token`, and the role the action needs. Errors are JSON
//! `{"error": "…"}` that say what to do.

use super::AppState;
use super::auth::{self, CSRF_HEADER, Role, Session};
use super::runner::StartError;
use axum::Router;
use axum::body::Bytes;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post, put};
use futures_util::Stream;
use serde::Deserialize;
use serde_json::{Value, json};
use spinbench_engine::TestPlan;
use spinbench_report::ReportFormat;
use std::collections::BTreeMap;
use std::convert::Infallible;
use std::sync::Arc;
use std::time::{Duration, Instant};

type App = Arc<AppState>;

/// An API error: a status and what to do about it.
#[derive(Debug)]
pub struct ApiError {
    status: StatusCode,
    message: String,
}

impl ApiError {
    fn new(status: StatusCode, message: impl Into<String>) -> ApiError {
        ApiError {
            status,
            message: message.into(),
        }
    }
    fn bad(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::BAD_REQUEST, message)
    }
    fn not_found(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::NOT_FOUND, message)
    }
    fn conflict(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::CONFLICT, message)
    }
    fn internal(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, message)
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.status, axum::Json(json!({ "error": self.message }))).into_response()
    }
}

impl From<spinbench_store::StoreError> for ApiError {
    fn from(e: spinbench_store::StoreError) -> ApiError {
        ApiError::internal(e.to_string())
    }
}

type ApiResult<T> = Result<T, ApiError>;

/// The session of the request, checked for its role and (when the request
/// changes something) its CSRF token.
fn authorize(app: &AppState, headers: &HeaderMap, min: Role, changes: bool) -> ApiResult<Session> {
    let session = headers
        .get(header::COOKIE)
        .and_then(|v| v.to_str().ok())
        .and_then(auth::session_token)
        .and_then(|t| app.sessions.get(&t))
        .ok_or_else(|| {
            ApiError::new(
                StatusCode::UNAUTHORIZED,
                "not logged in: POST /api/login first",
            )
        })?;
    if changes {
        let sent = headers
            .get(CSRF_HEADER)
            .and_then(|v| v.to_str().ok())
            .unwrap_or("");
        if !auth::same_token(sent, &session.csrf) {
            return Err(ApiError::new(
                StatusCode::FORBIDDEN,
                "missing or wrong X-CSRF-Token header (GET /api/session gives the token)",
            ));
        }
    }
    if session.role < min {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            format!(
                "this needs the {} role; {} is {}",
                min.as_str(),
                session.user,
                session.role.as_str()
            ),
        ));
    }
    Ok(session)
}

fn parse_json<T: for<'de> Deserialize<'de>>(body: &[u8]) -> ApiResult<T> {
    serde_json::from_slice(body).map_err(|e| ApiError::bad(format!("the request body: {e}")))
}

fn store(app: &AppState) -> std::sync::MutexGuard<'_, spinbench_store::Store> {
    app.store.lock().unwrap_or_else(|e| e.into_inner())
}

fn audit(app: &AppState, who: &str, action: &str, detail: &str) -> ApiResult<()> {
    store(app)
        .audit(who, action, detail)
        .map_err(ApiError::from)
}

/// Largest body of a login request [bytes].
pub const LOGIN_BODY_LIMIT: usize = 4 * 1024;

/// The router: the page, its files and the API.
pub fn router(app: App) -> Router {
    Router::new()
        .route("/", get(page))
        .route("/app.js", get(script))
        .route("/app.css", get(style))
        .route("/api/openapi.json", get(openapi))
        .route(
            "/api/login",
            post(login).layer(axum::extract::DefaultBodyLimit::max(LOGIN_BODY_LIMIT)),
        )
        .route("/api/logout", post(logout))
        .route("/api/session", get(session))
        .route("/api/status", get(status))
        .route("/api/events", get(events))
        .route("/api/plans", get(plans))
        .route("/api/plans/{name}", put(save_plan))
        .route("/api/station", get(station).put(save_station))
        .route("/api/runs", get(runs).post(start_run))
        .route("/api/runs/{id}", get(run))
        .route("/api/runs/{id}/report/{format}", get(report))
        .route("/api/run/prompt", post(answer_prompt))
        .route("/api/run/pause", post(pause))
        .route("/api/run/resume", post(resume))
        .route("/api/run/abort", post(abort))
        .route("/api/units/{serial}", get(unit))
        .route("/api/users", get(users).post(add_user))
        .route("/api/users/{name}", axum::routing::delete(delete_user))
        .route("/api/audit", get(audit_log))
        .with_state(app)
}

/// Every route of the API, as (method, path) — the OpenAPI document must list exactly these.
pub const API_ROUTES: [(&str, &str); 23] = [
    ("get", "/api/openapi.json"),
    ("post", "/api/login"),
    ("post", "/api/logout"),
    ("get", "/api/session"),
    ("get", "/api/status"),
    ("get", "/api/events"),
    ("get", "/api/plans"),
    ("put", "/api/plans/{name}"),
    ("get", "/api/station"),
    ("put", "/api/station"),
    ("get", "/api/runs"),
    ("post", "/api/runs"),
    ("get", "/api/runs/{id}"),
    ("get", "/api/runs/{id}/report/{format}"),
    ("post", "/api/run/prompt"),
    ("post", "/api/run/pause"),
    ("post", "/api/run/resume"),
    ("post", "/api/run/abort"),
    ("get", "/api/units/{serial}"),
    ("get", "/api/users"),
    ("post", "/api/users"),
    ("delete", "/api/users/{name}"),
    ("get", "/api/audit"),
];

fn asset(content_type: &'static str, body: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            (
                header::CONTENT_SECURITY_POLICY,
                "default-src 'self'; img-src 'self' data:; frame-ancestors 'none'",
            ),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

async fn page() -> Response {
    asset(
        "text/html; charset=utf-8",
        include_str!("assets/index.html"),
    )
}

async fn script() -> Response {
    asset(
        "text/javascript; charset=utf-8",
        include_str!("assets/app.js"),
    )
}

async fn style() -> Response {
    asset("text/css; charset=utf-8", include_str!("assets/app.css"))
}

async fn openapi() -> Response {
    ([(header::CONTENT_TYPE, "application/json")], super::OPENAPI).into_response()
}

#[derive(Deserialize)]
struct Login {
    user: String,
    password: String,
}

async fn login(
    State(app): State<App>,
    axum::extract::ConnectInfo(peer): axum::extract::ConnectInfo<std::net::SocketAddr>,
    body: Bytes,
) -> ApiResult<Response> {
    let login: Login = parse_json(&body)?;
    // A name that cannot be a user's is refused before the store is asked,
    // and only a short prefix of it is ever written to the audit log.
    let name = match auth::normalise_user_name(&login.user) {
        Ok(name) => name,
        Err(_) => spinbench_engine::bounds::shown(&login.user),
    };
    if let Err(locked) = app.logins.check(&name, peer.ip()) {
        let mut response = ApiError::new(
            StatusCode::TOO_MANY_REQUESTS,
            format!(
                "too many failed logins for {}; try again in {} s",
                locked.what, locked.retry_after_s
            ),
        )
        .into_response();
        response
            .headers_mut()
            .insert(header::RETRY_AFTER, HeaderValue::from(locked.retry_after_s));
        return Ok(response);
    }
    let user = match auth::normalise_user_name(&login.user) {
        Ok(name) => store(&app).user(&name)?,
        Err(_) => None,
    };
    let ok = match &user {
        Some(u) => auth::verify_password(&login.password, &u.password_hash),
        None => {
            // Spend the time a check takes, so a missing name is not faster to find.
            let _ = auth::hash_password(&login.password);
            false
        }
    };
    let role = user.as_ref().and_then(|u| Role::parse(&u.role));
    let (true, Some(role)) = (ok, role) else {
        audit(
            &app,
            &name,
            "login refused",
            &format!("wrong user name or password (from {})", peer.ip()),
        )?;
        for what in app.logins.failed(&name, peer.ip()) {
            audit(
                &app,
                &name,
                "login locked",
                &format!(
                    "{what} locked for {} s after repeated failures",
                    super::throttle::LOCKOUT.as_secs()
                ),
            )?;
        }
        return Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "wrong user name or password",
        ));
    };
    app.logins.succeeded(&name);
    let (token, session) = app.sessions.open(&name, role);
    audit(&app, &name, "login", role.as_str())?;
    let mut response = axum::Json(json!(session)).into_response();
    response.headers_mut().insert(
        header::SET_COOKIE,
        HeaderValue::from_str(&auth::session_cookie(Some(&token)))
            .map_err(|e| ApiError::internal(e.to_string()))?,
    );
    Ok(response)
}

// Handlers of a POST or DELETE without a body of their own still take it
// (`_body`): a body left unread makes the server close the connection, and a
// client that pooled it fails its next request.

async fn logout(State(app): State<App>, headers: HeaderMap, _body: Bytes) -> ApiResult<Response> {
    let session = authorize(&app, &headers, Role::Operator, true)?;
    if let Some(token) = headers
        .get(header::COOKIE)
        .and_then(|v| v.to_str().ok())
        .and_then(auth::session_token)
    {
        app.sessions.close(&token);
    }
    audit(&app, &session.user, "logout", "")?;
    let mut response = StatusCode::NO_CONTENT.into_response();
    response.headers_mut().insert(
        header::SET_COOKIE,
        HeaderValue::from_str(&auth::session_cookie(None))
            .map_err(|e| ApiError::internal(e.to_string()))?,
    );
    Ok(response)
}

async fn session(State(app): State<App>, headers: HeaderMap) -> ApiResult<axum::Json<Session>> {
    authorize(&app, &headers, Role::Operator, false).map(axum::Json)
}

async fn status(State(app): State<App>, headers: HeaderMap) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Operator, false)?;
    let mut status =
        serde_json::to_value(app.hub.status()).map_err(|e| ApiError::internal(e.to_string()))?;
    status["active"] = json!(app.runner.active());
    status["prompt"] = json!(app.runner.prompt());
    status["simulated"] = json!(app.runner.simulated());
    status["station"] = json!(app.runner.station().0.station);
    Ok(axum::Json(status))
}

#[derive(Deserialize)]
struct Since {
    since: Option<u64>,
}

/// Server-sent events: every engine event as JSON, `id` = its sequence
/// number. A browser that reconnects sends `Last-Event-ID` (or `?since=N`)
/// and first gets what it missed. One-second values are decimated to at
/// most one per 100 ms per browser (a fast virtual bench makes hundreds).
async fn events(
    State(app): State<App>,
    headers: HeaderMap,
    Query(q): Query<Since>,
) -> ApiResult<Sse<impl Stream<Item = Result<SseEvent, Infallible>>>> {
    authorize(&app, &headers, Role::Operator, false)?;
    let last = headers
        .get("last-event-id")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok())
        .or(q.since)
        .unwrap_or(0);
    let rx = app.hub.subscribe();
    let backlog = app.hub.since(last);
    struct Feed {
        backlog: std::vec::IntoIter<Arc<super::hub::HubEvent>>,
        rx: tokio::sync::broadcast::Receiver<Arc<super::hub::HubEvent>>,
        closing: tokio::sync::watch::Receiver<bool>,
        last: u64,
        last_values: Option<Instant>,
    }
    let feed = Feed {
        backlog: backlog.into_iter(),
        rx,
        closing: app.hub.closing(),
        last,
        last_values: None,
    };
    let stream = futures_util::stream::unfold(feed, |mut feed| async move {
        loop {
            if *feed.closing.borrow() {
                return None;
            }
            let next = match feed.backlog.next() {
                Some(e) => e,
                None => {
                    let received = tokio::select! {
                        received = feed.rx.recv() => received,
                        _ = feed.closing.changed() => return None,
                    };
                    match received {
                        Ok(e) => e,
                        Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => continue,
                        Err(tokio::sync::broadcast::error::RecvError::Closed) => return None,
                    }
                }
            };
            if next.seq <= feed.last {
                continue;
            }
            if next.kind == "values" {
                let now = Instant::now();
                if feed
                    .last_values
                    .is_some_and(|t| now.duration_since(t) < Duration::from_millis(100))
                    && feed.backlog.len() == 0
                {
                    continue;
                }
                feed.last_values = Some(now);
            }
            feed.last = next.seq;
            let event = SseEvent::default()
                .id(next.seq.to_string())
                .event(next.kind.clone())
                .data(next.json.clone());
            return Some((Ok(event), feed));
        }
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

fn plan_name_ok(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

async fn plans(State(app): State<App>, headers: HeaderMap) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Operator, false)?;
    let mut out = Vec::new();
    let dir = std::fs::read_dir(&app.plans_dir)
        .map_err(|e| ApiError::internal(format!("{}: {e}", app.plans_dir.display())))?;
    for entry in dir.flatten() {
        let path = entry.path();
        if path.extension().is_some_and(|e| e == "toml")
            && let Some(name) = path.file_stem().and_then(|s| s.to_str())
        {
            let text = std::fs::read_to_string(&path).unwrap_or_default();
            let plan = TestPlan::from_toml(&text);
            out.push(json!({
                "name": name,
                "text": text,
                "title": plan.as_ref().map(|p| p.name.clone()).unwrap_or_default(),
                "serials": plan.as_ref().map(|p| p.serials.clone()).unwrap_or_default(),
                "problem": plan.err().map(|e| e.to_string()),
            }));
        }
    }
    out.sort_by(|a, b| a["name"].as_str().cmp(&b["name"].as_str()));
    Ok(axum::Json(
        json!({ "slots": app.runner.station().0.slots(), "plans": out }),
    ))
}

async fn save_plan(
    State(app): State<App>,
    headers: HeaderMap,
    Path(name): Path<String>,
    body: Bytes,
) -> ApiResult<axum::Json<Value>> {
    let session = authorize(&app, &headers, Role::Engineer, true)?;
    if !plan_name_ok(&name) {
        return Err(ApiError::bad(format!(
            "plan name '{name}': 1 to 64 letters, digits, - or _"
        )));
    }
    let text =
        std::str::from_utf8(&body).map_err(|_| ApiError::bad("the plan is not UTF-8 text"))?;
    let plan = TestPlan::from_toml(text).map_err(|e| ApiError::bad(e.to_string()))?;
    plan.compile(&app.runner.station().0)
        .map_err(|e| ApiError::bad(format!("the plan cannot run on this station: {e}")))?;
    let path = app.plans_dir.join(format!("{name}.toml"));
    std::fs::write(&path, text)
        .map_err(|e| ApiError::internal(format!("{}: {e}", path.display())))?;
    audit(&app, &session.user, "save plan", &name)?;
    Ok(axum::Json(json!({ "name": name, "saved": true })))
}

async fn station(State(app): State<App>, headers: HeaderMap) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Operator, false)?;
    let (s, text) = app.runner.station();
    Ok(axum::Json(json!({
        "name": s.station,
        "slots": s.slots(),
        "simulated": app.runner.simulated(),
        "toml": text,
    })))
}

async fn save_station(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<axum::Json<Value>> {
    let session = authorize(&app, &headers, Role::Engineer, true)?;
    let text = std::str::from_utf8(&body)
        .map_err(|_| ApiError::bad("the station config is not UTF-8 text"))?;
    let config = spinbench_engine::StationConfig::from_toml(text)
        .map_err(|e| ApiError::bad(e.to_string()))?;
    let Some(path) = &app.station_path else {
        return Err(ApiError::conflict(
            "the virtual bench's station config is made from its devices; change the bench with --sim-config",
        ));
    };
    app.runner
        .set_station(config, text.to_string())
        .map_err(ApiError::conflict)?;
    std::fs::write(path, text)
        .map_err(|e| ApiError::internal(format!("{}: {e}", path.display())))?;
    audit(
        &app,
        &session.user,
        "save station config",
        &path.display().to_string(),
    )?;
    Ok(axum::Json(json!({ "saved": true })))
}

#[derive(Deserialize)]
struct StartRun {
    plan: String,
    #[serde(default)]
    serials: BTreeMap<String, String>,
}

async fn start_run(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<(StatusCode, axum::Json<Value>)> {
    let session = authorize(&app, &headers, Role::Operator, true)?;
    let start: StartRun = parse_json(&body)?;
    if !plan_name_ok(&start.plan) {
        return Err(ApiError::bad(format!("no plan named '{}'", start.plan)));
    }
    let path = app.plans_dir.join(format!("{}.toml", start.plan));
    let text = std::fs::read_to_string(&path)
        .map_err(|_| ApiError::bad(format!("no plan named '{}' (GET /api/plans)", start.plan)))?;
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
    let plan_text = toml::to_string(&plan).map_err(|e| ApiError::internal(e.to_string()))?;
    let run_id = app
        .runner
        .start(plan.clone(), &plan_text, &session.user)
        .map_err(|e| match e {
            StartError::Busy(id) => ApiError::conflict(format!(
                "run {id} is active; wait for it to end or abort it"
            )),
            StartError::Invalid(why) => ApiError::bad(why),
            StartError::Hardware(why) => ApiError::new(StatusCode::SERVICE_UNAVAILABLE, why),
        })?;
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
    )?;
    Ok((StatusCode::CREATED, axum::Json(json!({ "run_id": run_id }))))
}

#[derive(Deserialize)]
struct PromptAnswer {
    proceed: bool,
}

async fn answer_prompt(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<axum::Json<Value>> {
    let session = authorize(&app, &headers, Role::Operator, true)?;
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
    )?;
    Ok(axum::Json(json!({ "run_id": run_id })))
}

async fn control(
    app: &AppState,
    headers: &HeaderMap,
    action: &str,
    act: impl FnOnce(&super::runner::Runner, &str) -> Result<String, String>,
) -> ApiResult<axum::Json<Value>> {
    let session = authorize(app, headers, Role::Operator, true)?;
    let run_id = act(&app.runner, &session.user).map_err(ApiError::conflict)?;
    audit(app, &session.user, action, &run_id)?;
    Ok(axum::Json(json!({ "run_id": run_id })))
}

async fn pause(
    State(app): State<App>,
    headers: HeaderMap,
    _body: Bytes,
) -> ApiResult<axum::Json<Value>> {
    control(&app, &headers, "pause", |r, _| r.pause(true)).await
}

async fn resume(
    State(app): State<App>,
    headers: HeaderMap,
    _body: Bytes,
) -> ApiResult<axum::Json<Value>> {
    control(&app, &headers, "resume", |r, _| r.pause(false)).await
}

async fn abort(
    State(app): State<App>,
    headers: HeaderMap,
    _body: Bytes,
) -> ApiResult<axum::Json<Value>> {
    control(&app, &headers, "abort", |r, user| {
        r.abort(&format!("the web UI (user {user})"))
    })
    .await
}

async fn runs(State(app): State<App>, headers: HeaderMap) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Operator, false)?;
    let runs = store(&app).runs()?;
    Ok(axum::Json(json!(
        runs.iter()
            .map(|r| json!({
                "id": r.id,
                "station": r.station,
                "state": r.state,
                "reason": r.reason,
                "started_at": r.started_at,
                "units": r.units,
                "points": r.points,
            }))
            .collect::<Vec<_>>()
    )))
}

async fn run(
    State(app): State<App>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Operator, false)?;
    let report = {
        let store = store(&app);
        spinbench_report::gather(&store, &id)
    }
    .map_err(|e| match e {
        spinbench_report::ReportError::NoRun(_) => ApiError::not_found(e.to_string()),
        other => ApiError::internal(other.to_string()),
    })?;
    let rows: Vec<Value> = spinbench_report::summary(&report)
        .iter()
        .map(|r| {
            json!({
                "serial": r.serial, "slot": r.slot, "mount": r.mount,
                "radius_m": r.radius_m, "drawing_radius_m": r.drawing_radius_m,
                "k0_g": r.k0_g, "k1_hz_per_g": r.k1_hz_per_g,
                "k2_ug_per_g2": r.k2_ug_per_g2, "k2_ci95_half_ug_per_g2": r.k2_ci95_half_ug_per_g2,
                "k3_ug_per_g3": r.k3_ug_per_g3, "k2_max_ug_per_g2": r.k2_max_ug_per_g2,
                "sf_nonlinearity_ppm": r.sf_nonlinearity_ppm, "asymmetry_ppm": r.asymmetry_ppm,
                "hysteresis_ug": r.hysteresis_ug, "outcome": r.outcome, "reasons": r.reasons,
            })
        })
        .collect();
    let run = &report.run;
    Ok(axum::Json(json!({
        "id": run.id, "station": run.station, "state": run.state, "reason": run.reason,
        "started_at": run.started_at, "units": run.units, "points": run.points,
        "results": rows,
        "reports": ReportFormat::ALL.iter().map(|f| format!("/api/runs/{}/report/{}", run.id, f.ext())).collect::<Vec<_>>(),
    })))
}

async fn report(
    State(app): State<App>,
    headers: HeaderMap,
    Path((id, format)): Path<(String, String)>,
) -> ApiResult<Response> {
    authorize(&app, &headers, Role::Operator, false)?;
    let format = ReportFormat::parse(&format).ok_or_else(|| {
        ApiError::bad(format!(
            "report format '{format}': use pdf, html, xlsx or csv"
        ))
    })?;
    let db = app.db.clone();
    let run_id = id.clone();
    // A 96-instrument PDF takes a moment: off the async workers, on its own connection.
    let bytes = tokio::task::spawn_blocking(move || {
        let store = spinbench_store::Store::connect(&db)?;
        let report = spinbench_report::gather(&store, &run_id)?;
        spinbench_report::render(&report, format)
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

async fn unit(
    State(app): State<App>,
    headers: HeaderMap,
    Path(serial): Path<String>,
) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Operator, false)?;
    let history = store(&app).unit_history(&serial)?;
    if history.is_empty() {
        return Err(ApiError::not_found(format!(
            "no run holds serial '{serial}'"
        )));
    }
    Ok(axum::Json(json!({
        "serial": serial,
        "tests": history.iter().map(|h| json!({
            "run_id": h.run_id, "slot": h.slot + 1, "outcome": h.outcome,
            "k2_max_ug_per_g2": h.k2_max_ug_per_g2,
        })).collect::<Vec<_>>(),
    })))
}

async fn users(State(app): State<App>, headers: HeaderMap) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Admin, false)?;
    let users = store(&app).users()?;
    Ok(axum::Json(json!(
        users
            .iter()
            .map(|u| json!({ "name": u.name, "role": u.role, "created_at": u.created_at }))
            .collect::<Vec<_>>()
    )))
}

#[derive(Deserialize)]
struct NewUser {
    name: String,
    role: String,
    password: String,
}

async fn add_user(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<(StatusCode, axum::Json<Value>)> {
    let session = authorize(&app, &headers, Role::Admin, true)?;
    let new: NewUser = parse_json(&body)?;
    let role = Role::parse(&new.role).ok_or_else(|| {
        ApiError::bad(format!(
            "role '{}': use operator, engineer or admin",
            new.role
        ))
    })?;
    auth::check_new_user(&new.name, &new.password).map_err(ApiError::bad)?;
    if store(&app).user(&new.name)?.is_some() {
        return Err(ApiError::conflict(format!("user '{}' exists", new.name)));
    }
    let hash = auth::hash_password(&new.password).map_err(ApiError::internal)?;
    store(&app).add_user(&new.name, role.as_str(), &hash)?;
    audit(
        &app,
        &session.user,
        "add user",
        &format!("{} ({})", new.name, role.as_str()),
    )?;
    Ok((
        StatusCode::CREATED,
        axum::Json(json!({ "name": new.name, "role": role.as_str() })),
    ))
}

async fn delete_user(
    State(app): State<App>,
    headers: HeaderMap,
    Path(name): Path<String>,
    _body: Bytes,
) -> ApiResult<StatusCode> {
    let session = authorize(&app, &headers, Role::Admin, true)?;
    if name == session.user {
        return Err(ApiError::conflict(
            "you cannot remove yourself; another admin can",
        ));
    }
    if !store(&app).delete_user(&name)? {
        return Err(ApiError::not_found(format!("no user '{name}'")));
    }
    app.sessions.close_user(&name);
    audit(&app, &session.user, "remove user", &name)?;
    Ok(StatusCode::NO_CONTENT)
}

async fn audit_log(State(app): State<App>, headers: HeaderMap) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Admin, false)?;
    let rows = store(&app).audit_log(500)?;
    Ok(axum::Json(json!(
        rows.iter()
            .map(|r| json!({ "seq": r.seq, "at": r.at, "who": r.who, "action": r.action, "detail": r.detail }))
            .collect::<Vec<_>>()
    )))
}
