//! The OpenAPI document, generated from the handlers' `#[utoipa::path]`
//! attributes and the types of [`super::schema`]: the
//! schemas are the types the handlers parse and send, so the document
//! cannot drift from them; a test holds its paths to the route table.

use super::{
    assets, auth, charts, equipment, exclusions, history, live, plans, retest_offer, runs, schema,
    session, tokens, users,
};
use utoipa::openapi::security::{ApiKey, ApiKeyValue, HttpAuthScheme, HttpBuilder, SecurityScheme};
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
        components.add_security_scheme(
            "token",
            SecurityScheme::Http(
                HttpBuilder::new()
                    .scheme(HttpAuthScheme::Bearer)
                    .description(Some(
                        "a machine client's API token (an admin makes it: POST /api/tokens or spinbench token add), \
instead of the session cookie; a token call needs no CSRF token",
                    ))
                    .build(),
            ),
        );
    }
}

/// Every operation that takes a session also takes an API token (one
/// alternative more in its `security`), so a generated client can be given
/// either.
fn add_token_alternative(doc: &mut serde_json::Value) {
    let Some(paths) = doc["paths"].as_object_mut() else {
        return;
    };
    for op in paths
        .values_mut()
        .filter_map(|ops| ops.as_object_mut())
        .flat_map(|ops| ops.values_mut())
    {
        let Some(security) = op.get_mut("security").and_then(|s| s.as_array_mut()) else {
            continue;
        };
        if security.iter().any(|r| r.get("session").is_some()) {
            security.push(serde_json::json!({"token": []}));
        }
    }
}

/// A body of raw bytes (a PDF or XLSX report) in OpenAPI 3.1's idiom: its
/// media type with no schema (3.0's `type: string, format: binary` is not
/// 3.1's). utoipa writes a schema for every content it is given, so the
/// [`super::schema::BinaryFile`] ones are taken out here.
fn raw_bytes_without_schema(doc: &mut serde_json::Value) {
    if let Some(schemas) = doc["components"]["schemas"].as_object_mut() {
        schemas.remove("BinaryFile");
    }
    let Some(paths) = doc["paths"].as_object_mut() else {
        return;
    };
    let binary = serde_json::json!({"$ref": "#/components/schemas/BinaryFile"});
    for op in paths
        .values_mut()
        .filter_map(|ops| ops.as_object_mut())
        .flat_map(|ops| ops.values_mut())
    {
        let Some(responses) = op.get_mut("responses").and_then(|r| r.as_object_mut()) else {
            continue;
        };
        for media in responses
            .values_mut()
            .filter_map(|r| r.get_mut("content").and_then(|c| c.as_object_mut()))
            .flat_map(|c| c.values_mut())
        {
            if media.get("schema") == Some(&binary)
                && let Some(m) = media.as_object_mut()
            {
                m.remove("schema");
            }
        }
    }
}

/// OpenAPI 3.1's `webhooks`: what `serve --webhook-url` POSTs to the
/// plant's receiver, with its headers (utoipa 5 writes no webhooks).
fn add_webhooks(doc: &mut serde_json::Value) {
    let body = serde_json::json!({
        "type": "object",
        "required": ["event", "delivery", "station", "run_id", "at_unix_s", "run"],
        "properties": {
            "event": {"type": "string", "enum": ["run.started", "run.ended", "run.faulted"]},
            "delivery": {"type": "string", "description": "the delivery's id, the same on every try (X-Spinbench-Delivery): a receiver that got it already answers 2xx and does nothing"},
            "station": {"type": "string"},
            "run_id": {"type": "string"},
            "at_unix_s": {"type": "integer", "description": "when the station saw the event [Unix s]"},
            "run": {"type": "string", "description": "the run's path in this API (GET it with an API token for its results)"},
            "resumed": {"type": "boolean", "description": "run.started: continued from its journal"},
            "plan": {"type": "string", "description": "run.started: the plan's name"},
            "operator": {"type": "string", "description": "run.started: who started it (token:NAME for an API token)"},
            "serials": {"type": "array", "items": {"type": "string"}, "description": "run.started: the instruments by slot (empty: a free slot)"},
            "state": {"$ref": "#/components/schemas/LiveRunState", "description": "run.ended: how it ended"},
            "reason": {"type": ["string", "null"], "description": "run.ended, run.faulted: why, when not completed"},
            "outcomes": {"type": "object", "additionalProperties": {"$ref": "#/components/schemas/OutcomeName"}, "description": "run.ended: each instrument's outcome by serial"},
        },
    });
    doc["webhooks"] = serde_json::json!({
        "runEvent": {
            "post": {
                "summary": "A run started, ended or faulted",
                "description": "Sent by `spinbench serve --webhook-url URL --webhook-secret-file FILE`, one delivery at a time in the events' order; tried again with back-off (1 s doubling to 60 s, 8 tries) until the receiver answers 2xx. X-Spinbench-Signature is `sha256=` and the hex HMAC-SHA256 of `TIMESTAMP.BODY` under the shared secret, TIMESTAMP being X-Spinbench-Timestamp.",
                "parameters": [
                    {"name": "X-Spinbench-Event", "in": "header", "required": true, "schema": {"type": "string", "enum": ["run.started", "run.ended", "run.faulted"]}},
                    {"name": "X-Spinbench-Delivery", "in": "header", "required": true, "schema": {"type": "string"}},
                    {"name": "X-Spinbench-Timestamp", "in": "header", "required": true, "description": "Unix seconds of this try", "schema": {"type": "string"}},
                    {"name": "X-Spinbench-Signature", "in": "header", "required": true, "description": "sha256=HEX: the HMAC-SHA256 of TIMESTAMP.BODY", "schema": {"type": "string"}},
                ],
                "requestBody": {"required": true, "content": {"application/json": {"schema": body}}},
                "responses": {"2XX": {"description": "taken; anything else (or no answer in 10 s) is tried again"}},
            }
        }
    });
}

/// Links from the answers that name runs (`GET /api/runs`, `POST
/// /api/runs`) to every operation that takes a run id, so
/// a client (and Schemathesis's stateful phase) can follow them with a run
/// that exists, not only guess ids and meet 404. Added to the JSON rather
/// than through utoipa's `Link`, which (5.5) writes `operation_id` where
/// OpenAPI's Link Object has `operationId`.
fn add_run_links(doc: &mut serde_json::Value) {
    let mut targets: Vec<String> = Vec::new();
    if let Some(paths) = doc["paths"].as_object() {
        for (path, ops) in paths {
            if !path.starts_with("/api/runs/{id}") {
                continue;
            }
            for op in ops.as_object().into_iter().flat_map(|o| o.values()) {
                if let Some(id) = op["operationId"].as_str() {
                    targets.push(id.to_string());
                }
            }
        }
    }
    for (method, status, expression) in [
        ("get", "200", "$response.body#/0/id"),
        ("post", "201", "$response.body#/run_id"),
    ] {
        let Some(response) = doc
            .pointer_mut(&format!("/paths/~1api~1runs/{method}/responses/{status}"))
            .and_then(|r| r.as_object_mut())
        else {
            continue;
        };
        let links: serde_json::Map<String, serde_json::Value> = targets
            .iter()
            .map(|target| {
                (
                    target.clone(),
                    serde_json::json!({
                        "operationId": target,
                        "parameters": {"id": expression},
                        "description": format!("{target} of a run this answer names"),
                    }),
                )
            })
            .collect();
        response.insert("links".into(), serde_json::Value::Object(links));
    }
}

/// The document.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "spinbench station API",
        description = "The HTTP API of a spinbench centrifuge test station (the web UI uses the same). \
Log in with POST /api/login: the answer sets the session cookie and gives the CSRF token, which every \
request that changes something sends in X-CSRF-Token. A machine client (an MES) sends an API token \
instead (Authorization: Bearer sbt_…, made by an admin), and no CSRF token. Roles: operator < engineer < admin. Errors are \
JSON {\"error\": \"…\"} that say what to do. Request bodies: a login at most 4 KiB, any other at most \
2 MiB (413 beyond). Run results' reasons and control-chart rules are worded in the user's language \
(PUT /api/session/language), their codes stay machine names.",
        license(name = "MIT OR Apache-2.0"),
    ),
    paths(
        assets::openapi,
        session::login, session::logout, session::session, session::set_language, session::catalogue,
        live::status, live::events,
        plans::plans, plans::save_plan, plans::design_plan, plans::station, plans::save_station,
        history::runs, runs::start_run, history::run, history::report, exclusions::exclude_level, exclusions::withdraw_exclusion, runs::retest, retest_offer::retest_offer, runs::resume_run,
        runs::answer_prompt, runs::pause, runs::resume, runs::abort, runs::acknowledge_fault, history::unit,
        charts::control_charts,
        equipment::equipment, equipment::set_equipment, equipment::signature,
        live::fleet, live::retire_station, users::users, users::add_user, users::delete_user, users::change_user, users::audit_log,
        tokens::tokens, tokens::add_token, tokens::revoke_token, tokens::webhooks,
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
        let made = serde_json::to_value(ApiDoc::openapi()).and_then(|mut doc| {
            add_run_links(&mut doc);
            add_token_alternative(&mut doc);
            add_webhooks(&mut doc);
            raw_bytes_without_schema(&mut doc);
            serde_json::to_string_pretty(&doc)
        });
        made.unwrap_or_else(|e| format!("{{\"error\": \"the OpenAPI document: {e}\"}}"))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The names a documented enumeration lists.
    fn listed(doc: &serde_json::Value, name: &str) -> Vec<String> {
        doc["components"]["schemas"][name]["enum"]
            .as_array()
            .unwrap_or_else(|| panic!("{name} is not a documented enumeration"))
            .iter()
            .filter_map(|v| v.as_str().map(str::to_string))
            .collect()
    }

    /// Every schema `name` reaches through `$ref`s, `name` included.
    fn reached(doc: &serde_json::Value, name: &str) -> Vec<(String, serde_json::Value)> {
        fn refs(v: &serde_json::Value, out: &mut Vec<String>) {
            match v {
                serde_json::Value::Object(m) => {
                    if let Some(r) = m.get("$ref").and_then(|r| r.as_str()) {
                        out.push(r.trim_start_matches("#/components/schemas/").to_string());
                    }
                    m.values().for_each(|v| refs(v, out));
                }
                serde_json::Value::Array(a) => a.iter().for_each(|v| refs(v, out)),
                _ => {}
            }
        }
        let mut seen: Vec<(String, serde_json::Value)> = Vec::new();
        let mut todo = vec![name.to_string()];
        while let Some(n) = todo.pop() {
            if seen.iter().any(|(s, _)| *s == n) {
                continue;
            }
            let schema = doc["components"]["schemas"][&n].clone();
            assert!(!schema.is_null(), "{n} is referenced and not documented");
            refs(&schema, &mut todo);
            seen.push((n, schema));
        }
        seen
    }

    /// The places in `v` where an object is left untyped (`type: object`
    /// without properties or a value schema), by path.
    fn untyped_objects(v: &serde_json::Value, at: &str, out: &mut Vec<String>) {
        if let Some(m) = v.as_object() {
            let is_object = m.get("type").is_some_and(|t| {
                t == "object"
                    || t.as_array()
                        .is_some_and(|a| a.iter().any(|t| t == "object"))
            });
            if is_object && !m.contains_key("properties") && !m.contains_key("additionalProperties")
            {
                out.push(at.to_string());
            }
            for (k, v) in m {
                untyped_objects(v, &format!("{at}/{k}"), out);
            }
        } else if let Some(a) = v.as_array() {
            for (i, v) in a.iter().enumerate() {
                untyped_objects(v, &format!("{at}/{i}"), out);
            }
        }
    }

    #[test]
    fn reports_are_raw_bytes_in_the_3_1_idiom() {
        let doc: serde_json::Value = serde_json::from_str(json()).expect("the document is JSON");
        let content =
            &doc["paths"]["/api/runs/{id}/report/{format}"]["get"]["responses"]["200"]["content"];
        for media in [
            "application/pdf",
            "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet",
        ] {
            assert_eq!(content[media], serde_json::json!({}), "{media}: {content}");
        }
        assert_eq!(
            content["text/csv; charset=utf-8"]["schema"]["type"],
            "string"
        );
        assert!(
            !json().contains("\"format\": \"binary\""),
            "no 3.0 binary idiom left"
        );
    }

    #[test]
    fn the_status_is_typed_to_its_leaves() {
        let doc: serde_json::Value = serde_json::from_str(json()).expect("the document is JSON");
        let mut untyped = Vec::new();
        let schemas = reached(&doc, "StatusReply");
        for (name, schema) in &schemas {
            untyped_objects(schema, name, &mut untyped);
        }
        assert!(untyped.is_empty(), "untyped objects: {untyped:?}");
        let names: Vec<&str> = schemas.iter().map(|(n, _)| n.as_str()).collect();
        for typed in [
            "BoardSlot",
            "Wording",
            "ModuleCounters",
            "Prediction",
            "AchievedFigures",
            "FixtureName",
        ] {
            assert!(names.contains(&typed), "{typed} in {names:?}");
        }
        // A board slot refuses a field it does not document.
        assert_eq!(
            doc["components"]["schemas"]["BoardSlot"]["additionalProperties"],
            false
        );
    }

    #[test]
    fn documented_states_and_outcomes_are_the_ones_sent() {
        let doc: serde_json::Value = serde_json::from_str(json()).expect("the document is JSON");
        let live: Vec<String> = spinbench_engine::RunState::ALL
            .iter()
            .map(|s| s.as_str().to_string())
            .collect();
        assert_eq!(listed(&doc, "LiveRunState"), live);
        let stored: Vec<String> = spinbench_store::StoredState::ALL
            .iter()
            .map(|s| s.as_str().to_string())
            .collect();
        assert_eq!(listed(&doc, "StoredRunState"), stored);
        let outcomes: Vec<String> = spinbench_engine::Outcome::ALL
            .iter()
            .map(|o| o.as_str().to_string())
            .collect();
        let mut documented = listed(&doc, "OutcomeName");
        documented.sort();
        let mut sent = outcomes;
        sent.sort();
        assert_eq!(documented, sent);
        assert_eq!(
            listed(&doc, "MeasurandName"),
            [
                spinbench_engine::plan::Measurand::K2,
                spinbench_engine::plan::Measurand::K2Max
            ]
            .map(|m| m.name().to_string())
        );
        assert_eq!(
            listed(&doc, "DecisionRuleName"),
            [
                spinbench_engine::plan::DecisionRule::Guarded,
                spinbench_engine::plan::DecisionRule::Simple
            ]
            .map(|r| r.name().to_string())
        );
    }

    #[test]
    fn every_reference_of_the_document_resolves() {
        let doc: serde_json::Value = serde_json::from_str(json()).expect("the document is JSON");
        let mut refs = Vec::new();
        fn walk(v: &serde_json::Value, refs: &mut Vec<String>) {
            match v {
                serde_json::Value::Object(m) => {
                    if let Some(r) = m.get("$ref").and_then(|r| r.as_str()) {
                        refs.push(r.to_string());
                    }
                    m.values().for_each(|v| walk(v, refs));
                }
                serde_json::Value::Array(a) => a.iter().for_each(|v| walk(v, refs)),
                _ => {}
            }
        }
        walk(&doc, &mut refs);
        assert!(
            refs.len() > 20,
            "the document has references: {}",
            refs.len()
        );
        for r in refs {
            let pointer = r.trim_start_matches('#');
            assert!(doc.pointer(pointer).is_some(), "{r} does not resolve");
        }
    }
}
