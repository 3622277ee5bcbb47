//! The TLS client of `kinserve healthcheck` (blocking): it asks its own
//! server whether it is ready, so it does not check the server's
//! certificate (the answer is about readiness, not identity), and it can
//! present a client certificate for a server that requires one.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::sync::Arc;

use rustls::{ClientConfig, ClientConnection, StreamOwned};
use rustls_pki_types::ServerName;

use super::pem;
use super::verify::Unverified;

/// A TLS connection over `tcp` to `host` (a name or an address; any
/// certificate is accepted), presenting `client` (certificate and key
/// files) if given. The handshake runs on the first read or write.
pub fn connect(
    tcp: TcpStream,
    host: &str,
    client: Option<(&Path, &Path)>,
) -> Result<impl Read + Write, String> {
    let builder = ClientConfig::builder_with_provider(super::provider())
        .with_safe_default_protocol_versions()
        .map_err(|e| e.to_string())?
        .dangerous()
        .with_custom_certificate_verifier(Arc::new(Unverified::new()));
    let mut config = match client {
        None => builder.with_no_client_auth(),
        Some((cert, key)) => {
            let certs = pem::certs(&pem::read(cert, "client certificate")?, cert)?;
            let key = pem::key(&pem::read(key, "client key")?, key)?;
            builder
                .with_client_auth_cert(certs, key)
                .map_err(|e| format!("the client certificate and key: {e}"))?
        }
    };
    config.alpn_protocols = vec![b"http/1.1".to_vec()];
    let name = ServerName::try_from(host.to_string())
        .unwrap_or_else(|_| ServerName::try_from("localhost").expect("a valid name"));
    let conn = ClientConnection::new(Arc::new(config), name).map_err(|e| e.to_string())?;
    Ok(StreamOwned::new(conn, tcp))
}
