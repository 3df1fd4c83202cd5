//! Test plans and the station config, read by everyone, saved by engineers
//! after being checked against the station.

use super::schema::{
    DesignReply, DesignRequest, ErrorBody, PlanEntry, PlanSaved, PlanSummary, PlansReply, Saved,
    StationReply,
};
use super::{
    ApiError, ApiResult, App, BTreeMap, Bytes, HeaderMap, Json, Path, Role, State, TestPlan, audit,
    audit_now, authorize, blocking, parse_json, store,
};

pub(super) fn plan_name_ok(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

/// The station's plan `name` as a start or a design reads it, the form's
/// `serials` (blank ones dropped) replacing its own when any is given; with
/// whether they did.
pub(super) fn plan_with_serials(
    app: &App,
    name: &str,
    serials: BTreeMap<String, String>,
) -> ApiResult<(TestPlan, bool)> {
    let path = app.plans_dir.join(format!("{name}.toml"));
    let text = std::fs::read_to_string(&path)
        .map_err(|_| ApiError::not_found(format!("no plan named '{name}' (GET /api/plans)")))?;
    let mut plan = TestPlan::from_toml(&text).map_err(|e| ApiError::bad(e.to_string()))?;
    let typed: BTreeMap<String, String> = serials
        .into_iter()
        .filter(|(_, s)| !s.trim().is_empty())
        .collect();
    let given = !typed.is_empty();
    if given {
        plan.serials = typed;
    }
    Ok((plan, given))
}

/// Every plan of the station, with its text and whether it reads.
#[utoipa::path(get, path = "/api/plans", tag = "plans",
    security(("session" = [])),
    responses(
        (status = 200, description = "the plans", body = PlansReply),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn plans(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<PlansReply>> {
    authorize(&app, &headers, Role::Operator, false).await?;
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
            out.push(PlanEntry {
                name: name.to_string(),
                title: plan.as_ref().map(|p| p.name.clone()).unwrap_or_default(),
                serials: plan.as_ref().map(|p| p.serials.clone()).unwrap_or_default(),
                summary: plan.as_ref().ok().and_then(summary),
                problem: plan.err().map(|e| e.to_string()),
                text,
            });
        }
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(Json(PlansReply {
        slots: app.runner.station().0.slots(),
        plans: out,
    }))
}

/// A plan at a glance, designed on the station's defaults (nothing is
/// learned to list plans); `None` when it cannot be designed.
fn summary(plan: &TestPlan) -> Option<PlanSummary> {
    let designed = plan
        .designed(&spinbench_analysis::design::StationModel::default())
        .ok()?;
    let decision = designed.limits.decision();
    let warning = designed.decision_warning();
    Some(PlanSummary {
        range_g: designed.range_g,
        levels: designed.level_table().len(),
        passes: designed.passes.iter().map(ToString::to_string).collect(),
        measurand: decision.measurand.name().to_string(),
        limit_ug_per_g2: decision.limit_ug_per_g2,
        rule: decision.rule.name().to_string(),
        k2_u95_ug_per_g2: designed.prediction.as_ref().map(|p| p.k2_u95_ug_per_g2),
        centrifuge_time_s: designed.prediction.as_ref().map(|p| p.centrifuge_time_s),
        can_decide: warning.is_none(),
        decision_warning: warning,
        decision_wording: designed.decision_wording(),
    })
}

/// Save a plan (an engineer): checked against the station first.
#[utoipa::path(put, path = "/api/plans/{name}", tag = "plans",
    security(("session" = [], "csrf" = [])),
    params(("name" = String, Path, description = "1 to 64 letters, digits, `-` or `_`", pattern = "^[A-Za-z0-9_-]{1,64}$")),
    request_body(description = "The plan as TOML (see the README's plan keys), or the same keys as a JSON object. At most 2 MiB (413 beyond).",
        content((String = "text/plain"), (Object = "application/json"))),
    responses(
        (status = 200, description = "saved", body = PlanSaved),
        (status = 400, description = "not a plan, or one this station cannot run", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an engineer", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
    ))]
pub(super) async fn save_plan(
    State(app): State<App>,
    headers: HeaderMap,
    Path(name): Path<String>,
    body: Bytes,
) -> ApiResult<Json<PlanSaved>> {
    let session = authorize(&app, &headers, Role::Engineer, true).await?;
    if !plan_name_ok(&name) {
        return Err(ApiError::bad(format!(
            "plan name '{name}': 1 to 64 letters, digits, - or _"
        )));
    }
    let text = toml_body(&headers, &body, "the plan")?;
    let text = text.as_str();
    let plan = TestPlan::from_toml(text).map_err(|e| ApiError::bad(e.to_string()))?;
    // A plan whose levels are designed when it runs is checked as designed
    // on the defaults (nothing is learned to save a plan).
    let checked = plan
        .designed(&spinbench_analysis::design::StationModel::default())
        .map_err(|e| ApiError::bad(format!("the plan cannot run on this station: {e}")))?;
    checked
        .compile(&app.runner.station().0)
        .map_err(|e| ApiError::bad(format!("the plan cannot run on this station: {e}")))?;
    // One save of a name at a time; written beside under a name of its
    // own, put in place whole, then audited. A plan whose audit entry
    // cannot be written goes back to what it was: it is not saved.
    let path = app.plans_dir.join(format!("{name}.toml"));
    let _saving = saving(&path).await;
    let previous = std::fs::read_to_string(&path).ok();
    Beside::write(&path, text)
        .and_then(Beside::put_in_place)
        .map_err(|e| ApiError::internal(format!("{}: {e}; nothing was saved", path.display())))?;
    if let Err(e) = audit(&app, &session.user, "save plan", &name).await {
        let restored = match &previous {
            Some(old) => Beside::write(&path, old).and_then(Beside::put_in_place),
            None => std::fs::remove_file(&path),
        };
        return Err(match restored {
            Ok(()) => e.prefixed("nothing was saved"),
            Err(r) => e.prefixed(&format!(
                "the plan is in place unaudited ({}: {r}); remove or restore it by hand",
                path.display()
            )),
        });
    }
    Ok(Json(PlanSaved { name, saved: true }))
}

/// Design a plan's levels, readings on the way down and dwell for a K2
/// U95 target from the station's model of its own runs, with its
/// prediction beside the published plan's. Nothing moves.
#[utoipa::path(post, path = "/api/plans/{name}/design", tag = "plans",
    security(("session" = [], "csrf" = [])),
    params(("name" = String, Path, description = "1 to 64 letters, digits, `-` or `_`", pattern = "^[A-Za-z0-9_-]{1,64}$")),
    request_body(content = DesignRequest, description = "At most 2 MiB (413 beyond)."),
    responses(
        (status = 200, description = "the design", body = DesignReply),
        (status = 400, description = "a bad body or plan, or a target this station cannot reach (the smallest it can is named)", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token", body = ErrorBody),
        (status = 404, description = "no such plan", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
    ))]
pub(super) async fn design_plan(
    State(app): State<App>,
    headers: HeaderMap,
    Path(name): Path<String>,
    body: Bytes,
) -> ApiResult<Json<DesignReply>> {
    authorize(&app, &headers, Role::Operator, true).await?;
    if !plan_name_ok(&name) {
        return Err(ApiError::bad(format!(
            "plan name '{}': 1 to 64 letters, digits, - or _",
            spinbench_engine::bounds::shown(&name)
        )));
    }
    let ask: DesignRequest = parse_json(&body)?;
    // The form's serials, as a start takes them.
    let (mut plan, typed) = plan_with_serials(&app, &name, ask.serials)?;
    plan.set_target(ask.target_k2_u95_ug_per_g2)
        .map_err(|e| ApiError::bad(e.to_string()))?;
    let config = app.runner.station().0;
    let station = config.station.clone();
    let learned = blocking(&app, move |app| {
        Ok(crate::station_model::learn_from(
            &*store(app)?,
            &station,
            crate::station_model::DEFAULT_MODEL_RUNS,
        ))
    })
    .await?;
    let designed = plan
        .designed(&learned.model)
        .map_err(|e| ApiError::bad(e.to_string()))?;
    // With the form's serials, what a start would refuse (a slot this
    // station has not, a level beyond its rate) is refused here too.
    if typed {
        designed
            .compile(&config)
            .map_err(|e| ApiError::bad(e.to_string()))?;
    }
    let p = designed
        .prediction
        .clone()
        .ok_or_else(|| ApiError::internal("the design gave no prediction"))?;
    Ok(Json(DesignReply {
        decision_warning: designed.decision_warning(),
        decision_wording: designed.decision_wording(),
        levels_g: designed.level_table(),
        down_levels_g: designed.down_levels.clone().unwrap_or_default(),
        dwell_s: designed.dwell.seconds,
        k2_u95_ug_per_g2: p.k2_u95_ug_per_g2,
        k2_u95_run_range_ug_per_g2: p.k2_u95_run_range_ug_per_g2,
        instruments: designed.serials.len(),
        centrifuge_time_s: p.centrifuge_time_s,
        published_k2_u95_ug_per_g2: p.published_k2_u95_ug_per_g2,
        published_centrifuge_time_s: p.published_centrifuge_time_s,
        model_source: learned.source,
    }))
}

/// The station config in use.
#[utoipa::path(get, path = "/api/station", tag = "plans",
    security(("session" = [])),
    responses(
        (status = 200, description = "the station", body = StationReply),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn station(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<StationReply>> {
    authorize(&app, &headers, Role::Operator, false).await?;
    let (s, text) = app.runner.station();
    Ok(Json(StationReply {
        slots: s.slots(),
        name: s.station,
        simulated: app.runner.simulated(),
        toml: text,
    }))
}

/// Save the station config (an engineer; not on the virtual bench, nor during a run).
#[utoipa::path(put, path = "/api/station", tag = "plans",
    security(("session" = [], "csrf" = [])),
    request_body(description = "The station config as TOML, or the same keys as a JSON object. At most 2 MiB (413 beyond).",
        content((String = "text/plain"), (Object = "application/json"))),
    responses(
        (status = 200, description = "saved and in use", body = Saved),
        (status = 400, description = "not a station config", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an engineer", body = ErrorBody),
        (status = 409, description = "the virtual bench's config, a run is active, or the config file cannot be written (nothing changed)", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
    ))]
pub(super) async fn save_station(
    State(app): State<App>,
    headers: HeaderMap,
    body: Bytes,
) -> ApiResult<Json<Saved>> {
    let session = authorize(&app, &headers, Role::Engineer, true).await?;
    let text = toml_body(&headers, &body, "the station config")?;
    let config = spinbench_engine::StationConfig::from_toml(&text)
        .map_err(|e| ApiError::bad(e.to_string()))?;
    let Some(path) = app.station_path.clone() else {
        return Err(ApiError::conflict(
            "the virtual bench's station config is made from its devices; change the bench with --sim-config",
        ));
    };
    if let Some(run) = app.runner.active() {
        return Err(ApiError::conflict(format!(
            "run {run} is active; change the station after it"
        )));
    }
    // The name is the identity this server claimed in the fleet at its
    // start (its runs, its register, its yield): not changed under it.
    let held = app.runner.station().0.station;
    if config.station != held {
        return Err(ApiError::conflict(format!(
            "this server holds the station name '{held}' in the fleet; a running server's name is not changed \
             (its runs, its equipment register and its yield follow it). Keep `station = \"{held}\"` here; \
             to rename the station, change `station` in its station.toml and restart `spinbench serve` \
             (a name another live station holds is refused there)"
        ))
        .worded(
            spinbench_engine::event::Wording::new("error.station_rename")
                .with("held", &held),
        ));
    }
    // Written beside (a config that cannot be kept is neither used nor
    // audited), audited (no change without its entry), then put in place
    // and applied; a failure after the entry is audited too.
    let _saving = saving(&path).await;
    blocking(&app, move |app| {
        let shown = path.display().to_string();
        let beside = Beside::write(&path, &text).map_err(|e| {
            ApiError::conflict(format!(
                "{}: cannot write the station config ({e}); nothing was changed. Under the packaged service \
                 the config in /etc/spinbench is read-only to the service: edit it there as root, then \
                 `systemctl restart spinbench`",
                path.display()
            ))
        })?;
        audit_now(app, &session.user, "save station config", &shown)
            .map_err(|e| e.prefixed("nothing was changed"))?;
        let failed = |why: &str| {
            let _ = audit_now(
                app,
                &session.user,
                "save station config failed",
                &format!("{shown}: {why}"),
            );
        };
        let old = std::fs::read_to_string(&path).ok();
        if let Err(e) = beside.put_in_place() {
            failed(&e.to_string());
            return Err(ApiError::conflict(format!(
                "{shown}: cannot put the station config in place ({e}); nothing was changed"
            )));
        }
        if let Err(why) = app.runner.set_station(config, text) {
            // A run started meanwhile: the file goes back to what it was.
            if let Some(old) = old {
                let _ = Beside::write(&path, &old).and_then(Beside::put_in_place);
            }
            failed(&why.to_string());
            return Err(why.into());
        }
        Ok(())
    })
    .await?;
    Ok(Json(Saved { saved: true }))
}

/// A file's new text written beside it under a name no other save shares
/// (`.NAME.saving-XXXXXX`, created exclusively), so that a failed write
/// leaves the old file as it was; put in place whole by a rename, or
/// removed when dropped unused.
struct Beside {
    file: tempfile::NamedTempFile,
    path: std::path::PathBuf,
}

impl Beside {
    /// Write `text` beside `path`, synced.
    fn write(path: &std::path::Path, text: &str) -> std::io::Result<Beside> {
        use std::io::Write as _;
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => std::path::Path::new("."),
        };
        let prefix = format!(
            ".{}.saving-",
            path.file_name().unwrap_or_default().to_string_lossy()
        );
        let mut file = tempfile::Builder::new()
            .prefix(&prefix)
            .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o644))
            .tempfile_in(dir)?;
        file.write_all(text.as_bytes())?;
        file.as_file().sync_all()?;
        Ok(Beside {
            file,
            path: path.to_path_buf(),
        })
    }

    /// Replace the file with the new text (a rename).
    fn put_in_place(self) -> std::io::Result<()> {
        self.file
            .persist(&self.path)
            .map(|_| ())
            .map_err(|e| e.error)
    }
}

/// Hold the one save of `path` at a time: two saves of one plan (or of the
/// station config) never interleave their write, their audit entry and
/// their putting back.
async fn saving(path: &std::path::Path) -> tokio::sync::OwnedMutexGuard<()> {
    type Locks =
        std::collections::HashMap<std::path::PathBuf, std::sync::Arc<tokio::sync::Mutex<()>>>;
    static LOCKS: std::sync::LazyLock<std::sync::Mutex<Locks>> =
        std::sync::LazyLock::new(Default::default);
    let lock = {
        let mut locks = LOCKS
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        // Locks nobody holds or waits for are dropped, so the map stays
        // as small as the saves in flight.
        locks.retain(|_, l| std::sync::Arc::strong_count(l) > 1);
        locks.entry(path.to_path_buf()).or_default().clone()
    };
    lock.lock_owned().await
}

/// An uploaded plan or station config as TOML text: the body as sent
/// (`text/plain`), or a JSON object of the same keys
/// (`application/json`, for clients generated from the API document)
/// written as TOML. `what` names it in errors.
fn toml_body(headers: &HeaderMap, body: &[u8], what: &str) -> ApiResult<String> {
    let json = headers
        .get(axum::http::header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|t| {
            t.trim_start()
                .to_ascii_lowercase()
                .starts_with("application/json")
        });
    if !json {
        return std::str::from_utf8(body)
            .map(str::to_string)
            .map_err(|_| ApiError::bad(format!("{what} is not UTF-8 text")));
    }
    let value: toml::Value = serde_json::from_slice(body).map_err(|e| {
        ApiError::bad(format!(
            "{what} as JSON: {e} (an object of the TOML keys; null has no TOML form: leave the key out)"
        ))
    })?;
    if !value.is_table() {
        return Err(ApiError::bad(format!(
            "{what} as JSON: an object of its keys"
        )));
    }
    toml::to_string(&value).map_err(|e| ApiError::bad(format!("{what} as JSON: {e}")))
}
