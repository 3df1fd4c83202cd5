//! The HTTP API and the page's files. Every `/api` route but login, the
//! session check and the OpenAPI document needs a session; every request
//! that changes something also needs the session's CSRF token in
//! `X-CSRF-Token`, and the role the action needs. Errors are JSON
//! `{"error": "…"}` that say what to do.

use super::AppState;
use super::auth::{self, CSRF_HEADER, Role, Session};
use crate::web::runner::StartError;
use axum::Json;
use axum::Router;
use axum::body::Bytes;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{MethodRouter, delete, get, post, put};
use futures_util::Stream;
use serde::Deserialize;
use serde_json::json;
use spinbench_engine::TestPlan;
use spinbench_report::ReportFormat;
use std::collections::BTreeMap;
use std::convert::Infallible;
use std::sync::Arc;
use std::time::{Duration, Instant};

mod assets;
mod charts;
pub mod doc;
mod equipment;
mod exclusions;
mod history;
mod live;
mod plans;
mod retest_offer;
mod runs;
pub mod schema;
mod session;
mod tokens;
mod users;

type App = Arc<AppState>;

/// An API error: a status and what to do about it (in English, and for
/// the errors an operator meets, also as a key and values the page words
/// in its own language).
#[derive(Debug)]
pub struct ApiError {
    status: StatusCode,
    message: String,
    wording: Option<spinbench_engine::event::Wording>,
    /// Seconds after which the request may be tried again (503).
    retry_after_s: Option<u64>,
}

impl ApiError {
    fn new(status: StatusCode, message: impl Into<String>) -> ApiError {
        ApiError {
            status,
            message: message.into(),
            wording: None,
            retry_after_s: None,
        }
    }
    /// The same error, its message led by what did not happen because of
    /// it ("nothing was saved: …").
    pub(super) fn prefixed(mut self, what: &str) -> ApiError {
        self.message = format!("{what}: {}", self.message);
        self
    }

    /// The store cannot answer now (down, restarting, stalled): 503 with
    /// `Retry-After`, and what to do.
    fn store_unavailable(problem: impl std::fmt::Display) -> ApiError {
        let mut e = ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            format!(
                "the station's database cannot answer now ({problem}); try again in a few seconds — \
                 a run in progress goes on measuring and its record follows when the database is back"
            ),
        );
        e.retry_after_s = Some(RETRY_AFTER_S);
        e
    }
    /// The same error with its wording (`say.<key>` in the catalogue).
    fn worded(mut self, wording: spinbench_engine::event::Wording) -> ApiError {
        self.wording = Some(wording);
        self
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

impl From<crate::web::runner::ControlError> for ApiError {
    /// A control the run's state does not allow: a conflict, saying why.
    fn from(e: crate::web::runner::ControlError) -> ApiError {
        ApiError::conflict(e.to_string())
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut response = (
            self.status,
            Json(schema::ErrorBody {
                error: self.message,
                wording: self.wording,
            }),
        )
            .into_response();
        if let Some(s) = self.retry_after_s {
            response
                .headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(s));
        }
        response
    }
}

impl From<spinbench_store::StoreError> for ApiError {
    fn from(e: spinbench_store::StoreError) -> ApiError {
        if e.is_unavailable() {
            ApiError::store_unavailable(e)
        } else {
            ApiError::internal(e.to_string())
        }
    }
}

/// Seconds a 503 of the store asks the client to wait before trying again.
pub const RETRY_AFTER_S: u64 = 5;

/// How long a request waits for the store's answer before it is told 503
/// (a database that stopped answering: paused, a network partition).
pub const STORE_DEADLINE: Duration = Duration::from_secs(10);

/// How long a request waits for the store's connection while another
/// request holds it.
pub const STORE_LOCK_WAIT: Duration = Duration::from_secs(3);

type ApiResult<T> = Result<T, ApiError>;

/// The session of the request, checked for its role and (when the request
/// changes something) its CSRF token.
pub(super) async fn authorize(
    app: &App,
    headers: &HeaderMap,
    min: Role,
    changes: bool,
) -> ApiResult<Session> {
    authorize_as(app, headers, min, changes, changes).await
}

/// As [`authorize`] for a safety control (abort, pause, go on): a known
/// session from the cache, whatever the store does, so that a store that
/// does not answer never holds an abort.
pub(super) async fn authorize_control(app: &App, headers: &HeaderMap) -> ApiResult<Session> {
    authorize_as(app, headers, Role::Operator, true, false).await
}

/// The session of a request; with `confirm`, a cached session due for a
/// check is confirmed against the store first, and refused (503) when the
/// store cannot say (a change on a session that may have
/// ended elsewhere is not made).
async fn authorize_as(
    app: &App,
    headers: &HeaderMap,
    min: Role,
    changes: bool,
    confirm: bool,
) -> ApiResult<Session> {
    if let Some(secret) = bearer(headers) {
        return authorize_token(app, secret, min, confirm).await;
    }
    let token = headers
        .get(header::COOKIE)
        .and_then(|v| v.to_str().ok())
        .and_then(auth::session_token);
    let Some(token) = token else {
        return check_session(None, headers, min, changes);
    };
    let session = match app.sessions.from_cache(&token) {
        // Known here: answered from the cache; the store confirms it (a
        // logout, a removal or a role change elsewhere ends it within
        // auth::RECHECK) on a thread of its own, so that a database that
        // stops answering never holds a request of a known session.
        auth::CacheHit::Hit {
            session,
            recheck,
            keep,
        } if confirm && recheck => {
            let (found, token) = (session.clone(), token.clone());
            let said = blocking(app, move |app| {
                Ok(app.sessions.confirm(&app.store, &token, &found, true, keep))
            })
            .await?;
            match said {
                auth::Confirmation::Open => Some(session),
                auth::Confirmation::Ended => None,
                auth::Confirmation::Unknown => {
                    return Err(ApiError::store_unavailable(
                        "your session cannot be confirmed, so nothing was changed (abort and pause still work)",
                    ));
                }
            }
        }
        auth::CacheHit::Hit {
            session,
            recheck,
            keep,
        } => {
            if recheck || keep {
                let (app, found) = (Arc::clone(app), session.clone());
                tokio::task::spawn_blocking(move || {
                    app.sessions
                        .confirm(&app.store, &token, &found, recheck, keep)
                });
            }
            Some(session)
        }
        auth::CacheHit::Expired => {
            blocking(app, move |app| {
                app.sessions.expire(&app.store, &token);
                Ok(None)
            })
            .await?
        }
        // The session may have to be read from the store (another server's).
        auth::CacheHit::Miss => {
            blocking(app, move |app| Ok(app.sessions.get(&app.store, &token))).await?
        }
    };
    check_session(session, headers, min, changes)
}

/// The secret of an `Authorization: Bearer` header, if any.
pub(in crate::web) fn bearer(headers: &HeaderMap) -> Option<String> {
    let value = headers.get(header::AUTHORIZATION)?.to_str().ok()?;
    let (scheme, secret) = value.trim().split_once(' ')?;
    scheme
        .eq_ignore_ascii_case("bearer")
        .then(|| secret.trim().to_string())
}

/// The session of a call with an API token (a machine client): its role
/// checked; no CSRF token (no browser sends the header by itself).
async fn authorize_token(
    app: &App,
    secret: String,
    min: Role,
    confirm: bool,
) -> ApiResult<Session> {
    use super::machine_tokens::TokenCheck;
    let found = blocking(app, move |app| {
        Ok(app.machine_tokens.check(&app.store, &secret, confirm))
    })
    .await?;
    let session = match found {
        TokenCheck::Valid(session) => session,
        TokenCheck::Refused => {
            return Err(ApiError::new(
                StatusCode::UNAUTHORIZED,
                "this API token is unknown or revoked: ask an admin for one (spinbench token add)",
            ));
        }
        TokenCheck::Unknown => {
            return Err(ApiError::store_unavailable(
                "the API token cannot be confirmed while the store does not answer, so nothing was changed",
            ));
        }
    };
    check_session(Some(session), &HeaderMap::new(), min, false)
}

/// The request's session checked for its CSRF token (when it changes
/// something and came with a browser's cookie) and its role.
fn check_session(
    session: Option<Session>,
    headers: &HeaderMap,
    min: Role,
    changes: bool,
) -> ApiResult<Session> {
    let session = session.ok_or_else(|| {
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

/// A query string the handler's type refuses, as a JSON error.
fn query_error(e: QueryRejection) -> ApiError {
    ApiError::bad(format!("the query string: {}", e.body_text()))
}

fn parse_json<T: for<'de> Deserialize<'de>>(body: &[u8]) -> ApiResult<T> {
    serde_json::from_slice(body).map_err(|e| ApiError::bad(format!("the request body: {e}")))
}

/// The one way a handler reaches the store: `work` runs on
/// tokio's blocking pool, never on a runtime thread. The store's
/// connections are synchronous — rusqlite, and the `postgres` client, which
/// drives its own small runtime and panics inside another's — and a query
/// on a runtime thread would stall every request that thread serves. One
/// boundary for both back ends keeps one store API (the CLI's and the
/// engine's sink use it directly, off any runtime); the queries are short
/// and the blocking pool is sized for them (512 threads by default).
pub(super) async fn blocking<T: Send + 'static>(
    app: &App,
    work: impl FnOnce(&AppState) -> ApiResult<T> + Send + 'static,
) -> ApiResult<T> {
    let app = Arc::clone(app);
    // A database that stops answering holds the call's thread until it
    // answers again; the request is told 503 at the deadline instead.
    match tokio::time::timeout(
        STORE_DEADLINE,
        tokio::task::spawn_blocking(move || work(&app)),
    )
    .await
    {
        Ok(done) => {
            done.map_err(|e| ApiError::internal(format!("the store's call did not finish: {e}")))?
        }
        Err(_) => Err(ApiError::store_unavailable(format!(
            "no answer within {} s; a change asked for may still be made when it answers: \
             look before asking again",
            STORE_DEADLINE.as_secs()
        ))),
    }
}

/// As [`blocking`], with no deadline: for starting a run, which moves
/// hardware and must never be reported as not started while it starts.
pub(super) async fn blocking_to_the_end<T: Send + 'static>(
    app: &App,
    work: impl FnOnce(&AppState) -> ApiResult<T> + Send + 'static,
) -> ApiResult<T> {
    let app = Arc::clone(app);
    tokio::task::spawn_blocking(move || work(&app))
        .await
        .map_err(|e| ApiError::internal(format!("the store's call did not finish: {e}")))?
}

/// The store, locked: only inside [`blocking`] (the lock and the queries
/// block). One held longer than [`STORE_LOCK_WAIT`] by another request
/// (whose database call does not come back) is a 503.
pub(super) fn store(
    app: &AppState,
) -> ApiResult<std::sync::MutexGuard<'_, spinbench_store::Store>> {
    super::lock_within(&app.store, STORE_LOCK_WAIT).ok_or_else(|| {
        ApiError::store_unavailable(format!(
            "its connection is held by a call that has not come back for {} s",
            STORE_LOCK_WAIT.as_secs()
        ))
    })
}

/// Write an entry of the audit log (through [`blocking`]).
pub(super) async fn audit(app: &App, who: &str, action: &str, detail: &str) -> ApiResult<()> {
    let (who, action, detail) = (who.to_string(), action.to_string(), detail.to_string());
    blocking(app, move |app| audit_now(app, &who, &action, &detail)).await
}

/// Write entries of the audit log in one transaction (all or none), the
/// problem in words: only inside [`blocking`]. An action whose entries
/// cannot be written is not done.
pub(super) fn audit_all(
    app: &AppState,
    who: &str,
    entries: &[(String, String)],
) -> Result<(), crate::web::runner::NotAudited> {
    use crate::web::runner::NotAudited;
    store(app)
        .map_err(|e| NotAudited(e.message))?
        .audit_all(who, entries)
        .map_err(|e| NotAudited(e.to_string()))
}

/// Write an entry of the audit log: only inside [`blocking`].
pub(super) fn audit_now(app: &AppState, who: &str, action: &str, detail: &str) -> ApiResult<()> {
    store(app)?
        .audit(who, action, detail)
        .map_err(ApiError::from)
}

/// Largest body of a login request [bytes].
pub const LOGIN_BODY_LIMIT: usize = 4 * 1024;

/// Every route, once: (method, path, handler). The router and the list the
/// OpenAPI document is held to ([`api_routes`]) are both built from it.
fn routes() -> Vec<(&'static str, &'static str, MethodRouter<App>)> {
    vec![
        ("get", "/", get(assets::page)),
        ("get", "/app.js", get(assets::script)),
        ("get", "/js/{module}", get(assets::module)),
        ("get", "/app.css", get(assets::style)),
        ("get", "/cjk.ttf", get(assets::font)),
        ("get", "/api/openapi.json", get(assets::openapi)),
        ("get", "/metrics", get(metrics)),
        (
            "post",
            "/api/login",
            post(session::login).layer(axum::extract::DefaultBodyLimit::max(LOGIN_BODY_LIMIT)),
        ),
        ("post", "/api/logout", post(session::logout)),
        ("get", "/api/session", get(session::session)),
        ("put", "/api/session/language", put(session::set_language)),
        ("get", "/api/i18n/{language}", get(session::catalogue)),
        ("get", "/api/status", get(live::status)),
        ("get", "/api/events", get(live::events)),
        ("get", "/api/plans", get(plans::plans)),
        ("put", "/api/plans/{name}", put(plans::save_plan)),
        ("post", "/api/plans/{name}/design", post(plans::design_plan)),
        ("get", "/api/station", get(plans::station)),
        ("put", "/api/station", put(plans::save_station)),
        ("get", "/api/runs", get(history::runs)),
        ("post", "/api/runs", post(runs::start_run)),
        ("get", "/api/runs/{id}", get(history::run)),
        (
            "get",
            "/api/runs/{id}/report/{format}",
            get(history::report),
        ),
        (
            "post",
            "/api/runs/{id}/exclusions",
            post(exclusions::exclude_level),
        ),
        (
            "post",
            "/api/runs/{id}/exclusions/withdraw",
            post(exclusions::withdraw_exclusion),
        ),
        ("post", "/api/runs/{id}/retest", post(runs::retest)),
        (
            "get",
            "/api/runs/{id}/retest",
            get(retest_offer::retest_offer),
        ),
        ("post", "/api/runs/{id}/resume", post(runs::resume_run)),
        ("post", "/api/run/prompt", post(runs::answer_prompt)),
        ("post", "/api/run/pause", post(runs::pause)),
        ("post", "/api/run/resume", post(runs::resume)),
        ("post", "/api/run/abort", post(runs::abort)),
        (
            "post",
            "/api/run/acknowledge",
            post(runs::acknowledge_fault),
        ),
        ("get", "/api/units/{serial}", get(history::unit)),
        ("get", "/api/control-charts", get(charts::control_charts)),
        ("get", "/api/equipment", get(equipment::equipment)),
        ("get", "/api/station/signature", get(equipment::signature)),
        (
            "put",
            "/api/equipment/{role}",
            put(equipment::set_equipment),
        ),
        ("get", "/api/users", get(users::users)),
        ("post", "/api/users", post(users::add_user)),
        ("delete", "/api/users/{name}", delete(users::delete_user)),
        ("put", "/api/users/{name}", put(users::change_user)),
        ("get", "/api/audit", get(users::audit_log)),
        ("get", "/api/tokens", get(tokens::tokens)),
        ("post", "/api/tokens", post(tokens::add_token)),
        ("delete", "/api/tokens/{name}", delete(tokens::revoke_token)),
        ("get", "/api/webhooks", get(tokens::webhooks)),
        ("get", "/api/fleet", get(live::fleet)),
        (
            "delete",
            "/api/fleet/{station}",
            delete(live::retire_station),
        ),
    ]
}

/// The router: the page, its files and the API, from [`routes`] (the method
/// routers of one path are merged).
pub fn router(app: App) -> Router {
    routes()
        .into_iter()
        .fold(Router::new(), |router, (_, path, handler)| {
            router.route(path, handler)
        })
        .layer(axum::middleware::from_fn_with_state(
            app.clone(),
            count_request,
        ))
        .with_state(app)
}

/// `router` behind the session gate ([`session_before_body`]): applied by
/// the server outside the layer that reads a request's body.
pub fn gate_sessions(router: Router, app: App) -> Router {
    router.layer(axum::middleware::from_fn_with_state(
        app,
        session_before_body,
    ))
}

/// A request that may carry a body (anything but GET and HEAD) to the API,
/// but the login, is answered 401 before its body is read when it has no
/// session: a made-up cookie never makes the server take in a body of up
/// to the limit. The refusal closes the connection. The handler checks the
/// session's role and CSRF as before.
async fn session_before_body(
    State(app): State<App>,
    request: axum::extract::Request,
    next: axum::middleware::Next,
) -> axum::response::Response {
    use axum::http::Method;
    let path = request.uri().path();
    let carries_body = !matches!(
        *request.method(),
        Method::GET | Method::HEAD | Method::OPTIONS
    );
    if carries_body
        && path.starts_with("/api/")
        && !matches!(path, "/api/login" | "/api/logout")
        && let Err(refused) =
            authorize_as(&app, request.headers(), Role::Operator, false, false).await
    {
        // The body is left unread, so the connection cannot carry another
        // request: say so, or a client's pool reuses a connection the
        // server is closing and its next request fails.
        let mut response = refused.into_response();
        response.headers_mut().insert(
            axum::http::header::CONNECTION,
            axum::http::HeaderValue::from_static("close"),
        );
        return response;
    }
    next.run(request).await
}

/// Count every request by its route (the table's path, not the URL: a
/// run id does not make a series of its own) and its answer's status.
async fn count_request(
    State(app): State<App>,
    request: axum::extract::Request,
    next: axum::middleware::Next,
) -> Response {
    let route = request
        .extensions()
        .get::<axum::extract::MatchedPath>()
        .map_or_else(|| "unmatched".to_string(), |p| p.as_str().to_string());
    // What the connection showed itself to be, for the server's choice of
    // which connection to close when full.
    let connection = request
        .extensions()
        .get::<Arc<crate::web::server::ConnectionState>>()
        .cloned();
    let with_session = request
        .headers()
        .get(header::COOKIE)
        .and_then(|v| v.to_str().ok())
        .and_then(auth::session_token)
        .is_some();
    let response = next.run(request).await;
    if let Some(c) = connection {
        let accepted = with_session && response.status().is_success();
        c.answered(accepted, accepted && route == "/api/events");
    }
    app.metrics
        .http_requests
        .with_label_values(&[route.as_str(), response.status().as_str()])
        .inc();
    response
}

/// `GET /metrics`: the station for the plant's monitoring (Prometheus text
/// format; no session, as a scraper has none; nothing in it is a secret).
async fn metrics(State(app): State<App>) -> Response {
    let status = app.hub.status();
    let state = crate::web::station_state(&app, &status);
    (
        [(
            header::CONTENT_TYPE,
            "text/plain; version=0.0.4; charset=utf-8",
        )],
        app.metrics
            .render(&status, state, app.runner.store_health().as_ref()),
    )
        .into_response()
}

/// Every route of the API as (method, path), from the same table as the
/// router — the OpenAPI document must list exactly these.
pub fn api_routes() -> Vec<(&'static str, &'static str)> {
    routes()
        .into_iter()
        .filter(|(_, path, _)| path.starts_with("/api/"))
        .map(|(method, path, _)| (method, path))
        .collect()
}

// Handlers of a POST or DELETE without a body of their own still take it
// (`_body`): a body left unread makes the server close the connection, and a
// client that pooled it fails its next request.
