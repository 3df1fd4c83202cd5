//! Machine clients: their API tokens (admins make, list and revoke them;
//! see `crate::tokens`) and the webhooks pushed to them.

use super::schema::{ErrorBody, NewToken, TokenEntry, TokenMade, WebhooksReply};
use super::{
    ApiError, ApiResult, App, Bytes, HeaderMap, Json, Path, Role, State, StatusCode, authorize,
    blocking, parse_json, store,
};
use crate::tokens::TokenError;

fn token_error(e: TokenError) -> ApiError {
    match e {
        TokenError::Invalid(why) => ApiError::bad(why),
        TokenError::Exists(_) => ApiError::conflict(e.to_string()),
        TokenError::Unknown(_) => ApiError::not_found(e.to_string()),
        TokenError::Store(e) => ApiError::from(e),
    }
}

/// Every API token, the revoked ones too (an admin); never a secret.
#[utoipa::path(get, path = "/api/tokens", tag = "users",
    security(("session" = [])),
    responses(
        (status = 200, description = "the tokens", body = Vec<TokenEntry>),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "not an admin", body = ErrorBody),
    ))]
pub(super) async fn tokens(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<TokenEntry>>> {
    authorize(&app, &headers, Role::Admin, false).await?;
    let rows = blocking(&app, |app| Ok(store(app)?.api_tokens()?)).await?;
    Ok(Json(
        rows.into_iter()
            .map(|t| TokenEntry {
                name: t.name,
                role: t.role,
                created_by: t.created_by,
                created_at: t.created_at,
                last_used_at: t.last_used_at,
                revoked_at: t.revoked_at,
                revoked_by: t.revoked_by,
            })
            .collect(),
    ))
}

/// Make an API token for a machine client (an admin): its secret is in
/// this answer and nowhere else.
#[utoipa::path(post, path = "/api/tokens", tag = "users",
    security(("session" = [], "csrf" = [])),
    request_body(content = NewToken, description = "At most 2 MiB (413 beyond)."),
    responses(
        (status = 201, description = "made", body = TokenMade),
        (status = 400, description = "a bad name or role", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an admin", body = ErrorBody),
        (status = 409, description = "the name is taken (or was, by a revoked token)", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
    ))]
pub(super) async fn add_token(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<(StatusCode, Json<TokenMade>)> {
    let session = authorize(&app, &headers, Role::Admin, true).await?;
    let asked: NewToken = parse_json(&body)?;
    let made = blocking(&app, move |app| {
        Ok(crate::tokens::add_token(
            &*store(app)?,
            &asked.name,
            &asked.role,
            &session.user,
        ))
    })
    .await?
    .map_err(token_error)?;
    Ok((
        StatusCode::CREATED,
        Json(TokenMade {
            name: made.name,
            role: made.role.as_str().to_string(),
            secret: made.secret,
        }),
    ))
}

/// Revoke an API token (an admin): its calls are refused on every server
/// of the fleet within seconds.
#[utoipa::path(delete, path = "/api/tokens/{name}", tag = "users",
    security(("session" = [], "csrf" = [])),
    params(("name" = String, Path, description = "the token's name")),
    responses(
        (status = 204, description = "revoked"),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an admin", body = ErrorBody),
        (status = 404, description = "no such token, or revoked already", body = ErrorBody),
    ))]
pub(super) async fn revoke_token(
    State(app): State<App>,
    headers: HeaderMap,
    Path(name): Path<String>,
    _body: Bytes,
) -> ApiResult<StatusCode> {
    let session = authorize(&app, &headers, Role::Admin, true).await?;
    blocking(&app, move |app| {
        crate::tokens::revoke_token(&*store(app)?, &name, &session.user).map_err(token_error)?;
        app.machine_tokens.forget(&name);
        Ok(())
    })
    .await?;
    Ok(StatusCode::NO_CONTENT)
}

/// This server's webhooks and their last deliveries (an admin).
#[utoipa::path(get, path = "/api/webhooks", tag = "users",
    security(("session" = [])),
    responses(
        (status = 200, description = "the receiver and the deliveries", body = WebhooksReply),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "not an admin", body = ErrorBody),
    ))]
pub(super) async fn webhooks(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<WebhooksReply>> {
    authorize(&app, &headers, Role::Admin, false).await?;
    Ok(Json(WebhooksReply {
        url: app.webhooks.url(),
        deliveries: app.webhooks.deliveries(),
    }))
}
