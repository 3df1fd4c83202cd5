//! TLS to a PostgreSQL store, as libpq's `sslmode` and `sslrootcert`
//! parameters of the URL ask (the PostgreSQL documentation's "SSL Support").
//!
//! The PostgreSQL client (tokio-postgres) reads only `disable`, `prefer`
//! and `require` and does no TLS of its own: the URL is split here into
//! what it reads and the TLS asked for, and a rustls connector
//! (tokio-postgres-rustls, ring) does the TLS:
//!
//! - `disable`: clear text;
//! - `prefer` (libpq's default) and `require` without a root certificate:
//!   encrypted, the server's certificate not checked (libpq's meaning);
//! - `require` with `sslrootcert`, and `verify-ca`: the certificate must
//!   chain to the root certificate;
//! - `verify-full`: it must also name the host the URL names.
//!
//! A root certificate is `sslrootcert=FILE` (PEM), else libpq's
//! `~/.postgresql/root.crt` when it exists. `allow` is taken as `prefer`.

use rustls::DigitallySignedStruct;
use rustls::client::WebPkiServerVerifier;
use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, ServerName, UnixTime};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Largest root certificate file read [bytes].
const MAX_PEM_BYTES: u64 = 1 << 20;

/// The TLS a URL asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SslMode {
    /// Clear text.
    Disable,
    /// TLS when the server offers it.
    Prefer,
    /// TLS or no connection.
    Require,
    /// TLS to a server whose certificate chains to the root certificate.
    VerifyCa,
    /// `VerifyCa`, and the certificate names the host.
    VerifyFull,
}

/// A PostgreSQL URL split into what the client reads and the TLS asked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PgUrl {
    /// The URL for tokio-postgres (`sslmode` as it reads it, no `sslrootcert`).
    pub url: String,
    /// The TLS asked.
    pub mode: SslMode,
    /// The root certificate named (`sslrootcert`).
    pub root_cert: Option<PathBuf>,
}

/// Split `url`'s query into the client's and the TLS's parameters; an
/// `sslmode` that libpq does not know is refused by name.
pub fn split(url: &str) -> Result<PgUrl, String> {
    let (base, query) = url.split_once('?').unwrap_or((url, ""));
    let mut mode = SslMode::Prefer;
    let mut root_cert = None;
    let mut kept = Vec::new();
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
        match key {
            "sslmode" => {
                mode = match value {
                    "disable" => SslMode::Disable,
                    "allow" | "prefer" => SslMode::Prefer,
                    "require" => SslMode::Require,
                    "verify-ca" => SslMode::VerifyCa,
                    "verify-full" => SslMode::VerifyFull,
                    other => {
                        return Err(format!(
                            "sslmode={other} is not one of disable, allow, prefer, require, verify-ca, verify-full"
                        ));
                    }
                }
            }
            "sslrootcert" => root_cert = Some(PathBuf::from(percent_decoded(value))),
            _ => kept.push(pair.to_string()),
        }
    }
    kept.push(
        match mode {
            SslMode::Disable => "sslmode=disable",
            SslMode::Prefer => "sslmode=prefer",
            SslMode::Require | SslMode::VerifyCa | SslMode::VerifyFull => "sslmode=require",
        }
        .to_string(),
    );
    Ok(PgUrl {
        url: format!("{base}?{}", kept.join("&")),
        mode,
        root_cert,
    })
}

/// `%2F` → `/` and the like (a path in a URL's query).
fn percent_decoded(value: &str) -> String {
    let bytes = value.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%'
            && let Some(hex) = value.get(i + 1..i + 3)
            && let Ok(b) = u8::from_str_radix(hex, 16)
        {
            out.push(b);
            i += 3;
            continue;
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The connector for `url`'s TLS; `None` for clear text.
pub fn connector(url: &PgUrl) -> Result<Option<tokio_postgres_rustls::MakeRustlsConnect>, String> {
    if url.mode == SslMode::Disable {
        return Ok(None);
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let root = url.root_cert.clone().or_else(|| {
        let home = std::env::var_os("HOME")?;
        let default = Path::new(&home).join(".postgresql/root.crt");
        default.exists().then_some(default)
    });
    let verifier: Arc<dyn ServerCertVerifier> = match (url.mode, &root) {
        (SslMode::VerifyCa | SslMode::VerifyFull, None) => {
            return Err(
                "sslmode=verify-ca and verify-full need the root certificate that signed the server's: add sslrootcert=FILE (PEM) to the URL"
                    .into(),
            );
        }
        (SslMode::Disable | SslMode::Prefer | SslMode::Require, None) => {
            Arc::new(EncryptOnly(provider.clone()))
        }
        (mode, Some(path)) => {
            let mut roots = rustls::RootCertStore::empty();
            for cert in read_roots(path)? {
                roots
                    .add(cert)
                    .map_err(|e| format!("sslrootcert {}: {e}", path.display()))?;
            }
            let full =
                WebPkiServerVerifier::builder_with_provider(Arc::new(roots), provider.clone())
                    .build()
                    .map_err(|e| format!("sslrootcert {}: {e}", path.display()))?;
            if mode == SslMode::VerifyFull {
                full
            } else {
                Arc::new(ChainOnly(full))
            }
        }
    };
    let config = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| format!("the TLS library refused its default protocol versions: {e}"))?
        .dangerous()
        .with_custom_certificate_verifier(verifier)
        .with_no_client_auth();
    Ok(Some(tokio_postgres_rustls::MakeRustlsConnect::new(config)))
}

/// The certificates of a PEM file, refused by name when missing, too large
/// or empty.
fn read_roots(path: &Path) -> Result<Vec<CertificateDer<'static>>, String> {
    let meta =
        std::fs::metadata(path).map_err(|e| format!("sslrootcert {}: {e}", path.display()))?;
    if !meta.is_file() || meta.len() > MAX_PEM_BYTES {
        return Err(format!(
            "sslrootcert {}: not a PEM file of at most {MAX_PEM_BYTES} bytes",
            path.display()
        ));
    }
    let pem = std::fs::read(path).map_err(|e| format!("sslrootcert {}: {e}", path.display()))?;
    let certs: Vec<CertificateDer<'static>> = CertificateDer::pem_slice_iter(&pem)
        .collect::<Result<_, _>>()
        .map_err(|e| format!("sslrootcert {}: not PEM certificates ({e})", path.display()))?;
    if certs.is_empty() {
        return Err(format!(
            "sslrootcert {}: no -----BEGIN CERTIFICATE----- block in it",
            path.display()
        ));
    }
    Ok(certs)
}

/// libpq's `prefer` and `require` without a root certificate: the session
/// is encrypted and its handshake signed by the certificate's key, but the
/// certificate itself is not checked.
#[derive(Debug)]
struct EncryptOnly(Arc<rustls::crypto::CryptoProvider>);

impl ServerCertVerifier for EncryptOnly {
    fn verify_server_cert(
        &self,
        _end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _server_name: &ServerName<'_>,
        _ocsp_response: &[u8],
        _now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        Ok(ServerCertVerified::assertion())
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls12_signature(
            message,
            cert,
            dss,
            &self.0.signature_verification_algorithms,
        )
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls13_signature(
            message,
            cert,
            dss,
            &self.0.signature_verification_algorithms,
        )
    }

    fn supported_verify_schemes(&self) -> Vec<rustls::SignatureScheme> {
        self.0.signature_verification_algorithms.supported_schemes()
    }
}

/// `verify-ca`: the certificate must chain to the root certificate; the
/// name in it is not compared with the host.
#[derive(Debug)]
struct ChainOnly(Arc<WebPkiServerVerifier>);

impl ServerCertVerifier for ChainOnly {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        intermediates: &[CertificateDer<'_>],
        server_name: &ServerName<'_>,
        ocsp_response: &[u8],
        now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        match self
            .0
            .verify_server_cert(end_entity, intermediates, server_name, ocsp_response, now)
        {
            Err(rustls::Error::InvalidCertificate(
                rustls::CertificateError::NotValidForName
                | rustls::CertificateError::NotValidForNameContext { .. },
            )) => Ok(ServerCertVerified::assertion()),
            other => other,
        }
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        self.0.verify_tls12_signature(message, cert, dss)
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        self.0.verify_tls13_signature(message, cert, dss)
    }

    fn supported_verify_schemes(&self) -> Vec<rustls::SignatureScheme> {
        self.0.supported_verify_schemes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_url_is_split_into_the_clients_and_the_tls_parameters() {
        let u = split(
            "postgres://s@db/x?sslmode=verify-full&sslrootcert=%2Fetc%2Fca.crt&connect_timeout=5",
        )
        .expect("split");
        assert_eq!(u.mode, SslMode::VerifyFull);
        assert_eq!(u.root_cert.as_deref(), Some(Path::new("/etc/ca.crt")));
        assert_eq!(u.url, "postgres://s@db/x?connect_timeout=5&sslmode=require");
        let plain = split("postgres://s@db/x").expect("split");
        assert_eq!(
            (plain.mode, plain.url.as_str()),
            (SslMode::Prefer, "postgres://s@db/x?sslmode=prefer")
        );
        let e = split("postgres://s@db/x?sslmode=verify").expect_err("unknown");
        assert!(e.contains("sslmode=verify is not one of"), "{e}");
        let off = split("postgres://s@db/x?sslmode=disable").expect("split");
        assert!(connector(&off).expect("clear text").is_none());
        let no_root = split("postgres://s@db/x?sslmode=verify-ca").expect("split");
        let e = match connector(&no_root) {
            Ok(_) => panic!("verify-ca without a root certificate was taken"),
            Err(e) => e,
        };
        assert!(e.contains("sslrootcert=FILE"), "{e}");
    }
}
