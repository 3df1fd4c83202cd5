//! The OpenAPI document, generated from the handlers' `#[utoipa::path]`
//! attributes and the types of [`super::schema`] (issue 17, part 1): the
//! schemas are the types the handlers parse and send, so the document
//! cannot drift from them; a test holds its paths to the route table.

use super::*;
use utoipa::openapi::security::{ApiKey, ApiKeyValue, SecurityScheme};
use utoipa::{Modify, OpenApi};

/// The security schemes: the session cookie, and the CSRF token every
/// change also needs.
struct SecuritySchemes;

impl Modify for SecuritySchemes {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "session",
            SecurityScheme::ApiKey(ApiKey::Cookie(ApiKeyValue::with_description(
                auth::SESSION_COOKIE,
                "the session cookie POST /api/login sets (HttpOnly, SameSite=Strict; Secure under TLS)",
            ))),
        );
        components.add_security_scheme(
            "csrf",
            SecurityScheme::ApiKey(ApiKey::Header(ApiKeyValue::with_description(
                "X-CSRF-Token",
                "the session's CSRF token (in the login's answer and GET /api/session), on every request that changes something",
            ))),
        );
    }
}

/// The document.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "spinbench station API",
        description = "The HTTP API of a spinbench centrifuge test station (the web UI uses the same). \
Log in with POST /api/login: the answer sets the session cookie and gives the CSRF token, which every \
request that changes something sends in X-CSRF-Token. Roles: operator < engineer < admin. Errors are \
JSON {\"error\": \"…\"} that say what to do. Request bodies: a login at most 4 KiB, any other at most \
2 MiB (413 beyond). Run results' reasons and control-chart rules are worded in the user's language \
(PUT /api/session/language), their codes stay machine names.",
        license(name = "MIT OR Apache-2.0"),
    ),
    paths(
        assets::openapi,
        session::login, session::logout, session::session, session::set_language, session::catalogue,
        live::status, live::events,
        plans::plans, plans::save_plan, plans::station, plans::save_station,
        runs::runs, runs::start_run, runs::run, runs::report, runs::exclude_level, runs::retest,
        runs::answer_prompt, runs::pause, runs::resume, runs::abort, runs::unit,
        charts::control_charts,
        equipment::equipment, equipment::set_equipment,
        live::fleet, users::users, users::add_user, users::delete_user, users::change_user, users::audit_log,
    ),
    // Types used only as parameters are listed, so their references resolve.
    components(schemas(schema::ReportFormatName, schema::LanguageTag)),
    modifiers(&SecuritySchemes),
    tags(
        (name = "session", description = "log in and out, the session, its language"),
        (name = "live", description = "the station now, and its live events"),
        (name = "plans", description = "test plans and the station config"),
        (name = "runs", description = "start, steer and read runs"),
        (name = "charts", description = "control charts across runs"),
        (name = "equipment", description = "the equipment register"),
        (name = "users", description = "users and the audit log (admins)"),
        (name = "page", description = "this document (the web UI's own files are not part of the API)"),
    ),
)]
pub struct ApiDoc;

/// The document as JSON (made once).
pub fn json() -> &'static str {
    static JSON: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    JSON.get_or_init(|| {
        ApiDoc::openapi()
            .to_pretty_json()
            .unwrap_or_else(|e| format!("{{\"error\": \"the OpenAPI document: {e}\"}}"))
    })
}
