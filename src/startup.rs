//! Building and running the server: binds both listeners (port 0 works), loads
//! robots, serves until a shutdown signal, then drains gracefully.

use std::net::SocketAddr;
use std::sync::Arc;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use axum::Router;
use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use hyper_util::server::conn::auto;
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;
use tokio_util::sync::CancellationToken;
use tower::ServiceExt;

use crate::api::rest::{self, AppInner, AppState};
use crate::config::ServeConfig;
use crate::registry::postgres::sync::{Applier, Syncer};
use crate::registry::postgres::{PgSettings, PgStore};
use crate::registry::{FileStore, Registry, Store};
use crate::service::Service;

/// A built, not yet running server.
pub struct App {
    http: TcpListener,
    grpc: TcpListener,
    http_addr: SocketAddr,
    grpc_addr: SocketAddr,
    service: Arc<Service>,
    config: ServeConfig,
    shutdown: CancellationToken,
    syncer: Option<Syncer>,
}

/// Triggers a graceful shutdown of a running [`App`].
#[derive(Clone, Debug)]
pub struct ShutdownHandle(CancellationToken);

impl ShutdownHandle {
    /// Starts the graceful shutdown (readiness flips, streams close, in-flight requests finish).
    pub fn shutdown(&self) {
        self.0.cancel();
    }
}

impl App {
    /// Opens the store (the database when `--database-url` is set, else the
    /// data directory), loads robots (built-ins, then the stored ones) and
    /// binds both listeners.
    pub async fn build(config: ServeConfig) -> std::io::Result<App> {
        let limits = config.service_limits();
        let (store, syncer) = open_store(&config).await?;
        let registry = Registry::new(store).with_max_registered(config.max_robots);
        let token = api_token(config.api_token.as_deref())?;
        let builtins = registry.load_builtins(config.robots_dir.as_deref(), &limits.model);
        let model_limits = limits.model;
        let (registry, stored) = tokio::task::spawn_blocking(move || {
            let report = registry.load_stored(&model_limits);
            (registry, report)
        })
        .await
        .map_err(std::io::Error::other)?;
        for (label, e) in builtins.skipped.iter().chain(&stored.skipped) {
            tracing::error!(file = %label, error = %e, "skipping robot file (left in place)");
        }
        tracing::info!(
            builtin = builtins.loaded,
            registered = stored.loaded,
            store = registry.store_health().kind,
            "robots loaded"
        );
        let service = Arc::new(Service::new(registry, limits, token));
        let http = TcpListener::bind(config.http_addr).await?;
        let grpc = TcpListener::bind(config.grpc_addr).await?;
        Ok(App {
            http_addr: http.local_addr()?,
            grpc_addr: grpc.local_addr()?,
            http,
            grpc,
            service,
            config,
            shutdown: CancellationToken::new(),
            syncer,
        })
    }

    /// Address the REST listener is bound to.
    pub fn http_addr(&self) -> SocketAddr {
        self.http_addr
    }

    /// Address the gRPC listener is bound to.
    pub fn grpc_addr(&self) -> SocketAddr {
        self.grpc_addr
    }

    /// Port of the REST listener.
    pub fn http_port(&self) -> u16 {
        self.http_addr.port()
    }

    /// Port of the gRPC listener.
    pub fn grpc_port(&self) -> u16 {
        self.grpc_addr.port()
    }

    /// The shared service.
    pub fn service(&self) -> Arc<Service> {
        self.service.clone()
    }

    /// A handle that stops the server gracefully.
    pub fn shutdown_handle(&self) -> ShutdownHandle {
        ShutdownHandle(self.shutdown.clone())
    }

    /// Serves until [`ShutdownHandle::shutdown`] or SIGTERM/SIGINT, then drains.
    pub async fn run_until_stopped(self) -> std::io::Result<()> {
        let App {
            http,
            grpc,
            service,
            config,
            shutdown,
            http_addr,
            grpc_addr,
            syncer,
        } = self;
        if let Some(syncer) = syncer {
            tokio::spawn(syncer.run(applier(service.clone()), shutdown.clone()));
        }
        let permits = Arc::new(Semaphore::new(config.max_concurrent_requests.max(1)));
        let streams = config.stream_budget();
        let state = AppState::new(AppInner {
            service: service.clone(),
            settings: config.rest_settings(),
            shutdown: shutdown.clone(),
            metrics: crate::telemetry::metrics_handle(),
            permits: permits.clone(),
            streams: streams.clone(),
        });
        service.record_robot_count();
        let router = rest::router(state);
        let on_signal = shutdown.clone();
        tokio::spawn(async move {
            tokio::select! {
                _ = os_signal() => on_signal.cancel(),
                _ = on_signal.cancelled() => {}
            }
        });
        let grpc_server = crate::api::grpc::serve(
            grpc,
            service.clone(),
            config.grpc_settings(),
            permits,
            streams,
            shutdown.clone(),
        );
        let http_server = serve_http(
            http,
            router,
            config.header_timeout,
            config.max_batch_body_bytes,
            shutdown.clone(),
        );
        service.set_ready(true);
        tracing::info!(http = %http_addr, grpc = %grpc_addr, "kinserve serving");
        let svc = service.clone();
        let draining = shutdown.clone();
        tokio::spawn(async move {
            draining.cancelled().await;
            svc.set_ready(false);
            tracing::info!("shutdown requested: draining");
        });
        let both = async { tokio::try_join!(http_server.into_future(), grpc_server) };
        let drain_timeout = config.shutdown_timeout;
        tokio::select! {
            r = both => { r?; }
            _ = async {
                shutdown.cancelled().await;
                tokio::time::sleep(drain_timeout).await;
            } => {
                tracing::warn!("in-flight requests did not finish within the shutdown timeout");
            }
        }
        tracing::info!("kinserve stopped");
        Ok(())
    }
}

/// The API token to require: surrounding whitespace (a newline from a secret
/// file, say) is trimmed with a warning; a token of whitespace only is a
/// start-up error, since nobody could ever present it. Unset: open, warned.
fn api_token(raw: Option<&str>) -> std::io::Result<Option<String>> {
    let Some(raw) = raw.filter(|t| !t.is_empty()) else {
        tracing::warn!(
            "KINSERVE_API_TOKEN is not set: anyone who can reach the server may register and delete robots"
        );
        return Ok(None);
    };
    let trimmed = raw.trim();
    if trimmed.is_empty() {
        return Err(std::io::Error::other(
            "KINSERVE_API_TOKEN is only whitespace: set a real token, or unset it for an open server",
        ));
    }
    if trimmed.len() != raw.len() {
        tracing::warn!(
            "KINSERVE_API_TOKEN has surrounding whitespace (e.g. a trailing newline): it was trimmed"
        );
    }
    Ok(Some(trimmed.to_string()))
}

/// The store `config` asks for: PostgreSQL (with its sync task) when
/// `--database-url` is set, else the file store in the data directory.
async fn open_store(config: &ServeConfig) -> std::io::Result<(Box<dyn Store>, Option<Syncer>)> {
    let Some(url) = &config.database_url else {
        let store =
            FileStore::open(&config.data_dir).map_err(|e| std::io::Error::other(e.to_string()))?;
        return Ok((Box::new(store), None));
    };
    let settings = PgSettings {
        url: url.clone(),
        password_file: config.database_password_file.clone(),
        resync_interval: config.database_resync_interval,
    };
    let store = PgStore::connect(&settings)
        .await
        .map_err(std::io::Error::other)?;
    tracing::info!("registered robots live in the database (the data directory is not used)");
    let syncer = store.syncer(settings.resync_interval);
    Ok((Box::new(store), Some(syncer)))
}

/// Applies the changes the sync task reads to the service's snapshot, and
/// counts them by source (`notify`, `resync`).
fn applier(service: Arc<Service>) -> Applier {
    Arc::new(move |changes, source| {
        let limits = service.limits().model;
        let mut applied = 0u64;
        for change in changes {
            match service.registry().apply(change, &limits) {
                Ok(true) => applied += 1,
                Ok(false) => {}
                Err(e) => tracing::error!(error = %e, "ignoring a robot from the database"),
            }
        }
        if applied > 0 {
            metrics::counter!("kinserve_store_changes_applied_total", "source" => source)
                .increment(applied);
            service.record_robot_count();
        }
    })
}

/// Serves the REST router on `listener` (HTTP/1.1 and h2c, WebSocket upgrades)
/// until `shutdown` turns true, then waits for open connections to finish.
///
/// Unlike `axum::serve`, every connection must deliver its request headers within
/// `header_timeout`: HTTP/1 connections (the first request and every later one on
/// a kept-alive connection) through hyper's header read timeout, and any
/// connection, whatever the protocol, must complete its first request head
/// within that time or it is closed (a client that connects and sends nothing,
/// or a few bytes, holds nothing for long).
///
/// Connections close with a lingering close (see [`Lingering`]), so that a
/// client still sending a body the server refused (503 overloaded, 413 too
/// large) receives the answer instead of a connection reset.
async fn serve_http(
    listener: TcpListener,
    router: Router,
    header_timeout: Duration,
    max_body_bytes: usize,
    shutdown: CancellationToken,
) -> std::io::Result<()> {
    let header_timeout = header_timeout.max(Duration::from_millis(1));
    let mut builder = auto::Builder::new(TokioExecutor::new());
    builder
        .http1()
        .timer(TokioTimer::new())
        .header_read_timeout(header_timeout);
    // CONNECT protocol for WebSockets over HTTP/2; pings so dead h2 peers are noticed.
    builder
        .http2()
        .timer(TokioTimer::new())
        .enable_connect_protocol()
        .keep_alive_interval(Duration::from_secs(30));
    let builder = Arc::new(builder);
    let graceful = GracefulShutdown::new();
    loop {
        let (tcp, _peer) = tokio::select! {
            _ = shutdown.cancelled() => break,
            r = listener.accept() => match r {
                Ok(conn) => conn,
                Err(e) => {
                    accept_error(e).await;
                    continue;
                }
            },
        };
        let _ = tcp.set_nodelay(true);
        // Set by the first request that reaches the router on this connection.
        let seen = Arc::new(AtomicBool::new(false));
        let flag = seen.clone();
        // The connection's open streams (WebSockets), for the per-connection budget.
        let streams = crate::api::budget::ConnectionStreams::default();
        let service = router
            .clone()
            .map_request(move |mut req: axum::http::Request<_>| {
                flag.store(true, Ordering::Release);
                req.extensions_mut().insert(streams.clone());
                req
            });
        let builder = builder.clone();
        let watcher = graceful.watcher();
        tokio::spawn(async move {
            let conn = builder.serve_connection_with_upgrades(
                TokioIo::new(Lingering::new(tcp, max_body_bytes)),
                TowerToHyperService::new(service),
            );
            let mut conn = std::pin::pin!(watcher.watch(conn.into_owned()));
            tokio::select! {
                _ = conn.as_mut() => return,
                _ = tokio::time::sleep(header_timeout) => {}
            }
            if !seen.load(Ordering::Acquire) {
                tracing::debug!("closing a connection that sent no complete request head in time");
                return;
            }
            let _ = conn.await;
        });
    }
    drop(listener);
    graceful.shutdown().await;
    Ok(())
}

/// Longest a closed connection keeps reading what its client still sends.
const LINGER_TIME: Duration = Duration::from_secs(2);

/// A server-side TCP connection with a lingering close.
///
/// When the server answers before reading the whole request body (a request
/// refused with 503 or 413) and then closes, the kernel answers the unread
/// bytes with a reset, which can destroy the answer before the client has read
/// it: the client sees "connection reset" or "broken pipe", not the status.
/// So once a connection that sent something is dropped, its write side is
/// shut down (FIN after the complete answer) and what the client still sends
/// is read and discarded, for at most [`LINGER_TIME`] and `max_bytes`, before
/// the socket is closed. Connections that never sent anything (e.g. closed for
/// a header timeout) close at once.
struct Lingering {
    tcp: Option<tokio::net::TcpStream>,
    wrote: bool,
    max_bytes: usize,
}

impl Lingering {
    fn new(tcp: tokio::net::TcpStream, max_bytes: usize) -> Lingering {
        Lingering {
            tcp: Some(tcp),
            wrote: false,
            max_bytes,
        }
    }

    fn closed() -> std::io::Error {
        std::io::Error::from(std::io::ErrorKind::NotConnected)
    }
}

impl tokio::io::AsyncRead for Lingering {
    fn poll_read(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &mut tokio::io::ReadBuf<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        match self.get_mut().tcp.as_mut() {
            Some(tcp) => std::pin::Pin::new(tcp).poll_read(cx, buf),
            None => std::task::Poll::Ready(Err(Lingering::closed())),
        }
    }
}

impl tokio::io::AsyncWrite for Lingering {
    fn poll_write(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &[u8],
    ) -> std::task::Poll<std::io::Result<usize>> {
        let this = self.get_mut();
        this.wrote = true;
        match this.tcp.as_mut() {
            Some(tcp) => std::pin::Pin::new(tcp).poll_write(cx, buf),
            None => std::task::Poll::Ready(Err(Lingering::closed())),
        }
    }

    fn poll_write_vectored(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> std::task::Poll<std::io::Result<usize>> {
        let this = self.get_mut();
        this.wrote = true;
        match this.tcp.as_mut() {
            Some(tcp) => std::pin::Pin::new(tcp).poll_write_vectored(cx, bufs),
            None => std::task::Poll::Ready(Err(Lingering::closed())),
        }
    }

    fn is_write_vectored(&self) -> bool {
        self.tcp.as_ref().is_some_and(|t| t.is_write_vectored())
    }

    fn poll_flush(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        match self.get_mut().tcp.as_mut() {
            Some(tcp) => std::pin::Pin::new(tcp).poll_flush(cx),
            None => std::task::Poll::Ready(Ok(())),
        }
    }

    fn poll_shutdown(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        match self.get_mut().tcp.as_mut() {
            Some(tcp) => std::pin::Pin::new(tcp).poll_shutdown(cx),
            None => std::task::Poll::Ready(Ok(())),
        }
    }
}

impl Drop for Lingering {
    fn drop(&mut self) {
        let Some(mut tcp) = self.tcp.take() else {
            return;
        };
        if !self.wrote {
            return;
        }
        let Ok(runtime) = tokio::runtime::Handle::try_current() else {
            return;
        };
        let max_bytes = self.max_bytes;
        runtime.spawn(async move {
            use tokio::io::{AsyncReadExt, AsyncWriteExt};
            let _ = tcp.shutdown().await;
            let mut buf = vec![0u8; 16 << 10];
            let mut read = 0usize;
            let _ = tokio::time::timeout(LINGER_TIME, async {
                while read < max_bytes {
                    match tcp.read(&mut buf).await {
                        Ok(0) | Err(_) => break,
                        Ok(n) => read += n,
                    }
                }
            })
            .await;
        });
    }
}

/// Errors of `accept`: a connection that failed before it was accepted is
/// skipped; anything else (e.g. out of file descriptors) is logged and retried
/// after a pause instead of spinning.
async fn accept_error(e: std::io::Error) {
    use std::io::ErrorKind::{ConnectionAborted, ConnectionRefused, ConnectionReset};
    if matches!(
        e.kind(),
        ConnectionAborted | ConnectionRefused | ConnectionReset
    ) {
        return;
    }
    tracing::error!(error = %e, "accept failed; retrying shortly");
    tokio::time::sleep(Duration::from_millis(100)).await;
}

async fn os_signal() {
    #[cfg(unix)]
    {
        let mut term =
            match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                Ok(s) => s,
                Err(_) => {
                    let _ = tokio::signal::ctrl_c().await;
                    return;
                }
            };
        tokio::select! {
            _ = term.recv() => {}
            _ = tokio::signal::ctrl_c() => {}
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}
