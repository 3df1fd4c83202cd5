//! The HTTP API of `spinbench serve --simulate`, every endpoint, including
//! its refusals: not logged in, wrong role, missing CSRF token, bad input,
//! a run already active; and a whole run driven through the API as a line's
//! MES would: start, answer the prompts, pause, resume, results, reports,
//! the live event stream with catch-up, the audit log. Each on SQLite and
//! on PostgreSQL (`postgres_…`).

#[path = "common/web.rs"]
mod web;

use serde_json::{Value, json};
use spinbench_station::web::api::api_routes;
use std::io::{BufRead, BufReader};
use web::{Backend, Client, add_user, serve};

/// A short test plan (±6 g, both mountings).
fn plan() -> String {
    web::short_plan("api test", &["API-1", "API-2"])
}

fn concrete(path: &str) -> String {
    path.replace("{name}", "short")
        .replace("{id}", "no-such-run")
        .replace("{format}", "pdf")
        .replace("{serial}", "API-1")
        .replace("{role}", "centrifuge")
        .replace("{language}", "zh-CN")
}

#[test]
fn the_openapi_document_lists_every_route_and_every_route_refuses_strangers() {
    the_openapi_document_lists_every_route_and_every_route_refuses_strangers_on(Backend::Sqlite);
}

#[test]
fn postgres_the_openapi_document_lists_every_route_and_every_route_refuses_strangers() {
    the_openapi_document_lists_every_route_and_every_route_refuses_strangers_on(Backend::Postgres);
}

fn the_openapi_document_lists_every_route_and_every_route_refuses_strangers_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    let server = serve(dir.path(), "0");
    let mut anon = Client::new(&server);
    let doc = anon.get_json("/api/openapi.json", 200);
    assert_eq!(doc["openapi"], "3.1.0");
    // The security schemes: the session cookie and the CSRF header.
    let schemes = &doc["components"]["securitySchemes"];
    assert_eq!(schemes["session"]["in"], "cookie");
    assert_eq!(schemes["session"]["name"], "spinbench_session");
    assert_eq!(schemes["csrf"]["in"], "header");
    assert_eq!(schemes["csrf"]["name"], "X-CSRF-Token");
    let public = ["/api/openapi.json", "/api/login", "/api/i18n/{language}"];
    for (path, ops) in doc["paths"].as_object().expect("paths") {
        for (method, op) in ops.as_object().expect("operations") {
            let api = path.starts_with("/api/") && !public.contains(&path.as_str());
            let security = op["security"].as_array().cloned().unwrap_or_default();
            if api {
                // A session, and for a change the CSRF token too.
                assert!(
                    security.iter().any(|s| s.get("session").is_some()),
                    "{method} {path}"
                );
                let changes = method != "get";
                assert_eq!(
                    security.iter().any(|s| s.get("csrf").is_some()),
                    changes,
                    "{method} {path}"
                );
                assert_eq!(
                    op["responses"]["401"]["content"]["application/json"]["schema"]["$ref"],
                    "#/components/schemas/ErrorBody",
                    "{method} {path}: its 401 body"
                );
            }
            // Every body states its limit; every JSON answer has a schema.
            if let Some(body) = op.get("requestBody") {
                assert!(
                    body["description"]
                        .as_str()
                        .is_some_and(|d| d.contains("At most")),
                    "{method} {path}: the body's limit"
                );
            }
            for (status, answer) in op["responses"].as_object().expect("responses") {
                if let Some(json) = answer["content"].get("application/json") {
                    assert!(json.get("schema").is_some(), "{method} {path} {status}");
                }
            }
        }
    }
    // Arrays are arrays (an MES's generated client gets the right types).
    assert_eq!(
        doc["paths"]["/api/runs"]["get"]["responses"]["200"]["content"]["application/json"]["schema"]
            ["type"],
        "array"
    );
    // The runs' list and a new run link to every
    // operation that takes a run id, each link to an operation that exists.
    let mut taking_id: Vec<String> = Vec::new();
    for (path, ops) in doc["paths"].as_object().expect("paths") {
        if path.starts_with("/api/runs/{id}") {
            for op in ops.as_object().expect("operations").values() {
                taking_id.push(op["operationId"].as_str().expect("operationId").to_string());
            }
        }
    }
    assert!(taking_id.len() >= 5, "{taking_id:?}");
    for (method, status, expression) in [
        ("get", "200", "$response.body#/0/id"),
        ("post", "201", "$response.body#/run_id"),
    ] {
        let links = doc["paths"]["/api/runs"][method]["responses"][status]["links"]
            .as_object()
            .unwrap_or_else(|| panic!("no links from {method} /api/runs"));
        let mut linked: Vec<String> = links
            .values()
            .map(|l| {
                assert_eq!(l["parameters"]["id"], expression, "{l}");
                l["operationId"].as_str().expect("operationId").to_string()
            })
            .collect();
        linked.sort();
        taking_id.sort();
        assert_eq!(linked, taking_id, "{method} /api/runs");
    }
    let mut documented: Vec<(String, String)> = Vec::new();
    for (path, ops) in doc["paths"].as_object().expect("paths") {
        for method in ops.as_object().expect("operations").keys() {
            documented.push((method.clone(), path.clone()));
        }
    }
    let mut routed: Vec<(String, String)> = api_routes()
        .iter()
        .map(|(m, p)| (m.to_string(), p.to_string()))
        .collect();
    documented.sort();
    routed.sort();
    assert_eq!(
        documented, routed,
        "the OpenAPI document and the router differ"
    );

    for (method, path) in api_routes() {
        let public = ["/api/openapi.json", "/api/login", "/api/i18n/{language}"].contains(&path);
        if public {
            continue;
        }
        let r = anon.send(&method.to_uppercase(), &concrete(path), Some("{}"));
        assert_eq!(
            r.status,
            401,
            "{method} {path} without a session: {:?}",
            r.json()
        );
        assert!(
            r.json()["error"]
                .as_str()
                .is_some_and(|e| e.contains("login")),
            "{method} {path}: the error says what to do"
        );
    }
    // Login: bad bodies and bad credentials.
    assert_eq!(
        anon.send("POST", "/api/login", Some("not json")).status,
        400
    );
    let r = anon.send(
        "POST",
        "/api/login",
        Some(&json!({"user": "nobody", "password": "whatever1"}).to_string()),
    );
    assert_eq!(r.status, 401);
    // The page and its files are served with a content security policy.
    let page = anon.send("GET", "/", None);
    assert_eq!(page.status, 200);
    assert!(String::from_utf8_lossy(&page.body).contains("<canvas id=\"curves\""));
    assert_eq!(anon.send("GET", "/app.js", None).status, 200);
    // The page's ES modules: each served as JavaScript; no other file.
    let module = anon.send("GET", "/js/core.js", None);
    assert_eq!(module.status, 200);
    assert!(
        module.content_type.starts_with("text/javascript"),
        "{}",
        module.content_type
    );
    assert_eq!(anon.send("GET", "/js/secret.js", None).status, 404);
    // The web UI's words, open to everyone (the login page needs them).
    let words = anon.get_json("/api/i18n/zh-CN", 200);
    assert_eq!(words["words"]["web.nav.history"], "历史");
    assert_eq!(anon.send("GET", "/api/i18n/de", None).status, 404);
}

#[test]
fn roles_csrf_users_plans_and_the_audit_log() {
    roles_csrf_users_plans_and_the_audit_log_on(Backend::Sqlite);
}

#[test]
fn postgres_roles_csrf_users_plans_and_the_audit_log() {
    roles_csrf_users_plans_and_the_audit_log_on(Backend::Postgres);
}

fn roles_csrf_users_plans_and_the_audit_log_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "admin", "admin", "admin-password");
    let server = serve(dir.path(), "0");
    let mut admin = Client::login(&server, "admin", "admin-password");

    // The session cookie is HttpOnly and SameSite=Strict.
    let mut probe = Client::new(&server);
    let r = probe.send(
        "POST",
        "/api/login",
        Some(&json!({"user": "admin", "password": "admin-password"}).to_string()),
    );
    let cookie = r.set_cookie.expect("cookie");
    assert!(
        cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"),
        "{cookie}"
    );
    // Wrong password.
    let r = probe.send(
        "POST",
        "/api/login",
        Some(&json!({"user": "admin", "password": "wrong-password"}).to_string()),
    );
    assert_eq!(r.status, 401);

    // A state change without the CSRF token is refused.
    let body = json!({"name": "op", "role": "operator", "password": "op-password"}).to_string();
    assert_eq!(
        admin
            .send_with("POST", "/api/users", Some(&body), false)
            .status,
        403
    );
    assert_eq!(admin.send("POST", "/api/users", Some(&body)).status, 201);
    assert_eq!(
        admin.send("POST", "/api/users", Some(&body)).status,
        409,
        "taken"
    );
    let bad_role = json!({"name": "x", "role": "boss", "password": "long-enough"}).to_string();
    assert_eq!(
        admin.send("POST", "/api/users", Some(&bad_role)).status,
        400
    );
    let short = json!({"name": "x", "role": "operator", "password": "short"}).to_string();
    assert_eq!(admin.send("POST", "/api/users", Some(&short)).status, 400);
    let bad_name =
        json!({"name": "a b", "role": "operator", "password": "long-enough"}).to_string();
    assert_eq!(
        admin.send("POST", "/api/users", Some(&bad_name)).status,
        400
    );
    let eng = json!({"name": "eng", "role": "engineer", "password": "eng-password"}).to_string();
    assert_eq!(admin.send("POST", "/api/users", Some(&eng)).status, 201);
    let users = admin.get_json("/api/users", 200);
    assert_eq!(users.as_array().map(Vec::len), Some(3));
    assert!(
        !users.to_string().contains("argon2"),
        "password hashes never leave the server"
    );

    let mut op = Client::login(&server, "op", "op-password");
    let mut engineer = Client::login(&server, "eng", "eng-password");
    assert_eq!(op.get_json("/api/session", 200)["role"], "operator");
    // Wrong role.
    assert_eq!(op.send("GET", "/api/users", None).status, 403);
    assert_eq!(op.send("GET", "/api/audit", None).status, 403);
    assert_eq!(op.send("DELETE", "/api/users/eng", None).status, 403);
    assert_eq!(op.send("PUT", "/api/plans/mine", Some(&plan())).status, 403);
    assert_eq!(engineer.send("GET", "/api/users", None).status, 403);
    // Plans: an engineer saves them, checked first.
    assert_eq!(
        engineer.send("PUT", "/api/plans/api", Some(&plan())).status,
        200
    );
    let r = engineer.send("PUT", "/api/plans/api", Some("range_g = 'x'"));
    assert_eq!(r.status, 400, "{:?}", r.json());
    let r = engineer.send("PUT", "/api/plans/bad", Some("[serials]\n99 = \"X\"\n"));
    assert_eq!(r.status, 400);
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("serials.99"))
    );
    assert_eq!(
        engineer
            .send("PUT", "/api/plans/..%2Fx", Some(&plan()))
            .status,
        400
    );
    // A plan sent as a JSON object of its keys (a generated client's way)
    // is kept as TOML; JSON that is not an object, or null, is refused.
    let as_json = serde_json::json!({
        "name": "from json", "range_g": 6, "levels": [0, 1, 2, 3, 4, 6],
        "passes": ["P", "N"], "warmup_s": 0, "dwell": {"seconds": 3},
        "stability": {"hold_s": 3}, "serials": {"1": "J-1"}
    });
    let r = engineer.send("PUT", "/api/plans/json", Some(&as_json.to_string()));
    assert_eq!(r.status, 200, "{:?}", r.json());
    let kept = std::fs::read_to_string(dir.path().join("plans").join("json.toml")).expect("kept");
    assert!(
        spinbench_engine::TestPlan::from_toml(&kept).is_ok_and(|p| p.name == "from json"),
        "{kept}"
    );
    assert_eq!(
        engineer
            .send("PUT", "/api/plans/json", Some("{\"range_g\": null}"))
            .status,
        400
    );
    assert_eq!(
        engineer
            .send("PUT", "/api/plans/json", Some("{\"levels\": [0, 1]"))
            .status,
        400
    );
    let plans = op.get_json("/api/plans", 200);
    assert!(
        plans["plans"]
            .as_array()
            .is_some_and(|p| p.iter().any(|p| p["name"] == "api"))
    );
    let station = op.get_json("/api/station", 200);
    assert!(station["slots"].as_u64() >= Some(6));
    // The station config: an engineer's edit is checked; the virtual bench's is its own.
    let toml = station["toml"].as_str().expect("toml").to_string();
    assert_eq!(op.send("PUT", "/api/station", Some(&toml)).status, 403);
    let r = engineer.send("PUT", "/api/station", Some("[arm]\nradius_m = -1\n"));
    assert_eq!(r.status, 400, "{:?}", r.json());
    let r = engineer.send("PUT", "/api/station", Some(&toml));
    assert_eq!(r.status, 409, "{:?}", r.json());

    // Removing users.
    assert_eq!(
        admin.send("DELETE", "/api/users/admin", None).status,
        409,
        "not yourself"
    );
    assert_eq!(admin.send("DELETE", "/api/users/ghost", None).status, 404);
    assert_eq!(admin.send("DELETE", "/api/users/eng", None).status, 204);
    assert_eq!(
        engineer.send("GET", "/api/session", None).status,
        401,
        "a removed user's session ends"
    );
    // Log out.
    assert_eq!(op.send("POST", "/api/logout", None).status, 204);
    assert_eq!(op.send("GET", "/api/status", None).status, 401);

    // Every action is in the audit log with who did it.
    let log = admin.get_json("/api/audit", 200);
    let entries: Vec<(String, String)> = log
        .as_array()
        .expect("entries")
        .iter()
        .map(|e| {
            (
                e["who"].as_str().unwrap_or("").to_string(),
                e["action"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect();
    for want in [
        ("admin", "login"),
        ("admin", "login refused"),
        ("admin", "add user"),
        ("eng", "save plan"),
        ("admin", "remove user"),
        ("op", "logout"),
        ("spinbench (command line)", "add user"),
    ] {
        assert!(
            entries.contains(&(want.0.to_string(), want.1.to_string())),
            "{want:?} in {entries:?}"
        );
    }
}

#[test]
fn a_run_through_the_api_from_start_to_report() {
    a_run_through_the_api_from_start_to_report_on(Backend::Sqlite);
}

#[test]
fn postgres_a_run_through_the_api_from_start_to_report() {
    a_run_through_the_api_from_start_to_report_on(Backend::Postgres);
}

#[test]
fn pgbouncer_a_run_through_the_api_from_start_to_report() {
    // Transaction pooling over one server connection: every client of the
    // server (its requests, the heartbeat, the run's outbox) shares it.
    a_run_through_the_api_from_start_to_report_on(Backend::PgBouncer);
}

fn a_run_through_the_api_from_start_to_report_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "admin", "admin", "admin-password");
    add_user(dir.path(), "op", "operator", "op-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(dir.path().join("plans").join("api.toml"), plan()).expect("plan");
    let server = serve(dir.path(), "0");
    let mut op = Client::login(&server, "op", "op-password");

    // Nothing to steer yet.
    for path in [
        "/api/run/prompt",
        "/api/run/pause",
        "/api/run/resume",
        "/api/run/abort",
    ] {
        let r = op.send("POST", path, Some(r#"{"proceed": true}"#));
        assert_eq!(r.status, 409, "{path}: {:?}", r.json());
    }
    // Bad input.
    let start = |plan: &str, serials: Value| json!({"plan": plan, "serials": serials}).to_string();
    let r = op.send("POST", "/api/runs", Some(&start("nope", json!({}))));
    assert_eq!(r.status, 404, "an unknown plan: {:?}", r.json());
    let r = op.send(
        "POST",
        "/api/runs",
        Some(&start("api", json!({"1": "X:API-1"}))),
    );
    assert_eq!(r.status, 400);
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("mounting prefix"))
    );
    let r = op.send(
        "POST",
        "/api/runs",
        Some(&start("api", json!({"99": "API-9"}))),
    );
    assert_eq!(r.status, 400);
    assert_eq!(op.send("POST", "/api/runs", Some("{")).status, 400);

    // The planner: a design for a target, nothing moved.
    let design = |op: &mut Client, plan: &str, target: f64| {
        op.send(
            "POST",
            &format!("/api/plans/{plan}/design"),
            Some(&json!({"target_k2_u95_ug_per_g2": target}).to_string()),
        )
    };
    let r = design(&mut op, "api", 1000.0);
    assert_eq!(r.status, 200, "{:?}", r.json());
    let d = r.json();
    assert!(
        d["levels_g"].as_array().is_some_and(|l| l.len() >= 6),
        "{d}"
    );
    assert!(
        d["k2_u95_ug_per_g2"].as_f64().is_some_and(|u| u <= 1000.0),
        "{d}"
    );
    assert!(
        d["model_source"]
            .as_str()
            .is_some_and(|s| s.contains("no history")),
        "{d}"
    );
    let r = design(&mut op, "api", 1e-4);
    assert_eq!(r.status, 400);
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("cannot be reached")),
        "{:?}",
        r.json()
    );
    assert_eq!(design(&mut op, "nope", 1.0).status, 404);
    assert_eq!(design(&mut op, "api", -1.0).status, 400);
    // The form's serials size the run the range is for; a bad slot is
    // refused as a start refuses it.
    let with_serials = |op: &mut Client, serials: Value| {
        op.send(
            "POST",
            "/api/plans/api/design",
            Some(&json!({"target_k2_u95_ug_per_g2": 1000.0, "serials": serials}).to_string()),
        )
    };
    let r = with_serials(&mut op, json!({"1": "D-1", "2": "D-2", "3": " "}));
    assert_eq!(r.status, 200, "{:?}", r.json());
    assert_eq!(r.json()["instruments"], json!(2), "{:?}", r.json());
    assert_eq!(with_serials(&mut op, json!({"99": "D-99"})).status, 400);
    let r = op.send(
        "POST",
        "/api/runs",
        Some(&json!({"plan": "api", "serials": {}, "target_k2_u95_ug_per_g2": 1e-4}).to_string()),
    );
    assert_eq!(
        r.status,
        400,
        "an unreachable target starts nothing: {:?}",
        r.json()
    );
    assert!(op.get_json("/api/status", 200)["active"].is_null());

    // Start; a second start is refused while it runs.
    let r = op.send(
        "POST",
        "/api/runs",
        Some(&start("api", json!({"1": "API-1", "2": "API-2"}))),
    );
    assert_eq!(r.status, 201, "{:?}", r.json());
    let run_id = r.json()["run_id"].as_str().expect("run id").to_string();
    // The started run's own link answers at once.
    let r = op.send("GET", &format!("/api/runs/{run_id}"), None);
    assert_eq!(r.status, 200, "{:?}", r.json());
    let r = op.send("POST", "/api/runs", Some(&start("api", json!({}))));
    assert_eq!(r.status, 409);

    // Answer every prompt; pause and resume once on the way.
    let mut prompts = 0;
    let mut paused = false;
    loop {
        let s = op.wait_status(120, |s| {
            s["prompt"].is_string() || s["active"].is_null() && s["run_id"] == run_id.as_str()
        });
        // What is sent matches the document, at a prompt too.
        web::matches_document(&mut op, "StatusReply", &s, "GET /api/status");
        if s["active"].is_null() {
            break;
        }
        if !paused {
            assert_eq!(op.send("POST", "/api/run/pause", None).status, 200);
            assert_eq!(op.send("POST", "/api/run/resume", None).status, 200);
            paused = true;
        }
        let r = op.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
        assert_eq!(r.status, 200, "{:?}", r.json());
        prompts += 1;
        // And at a step, settling or averaging.
        let s = op.wait_status(60, |s| {
            s["progress"].is_object() || s["prompt"].is_string() || s["active"].is_null()
        });
        web::matches_document(&mut op, "StatusReply", &s, "GET /api/status at a step");
        assert!(prompts < 10, "too many prompts");
    }
    assert!(prompts >= 3, "tumble up, tumble down, remount: {prompts}");
    let end = op.get_json("/api/status", 200);
    // Every JSON answer so far was held to the document (common/web.rs).
    assert!(
        web::CHECKED.load(std::sync::atomic::Ordering::Relaxed) > 20,
        "answers checked against the document: {}",
        web::CHECKED.load(std::sync::atomic::Ordering::Relaxed)
    );
    web::matches_document(&mut op, "StatusReply", &end, "GET /api/status at the end");
    // The check can fail: the step as the tuple it once was sent as.
    let mut tuple = end.clone();
    tuple["step"] = json!([3, 21, "10 g Up"]);
    assert!(!web::document_errors(&mut op, "StatusReply", &tuple).is_empty());
    let s = op.get_json("/api/status", 200);
    assert_eq!(s["state"], "completed", "{s}");
    // The plan's prediction beside what the run achieved.
    assert!(s["prediction"]["k2_u95_ug_per_g2"].is_number(), "{s}");
    assert!(
        s["achieved"]["centrifuge_time_s"]
            .as_f64()
            .is_some_and(|t| t > 0.0),
        "{s}"
    );
    assert_eq!(
        op.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#))
            .status,
        409
    );

    // Results and reports.
    let run = op.get_json(&format!("/api/runs/{run_id}"), 200);
    assert_eq!(run["state"], "completed");
    // Two instruments cannot tell the table from an instrument: the
    // station page says nothing is learned yet, and why.
    let signature = op.get_json("/api/station/signature", 200);
    assert_eq!(signature["runs"], 0, "{signature}");
    assert!(
        signature["text"]
            .as_str()
            .is_some_and(|t| t.contains("at least four instruments")),
        "{signature}"
    );
    assert_eq!(
        run["results"].as_array().map(Vec::len),
        Some(4),
        "2 instruments × 2 mountings"
    );
    assert!(run["results"][0]["k2_ug_per_g2"].is_number());
    // Each row says what its verdict judged: the quantity, its value ± U95,
    // the plan's limit and the rule, and its reasons' codes for an MES.
    for row in run["results"].as_array().into_iter().flatten() {
        let judged = &row["judged"];
        assert_eq!(judged["measurand"], "K2", "{row}");
        assert!(judged["limit_ug_per_g2"].is_number(), "{row}");
        assert!(
            ["guarded", "simple"].contains(&judged["rule"].as_str().unwrap_or_default()),
            "{row}"
        );
        assert_eq!(
            judged["value_ug_per_g2"], row["instrument_k2_ug_per_g2"],
            "{row}"
        );
        assert_eq!(judged["U95"], row["instrument_k2_U95"], "{row}");
        assert!(row["reason_codes"].is_array(), "{row}");
    }
    let r = op.send("GET", &format!("/api/runs/{run_id}/report/pdf"), None);
    assert_eq!(r.status, 200);
    assert_eq!(r.content_type, "application/pdf");
    assert!(r.body.starts_with(b"%PDF"));
    let r = op.send("GET", &format!("/api/runs/{run_id}/report/csv"), None);
    assert!(String::from_utf8_lossy(&r.body).contains("API-2"));
    assert_eq!(
        op.send("GET", &format!("/api/runs/{run_id}/report/doc"), None)
            .status,
        400
    );
    assert_eq!(op.send("GET", "/api/runs/no-such-run", None).status, 404);
    assert_eq!(
        op.send("GET", "/api/runs/no-such-run/report/pdf", None)
            .status,
        404
    );
    let runs = op.get_json("/api/runs", 200);
    assert_eq!(runs[0]["id"], run_id.as_str());
    let unit = op.get_json("/api/units/API-1", 200);
    assert_eq!(unit["tests"][0]["run_id"], run_id.as_str());
    let api_1 = run["results"]
        .as_array()
        .and_then(|rows| rows.iter().find(|r| r["serial"] == "API-1"))
        .expect("API-1's results");
    assert_eq!(unit["tests"][0]["judged"], api_1["judged"], "{unit}");
    assert!(unit["tests"][0]["reason_codes"].is_array(), "{unit}");
    assert_eq!(op.send("GET", "/api/units/NOBODY", None).status, 404);

    // The event stream: everything from the start, numbered; a reconnect
    // with Last-Event-ID gets only what came after.
    let (ids, kinds) = read_events(&server.base, op.cookie.as_deref(), None, "run_finished");
    assert!(ids.windows(2).all(|w| w[0] < w[1]), "ids increase");
    for kind in [
        "run_started",
        "prompt",
        "prompt_answered",
        "values",
        "point_done",
        "health",
    ] {
        assert!(kinds.iter().any(|k| k == kind), "{kind} in the stream");
    }
    let middle = ids[ids.len() / 2];
    let (later, _) = read_events(
        &server.base,
        op.cookie.as_deref(),
        Some(middle),
        "run_finished",
    );
    assert!(
        later.first().is_some_and(|&first| first > middle),
        "catch-up starts after {middle}"
    );

    // An engineer leaves a level out of the finished run, with a reason: the
    // record is graded again, the report and the audit log say who and why.
    let mut admin = Client::login(&server, "admin", "admin-password");
    let exclusions = format!("/api/runs/{run_id}/exclusions");
    let ask = |serial: &str, g: f64, reason: &str| {
        json!({"serial": serial, "mount": "P", "g": g, "reason": reason}).to_string()
    };
    let r = op.send("POST", &exclusions, Some(&ask("API-1", 4.0, "knock")));
    assert_eq!(r.status, 403, "an operator may not: {:?}", r.json());
    let r = admin.send(
        "POST",
        &exclusions,
        Some(&ask("API-1", 4.0, "fixture knocked at 4 g")),
    );
    assert_eq!(r.status, 200, "{:?}", r.json());
    let left_out = r.json();
    assert_eq!(left_out["exclusions"][0]["by"], "admin", "{left_out}");
    assert!(
        left_out["exclusions"][0]["points_removed"].as_u64() >= Some(1),
        "{left_out}"
    );
    for (body, status, says) in [
        (ask("API-1", 4.0, "again"), 409, "already left out"),
        (ask("API-1", 5.0, "no such level"), 409, "no reading at 5 g"),
        (ask("API-1", 2.0, "  "), 400, "reason"),
        (ask("API-9", 2.0, "nobody"), 404, "no instrument 'API-9'"),
        (ask("API-1", f64::MAX, "huge"), 400, "levels"),
    ] {
        let r = admin.send("POST", &exclusions, Some(&body));
        assert_eq!(r.status, status, "{body}: {:?}", r.json());
        let error = r.json()["error"].as_str().unwrap_or_default().to_string();
        assert!(error.contains(says), "{body}: {error}");
    }
    let r = admin.send(
        "POST",
        "/api/runs/no-such-run/exclusions",
        Some(&ask("API-1", 2.0, "x")),
    );
    assert_eq!(r.status, 404);
    // Levels left out one by one until the fit could no
    // longer be made: that last exclusion is refused, the record stays
    // graded; an exclusion is withdrawn with a reason (audited).
    let mut refused = None;
    for g in [1.0, 2.0, 3.0, 6.0] {
        let r = admin.send("POST", &exclusions, Some(&ask("API-1", g, "trying")));
        if r.status != 200 {
            refused = Some((g, r.status, r.json()));
            break;
        }
        assert_ne!(r.json()["outcome"], "incomplete", "{:?}", r.json());
    }
    let (g, status, body) = refused.expect("an exclusion leaving too few levels is refused");
    assert_eq!(status, 409, "{g} g: {body}");
    assert!(
        body["error"]
            .as_str()
            .is_some_and(|e| e.contains("too few levels")),
        "{body}"
    );
    let withdraw = format!("/api/runs/{run_id}/exclusions/withdraw");
    let r = op.send("POST", &withdraw, Some(&ask("API-1", 1.0, "back")));
    assert_eq!(r.status, 403, "an operator may not: {:?}", r.json());
    let r = admin.send(
        "POST",
        &withdraw,
        Some(&ask("API-1", 1.0, "1 g was fine after all")),
    );
    assert_eq!(r.status, 200, "{:?}", r.json());
    let back = r.json();
    assert!(
        back["exclusions"]
            .as_array()
            .is_some_and(|l| l.iter().all(|e| e["g"] != 1.0) && l.iter().any(|e| e["g"] == 4.0)),
        "{back}"
    );
    let r = admin.send("POST", &withdraw, Some(&ask("API-1", 1.0, "twice")));
    assert_eq!(r.status, 409, "{:?}", r.json());
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("is not left out")),
        "{:?}",
        r.json()
    );
    let html = admin.send("GET", &format!("/api/runs/{run_id}/report/html"), None);
    assert!(
        String::from_utf8_lossy(&html.body).contains("fixture knocked at 4 g"),
        "the report names the exclusion and its reason"
    );
    assert!(
        String::from_utf8_lossy(&html.body).contains("°C over the points"),
        "the report gives each instrument's temperatures"
    );

    // The audit log has the operator's and the engineer's actions.
    let log = admin.get_json("/api/audit", 200).to_string();
    for action in [
        "start run",
        "answer prompt: done",
        "pause",
        "resume",
        "exclude level",
        "withdraw exclusion",
    ] {
        assert!(log.contains(action), "{action} in the audit log");
    }
    assert!(
        log.contains("fixture knocked at 4 g") && log.contains("k2_max"),
        "{log}"
    );

    // Control charts across the runs (one so far): the product's charts and
    // each fixture position's radius, with the yields; a bad baseline refused.
    let charts = op.get_json("/api/control-charts?baseline_runs=5", 200);
    assert_eq!(charts["baseline_runs"], 5);
    let quantities: Vec<&str> = charts["charts"]
        .as_array()
        .expect("charts")
        .iter()
        .filter_map(|c| c["quantity"].as_str())
        .collect();
    assert!(quantities.contains(&"k2_max"), "{quantities:?}");
    assert!(
        quantities.iter().any(|q| q.starts_with("radius slot 1")),
        "{quantities:?}"
    );
    assert!(
        charts["charts"][0]["svg"]
            .as_str()
            .is_some_and(|s| s.contains("<svg"))
    );
    assert_eq!(charts["yield_by_run"][0]["first_tests"], 2);
    let r = op.send("GET", "/api/control-charts?baseline_runs=0", None);
    assert_eq!(r.status, 400);

    // Retest: the run's instruments to retest, in one action.
    let shown = op.get_json(&format!("/api/runs/{run_id}"), 200);
    let to_retest: Vec<String> = shown["to_retest"]
        .as_array()
        .expect("to_retest")
        .iter()
        .filter_map(|s| s.as_str().map(String::from))
        .collect();
    let retest = format!("/api/runs/{run_id}/retest");
    assert_eq!(
        op.send("POST", "/api/runs/no-such-run/retest", None).status,
        404
    );
    // What the retest would take, before it starts: the same serials, and
    // for each inconclusive one what would decide it.
    let offered = op.send("GET", &retest, None);
    if to_retest.is_empty() {
        assert_eq!(offered.status, 409);
    } else {
        assert_eq!(offered.status, 200);
        let offer: Value = serde_json::from_slice(&offered.body).expect("json");
        assert_eq!(offer["serials"], json!(to_retest), "{offer}");
        for a in offer["advice"].as_array().into_iter().flatten() {
            assert!(
                a["deciding_u95_ug_per_g2"].is_number() && a["text"].is_string(),
                "{a}"
            );
        }
    }
    assert_eq!(
        op.send("GET", "/api/runs/no-such-run/retest", None).status,
        404
    );
    let r = op.send("POST", &retest, None);
    if to_retest.is_empty() {
        assert_eq!(r.status, 409, "{:?}", r.json());
        assert!(
            r.json()["error"]
                .as_str()
                .is_some_and(|e| e.contains("nothing to retest"))
        );
    } else {
        assert_eq!(r.status, 201, "{:?}", r.json());
        let started = r.json();
        assert_eq!(started["retest_of"], run_id.as_str());
        assert_eq!(started["serials"], json!(to_retest));
        let new_id = started["run_id"].as_str().expect("id").to_string();
        op.wait_status(60, |s| s["prompt"].is_string() || s["active"].is_null());
        assert_eq!(op.send("POST", "/api/run/abort", None).status, 200);
        op.wait_status(60, |s| s["active"].is_null());
        let linked = op.get_json(&format!("/api/runs/{run_id}"), 200);
        assert_eq!(linked["retested_by"], json!([new_id]));
        let runs = op.get_json("/api/runs", 200);
        assert!(
            runs.as_array()
                .expect("runs")
                .iter()
                .any(|r| r["id"] == new_id.as_str() && r["retest_of"] == run_id.as_str()),
            "{runs}"
        );
    }
}

#[test]
fn an_abort_from_the_api_ends_the_run_safely() {
    an_abort_from_the_api_ends_the_run_safely_on(Backend::Sqlite);
}

#[test]
fn postgres_an_abort_from_the_api_ends_the_run_safely() {
    an_abort_from_the_api_ends_the_run_safely_on(Backend::Postgres);
}

fn an_abort_from_the_api_ends_the_run_safely_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "op", "operator", "op-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(dir.path().join("plans").join("api.toml"), plan()).expect("plan");
    let server = serve(dir.path(), "0");
    let mut op = Client::login(&server, "op", "op-password");
    let r = op.send("POST", "/api/runs", Some(r#"{"plan": "api"}"#));
    assert_eq!(r.status, 201, "{:?}", r.json());
    op.wait_status(60, |s| {
        s["prompt"].is_string() && s["rate_deg_s"].is_number()
    });
    assert_eq!(op.send("POST", "/api/run/abort", None).status, 200);
    let s = op.wait_status(60, |s| s["active"].is_null());
    assert_eq!(s["state"], "aborted", "{s}");
    // Nothing is read once the run has ended: no last reading is shown as
    // if the table were still spinning or the rails still on.
    assert!(
        s["rate_deg_s"].is_null()
            && s["g_at_r0"].is_null()
            && s["on_speed"].is_null()
            && s["interlocks_closed"].is_null()
            && s["supply"].as_array().is_some_and(Vec::is_empty),
        "{s}"
    );
    // The record names who aborted, not "abort".
    let run_id = s["run_id"].as_str().expect("run id").to_string();
    let run = op.get_json(&format!("/api/runs/{run_id}"), 200);
    let reason = run["reason"].as_str().unwrap_or_default();
    assert!(reason.contains("user op"), "{run}");
}

/// Read the event stream until an event of kind `until`; (ids, kinds).
fn read_events(
    base: &str,
    cookie: Option<&str>,
    last: Option<u64>,
    until: &str,
) -> (Vec<u64>, Vec<String>) {
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into();
    let mut request = agent.get(format!("{base}/api/events"));
    if let Some(c) = cookie {
        request = request.header("Cookie", c);
    }
    if let Some(id) = last {
        request = request.header("Last-Event-ID", id.to_string());
    }
    let response = request.call().expect("events");
    assert_eq!(response.status().as_u16(), 200);
    let reader = BufReader::new(response.into_body().into_reader());
    let (mut ids, mut kinds) = (Vec::new(), Vec::new());
    for line in reader.lines() {
        let line = line.expect("a line");
        if let Some(id) = line
            .strip_prefix("id: ")
            .or_else(|| line.strip_prefix("id:"))
        {
            ids.push(id.trim().parse().expect("numeric id"));
        } else if let Some(kind) = line
            .strip_prefix("event: ")
            .or_else(|| line.strip_prefix("event:"))
        {
            kinds.push(kind.trim().to_string());
            if kind.trim() == until {
                break;
            }
        }
    }
    (ids, kinds)
}

#[test]
fn the_equipment_register_blocks_an_overdue_device_until_an_admin_overrides() {
    the_equipment_register_blocks_an_overdue_device_until_an_admin_overrides_on(Backend::Sqlite);
}

#[test]
fn postgres_the_equipment_register_blocks_an_overdue_device_until_an_admin_overrides() {
    the_equipment_register_blocks_an_overdue_device_until_an_admin_overrides_on(Backend::Postgres);
}

fn the_equipment_register_blocks_an_overdue_device_until_an_admin_overrides_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "admin", "admin", "admin-password");
    add_user(dir.path(), "eng", "engineer", "eng-password");
    add_user(dir.path(), "op", "operator", "op-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(dir.path().join("plans").join("api.toml"), plan()).expect("plan");
    let server = serve(dir.path(), "0");
    let mut op = Client::login(&server, "op", "op-password");
    let mut eng = Client::login(&server, "eng", "eng-password");
    let mut admin = Client::login(&server, "admin", "admin-password");

    // The station's devices, none registered yet.
    let list = op.get_json("/api/equipment", 200);
    let roles: Vec<&str> = list
        .as_array()
        .expect("devices")
        .iter()
        .filter_map(|d| d["role"].as_str())
        .collect();
    assert!(roles.starts_with(&["centrifuge", "fmu 1"]), "{roles:?}");
    assert!(
        list.as_array()
            .expect("devices")
            .iter()
            .all(|d| d["status"] == "not in the register" && d["read_identity"].is_null())
    );

    let entry = |cal: &str, due: &str| {
        json!({"identity": "Acutrol 3000 SN 117", "certificate": "NIM-2026-0042",
               "calibrated_on": cal, "due_on": due})
        .to_string()
    };
    // Kept by engineers, with what is wrong named.
    let path = "/api/equipment/centrifuge";
    assert_eq!(
        op.send("PUT", path, Some(&entry("2025-01-01", "2026-01-01")))
            .status,
        403
    );
    for (body, says) in [
        (entry("2025-01-01", "2026-02-30"), "due_on"),
        (entry("2025-13-01", "2026-01-01"), "calibrated_on"),
        (entry("2026-01-01", "2025-01-01"), "not after"),
    ] {
        let r = eng.send("PUT", path, Some(&body));
        assert_eq!(r.status, 400, "{body}");
        assert!(
            r.json()["error"].as_str().is_some_and(|e| e.contains(says)),
            "{:?}",
            r.json()
        );
    }
    assert_eq!(
        eng.send(
            "PUT",
            "/api/equipment/toaster",
            Some(&entry("2025-01-01", "2026-01-01"))
        )
        .status,
        404
    );
    // Overdue since 2026-01-01.
    let r = eng.send("PUT", path, Some(&entry("2025-01-01", "2026-01-01")));
    assert_eq!(r.status, 200, "{:?}", r.json());
    let list = op.get_json("/api/equipment", 200);
    assert_eq!(list[0]["status"], "overdue");
    assert_eq!(list[0]["updated_by"], "eng");

    // A run does not start; an operator's override is refused; an admin's is recorded.
    let start = |over: Option<&str>| {
        let mut body = json!({"plan": "api", "serials": {"1": "EQ-1"}});
        if let Some(reason) = over {
            body["override_overdue"] = json!(reason);
        }
        body.to_string()
    };
    let r = op.send("POST", "/api/runs", Some(&start(None)));
    assert_eq!(r.status, 409);
    assert!(
        r.json()["error"]
            .as_str()
            .is_some_and(|e| e.contains("centrifuge (due 2026-01-01, overdue)")),
        "{:?}",
        r.json()
    );
    assert_eq!(
        op.send("POST", "/api/runs", Some(&start(Some("line stop"))))
            .status,
        403
    );
    let r = admin.send(
        "POST",
        "/api/runs",
        Some(&start(Some("recalibration booked for Monday"))),
    );
    assert_eq!(r.status, 201, "{:?}", r.json());
    let run_id = r.json()["run_id"].as_str().expect("id").to_string();
    let log = admin.get_json("/api/audit", 200).to_string();
    assert!(
        log.contains("override overdue calibration") && log.contains("recalibration booked"),
        "{log}"
    );
    assert!(
        log.contains("set equipment") && log.contains("NIM-2026-0042"),
        "{log}"
    );
    // The run's report lists the equipment with its calibration as it stood.
    admin.wait_status(60, |s| s["prompt"].is_string());
    assert_eq!(admin.send("POST", "/api/run/abort", None).status, 200);
    admin.wait_status(60, |s| s["active"].is_null());
    // After its first run the station offers each device
    // the identity it read from it (the virtual bench's *IDN? answers).
    let list = op.get_json("/api/equipment", 200);
    let fmu = list
        .as_array()
        .expect("devices")
        .iter()
        .find(|d| d["role"] == "fmu 1")
        .expect("fmu 1");
    assert_eq!(fmu["status"], "not in the register");
    assert!(
        fmu["read_identity"].as_str().is_some_and(|i| !i.is_empty()),
        "{fmu}"
    );
    let html = admin.send("GET", &format!("/api/runs/{run_id}/report/html"), None);
    let html = String::from_utf8_lossy(&html.body);
    assert!(
        html.contains("certificate NIM-2026-0042, due 2026-01-01 (overdue)")
            && html.contains("not in the register"),
        "the report's equipment table"
    );
    // Calibrated again: runs start without an override.
    let r = eng.send("PUT", path, Some(&entry("2026-11-01", "2027-11-01")));
    assert_eq!(r.status, 200);
    let r = op.send("POST", "/api/runs", Some(&start(None)));
    assert_eq!(r.status, 201, "{:?}", r.json());
    op.wait_status(60, |s| s["prompt"].is_string());
    assert_eq!(op.send("POST", "/api/run/abort", None).status, 200);
    op.wait_status(60, |s| s["active"].is_null());
}

#[test]
fn a_session_survives_a_restart_and_a_removed_users_does_not() {
    let dir = tempfile::tempdir().expect("tempdir");
    add_user(dir.path(), "admin", "admin", "admin-password");
    add_user(dir.path(), "op", "operator", "op-password");
    let server = serve(dir.path(), "0");
    let mut op = Client::login(&server, "op", "op-password");
    let mut admin = Client::login(&server, "admin", "admin-password");
    let before = op.get_json("/api/session", 200);
    // The server stops (a restart mid-shift) and comes back on the same store.
    drop(server);
    let server = serve(dir.path(), "0");
    op.moved_to(&server);
    admin.moved_to(&server);
    let after = op.get_json("/api/session", 200);
    assert_eq!(after["user"], "op");
    assert_eq!(after["csrf"], before["csrf"], "the same session");
    // A state change with its CSRF token still works.
    let r = op.send(
        "PUT",
        "/api/session/language",
        Some(r#"{"language": "zh-CN"}"#),
    );
    assert_eq!(r.status, 200, "{:?}", r.json());
    // The store keeps hashes, never the token.
    let token = op.cookie.clone().unwrap_or_default();
    let token = token.split('=').nth(1).unwrap_or_default().to_string();
    let db = std::fs::read(dir.path().join("spinbench.db")).unwrap_or_default();
    assert!(
        !String::from_utf8_lossy(&db).contains(&token) && !token.is_empty(),
        "the token is not in the store"
    );
    // The user is removed: their session ends, also after another restart.
    assert_eq!(admin.send("DELETE", "/api/users/op", None).status, 204);
    assert_eq!(op.send("GET", "/api/session", None).status, 401);
    drop(server);
    let server = serve(dir.path(), "0");
    op.moved_to(&server);
    admin.moved_to(&server);
    assert_eq!(op.send("GET", "/api/session", None).status, 401);
    // Logout ends a session for good.
    assert_eq!(admin.send("POST", "/api/logout", None).status, 204);
    assert_eq!(admin.send("GET", "/api/session", None).status, 401);
}
