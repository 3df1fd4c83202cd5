//! Users (admins manage them) and the audit log.

use super::schema::{AuditEntry, ChangeUser, ErrorBody, NewUser, UserAdded, UserEntry};
use super::{
    ApiError, ApiResult, App, Bytes, HeaderMap, Json, Path, Role, State, StatusCode, authorize,
    blocking, parse_json, store,
};

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
    authorize(&app, &headers, Role::Admin, false).await?;
    let users = blocking(&app, |app| Ok(store(app)?.users()?)).await?;
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
    let session = authorize(&app, &headers, Role::Admin, true).await?;
    let new: NewUser = parse_json(&body)?;
    use crate::users::AddUserError;
    let admin = session.user.clone();
    let (name, role, password) = (new.name.clone(), new.role.clone(), new.password.clone());
    let role = blocking(&app, move |app| {
        Ok(crate::users::add_user(
            &*store(app)?,
            &name,
            &role,
            &password,
            &admin,
        ))
    })
    .await?
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

/// Remove a user (an admin; not oneself): their sessions end on every
/// server of the fleet within seconds, and their event streams close.
#[utoipa::path(delete, path = "/api/users/{name}", tag = "users",
    security(("session" = [], "csrf" = [])),
    params(("name" = String, Path, description = "the user")),
    responses(
        (status = 204, description = "removed"),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an admin", body = ErrorBody),
        (status = 404, description = "no such user", body = ErrorBody),
        (status = 409, description = "one's own name, or the only admin", body = ErrorBody),
    ))]
pub(super) async fn delete_user(
    State(app): State<App>,
    headers: HeaderMap,
    Path(name): Path<String>,
    _body: Bytes,
) -> ApiResult<StatusCode> {
    let session = authorize(&app, &headers, Role::Admin, true).await?;
    if name == session.user {
        return Err(ApiError::conflict(
            "you cannot remove yourself; another admin can",
        ));
    }
    blocking(&app, move |app| {
        let removed =
            crate::users::remove_user(&*store(app)?, &name, &session.user).map_err(user_error)?;
        if !removed {
            return Err(ApiError::not_found(format!("no user '{name}'")));
        }
        app.sessions.close_user(&*store(app)?, &name);
        Ok(())
    })
    .await?;
    Ok(StatusCode::NO_CONTENT)
}

/// Change a user's role and/or password (an admin): their sessions end on
/// every server of the fleet within seconds.
#[utoipa::path(put, path = "/api/users/{name}", tag = "users",
    security(("session" = [], "csrf" = [])),
    params(("name" = String, Path, description = "the user")),
    request_body(content = ChangeUser, description = "At most 2 MiB (413 beyond)."),
    responses(
        (status = 200, description = "changed", body = UserAdded),
        (status = 400, description = "a bad role or password, or nothing to change", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an admin", body = ErrorBody),
        (status = 404, description = "no such user", body = ErrorBody),
        (status = 409, description = "the only admin's role", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
    ))]
pub(super) async fn change_user(
    State(app): State<App>,
    headers: HeaderMap,
    Path(name): Path<String>,
    body: Bytes,
) -> ApiResult<Json<UserAdded>> {
    let session = authorize(&app, &headers, Role::Admin, true).await?;
    let change: ChangeUser = parse_json(&body)?;
    if change.role.is_none() && change.password.is_none() {
        return Err(ApiError::bad("give a role, a password or both"));
    }
    let user = name.clone();
    let role = blocking(&app, move |app| {
        if store(app)?.user(&user)?.is_none() {
            return Err(ApiError::not_found(format!("no user '{user}'")));
        }
        let role = crate::users::change_user(
            &*store(app)?,
            &user,
            change.role.as_deref(),
            change.password.as_deref(),
            &session.user,
        )
        .map_err(user_error)?;
        app.sessions.close_user(&*store(app)?, &user);
        Ok(role)
    })
    .await?;
    Ok(Json(UserAdded {
        name,
        role: role.as_str().to_string(),
    }))
}

/// A user operation's error as the API answers it.
fn user_error(e: crate::users::AddUserError) -> ApiError {
    use crate::users::AddUserError;
    match e {
        AddUserError::Invalid(why) if why.contains("only admin") => ApiError::conflict(why),
        AddUserError::Invalid(why) => ApiError::bad(why),
        AddUserError::Exists(_) => ApiError::conflict(e.to_string()),
        AddUserError::Hash(why) => ApiError::internal(why),
        AddUserError::Store(e) => ApiError::from(e),
    }
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
    authorize(&app, &headers, Role::Admin, false).await?;
    let rows = blocking(&app, |app| Ok(store(app)?.audit_log(500)?)).await?;
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
