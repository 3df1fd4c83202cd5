//! Test plans and the station config, read by everyone, saved by engineers
//! after being checked against the station.

use super::*;

pub(super) fn plan_name_ok(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

pub(super) async fn plans(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<axum::Json<Value>> {
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

pub(super) async fn save_plan(
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

pub(super) async fn station(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Operator, false)?;
    let (s, text) = app.runner.station();
    Ok(axum::Json(json!({
        "name": s.station,
        "slots": s.slots(),
        "simulated": app.runner.simulated(),
        "toml": text,
    })))
}

pub(super) async fn save_station(
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
