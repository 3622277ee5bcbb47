//! Building and running the server: binds both listeners (port 0 works), loads
//! robots, serves until a shutdown signal, then drains gracefully.

mod http_server;

use std::net::SocketAddr;
use std::sync::Arc;

use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

pub use http_server::HttpServerSettings;

use crate::api::budget::{Budgets, ConnectionSlots};
use crate::api::rest::{self, AppInner, AppState};
use crate::compute::{FairBudget, share_of};
use crate::config::ServeConfig;
use crate::registry::postgres::sync::{Applier, Syncer};
use crate::registry::postgres::{PgSettings, PgStore};
use crate::registry::{FileStore, Registry, Store};
use crate::service::{Service, WriteAccess};

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
    tls: Option<crate::tls::TlsServer>,
}

/// Triggers a graceful shutdown of a running [`App`].
#[derive(Clone, Debug)]
pub struct ShutdownHandle(CancellationToken);

impl ShutdownHandle {
    /// Starts the graceful shutdown: readiness flips at once, requests are
    /// served as usual for the shutdown grace period, then the listeners close,
    /// streams close and in-flight requests finish.
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
        let tls = crate::tls::TlsServer::load(&config.tls).map_err(std::io::Error::other)?;
        let (store, syncer) = open_store(&config).await?;
        let registry = Registry::new(store).with_max_registered(config.max_robots);
        let writes = write_access(
            config.api_token.as_deref(),
            config.allow_unauthenticated_writes,
        )?;
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
        let service = Arc::new(Service::new(registry, limits, writes));
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
            tls,
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
            tls,
        } = self;
        // `shutdown`: the drain starts (not ready); `stop`: the listeners close.
        let stop = CancellationToken::new();
        if let Some(syncer) = syncer {
            tokio::spawn(syncer.run(applier(service.clone()), stop.clone()));
        }
        if let Some(tls) = &tls {
            tokio::spawn(
                tls.clone()
                    .watch(config.tls.tls_reload_interval, stop.clone()),
            );
        }
        let permits = FairBudget::new(
            "requests in flight",
            "--max-concurrent-requests",
            config.max_concurrent_requests,
            share_of(config.max_concurrent_requests, config.client_share_percent),
        );
        let streams = config.stream_budget();
        let request_bytes = config.request_byte_budget();
        let connections = ConnectionSlots::new(config.max_connections);
        let state = AppState::new(AppInner {
            service: service.clone(),
            settings: config.rest_settings(),
            shutdown: stop.clone(),
            metrics: crate::telemetry::metrics_handle(),
            permits: permits.clone(),
            streams: streams.clone(),
            request_bytes: request_bytes.clone(),
        });
        service.record_robot_count();
        let router = rest::router(state);
        // SIGTERM / Ctrl-C starts the drain; a second one during it stops at once.
        let (on_signal, now) = (shutdown.clone(), CancellationToken::new());
        let (stop_now, abort) = (stop.clone(), now.clone());
        tokio::spawn(async move {
            tokio::select! {
                _ = os_signal() => on_signal.cancel(),
                _ = on_signal.cancelled() => {}
            }
            os_signal().await;
            tracing::warn!("a second signal: stopping now, without waiting for in-flight requests");
            stop_now.cancel();
            abort.cancel();
        });
        let grpc_server = crate::api::grpc::serve(
            grpc,
            service.clone(),
            config.grpc_settings(),
            Budgets {
                permits,
                streams,
                request_bytes,
                connections: connections.clone(),
            },
            crate::api::grpc::Lifecycle {
                draining: shutdown.clone(),
                stop: stop.clone(),
            },
            tls.as_ref().map(|t| t.grpc(config.header_timeout)),
        );
        let http_server = http_server::serve_http(
            http,
            router,
            HttpServerSettings {
                header_timeout: config.header_timeout,
                write_timeout: config.write_timeout,
                linger_timeout: config.linger_timeout,
            },
            connections,
            tls.as_ref().map(|t| t.rest(config.header_timeout)),
            stop.clone(),
        );
        service.set_ready(true);
        tracing::info!(http = %http_addr, grpc = %grpc_addr, "kinserve serving");
        tokio::spawn(drain(
            service.clone(),
            shutdown.clone(),
            stop.clone(),
            config.shutdown_grace,
        ));
        let both = async { tokio::try_join!(http_server, grpc_server) };
        let drain_timeout = config.shutdown_timeout;
        tokio::select! {
            r = both => { r?; }
            _ = async {
                stop.cancelled().await;
                tokio::time::sleep(drain_timeout).await;
            } => {
                tracing::warn!("in-flight requests did not finish within the shutdown timeout");
            }
            _ = now.cancelled() => {}
        }
        tracing::info!("kinserve stopped");
        Ok(())
    }
}

/// The drain: once `shutdown` is asked for, readiness turns false (`/readyz`
/// 503, gRPC health NOT_SERVING) while everything else is served as usual for
/// `grace`, so that load balancers take the instance out before its
/// listeners close; then `stop` closes them.
async fn drain(
    service: Arc<Service>,
    shutdown: CancellationToken,
    stop: CancellationToken,
    grace: std::time::Duration,
) {
    tokio::select! {
        _ = shutdown.cancelled() => {}
        _ = stop.cancelled() => return,
    }
    service.set_ready(false);
    tracing::info!(
        grace_seconds = grace.as_secs_f64(),
        "shutdown requested: not ready; serving until the grace period ends"
    );
    tokio::time::sleep(grace).await;
    tracing::info!("closing the listeners; draining in-flight requests");
    stop.cancel();
}

/// Who may change the registry: holders of the API token, whose surrounding
/// whitespace (a newline from a secret file, say) is trimmed with a warning;
/// a token of whitespace only is a start-up error, since nobody could ever
/// present it. No token: nobody (a read-only registry), or anyone with
/// `allow_unauthenticated` (warned).
fn write_access(raw: Option<&str>, allow_unauthenticated: bool) -> std::io::Result<WriteAccess> {
    let Some(raw) = raw.filter(|t| !t.is_empty()) else {
        if allow_unauthenticated {
            tracing::warn!(
                "KINSERVE_API_TOKEN is not set and --allow-unauthenticated-writes is on: anyone who can reach the server may register and delete robots"
            );
            return Ok(WriteAccess::Open);
        }
        tracing::info!(
            "KINSERVE_API_TOKEN is not set: the registry is read-only (set a token to register robots)"
        );
        return Ok(WriteAccess::Closed);
    };
    let trimmed = raw.trim();
    if trimmed.is_empty() {
        return Err(std::io::Error::other(
            "KINSERVE_API_TOKEN is only whitespace: set a real token, or unset it for a read-only registry",
        ));
    }
    if trimmed.len() != raw.len() {
        tracing::warn!(
            "KINSERVE_API_TOKEN has surrounding whitespace (e.g. a trailing newline): it was trimmed"
        );
    }
    Ok(WriteAccess::Token(trimmed.to_string()))
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
        ca_file: config.tls.database_ca_file.clone(),
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
