//! Sessions: login (bounded, throttled per name and address, audited),
//! logout and the session check.

use super::{
    ApiError, ApiResult, App, Bytes, HeaderMap, HeaderValue, Json, Path, Response, Role, Session,
    State, StatusCode, audit, auth, authorize, blocking, header, parse_json, store,
};
use axum::response::IntoResponse;
use spinbench_report::Lang;

use super::schema::{Catalogue, ErrorBody, Language, Login, SessionReply};

/// The session as the API shows it.
fn reply(session: &Session, language: Option<Lang>) -> SessionReply {
    SessionReply {
        user: session.user.clone(),
        role: session.role,
        csrf: session.csrf.clone(),
        language: language.map(|l| l.code().to_string()),
    }
}

/// Log in: the session cookie, and the CSRF token in the answer.
#[utoipa::path(post, path = "/api/login", tag = "session",
    request_body(content = Login, description = "At most 4 KiB (413 beyond)."),
    responses(
        (status = 200, description = "logged in; the session cookie is set", body = SessionReply,
            headers(("set-cookie" = String, description = "the session cookie (HttpOnly, SameSite=Strict; Secure under TLS)"))),
        (status = 400, description = "not a login body", body = ErrorBody),
        (status = 401, description = "wrong user name or password", body = ErrorBody),
        (status = 413, description = "a body over 4 KiB"),
        (status = 415, description = "a body that is not application/json", body = ErrorBody),
        (status = 429, description = "too many failed logins; wait Retry-After seconds", body = ErrorBody,
            headers(("retry-after" = u64, description = "seconds to wait"))),
    ))]
pub(super) async fn login(
    State(app): State<App>,
    axum::extract::ConnectInfo(peer): axum::extract::ConnectInfo<std::net::SocketAddr>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Response> {
    // Only a script sends JSON: a cross-site form (text/plain, form data)
    // cannot log a browser into someone's account.
    let json = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.split(';').next())
        .is_some_and(|v| v.trim().eq_ignore_ascii_case("application/json"));
    if !json {
        return Err(ApiError::new(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "a login is a JSON body: send Content-Type: application/json",
        ));
    }
    let login: Login = parse_json(&body)?;
    // A name that cannot be a user's is refused before the store is asked,
    // and only a short prefix of it is ever written to the audit log.
    let name = match auth::normalise_user_name(&login.user) {
        Ok(name) => name,
        Err(_) => spinbench_engine::bounds::shown(&login.user),
    };
    if let Err(locked) = app.logins.check(&name, peer.ip()) {
        app.metrics.login_failures.inc();
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
    let known = auth::normalise_user_name(&login.user).ok();
    let password = login.password.clone();
    // The store's row and the password's check (a deliberately slow hash)
    // both off the runtime.
    let (user, ok) = blocking(&app, move |app| {
        let user = match known {
            Some(name) => store(app)?.user(&name)?,
            None => None,
        };
        let ok = check_password(&password, user.as_ref());
        Ok((user, ok))
    })
    .await?;
    let role = user.as_ref().and_then(|u| Role::parse(&u.role));
    let (true, Some(role)) = (ok, role) else {
        app.metrics.login_failures.inc();
        // A flood is counted, not written line by line (throttle docs).
        let budget = app.logins.refusal_audit();
        if budget.counted_before > 0 {
            audit(
                &app,
                "spinbench",
                "logins refused",
                &format!(
                    "{} more refused logins in the minute before were counted, not written one by one",
                    budget.counted_before
                ),
            )
            .await?;
        }
        if budget.write {
            audit(
                &app,
                &name,
                "login refused",
                &format!("wrong user name or password (from {})", peer.ip()),
            )
            .await?;
        }
        for what in app.logins.failed(&name, peer.ip()) {
            audit(
                &app,
                &name,
                "login locked",
                &format!(
                    "{what} locked for {} s after repeated failures",
                    crate::web::throttle::LOCKOUT.as_secs()
                ),
            )
            .await?;
        }
        return Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "wrong user name or password",
        ));
    };
    app.logins.succeeded(&name);
    let opened = name.clone();
    let (token, session) = blocking(&app, move |app| {
        Ok(app.sessions.open(&*store(app)?, &opened, role))
    })
    .await?;
    audit(&app, &name, "login", role.as_str()).await?;
    let mut response = Json(reply(&session, None)).into_response();
    response.headers_mut().insert(
        header::SET_COOKIE,
        HeaderValue::from_str(&auth::session_cookie(Some(&token), app.secure_cookies))
            .map_err(|e| ApiError::internal(e.to_string()))?,
    );
    Ok(response)
}

/// Log out: the session ends.
#[utoipa::path(post, path = "/api/logout", tag = "session",
    security(("session" = [], "csrf" = [])),
    responses(
        (status = 204, description = "logged out; the cookie is cleared"),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token", body = ErrorBody),
    ))]
pub(super) async fn logout(
    State(app): State<App>,
    headers: HeaderMap,
    _body: Bytes,
) -> ApiResult<Response> {
    let session = authorize(&app, &headers, Role::Operator, true).await?;
    if let Some(token) = headers
        .get(header::COOKIE)
        .and_then(|v| v.to_str().ok())
        .and_then(auth::session_token)
    {
        blocking(&app, move |app| {
            app.sessions.close(&*store(app)?, &token);
            Ok(())
        })
        .await?;
    }
    audit(&app, &session.user, "logout", "").await?;
    let mut response = StatusCode::NO_CONTENT.into_response();
    response.headers_mut().insert(
        header::SET_COOKIE,
        HeaderValue::from_str(&auth::session_cookie(None, app.secure_cookies))
            .map_err(|e| ApiError::internal(e.to_string()))?,
    );
    Ok(response)
}

/// The session of the request: user, role, CSRF token, language.
#[utoipa::path(get, path = "/api/session", tag = "session",
    security(("session" = [])),
    responses(
        (status = 200, description = "the session", body = SessionReply),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn session(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<SessionReply>> {
    let session = authorize(&app, &headers, Role::Operator, false).await?;
    let language = language_of(&app, &headers, Some(&session)).await;
    Ok(Json(reply(&session, Some(language))))
}

/// Whether `password` is the user's; without a user, the time a check
/// takes is spent anyway, so a missing name is not faster to find.
fn check_password(password: &str, user: Option<&spinbench_store::UserRow>) -> bool {
    match user {
        Some(u) => auth::verify_password(password, &u.password_hash),
        None => {
            let _ = auth::hash_password(password);
            false
        }
    }
}

/// The language of a request: the user's own choice, else the browser's
/// `Accept-Language`, else English.
pub(super) async fn language_of(app: &App, headers: &HeaderMap, session: Option<&Session>) -> Lang {
    let chosen = match session.map(|s| s.user.clone()) {
        Some(user) => blocking(app, move |app| {
            Ok(store(app)?.user_language(&user).ok().flatten())
        })
        .await
        .ok()
        .flatten(),
        None => None,
    };
    chosen.and_then(|tag| Lang::parse(&tag)).unwrap_or_else(|| {
        Lang::from_accept_language(
            headers
                .get(header::ACCEPT_LANGUAGE)
                .and_then(|v| v.to_str().ok())
                .unwrap_or(""),
        )
    })
}

/// `PUT /api/session/language`: the user's language, kept in the store.
#[utoipa::path(put, path = "/api/session/language", tag = "session",
    security(("session" = [], "csrf" = [])),
    request_body(content = Language, description = "At most 2 MiB (413 beyond)."),
    responses(
        (status = 200, description = "kept", body = Language),
        (status = 400, description = "a language the station does not speak", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token", body = ErrorBody),
    ))]
pub(super) async fn set_language(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Json<Language>> {
    let session = authorize(&app, &headers, Role::Operator, true).await?;
    let set: Language = parse_json(&body)?;
    let lang = Lang::parse(&set.language).ok_or_else(|| {
        ApiError::bad(format!(
            "language '{}': the station speaks en and zh-CN",
            set.language.chars().take(40).collect::<String>()
        ))
    })?;
    let user = session.user.clone();
    blocking(&app, move |app| {
        Ok(store(app)?.set_user_language(&user, lang.code())?)
    })
    .await?;
    Ok(Json(Language {
        language: lang.code().to_string(),
    }))
}

/// `GET /api/i18n/{language}`: the web UI's words in that language (the
/// `web.` part of the one catalogue, and the parts it shares with the
/// reports under `web.`: the engine's texts (`say.`, `reason.` as
/// `web.say.reason.`), their word-valued values (`arg.`), the table headers
/// (`head.`) and the run states (`state.`), so the page words them as the
/// reports do); open to everyone, the login page needs it.
#[utoipa::path(get, path = "/api/i18n/{language}", tag = "session",
    params(("language" = String, Path, description = "`en` or `zh-CN` (also `zh`, `zh-Hans`, …)")),
    responses(
        (status = 200, description = "the words", body = Catalogue),
        (status = 404, description = "no catalogue for that language", body = ErrorBody),
    ))]
pub(super) async fn catalogue(Path(language): Path<String>) -> ApiResult<Json<Catalogue>> {
    let lang = Lang::parse(&language).ok_or_else(|| {
        ApiError::not_found(format!(
            "no catalogue for '{}': en and zh-CN",
            language.chars().take(40).collect::<String>()
        ))
    })?;
    use spinbench_report::lang::catalogue;
    let mut words = catalogue(lang, "web.");
    for (prefix, shown_as) in [
        ("say.", "web.say."),
        ("reason.", "web.say.reason."),
        ("arg.", "web.arg."),
        ("head.", "web.head."),
        ("state.", "web.state."),
        ("device.", "web.device."),
    ] {
        words.extend(
            catalogue(lang, prefix)
                .into_iter()
                .map(|(key, text)| (format!("{shown_as}{}", &key[prefix.len()..]), text)),
        );
    }
    Ok(Json(Catalogue {
        language: lang.code().to_string(),
        words,
    }))
}
