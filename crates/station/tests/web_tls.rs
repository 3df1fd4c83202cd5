//! `spinbench serve --tls-cert --tls-key`: HTTPS with a
//! self-signed certificate made here, checked by a client that trusts only
//! it; the session cookie is `Secure`; plain HTTP on the port and a client
//! that does not trust the certificate get nothing; a wrong certificate or
//! key is refused at start, naming the file.

#[path = "common/web.rs"]
mod web;

use std::sync::Arc;
use web::{Backend, Client};

/// A self-signed certificate for this machine's loopback names, as PEM
/// files in `dir`: (certificate, key, the certificate's DER).
fn certificate(dir: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf, Vec<u8>) {
    let rcgen::CertifiedKey { cert, signing_key } =
        rcgen::generate_simple_self_signed(vec!["localhost".to_string(), "127.0.0.1".to_string()])
            .expect("a self-signed certificate");
    let (cert_path, key_path) = (dir.join("cert.pem"), dir.join("key.pem"));
    std::fs::write(&cert_path, cert.pem()).expect("cert.pem");
    std::fs::write(&key_path, signing_key.serialize_pem()).expect("key.pem");
    (cert_path, key_path, cert.der().to_vec())
}

/// A ureq agent that trusts only `der`.
fn trusting(der: &[u8]) -> ureq::Agent {
    use ureq::tls::{Certificate, RootCerts, TlsConfig};
    let roots = vec![Certificate::from_der(der).to_owned()];
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .tls_config(
            TlsConfig::builder()
                .root_certs(RootCerts::Specific(Arc::new(roots)))
                .build(),
        )
        .build()
        .into()
}

#[test]
fn the_server_speaks_https_with_a_secure_session_cookie() {
    the_server_speaks_https_with_a_secure_session_cookie_on(Backend::Sqlite);
}

#[test]
fn postgres_the_server_speaks_https_with_a_secure_session_cookie() {
    the_server_speaks_https_with_a_secure_session_cookie_on(Backend::Postgres);
}

fn the_server_speaks_https_with_a_secure_session_cookie_on(backend: Backend) {
    let dir = tempfile::tempdir().expect("tempdir");
    backend.prepare(dir.path());
    let (cert, key, der) = certificate(dir.path());
    web::add_user(dir.path(), "op", "operator", "op-password");
    let server = web::serve_with(
        dir.path(),
        "10",
        &[
            "--tls-cert",
            cert.to_str().expect("utf-8"),
            "--tls-key",
            key.to_str().expect("utf-8"),
        ],
    );
    assert!(
        server.base.starts_with("https://127.0.0.1:"),
        "{}",
        server.base
    );

    // Logged in over TLS: the cookie is Secure (and still HttpOnly).
    let mut client = Client::with_agent(&server, trusting(&der));
    let login = client.send(
        "POST",
        "/api/login",
        Some(r#"{"user": "op", "password": "op-password"}"#),
    );
    assert_eq!(login.status, 200, "{:?}", login.json());
    let cookie = login.set_cookie.clone().expect("a session cookie");
    assert!(
        cookie.contains("; Secure") && cookie.contains("HttpOnly"),
        "{cookie}"
    );
    let mut client = Client::with_agent(&server, trusting(&der)).log_in("op", "op-password");
    let session = client.send("GET", "/api/session", None);
    assert_eq!(session.status, 200);
    assert_eq!(session.json()["user"], "op");
    let status = client.send("GET", "/api/status", None);
    assert_eq!(status.status, 200);

    // The same public page through the trusting client: served.
    let words = trusting(&der)
        .get(format!("{}/api/i18n/en", server.base))
        .call()
        .expect("served over TLS");
    assert_eq!(words.status(), 200);

    // A client with the usual roots does not trust it: no answer.
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into();
    let refused = agent.get(format!("{}/api/i18n/en", server.base)).call();
    assert!(
        refused.is_err(),
        "an untrusted certificate was accepted: {refused:?}"
    );

    // Plain HTTP on the TLS port: no page, no API (the handshake fails).
    let plain = server.base.replace("https://", "http://");
    let answer = agent.get(format!("{plain}/api/i18n/en")).call();
    assert!(
        answer.as_ref().map_or(true, |r| r.status() != 200),
        "plain HTTP was served on the TLS port"
    );
}

#[test]
fn a_wrong_certificate_or_key_is_refused_at_start_naming_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (cert, key, _) = certificate(dir.path());
    let other = tempfile::tempdir().expect("tempdir");
    let (_, other_key, _) = certificate(other.path());
    let missing = dir.path().join("missing.pem");
    let not_pem = dir.path().join("not.pem");
    std::fs::write(&not_pem, "hello").expect("not.pem");
    let start = |cert: &std::path::Path, key: &std::path::Path| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_spinbench"))
            .args(["serve", "--simulate", "--bind", "127.0.0.1:0", "--data"])
            .arg(dir.path().join("data"))
            .arg("--tls-cert")
            .arg(cert)
            .arg("--tls-key")
            .arg(key)
            .output()
            .expect("spinbench serve");
        assert!(!out.status.success(), "it started");
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    let err = start(&missing, &key);
    assert!(
        err.contains("--tls-cert") && err.contains("missing.pem"),
        "{err}"
    );
    let err = start(&not_pem, &key);
    assert!(
        err.contains("not.pem") && err.contains("no certificate"),
        "{err}"
    );
    let err = start(&cert, &not_pem);
    assert!(
        err.contains("not.pem") && err.contains("private key"),
        "{err}"
    );
    let err = start(&cert, &other_key);
    assert!(err.contains("does not belong"), "{err}");
    // One without the other is a usage error.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["serve", "--simulate", "--tls-cert"])
        .arg(&cert)
        .output()
        .expect("spinbench serve");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--tls-key"));
}
