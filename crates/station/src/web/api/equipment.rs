//! The equipment register: every device of the station
//! with its calibration certificate, dates and status, read by everyone and
//! kept by engineers (each change in the audit log).

use super::schema::{
    EquipmentEntry, EquipmentSaved, ErrorBody, SetEquipment, SignatureReply, SignatureSpike,
};
use super::{
    ApiError, ApiResult, App, Bytes, HeaderMap, Json, Path, Role, State, authorize, blocking,
    parse_json, store,
};
use spinbench_engine::bounds::person_text;
use spinbench_store::equipment::{EquipmentRow, parse_date};

/// The centrifuge's signature this station has learned from its runs'
/// instruments (docs/method.md §6): what it rests on, its resonances and
/// its plot; `runs` 0 before any run on this table learned one.
#[utoipa::path(get, path = "/api/station/signature", tag = "equipment",
    security(("session" = [])),
    responses(
        (status = 200, description = "the signature", body = SignatureReply),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn signature(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<SignatureReply>> {
    let session = authorize(&app, &headers, Role::Operator, false).await?;
    let lang = super::session::language_of(&app, &headers, Some(&session)).await;
    let station = app.runner.station().0;
    let found = blocking(&app, move |app| {
        Ok(crate::station_model::latest_signature(
            &*store(app)?,
            &station,
        ))
    })
    .await?;
    Ok(Json(match found {
        Some((run_id, sig)) => SignatureReply {
            run_id: Some(run_id),
            runs: sig.runs,
            instruments: sig.instruments,
            spikes: sig
                .correction
                .spikes
                .iter()
                .map(|s| SignatureSpike {
                    g: s.g,
                    height_ug: s.height_ug,
                })
                .collect(),
            changed_at_g: sig
                .change
                .as_ref()
                .map_or_else(Vec::new, |c| c.levels_g.clone()),
            text: spinbench_report::signature::describe(&sig, lang),
            svg: spinbench_report::signature::svg(&sig, lang),
        },
        None => SignatureReply {
            run_id: None,
            runs: 0,
            instruments: 0,
            spikes: Vec::new(),
            changed_at_g: Vec::new(),
            text: spinbench_report::lang::tr(lang, "signature.none"),
            svg: None,
        },
    }))
}

/// Every device of the station with its calibration and status.
#[utoipa::path(get, path = "/api/equipment", tag = "equipment",
    security(("session" = [])),
    responses(
        (status = 200, description = "the register", body = Vec<EquipmentEntry>),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn equipment(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<EquipmentEntry>>> {
    authorize(&app, &headers, Role::Operator, false).await?;
    let station = app.runner.station().0;
    let name = station.station.clone();
    let station_name = name.clone();
    let (list, read) = blocking(&app, move |app| {
        let store = store(app)?;
        let list = crate::equipment::station_equipment(&store, &station)?;
        let read = store.last_identified_devices(&station_name)?;
        Ok((list, read))
    })
    .await?;
    Ok(Json(
        list.iter()
            .map(|(role, row, status)| EquipmentEntry {
                read_identity: read
                    .iter()
                    .find(|d| d.role.name() == *role)
                    .map(|d| d.identity.clone()),
                station: name.clone(),
                role: role.clone(),
                identity: row.as_ref().map(|r| r.identity.clone()),
                certificate: row.as_ref().map(|r| r.certificate.clone()),
                calibrated_on: row.as_ref().map(|r| r.calibrated_on.clone()),
                due_on: row.as_ref().map(|r| r.due_on.clone()),
                updated_by: row.as_ref().map(|r| r.updated_by.clone()),
                status: status.as_str().to_string(),
            })
            .collect(),
    ))
}

/// Longest text of a register entry [characters].
const MAX_TEXT_CHARS: usize = 200;

/// Record a device's calibration (an engineer; in the audit log).
#[utoipa::path(put, path = "/api/equipment/{role}", tag = "equipment",
    security(("session" = [], "csrf" = [])),
    params(("role" = String, Path, description = "the device (`centrifuge`, `fmu 1`, `instrument supply`, …)")),
    request_body(content = SetEquipment, description = "At most 2 MiB (413 beyond)."),
    responses(
        (status = 200, description = "recorded", body = EquipmentSaved),
        (status = 400, description = "a bad text or date, calibrated after today, or due before calibrated", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an engineer", body = ErrorBody),
        (status = 404, description = "no such device in this station", body = ErrorBody),
        (status = 413, description = "a body over 2 MiB"),
    ))]
pub(super) async fn set_equipment(
    State(app): State<App>,
    headers: HeaderMap,
    Path(role): Path<String>,
    body: Bytes,
) -> ApiResult<Json<EquipmentSaved>> {
    let session = authorize(&app, &headers, Role::Engineer, true).await?;
    // The device first: a body for a device the station has not is not looked at.
    let roles = app.runner.station().0.device_roles();
    if !roles.contains(&role) {
        return Err(ApiError::not_found(format!(
            "no device '{}' in this station; its devices: {}",
            role.chars().take(80).collect::<String>(),
            roles.join(", ")
        )));
    }
    let set: SetEquipment = parse_json(&body)?;
    for (field, text) in [
        ("identity", &set.identity),
        ("certificate", &set.certificate),
    ] {
        if text.trim().is_empty()
            || text.chars().count() > MAX_TEXT_CHARS
            || text.chars().any(char::is_control)
        {
            return Err(ApiError::bad(format!(
                "{field}: 1 to {MAX_TEXT_CHARS} characters, no control characters"
            )));
        }
    }
    let calibrated = parse_date(&set.calibrated_on)
        .ok_or_else(|| ApiError::bad("calibrated_on: a date YYYY-MM-DD (1970 to 2200)"))?;
    let due = parse_date(&set.due_on)
        .ok_or_else(|| ApiError::bad("due_on: a date YYYY-MM-DD (1970 to 2200)"))?;
    let today = spinbench_store::now_s().div_euclid(86_400);
    spinbench_store::equipment::check_calibration_dates(calibrated, due, today)
        .map_err(|why| ApiError::bad(why.to_string()))?;
    let row = EquipmentRow {
        station: app.runner.station().0.station,
        role: role.clone(),
        identity: person_text(&set.identity)
            .map_err(|why| ApiError::bad(format!("identity: {why}")))?,
        certificate: person_text(&set.certificate)
            .map_err(|why| ApiError::bad(format!("certificate: {why}")))?,
        calibrated_on: set.calibrated_on,
        due_on: set.due_on,
        updated_by: session.user.clone(),
        updated_at: 0,
    };
    let due_on = row.due_on.clone();
    blocking(&app, move |app| {
        Ok(store(app)?.set_equipment(&row, &session.user)?)
    })
    .await?;
    Ok(Json(EquipmentSaved { role, due_on }))
}
