//! HTTPS for a plant network (`spinbench serve --tls-cert CERT --tls-key KEY`):
//! the certificate chain and its private key read from PEM files into a
//! rustls server configuration (ring, TLS 1.2 and 1.3; HTTP/1.1 over ALPN).
//! The server stays on loopback by default; with TLS, session cookies are
//! `Secure`.

use anyhow::{Context, Result, bail};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use std::path::Path;
use std::sync::Arc;

/// Largest certificate or key file read (a chain of a few certificates is
/// a few kB; anything far bigger is not one).
const MAX_PEM_BYTES: u64 = 1 << 20;

/// The server's TLS configuration from a PEM certificate chain (the
/// server's certificate first) and its PEM private key (PKCS#8, PKCS#1 or
/// SEC1). Every error names the file and what to do.
pub fn server_config(cert_path: &Path, key_path: &Path) -> Result<Arc<rustls::ServerConfig>> {
    let cert_pem = read_bounded(cert_path, "--tls-cert")?;
    let key_pem = read_bounded(key_path, "--tls-key")?;
    let chain: Vec<CertificateDer<'static>> = CertificateDer::pem_slice_iter(&cert_pem)
        .collect::<Result<_, _>>()
        .map_err(|e| {
            anyhow::anyhow!(
                "{}: not a PEM certificate chain ({e}); give the server's certificate, then its issuers, each in -----BEGIN CERTIFICATE----- blocks",
                cert_path.display()
            )
        })?;
    if chain.is_empty() {
        bail!(
            "{}: no certificate in it (expected -----BEGIN CERTIFICATE----- blocks)",
            cert_path.display()
        );
    }
    let key = PrivateKeyDer::from_pem_slice(&key_pem).map_err(|e| {
        anyhow::anyhow!(
            "{}: no private key in it ({e}); give the key of the certificate as PEM (PKCS#8, PKCS#1 or SEC1)",
            key_path.display()
        )
    })?;
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let mut config = rustls::ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .context("the TLS library refused its own default protocol versions")?
        .with_no_client_auth()
        .with_single_cert(chain, key)
        .with_context(|| {
            format!(
                "{} and {}: the key does not belong to the certificate, or the certificate is unusable",
                cert_path.display(),
                key_path.display()
            )
        })?;
    config.alpn_protocols = vec![b"http/1.1".to_vec()];
    Ok(Arc::new(config))
}

/// A PEM file, refused when missing, unreadable or implausibly large.
fn read_bounded(path: &Path, option: &str) -> Result<Vec<u8>> {
    let meta = std::fs::metadata(path)
        .with_context(|| format!("{option} {}: cannot read it", path.display()))?;
    // A device (/dev/zero) or a FIFO would be read for ever: a PEM is a file.
    if !meta.is_file() {
        bail!(
            "{option} {}: not a regular file; give the PEM file itself",
            path.display()
        );
    }
    let size = meta.len();
    if size > MAX_PEM_BYTES {
        bail!(
            "{option} {}: {size} bytes, more than a PEM file of a certificate or key ({MAX_PEM_BYTES} at most)",
            path.display()
        );
    }
    // Bounded even if the file grows while it is read.
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(
        &mut std::io::Read::take(
            std::fs::File::open(path)
                .with_context(|| format!("{option} {}: cannot read it", path.display()))?,
            MAX_PEM_BYTES + 1,
        ),
        &mut bytes,
    )
    .with_context(|| format!("{option} {}: cannot read it", path.display()))?;
    if bytes.len() as u64 > MAX_PEM_BYTES {
        bail!(
            "{option} {}: more than a PEM file of a certificate or key ({MAX_PEM_BYTES} bytes at most)",
            path.display()
        );
    }
    Ok(bytes)
}
