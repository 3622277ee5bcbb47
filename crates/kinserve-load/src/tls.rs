//! gRPC channels, plain or over TLS (`--tls-ca`): a rustls client (ring
//! provider, TLS 1.2+, ALPN `h2`) trusting the CAs of one PEM file and
//! checking the server's certificate for `--tls-server-name`.
//!
//! Owns channel set-up for every gRPC target; depends on nothing else of the
//! crate. The REST and WebSocket targets stay plain: reqwest is built here
//! without a TLS stack, and `scripts/bench.sh` measures REST over TLS with
//! wrk instead.

use std::path::Path;
use std::sync::Arc;

use rustls::ClientConfig;
use rustls_pki_types::pem::PemObject;
use rustls_pki_types::{CertificateDer, ServerName};
use tonic::transport::{Channel, Endpoint};

/// How gRPC targets reach the server over TLS.
#[derive(Clone, Debug)]
pub(crate) struct GrpcTls {
    config: Arc<ClientConfig>,
    name: ServerName<'static>,
}

impl GrpcTls {
    /// Trusts every certificate in the PEM file `ca` and expects `server_name`
    /// (a DNS name or an IP address) in the server's certificate.
    pub(crate) fn new(ca: &Path, server_name: &str) -> Result<GrpcTls, String> {
        let pem = std::fs::read(ca).map_err(|e| format!("--tls-ca {}: {e}", ca.display()))?;
        let mut roots = rustls::RootCertStore::empty();
        for cert in CertificateDer::pem_slice_iter(&pem) {
            let cert = cert.map_err(|e| format!("--tls-ca {}: {e}", ca.display()))?;
            roots
                .add(cert)
                .map_err(|e| format!("--tls-ca {}: {e}", ca.display()))?;
        }
        if roots.is_empty() {
            return Err(format!(
                "--tls-ca {}: no certificate in the file (expected PEM \"BEGIN CERTIFICATE\" blocks)",
                ca.display()
            ));
        }
        let provider = Arc::new(rustls::crypto::ring::default_provider());
        let mut config = ClientConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .map_err(|e| format!("TLS: {e}"))?
            .with_root_certificates(roots)
            .with_no_client_auth();
        config.alpn_protocols = vec![b"h2".to_vec()];
        let name = ServerName::try_from(server_name.to_string())
            .map_err(|e| format!("--tls-server-name {server_name:?}: {e}"))?;
        Ok(GrpcTls {
            config: Arc::new(config),
            name,
        })
    }
}

/// HTTP/2 receive window of each call: a 10,000-pose `full` answer (~1.7 MB)
/// in one window, instead of h2's 64 KiB default, which made the server wait
/// for ~25 window updates per answer.
const STREAM_WINDOW: u32 = 4 << 20;
/// HTTP/2 receive window of the connection (every call's answers in flight).
const CONNECTION_WINDOW: u32 = 16 << 20;

/// Largest HTTP/2 frame the server may send: a 10,000-pose `matrix` answer
/// (~960 KB) in 4 DATA frames instead of h2's 16 KiB default's 59, each
/// with its own header, wake-up and copy (20 % less of the load generator's
/// CPU per such batch, measured).
const MAX_FRAME: u32 = 256 << 10;

/// The endpoint of `addr`, with receive windows and frames for large answers.
fn endpoint(addr: &str) -> Result<Endpoint, String> {
    Ok(Endpoint::from_shared(format!("http://{addr}"))
        .map_err(|e| e.to_string())?
        .initial_stream_window_size(STREAM_WINDOW)
        .max_frame_size(MAX_FRAME)
        .initial_connection_window_size(CONNECTION_WINDOW))
}

/// A connected gRPC channel to `addr` (`host:port`), over TLS when `tls` is set.
pub(crate) async fn channel(addr: &str, tls: Option<&GrpcTls>) -> Result<Channel, String> {
    let Some(tls) = tls else {
        return endpoint(addr)?
            .connect()
            .await
            .map_err(|e| format!("connect {addr}: {e}"));
    };
    let (target, tls) = (addr.to_string(), tls.clone());
    // The URI is only the :authority of the requests: the connector below
    // dials `addr` and speaks TLS itself.
    endpoint(addr)?
        .connect_with_connector(tower::service_fn(move |_uri| {
            let (target, tls) = (target.clone(), tls.clone());
            async move {
                let tcp = tokio::net::TcpStream::connect(&target).await?;
                tcp.set_nodelay(true)?;
                let stream = tokio_rustls::TlsConnector::from(tls.config)
                    .connect(tls.name, tcp)
                    .await?;
                Ok::<_, std::io::Error>(hyper_util::rt::TokioIo::new(stream))
            }
        }))
        .await
        .map_err(|e| format!("connect {addr} over TLS: {e}"))
}
