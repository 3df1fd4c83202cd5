//! A finished run's records changed by an engineer: a level of one
//! instrument left out of its reduction, or such an exclusion withdrawn;
//! reduced and graded again by the run's own plan and station config, with
//! the figures before and after in the audit log.

use super::schema::{ErrorBody, ExcludeLevel, Excluded};
use super::{
    ApiError, ApiResult, App, Bytes, HeaderMap, Json, Path, Role, State, TestPlan, authorize,
    blocking, json, parse_json, store,
};

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
    change_level(app, headers, id, body, LevelChange::Exclude).await
}

/// Withdraw an engineer's exclusion of a level of one instrument of a
/// finished run (an engineer, with a reason): the record is
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
    change_level(app, headers, id, body, LevelChange::Withdraw).await
}

/// What an engineer does to a level of a finished run.
#[derive(Debug, Clone, Copy)]
enum LevelChange {
    /// Leave it out.
    Exclude,
    /// Put it back (withdraw its exclusion).
    Withdraw,
}

/// Both routes: the body checked, the record changed by the run's own plan
/// and station config, stored with its audit entry (figures before and
/// after), and answered.
async fn change_level(
    app: App,
    headers: HeaderMap,
    id: String,
    body: Bytes,
    change: LevelChange,
) -> ApiResult<Json<Excluded>> {
    let session = authorize(&app, &headers, Role::Engineer, true).await?;
    let ask: ExcludeLevel = parse_json(&body)?;
    check_exclusion_ask(&app, &id, &ask)?;
    blocking(&app, move |app| {
        let store = store(app)?;
        let (before, after, revision) =
            change_record(
                &store,
                &id,
                &ask.serial,
                |record, plan, station| match change {
                    LevelChange::Exclude => spinbench_engine::judgement::exclude_after_run(
                        record,
                        plan,
                        station,
                        spinbench_analysis::exclusion::LevelExclusion {
                            unit: Some(ask.serial.clone()),
                            mount: ask.mount,
                            g: ask.g,
                            reason: ask.reason.trim().to_string(),
                            by: session.user.clone(),
                            points_removed: 0,
                        },
                    ),
                    LevelChange::Withdraw => {
                        spinbench_engine::judgement::withdraw_exclusion_after_run(
                            record, plan, station, ask.mount, ask.g,
                        )
                    }
                },
            )?;
        let (action, back) = match change {
            LevelChange::Exclude => ("exclude level", ""),
            LevelChange::Withdraw => ("withdraw exclusion", " back in"),
        };
        let detail = format!(
            "{id} {} {}:{} g{back} ({}): k2_max {} → {} µg/g², outcome {} → {}",
            ask.serial,
            ask.mount,
            ask.g,
            ask.reason.trim(),
            k2_shown(&before),
            k2_shown(&after),
            before.outcome,
            after.outcome
        );
        if store.replace_result(&id, &after, revision, &session.user, action, &detail)?
            == spinbench_store::Replaced::ChangedMeanwhile
        {
            return Err(ApiError::conflict(format!(
                "{}'s result in run {id} was changed by someone else while this change was made; nothing was changed: reload the run and try again",
                ask.serial
            )));
        }
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
    // Nor a right-to-left override or a zero-width character:
    // the one rule for every reason typed from outside.
    spinbench_engine::bounds::reason_text(&ask.reason, 500)
        .map_err(|why| ApiError::bad(format!("reason: {why}")))?;
    if app.runner.active().as_deref() == Some(id) {
        return Err(ApiError::conflict(format!(
            "run {id} is still going; change its records once it has ended"
        )));
    }
    Ok(())
}

/// Instrument `serial` of finished run `id` changed by `change` under the
/// run's own plan and station config: its record before and after, and
/// the stored revision it was read at (a refusal of `change` is a 409).
fn change_record(
    store: &spinbench_store::Store,
    id: &str,
    serial: &str,
    change: impl FnOnce(
        &spinbench_engine::UnitRecord,
        &spinbench_engine::CompiledPlan,
        &spinbench_engine::StationConfig,
    ) -> Result<
        spinbench_engine::UnitRecord,
        spinbench_engine::judgement::ExclusionError,
    >,
) -> ApiResult<(
    spinbench_engine::UnitRecord,
    spinbench_engine::UnitRecord,
    i64,
)> {
    let record = store
        .run_record(id)?
        .ok_or_else(|| ApiError::not_found(format!("no run '{id}' (GET /api/runs)")))?;
    let start = record.start;
    let station_toml = start.station_config.ok_or_else(|| {
        ApiError::conflict(format!(
            "run {id} did not record its station config, so it cannot be reduced again here; use `spinbench analyze --exclude-level`"
        ))
    })?;
    // A config another release wrote (a key this one does not know) cannot
    // reduce the run again here: said, not a server error.
    let station = spinbench_engine::StationConfig::from_toml(&station_toml).map_err(|e| {
        ApiError::conflict(format!(
            "run {id}'s recorded station config cannot be read by this release ({e}), so it cannot be reduced again here; nothing was changed"
        ))
    })?;
    let plan: TestPlan = start.plan.plan.ok_or_else(|| {
        ApiError::conflict(format!(
            "run {id}'s plan: {}",
            start.plan.unread.unwrap_or_default()
        ))
    })?;
    let compiled = plan
        .compile(&station)
        .map_err(|e| ApiError::internal(format!("run {id}'s plan: {e}")))?;
    let state = record.end.state;
    let result = record
        .results
        .into_iter()
        .find(|r| r.serial == serial)
        .ok_or_else(|| {
            ApiError::not_found(format!("run {id} ({state}) has no instrument '{serial}'"))
        })?;
    // A stand-in for a record this release cannot read is never written
    // back over the stored one.
    if let Some(why) = &result.unreadable {
        return Err(ApiError::conflict(format!(
            "the stored record of '{serial}' in run {id} cannot be read by this release ({why}), so it cannot be reduced again here; nothing was changed"
        )));
    }
    // The body was well formed; the record's state refuses it (a level the
    // run does not have, one already out or not out, too few levels left).
    let after = change(&result.record, &compiled, &station)
        .map_err(|refused| ApiError::conflict(refused.to_string()))?;
    Ok((result.record, after, result.revision))
}
