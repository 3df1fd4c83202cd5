//! The MES path with a client someone else's generator made:
//! openapi-python-client (in `scripts/test-tools`' `target/venv-mes`)
//! generates a Python client from the document the server serves, and
//! `scripts/mes/mes_path.py` logs in, starts a run, answers every prompt
//! while parsing every `/api/status` with the generated model, reads the
//! run and downloads its PDF — on SQLite and on PostgreSQL, as a person
//! (login, cookie, CSRF token) and as a machine (an API token, nothing else).

#[path = "common/web.rs"]
mod web;

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use web::{Backend, Client, add_user, serve};

/// The generator's Python, or None (said) outside `scripts/test`.
fn python() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/venv-mes/bin/python");
    if p.is_file() {
        return Some(p);
    }
    assert!(
        std::env::var(spinbench_store::testing::POSTGRES_ENV).is_err(),
        "{}: missing; scripts/test-tools makes it",
        p.display()
    );
    eprintln!("skipped: no {} (run ./scripts/test)", p.display());
    None
}

fn scripts() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scripts/mes")
}

/// A PDF's text, by poppler's pdftotext.
fn pdf_text(pdf: &Path) -> String {
    let out = Command::new("pdftotext")
        .args(["-layout"])
        .arg(pdf)
        .arg("-")
        .output()
        .expect("pdftotext (poppler-utils; scripts/test-tools says so)");
    assert!(out.status.success(), "pdftotext {}", pdf.display());
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// How the MES is known to the station.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Auth {
    /// Logged in as the user `mes`.
    Password,
    /// An operator's API token `mes`, made by `spinbench token add`.
    Token,
}

#[test]
fn a_generated_client_completes_the_mes_path() {
    mes_path_on(Backend::Sqlite, Auth::Password);
}

#[test]
fn postgres_a_generated_client_completes_the_mes_path() {
    mes_path_on(Backend::Postgres, Auth::Password);
}

#[test]
fn a_generated_client_completes_the_mes_path_with_an_api_token() {
    mes_path_on(Backend::Sqlite, Auth::Token);
}

#[test]
fn postgres_a_generated_client_completes_the_mes_path_with_an_api_token() {
    mes_path_on(Backend::Postgres, Auth::Token);
}

/// `spinbench token add mes` on the store of `data`: the secret.
fn make_token(data: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["token", "add", "mes", "--role", "operator", "--db"])
        .arg(web::store_of(data))
        .output()
        .expect("spinbench token add");
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    said.lines().last().unwrap_or("").trim().to_string()
}

fn mes_path_on(backend: Backend, auth: Auth) {
    let Some(python) = python() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    let (user, password) = match auth {
        Auth::Password => {
            add_user(dir.path(), "mes", "operator", "mes-password-1");
            ("mes".to_string(), "mes-password-1".to_string())
        }
        Auth::Token => ("token:".to_string(), make_token(dir.path())),
    };
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(
        dir.path().join("plans").join("mes.toml"),
        web::short_plan("mes", &["MES-1"]),
    )
    .expect("plan");
    let server = serve(dir.path(), "0");

    // The client, generated from the document this server serves.
    let document = dir.path().join("openapi.json");
    let mut anonymous = Client::new(&server);
    let served = anonymous.send("GET", "/api/openapi.json", None);
    assert_eq!(served.status, 200);
    std::fs::write(&document, &served.body).expect("the document");
    let generated = dir.path().join("client");
    let generator = python.with_file_name("openapi-python-client");
    let out = Command::new(&generator)
        .args(["generate", "--meta", "none", "--path"])
        .arg(&document)
        .arg("--output-path")
        .arg(generated.join("spinbench_mes"))
        .arg("--config")
        .arg(scripts().join("generator.yaml"))
        .output()
        .expect("openapi-python-client");
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Every operation the MES path takes is generated (the generator skips
    // what it cannot read, and says so).
    for skipped in [
        "/api/runs",
        "/api/status",
        "/api/run/prompt",
        "/api/login",
        "report",
    ] {
        assert!(
            !said.lines().any(|l| l.contains("WARNING")
                && l.contains(skipped)
                && l.contains("will not be generated")),
            "{skipped} was skipped by the generator:\n{said}"
        );
    }

    let pdf = dir.path().join("mes.pdf");
    let out = Command::new(&python)
        .arg(scripts().join("mes_path.py"))
        .arg(&generated)
        .arg(&server.base)
        .args([
            user.as_str(),
            password.as_str(),
            "mes",
            r#"{"1": "MES-1", "2": "MES-2"}"#,
        ])
        .arg(&pdf)
        .output()
        .expect("the MES path");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{backend:?}: {stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: Value = serde_json::from_str(stdout.trim()).expect("one JSON line");
    assert_eq!(summary["state"], "completed", "{summary}");
    assert!(
        summary["prompts"].as_u64().is_some_and(|n| n >= 3),
        "{summary}"
    );
    assert_eq!(summary["serials"], serde_json::json!(["MES-1", "MES-2"]));
    let seen = summary["status_states"].as_array().expect("states");
    assert!(
        seen.iter().any(|s| s == "prompting") && seen.iter().any(|s| s == "running"),
        "the generated model parsed /api/status at a prompt and at a step: {summary}"
    );

    // The PDF the generated client handed back is the server's, unmangled:
    // its length as sent, and its text the same as a download of our own
    // (the bytes differ only by the document's creation time and random ids).
    let run_id = summary["run_id"].as_str().expect("run id");
    let bytes = std::fs::read(&pdf).expect("the client's PDF");
    assert_eq!(
        bytes.len() as u64,
        summary["pdf_bytes"].as_u64().unwrap_or(0)
    );
    assert!(bytes.starts_with(b"%PDF-") && bytes.windows(5).any(|w| w == b"%%EOF"));
    let mut ours = match auth {
        Auth::Password => Client::login(&server, "mes", "mes-password-1"),
        Auth::Token => {
            let mut c = Client::new(&server);
            c.bearer = Some(password.clone());
            c
        }
    };
    let r = ours.send("GET", &format!("/api/runs/{run_id}/report/pdf"), None);
    assert_eq!(r.status, 200);
    let own = dir.path().join("own.pdf");
    std::fs::write(&own, &r.body).expect("own PDF");
    let text = pdf_text(&pdf);
    assert!(text.contains("MES-1") && text.contains(run_id), "{text}");
    assert_eq!(text, pdf_text(&own), "{backend:?}");
}
