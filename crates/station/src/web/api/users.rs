//! Users (admins manage them) and the audit log.

use super::schema::{AuditEntry, ErrorBody, NewUser, UserAdded, UserEntry};
use super::*;

/// Every user (an admin).
#[utoipa::path(get, path = "/api/users", tag = "users",
    security(("session" = [])),
    responses(
        (status = 200, description = "the users", body = Vec<UserEntry>),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "not an admin", body = ErrorBody),
    ))]
pub(super) async fn users(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<UserEntry>>> {
    authorize(&app, &headers, Role::Admin, false)?;
    let users = store(&app).users()?;
    Ok(Json(
        users
            .iter()
            .map(|u| UserEntry {
                name: u.name.clone(),
                role: u.role.clone(),
                created_at: u.created_at,
            })
            .collect(),
    ))
}

/// Add a user (an admin).
#[utoipa::path(post, path = "/api/users", tag = "users",
    security(("session" = [], "csrf" = [])),
    request_body(content = NewUser, description = "At most 2 MiB (413 beyond)."),
    responses(
        (status = 201, description = "added", body = UserAdded),
        (status = 400, description = "a bad name, role or password", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an admin", body = ErrorBody),
        (status = 409, description = "the name is taken", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
    ))]
pub(super) async fn add_user(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<(StatusCode, Json<UserAdded>)> {
    let session = authorize(&app, &headers, Role::Admin, true)?;
    let new: NewUser = parse_json(&body)?;
    use crate::users::AddUserError;
    let role = crate::users::add_user(
        &store(&app),
        &new.name,
        &new.role,
        &new.password,
        &session.user,
    )
    .map_err(|e| match e {
        AddUserError::Invalid(why) => ApiError::bad(why),
        AddUserError::Exists(_) => ApiError::conflict(e.to_string()),
        AddUserError::Hash(why) => ApiError::internal(why),
        AddUserError::Store(e) => ApiError::from(e),
    })?;
    Ok((
        StatusCode::CREATED,
        Json(UserAdded {
            name: new.name,
            role: role.as_str().to_string(),
        }),
    ))
}

/// Remove a user (an admin; not oneself): their sessions end.
#[utoipa::path(delete, path = "/api/users/{name}", tag = "users",
    security(("session" = [], "csrf" = [])),
    params(("name" = String, Path, description = "the user")),
    responses(
        (status = 204, description = "removed"),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an admin", body = ErrorBody),
        (status = 404, description = "no such user", body = ErrorBody),
        (status = 409, description = "one's own name", body = ErrorBody),
    ))]
pub(super) async fn delete_user(
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
    app.sessions.close_user(&store(&app), &name);
    audit(&app, &session.user, "remove user", &name)?;
    Ok(StatusCode::NO_CONTENT)
}

/// The last 500 entries of the audit log, newest first (an admin).
#[utoipa::path(get, path = "/api/audit", tag = "users",
    security(("session" = [])),
    responses(
        (status = 200, description = "the entries", body = Vec<AuditEntry>),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "not an admin", body = ErrorBody),
    ))]
pub(super) async fn audit_log(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<AuditEntry>>> {
    authorize(&app, &headers, Role::Admin, false)?;
    let rows = store(&app).audit_log(500)?;
    Ok(Json(
        rows.iter()
            .map(|r| AuditEntry {
                seq: r.seq,
                at: r.at,
                who: r.who.clone(),
                action: r.action.clone(),
                detail: r.detail.clone(),
            })
            .collect(),
    ))
}
