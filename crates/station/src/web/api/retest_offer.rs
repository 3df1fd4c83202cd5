//! What a retest of a finished run would do, before it is started: the
//! instruments it takes and, for each inconclusive one, what would decide
//! it and whether the retest is predicted to (`GET /api/runs/{id}/retest`).

use super::schema::{ErrorBody, RetestAdviceRow, RetestOffer};
use super::{
    ApiError, ApiResult, App, HeaderMap, Json, Path, Role, State, authorize, blocking, store,
};
use axum::http::StatusCode;

/// The retest a finished run would get (the web's Retest takes what needs
/// one; a clear fail is set aside).
#[utoipa::path(get, path = "/api/runs/{id}/retest", tag = "runs",
    security(("session" = [])),
    params(("id" = String, Path, description = "the finished run")),
    responses(
        (status = 200, description = "the retest offered", body = RetestOffer),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 404, description = "no such run", body = ErrorBody),
        (status = 409, description = "the run has not ended, or has nothing to retest", body = ErrorBody),
    ))]
pub(super) async fn retest_offer(
    State(app): State<App>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> ApiResult<Json<RetestOffer>> {
    use crate::retest::{RetestFromStoreError as E, retest_plan_from_store};
    use spinbench_engine::retest::{RetestChoice, RetestError};
    authorize(&app, &headers, Role::Operator, false).await?;
    let asked = id.clone();
    let found = blocking(&app, move |app| {
        Ok(retest_plan_from_store(
            &*store(app)?,
            &asked,
            RetestChoice::default(),
        ))
    })
    .await?;
    let retest = found.map_err(|e| match e {
        E::NotFound(_) | E::Retest(RetestError::BadRunId(_)) => ApiError::not_found(e.to_string()),
        E::NotEnded(..)
        | E::Retest(RetestError::NothingToRetest(_) | RetestError::NotGraded(_))
        | E::NotToRetest { .. }
        | E::LookAlikeSerial { .. } => ApiError::conflict(e.to_string()),
        E::Plan(..) => ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()),
        E::Store(s) => ApiError::from(s),
    })?;
    Ok(Json(RetestOffer {
        retest_of: id,
        serials: retest.serials,
        sequential_levels_per_mounting: retest.plan.sequential.map(|s| s.max_levels_per_pass),
        advice: retest.advice.iter().map(RetestAdviceRow::from).collect(),
    }))
}
