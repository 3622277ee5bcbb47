//! The listeners' TLS configuration and its reload without a restart.
//!
//! [`TlsServer`] holds one rustls configuration per listener (REST offers
//! ALPN `h2` and `http/1.1`, gRPC `h2`), both built from the same
//! certificate, key and client CA. Each new connection takes the current
//! configuration; a reload swaps it, so connections open at the time keep
//! the session they have and later ones get the new certificate.
//!
//! [`TlsServer::watch`] reloads when the files' contents change (checked
//! every `--tls-reload-interval`; contents, not modification times, so a
//! Kubernetes Secret's symlink swap is seen whatever the times say) and on
//! SIGHUP. Files that do not load (a half-written rotation, a key that does
//! not match its certificate) keep the previous configuration and log one
//! WARN per distinct content (every SIGHUP warns again).

use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use arc_swap::ArcSwap;
use rustls::ServerConfig;
use rustls::server::WebPkiClientVerifier;
use rustls::server::danger::ClientCertVerifier;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio_rustls::TlsAcceptor;
use tokio_util::sync::CancellationToken;

use super::options::{ClientAuth, TlsOptions};
use super::pem;
use super::stream::{HandshakeError, MaybeTls, handshake};

/// Where the certificate comes from.
#[derive(Clone, Debug)]
struct Files {
    cert: PathBuf,
    key: PathBuf,
    client_ca: Option<PathBuf>,
    client_auth: ClientAuth,
}

/// The files' contents, as last tried.
#[derive(Clone, PartialEq, Eq)]
struct Contents {
    cert: Vec<u8>,
    key: Vec<u8>,
    client_ca: Option<Vec<u8>>,
}

/// The two listeners' configurations.
struct Configs {
    rest: Arc<ServerConfig>,
    grpc: Arc<ServerConfig>,
    /// The leaf's subject and expiry, for the log.
    leaf: String,
    /// The leaf's expiry (Unix seconds).
    not_after: i64,
}

/// What a reload did.
#[derive(Debug, PartialEq, Eq)]
pub enum Reload {
    /// The files are as last tried.
    Unchanged,
    /// New certificate in use.
    Reloaded,
    /// The new files do not load: the previous certificate stays.
    Failed(String),
}

struct Inner {
    files: Files,
    rest: ArcSwap<ServerConfig>,
    grpc: ArcSwap<ServerConfig>,
    /// What the files held when last tried (good or bad), or why they
    /// could not be read.
    tried: Mutex<Result<Contents, String>>,
}

/// The listeners' TLS: current configurations and their reload. Cheap to clone.
#[derive(Clone)]
pub struct TlsServer(Arc<Inner>);

impl std::fmt::Debug for TlsServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TlsServer")
            .field("files", &self.0.files)
            .finish()
    }
}

impl TlsServer {
    /// Loads the certificate the options name; `Ok(None)` without
    /// `--tls-cert`. Errors name the file and what is wrong with it.
    pub fn load(options: &TlsOptions) -> Result<Option<TlsServer>, String> {
        options.check()?;
        let (Some(cert), Some(key)) = (&options.tls_cert, &options.tls_key) else {
            return Ok(None);
        };
        let files = Files {
            cert: cert.clone(),
            key: key.clone(),
            client_ca: options.tls_client_ca.clone(),
            client_auth: options.tls_client_auth,
        };
        let contents = files.read()?;
        let configs = files.build(&contents)?;
        tracing::info!(
            certificate = %configs.leaf,
            client_certificates = files.client_auth_label(),
            "TLS on both listeners"
        );
        record_expiry(configs.not_after);
        Ok(Some(TlsServer(Arc::new(Inner {
            rest: ArcSwap::new(configs.rest),
            grpc: ArcSwap::new(configs.grpc),
            files,
            tried: Mutex::new(Ok(contents)),
        }))))
    }

    /// The REST listener's TLS, with handshakes bounded by `handshake_timeout`.
    pub fn rest(&self, handshake_timeout: Duration) -> Listener {
        Listener {
            server: self.clone(),
            grpc: false,
            handshake_timeout,
        }
    }

    /// The gRPC listener's TLS, with handshakes bounded by `handshake_timeout`.
    pub fn grpc(&self, handshake_timeout: Duration) -> Listener {
        Listener {
            server: self.clone(),
            grpc: true,
            handshake_timeout,
        }
    }

    /// Reads the files again and, if they changed since last tried (or
    /// `force`), builds and swaps in the new configurations. Blocking (reads
    /// files): call on a blocking thread.
    pub fn reload(&self, force: bool) -> Reload {
        let inner = &self.0;
        let read = inner.files.read();
        let mut tried = inner.tried.lock().unwrap_or_else(PoisonError::into_inner);
        if !force && *tried == read {
            return Reload::Unchanged;
        }
        *tried = read.clone();
        drop(tried);
        let contents = match read {
            Ok(c) => c,
            Err(e) => return Reload::Failed(e),
        };
        match inner.files.build(&contents) {
            Ok(configs) => {
                inner.rest.store(configs.rest);
                inner.grpc.store(configs.grpc);
                record_expiry(configs.not_after);
                tracing::info!(certificate = %configs.leaf, "TLS certificate reloaded");
                Reload::Reloaded
            }
            Err(e) => Reload::Failed(e),
        }
    }

    /// Reloads on SIGHUP and, unless `interval` is zero, whenever the files
    /// change (checked every `interval`), until `stop` is cancelled.
    pub async fn watch(self, interval: Duration, stop: CancellationToken) {
        let mut hup = sighup();
        let mut tick = (!interval.is_zero()).then(|| {
            let mut t = tokio::time::interval_at(tokio::time::Instant::now() + interval, interval);
            t.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            t
        });
        loop {
            let force = tokio::select! {
                _ = stop.cancelled() => return,
                _ = async { tick.as_mut().expect("some").tick().await }, if tick.is_some() => false,
                Some(()) = recv(&mut hup) => true,
            };
            let this = self.clone();
            let Ok(result) = tokio::task::spawn_blocking(move || this.reload(force)).await else {
                continue;
            };
            log_reload(&result, force);
        }
    }
}

/// Counts and logs a reload's outcome.
fn log_reload(result: &Reload, on_signal: bool) {
    let label = match result {
        Reload::Unchanged if on_signal => "unchanged",
        Reload::Unchanged => return,
        Reload::Reloaded => "ok",
        Reload::Failed(e) => {
            tracing::warn!(error = %e, "the TLS certificate files do not load: keeping the previous certificate");
            "failed"
        }
    };
    metrics::counter!("kinserve_tls_reloads_total", "result" => label).increment(1);
}

fn record_expiry(not_after: i64) {
    metrics::gauge!("kinserve_tls_certificate_expiry_timestamp_seconds").set(not_after as f64);
}

#[cfg(unix)]
fn sighup() -> Option<tokio::signal::unix::Signal> {
    tokio::signal::unix::signal(tokio::signal::unix::SignalKind::hangup()).ok()
}

#[cfg(not(unix))]
fn sighup() -> Option<()> {
    None
}

#[cfg(unix)]
async fn recv(hup: &mut Option<tokio::signal::unix::Signal>) -> Option<()> {
    match hup {
        Some(s) => s.recv().await,
        None => std::future::pending().await,
    }
}

#[cfg(not(unix))]
async fn recv(_: &mut Option<()>) -> Option<()> {
    std::future::pending().await
}

impl Files {
    fn read(&self) -> Result<Contents, String> {
        Ok(Contents {
            cert: pem::read(&self.cert, "TLS certificate")?,
            key: pem::read(&self.key, "TLS key")?,
            client_ca: match &self.client_ca {
                Some(p) => Some(pem::read(p, "TLS client CA")?),
                None => None,
            },
        })
    }

    fn client_auth_label(&self) -> &'static str {
        match (&self.client_ca, self.client_auth) {
            (None, _) => "not asked for",
            (Some(_), ClientAuth::Require) => "required",
            (Some(_), ClientAuth::Optional) => "optional",
        }
    }

    fn verifier(&self, contents: &Contents) -> Result<Arc<dyn ClientCertVerifier>, String> {
        let (Some(path), Some(pem)) = (&self.client_ca, &contents.client_ca) else {
            return Ok(WebPkiClientVerifier::no_client_auth());
        };
        let roots = pem::roots(pem, path)?;
        let builder = WebPkiClientVerifier::builder_with_provider(roots, super::provider());
        let builder = match self.client_auth {
            ClientAuth::Require => builder,
            ClientAuth::Optional => builder.allow_unauthenticated(),
        };
        builder
            .build()
            .map_err(|e| format!("{}: cannot check client certificates: {e}", path.display()))
    }

    /// Both listeners' configurations from `contents`.
    fn build(&self, contents: &Contents) -> Result<Configs, String> {
        let certs = pem::certs(&contents.cert, &self.cert)?;
        let key = pem::key(&contents.key, &self.key)?;
        let verifier = self.verifier(contents)?;
        let (leaf, not_after) = describe(&certs[0]);
        let make = |alpn: &[&[u8]]| -> Result<Arc<ServerConfig>, String> {
            let mut config = ServerConfig::builder_with_provider(super::provider())
                .with_safe_default_protocol_versions()
                .map_err(|e| e.to_string())?
                .with_client_cert_verifier(verifier.clone())
                .with_single_cert(certs.clone(), key.clone_key())
                .map_err(|e| {
                    format!(
                        "{} and {} are not a certificate and its key: {e}",
                        self.cert.display(),
                        self.key.display()
                    )
                })?;
            config.alpn_protocols = alpn.iter().map(|p| p.to_vec()).collect();
            Ok(Arc::new(config))
        };
        Ok(Configs {
            rest: make(&[b"h2", b"http/1.1"])?,
            grpc: make(&[b"h2"])?,
            leaf,
            not_after,
        })
    }
}

/// A leaf's subject and expiry for the log, and its expiry in Unix seconds.
fn describe(der: &rustls_pki_types::CertificateDer<'_>) -> (String, i64) {
    match x509_parser::parse_x509_certificate(der.as_ref()) {
        Ok((_, cert)) => {
            let not_after = cert.validity().not_after;
            (
                format!("{} (expires {not_after})", cert.subject()),
                not_after.timestamp(),
            )
        }
        Err(_) => ("(unparsable certificate)".into(), 0),
    }
}

/// One listener's TLS: which configuration, and how long a handshake may take.
#[derive(Clone, Debug)]
pub struct Listener {
    server: TlsServer,
    grpc: bool,
    handshake_timeout: Duration,
}

impl Listener {
    fn acceptor(&self) -> TlsAcceptor {
        let config = if self.grpc {
            self.server.0.grpc.load_full()
        } else {
            self.server.0.rest.load_full()
        };
        TlsAcceptor::from(config)
    }
}

/// An accepted connection made ready: the TLS handshake when `tls` is set
/// (bounded by its handshake timeout), else the plain connection.
pub async fn accept<IO>(tls: Option<&Listener>, io: IO) -> Result<MaybeTls<IO>, HandshakeError>
where
    IO: AsyncRead + AsyncWrite + Unpin,
{
    let Some(tls) = tls else {
        return Ok(MaybeTls::Plain(io));
    };
    let listener = if tls.grpc { "grpc" } else { "http" };
    handshake(tls.acceptor(), io, tls.handshake_timeout, listener).await
}
