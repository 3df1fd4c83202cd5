//! The page's own files (one page, plain JS and CSS) and the OpenAPI document.

use super::{ApiError, Path, Response, StatusCode, header};
use axum::response::IntoResponse;

pub(super) fn asset(content_type: &'static str, body: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            (
                header::CONTENT_SECURITY_POLICY,
                "default-src 'self'; img-src 'self' data:; frame-ancestors 'none'",
            ),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

/// The web UI's page.
pub(super) async fn page() -> Response {
    asset(
        "text/html; charset=utf-8",
        include_str!("../assets/index.html"),
    )
}

/// The web UI's entry module (it routes between the pages).
pub(super) async fn script() -> Response {
    asset(
        "text/javascript; charset=utf-8",
        include_str!("../assets/app.js"),
    )
}

/// The web UI's other modules (`GET /js/{module}`): one per page, and the
/// shared ones; ES modules the browser loads as they are (no build step).
const MODULES: [(&str, &str); 10] = [
    ("core.js", include_str!("../assets/js/core.js")),
    ("i18n.js", include_str!("../assets/js/i18n.js")),
    ("live.js", include_str!("../assets/js/live.js")),
    ("charts.js", include_str!("../assets/js/charts.js")),
    ("new_run.js", include_str!("../assets/js/new_run.js")),
    ("history.js", include_str!("../assets/js/history.js")),
    (
        "control_charts.js",
        include_str!("../assets/js/control_charts.js"),
    ),
    ("fleet.js", include_str!("../assets/js/fleet.js")),
    ("equipment.js", include_str!("../assets/js/equipment.js")),
    ("users.js", include_str!("../assets/js/users.js")),
];

/// `GET /js/{module}`: one of [`MODULES`], else 404.
pub(super) async fn module(Path(name): Path<String>) -> Response {
    match MODULES.iter().find(|(n, _)| *n == name) {
        Some((_, body)) => asset("text/javascript; charset=utf-8", body),
        None => (StatusCode::NOT_FOUND, "no such module").into_response(),
    }
}

/// The web UI's style sheet.
pub(super) async fn style() -> Response {
    asset("text/css; charset=utf-8", include_str!("../assets/app.css"))
}

/// This document (generated from the handlers and their types).
#[utoipa::path(get, path = "/api/openapi.json", tag = "page",
    responses((status = 200, description = "the OpenAPI document", content_type = "application/json", body = Object)))]
pub(super) async fn openapi() -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        super::doc::json(),
    )
        .into_response()
}

/// `GET /cjk.ttf`: the embedded CJK font cut down to the characters of the
/// Chinese catalogue, so a browser without a CJK font still shows the UI in
/// Chinese (made once, a few tens of kB).
pub(super) async fn font() -> Response {
    static FONT: std::sync::OnceLock<Option<Vec<u8>>> = std::sync::OnceLock::new();
    let font = FONT.get_or_init(|| {
        let words = spinbench_report::lang::catalogue(spinbench_report::Lang::ZhCn, "");
        let text: String = words.values().map(String::as_str).collect();
        spinbench_report::web_font(&text).ok()
    });
    match font {
        Some(bytes) => (
            [
                (header::CONTENT_TYPE, "font/ttf"),
                (header::CACHE_CONTROL, "max-age=86400"),
            ],
            bytes.clone(),
        )
            .into_response(),
        None => ApiError::internal("the embedded font could not be cut down").into_response(),
    }
}
