//! The users' commands: `spinbench user role`, `passwd` and
//! `remove`, and the web API's `PUT /api/users/{name}`, each ending the
//! user's sessions on a running server within seconds; the only admin
//! cannot be demoted or removed.

#[path = "common/web.rs"]
mod web;

use std::process::Command;
use std::time::{Duration, Instant};
use web::{Backend, Client, add_user, serve, store_of};

/// `spinbench user ARGS --db STORE` with `password` in the environment.
fn user(data: &std::path::Path, args: &[&str], password: Option<&str>) -> (bool, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_spinbench"));
    cmd.arg("user").args(args).arg("--db").arg(store_of(data));
    if let Some(p) = password {
        cmd.env("SPINBENCH_PASSWORD", p);
    }
    let out = cmd.output().expect("spinbench user");
    (
        out.status.success(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
    )
}

/// Wait until `client`'s session is refused (at most 5 s); how long it took.
fn refused_within_5_s(client: &mut Client) -> Duration {
    let start = Instant::now();
    loop {
        if client.send("GET", "/api/status", None).status == 401 {
            return start.elapsed();
        }
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "the session still works after 5 s"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn role_password_and_removal_end_the_users_sessions() {
    role_password_and_removal_end_the_users_sessions_on(Backend::Sqlite);
}

#[test]
fn postgres_role_password_and_removal_end_the_users_sessions() {
    role_password_and_removal_end_the_users_sessions_on(Backend::Postgres);
}

fn role_password_and_removal_end_the_users_sessions_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    add_user(dir.path(), "admin", "admin", "admin-password");
    add_user(dir.path(), "op", "operator", "op-password");
    let server = serve(dir.path(), "0");

    // A role change from the command line ends op's session.
    let mut op = Client::login(&server, "op", "op-password");
    let (ok, said) = user(dir.path(), &["role", "op", "engineer"], None);
    assert!(ok && said.contains("op is engineer"), "{said}");
    refused_within_5_s(&mut op);
    let (_, list) = user(dir.path(), &["list"], None);
    assert!(
        list.lines()
            .any(|l| l.starts_with("op") && l.contains("engineer")),
        "{list}"
    );

    // A new password: the old one is refused, the new one works.
    let mut op = Client::login(&server, "op", "op-password");
    let (ok, said) = user(dir.path(), &["passwd", "op"], Some("new-op-password"));
    assert!(ok, "{said}");
    refused_within_5_s(&mut op);
    let r = Client::new(&server).send(
        "POST",
        "/api/login",
        Some(r#"{"user": "op", "password": "op-password"}"#),
    );
    assert_eq!(r.status, 401);
    let mut op = Client::login(&server, "op", "new-op-password");

    // The web API: an admin makes op an operator again; a short password
    // and an unknown role are refused; the only admin stays an admin.
    let mut admin = Client::login(&server, "admin", "admin-password");
    let r = admin.send("PUT", "/api/users/op", Some(r#"{"role": "operator"}"#));
    assert_eq!(r.status, 200, "{:?}", r.json());
    assert_eq!(r.json()["role"], "operator");
    refused_within_5_s(&mut op);
    assert_eq!(
        admin
            .send("PUT", "/api/users/op", Some(r#"{"password": "short"}"#))
            .status,
        400
    );
    assert_eq!(
        admin
            .send("PUT", "/api/users/op", Some(r#"{"role": "king"}"#))
            .status,
        400
    );
    assert_eq!(admin.send("PUT", "/api/users/op", Some("{}")).status, 400);
    assert_eq!(
        admin
            .send("PUT", "/api/users/nobody", Some(r#"{"role": "operator"}"#))
            .status,
        404
    );
    let r = admin.send("PUT", "/api/users/admin", Some(r#"{"role": "operator"}"#));
    assert_eq!(r.status, 409, "{:?}", r.json());
    let (ok, said) = user(dir.path(), &["remove", "admin"], None);
    assert!(!ok && said.contains("only admin"), "{said}");

    // Removal from the command line ends the session.
    let mut op = Client::login(&server, "op", "new-op-password");
    let (ok, said) = user(dir.path(), &["remove", "op"], None);
    assert!(ok, "{said}");
    refused_within_5_s(&mut op);
    let (ok, said) = user(dir.path(), &["remove", "op"], None);
    assert!(!ok && said.contains("no user 'op'"), "{said}");
    // Every change is in the audit log.
    let audit = admin.get_json("/api/audit", 200);
    let actions: Vec<&str> = audit
        .as_array()
        .expect("a list")
        .iter()
        .filter_map(|e| e["action"].as_str())
        .collect();
    assert!(
        actions.iter().filter(|a| **a == "change user").count() >= 3,
        "{actions:?}"
    );
    assert!(actions.contains(&"remove user"), "{actions:?}");
}
