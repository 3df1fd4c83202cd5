//! API tokens of machine clients, on SQLite and on PostgreSQL: an admin
//! makes them (web and command line), a token's calls need no cookie and
//! no CSRF token and are held to its role, a run started with one names
//! the token as its operator, every step is audited, the store keeps no
//! secret, and a revoked token is refused at once.

#[path = "common/web.rs"]
mod web;

use serde_json::{Value, json};
use std::process::Command;
use web::{Backend, Client, Server, add_user, serve, store_of};

#[test]
fn api_tokens_made_used_scoped_audited_and_revoked() {
    tokens_on(Backend::Sqlite);
}

#[test]
fn postgres_api_tokens_made_used_scoped_audited_and_revoked() {
    tokens_on(Backend::Postgres);
}

/// A client that sends only `secret` as a bearer token.
fn machine(server: &Server, secret: &str) -> Client {
    let mut c = Client::new(server);
    c.bearer = Some(secret.to_string());
    c
}

/// `spinbench token …` on the store of `data`: (success, stdout, stderr).
fn token_cli(data: &std::path::Path, args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .arg("token")
        .args(args)
        .arg("--db")
        .arg(store_of(data))
        .output()
        .expect("spinbench token");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn tokens_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "admin", "admin", "admin-password");
    std::fs::create_dir_all(dir.path().join("plans")).expect("plans");
    std::fs::write(
        dir.path().join("plans").join("mes.toml"),
        web::short_plan("mes", &["TOK-1"]),
    )
    .expect("plan");

    // The command line makes one (as the first admin is made).
    let (ok, out, err) = token_cli(dir.path(), &["add", "line-ctl", "--role", "engineer"]);
    assert!(ok, "{err}");
    let cli_secret = out.lines().last().unwrap_or("").trim().to_string();
    assert!(
        cli_secret.starts_with("sbt_") && cli_secret.len() == 68,
        "{out}"
    );
    let (ok, _, err) = token_cli(dir.path(), &["add", "line-ctl"]);
    assert!(!ok && err.contains("exists"), "a taken name: {err}");
    let (ok, _, err) = token_cli(dir.path(), &["add", "x", "--role", "boss"]);
    assert!(!ok && err.contains("operator, engineer or admin"), "{err}");

    let server = serve(dir.path(), "0");
    let mut admin = Client::login(&server, "admin", "admin-password");

    // An admin's browser session needs its CSRF token to make one.
    let body = json!({"name": "mes-line-1", "role": "operator"}).to_string();
    assert_eq!(
        admin
            .send_with("POST", "/api/tokens", Some(&body), false)
            .status,
        403
    );
    let r = admin.send("POST", "/api/tokens", Some(&body));
    assert_eq!(r.status, 201, "{:?}", r.json());
    let made = r.json();
    web::matches_document(&mut admin, "TokenMade", &made, "POST /api/tokens");
    assert_eq!(made["role"], "operator");
    let secret = made["secret"].as_str().expect("secret").to_string();
    assert!(secret.starts_with("sbt_"), "{made}");
    assert_eq!(admin.send("POST", "/api/tokens", Some(&body)).status, 409);
    for bad in [
        json!({"name": "MES", "role": "operator"}),
        json!({"name": "a b", "role": "operator"}),
        json!({"name": "m2", "role": "boss"}),
    ] {
        let r = admin.send("POST", "/api/tokens", Some(&bad.to_string()));
        assert_eq!(r.status, 400, "{bad}: {:?}", r.json());
    }

    // A token call: no cookie, no CSRF token; held to its role.
    let mut mes = machine(&server, &secret);
    assert!(mes.cookie.is_none() && mes.csrf.is_none());
    assert_eq!(mes.send("GET", "/api/runs", None).status, 200);
    assert_eq!(mes.send("GET", "/api/tokens", None).status, 403, "operator");
    assert_eq!(mes.send("GET", "/api/users", None).status, 403, "operator");
    let mut engineer = machine(&server, &cli_secret);
    assert_eq!(engineer.send("GET", "/api/runs", None).status, 200);
    assert_eq!(engineer.send("GET", "/api/tokens", None).status, 403);
    // Not a token, a token of another shape, a bearer beside a good cookie:
    // the bearer is what is judged.
    for fake in [
        "nonsense".to_string(),
        format!("sbt_{}", "0".repeat(64)),
        secret.replace("sbt_", "sbx_"),
    ] {
        let r = machine(&server, &fake).send("GET", "/api/runs", None);
        assert_eq!(r.status, 401, "{fake}: {:?}", r.json());
    }

    // The MES starts a run and answers its prompts without a CSRF token.
    let r = mes.send(
        "POST",
        "/api/runs",
        Some(&json!({"plan": "mes", "serials": {"1": "TOK-1"}}).to_string()),
    );
    assert_eq!(r.status, 201, "{:?}", r.json());
    let run_id = r.json()["run_id"].as_str().expect("run id").to_string();
    assert!(mes.answer_prompts_until_end(&run_id) >= 3);
    let run = mes.get_json(&format!("/api/runs/{run_id}"), 200);
    assert_eq!(run["state"], "completed", "{run}");
    assert!(
        run["results"]
            .as_array()
            .is_some_and(|r| r.len() == 2 && r.iter().all(|u| u["serial"] == "TOK-1")),
        "one instrument in two mountings: {run}"
    );

    // Listed for the admin, with its use, never a secret.
    let list = admin.send("GET", "/api/tokens", None);
    assert_eq!(list.status, 200);
    let text = String::from_utf8_lossy(&list.body).into_owned();
    assert!(!text.contains(&secret) && !text.contains(&cli_secret) && !text.contains("secret"));
    let list = list.json();
    web::matches_document(&mut admin, "TokenEntry", &list[0], "GET /api/tokens");
    let entry = |list: &Value, name: &str| {
        list.as_array()
            .and_then(|l| l.iter().find(|t| t["name"] == name).cloned())
            .unwrap_or_else(|| panic!("{name} in {list}"))
    };
    let line1 = entry(&list, "mes-line-1");
    assert_eq!(line1["created_by"], "admin");
    assert!(line1["last_used_at"].is_i64(), "{line1}");
    assert!(line1["revoked_at"].is_null(), "{line1}");
    assert_eq!(entry(&list, "line-ctl")["role"], "engineer");

    // The store keeps the hash only.
    if backend == Backend::Sqlite {
        let bytes = std::fs::read(dir.path().join("spinbench.db")).expect("the SQLite file");
        let file = String::from_utf8_lossy(&bytes);
        assert!(!file.contains(&secret[4..]) && !file.contains(&cli_secret[4..]));
    }

    // Revoked: refused at once here, and the name is not reused.
    assert_eq!(
        admin
            .send_with("DELETE", "/api/tokens/mes-line-1", None, false)
            .status,
        403,
        "a browser's revoke needs its CSRF token"
    );
    assert_eq!(
        admin.send("DELETE", "/api/tokens/mes-line-1", None).status,
        204
    );
    assert_eq!(mes.send("GET", "/api/runs", None).status, 401);
    assert_eq!(
        admin.send("DELETE", "/api/tokens/mes-line-1", None).status,
        404
    );
    assert_eq!(admin.send("POST", "/api/tokens", Some(&body)).status, 409);
    let (ok, out, err) = token_cli(dir.path(), &["revoke", "line-ctl"]);
    assert!(ok, "{err}");
    assert!(out.contains("revoked"), "{out}");
    let (ok, out, _) = token_cli(dir.path(), &["list"]);
    assert!(ok);
    assert!(
        out.lines().filter(|l| l.contains("revoked")).count() == 2,
        "{out}"
    );
    // Another server of the store (a restart) refuses it too.
    drop(server);
    let server = serve(dir.path(), "0");
    let r = machine(&server, &cli_secret).send("GET", "/api/runs", None);
    assert_eq!(r.status, 401);

    // Every step audited, the token's calls under its own name.
    let mut admin = Client::login(&server, "admin", "admin-password");
    let audit = admin.get_json("/api/audit", 200);
    let rows = audit.as_array().expect("audit");
    let has = |who: &str, action: &str| {
        rows.iter().any(|e| {
            e["who"].as_str().is_some_and(|w| w.starts_with(who))
                && e["action"].as_str() == Some(action)
        })
    };
    assert!(has("admin", "add API token"), "{audit}");
    assert!(has("admin", "revoke API token"), "{audit}");
    assert!(has("token:mes-line-1", "start run"), "{audit}");
    assert!(
        rows.iter()
            .filter(|e| e["action"] == "add API token")
            .count()
            == 2,
        "{audit}"
    );
}
