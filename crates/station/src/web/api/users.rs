//! Users (admins manage them) and the audit log.

use super::*;

pub(super) async fn users(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<axum::Json<Value>> {
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
pub(super) struct NewUser {
    name: String,
    role: String,
    password: String,
}

pub(super) async fn add_user(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<(StatusCode, axum::Json<Value>)> {
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
        axum::Json(json!({ "name": new.name, "role": role.as_str() })),
    ))
}

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

pub(super) async fn audit_log(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Admin, false)?;
    let rows = store(&app).audit_log(500)?;
    Ok(axum::Json(json!(
        rows.iter()
            .map(|r| json!({ "seq": r.seq, "at": r.at, "who": r.who, "action": r.action, "detail": r.detail }))
            .collect::<Vec<_>>()
    )))
}
