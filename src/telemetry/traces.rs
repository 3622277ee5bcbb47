//! The tracing subscriber (its log lines written directly or by a thread of
//! their own, [`LogLines`]), and OpenTelemetry trace export over OTLP when
//! `--otlp-endpoint` is set: configuration, the exporter (gRPC or
//! HTTP/protobuf, batched), the parent-based ratio sampler, and the flush on
//! exit. Without an endpoint no exporter, span buffer or exporter thread
//! exists and the trace spans (target `kinserve::trace`, level DEBUG) are
//! disabled at their call sites. Depends on no other module of the crate.

use std::sync::atomic::{AtomicBool, Ordering};

use opentelemetry::trace::TracerProvider as _;
use opentelemetry_otlp::WithExportConfig;
use opentelemetry_sdk::trace::{Sampler, SdkTracerProvider, SpanData, SpanExporter};
use tracing_subscriber::filter::{EnvFilter, Targets};
use tracing_subscriber::fmt::writer::BoxMakeWriter;
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::{Layer, Registry};

use super::LogFormat;

/// The target of every span sent to the trace exporter.
pub const TARGET: &str = "kinserve::trace";

/// Protocol of the OTLP exporter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum OtlpProtocol {
    /// OTLP/gRPC (the collector's port 4317).
    #[default]
    Grpc,
    /// OTLP/HTTP with protobuf bodies (the collector's port 4318, `/v1/traces`).
    Http,
}

/// Trace export options of `kinserve serve` (flattened into its configuration).
#[derive(Clone, Debug, clap::Args)]
pub struct TraceConfig {
    /// Export OpenTelemetry traces over OTLP to this collector URL
    /// (`http://collector:4317` for grpc, `http://collector:4318` for http,
    /// to which `/v1/traces` is added unless the URL has a path). Unset: no
    /// export, no span buffer, no exporter thread.
    #[arg(long, env = "KINSERVE_OTLP_ENDPOINT")]
    pub otlp_endpoint: Option<String>,
    /// OTLP transport: grpc or http (protobuf).
    #[arg(long, env = "KINSERVE_OTLP_PROTOCOL", value_enum, default_value_t = OtlpProtocol::Grpc)]
    pub otlp_protocol: OtlpProtocol,
    /// Fraction of new traces recorded (0 to 1): requests without a sampled
    /// caller (`traceparent` flag) are kept with this probability; a caller's
    /// decision is always followed (parent-based).
    #[arg(long, env = "KINSERVE_TRACE_SAMPLE_RATIO", default_value_t = 1.0, value_parser = parse_ratio)]
    pub trace_sample_ratio: f64,
}

impl Default for TraceConfig {
    /// No export (the flag defaults).
    fn default() -> Self {
        TraceConfig {
            otlp_endpoint: None,
            otlp_protocol: OtlpProtocol::Grpc,
            trace_sample_ratio: 1.0,
        }
    }
}

fn parse_ratio(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(r) if (0.0..=1.0).contains(&r) => Ok(r),
        _ => Err(format!("not a ratio from 0 to 1: '{s}'")),
    }
}

static EXPORTING: AtomicBool = AtomicBool::new(false);

/// Whether spans are exported (set once at start-up). The adapters check it
/// before any work that only feeds traces (reading `traceparent` into a
/// context, recording attributes), so that with export off it costs one load.
pub fn exporting() -> bool {
    EXPORTING.load(Ordering::Relaxed)
}

/// The installed subscriber's trace exporter and log writer thread;
/// [`Tracing::shutdown`] flushes both.
#[must_use = "call shutdown() before exit to send the spans and log lines still buffered"]
pub struct Tracing {
    provider: Option<SdkTracerProvider>,
    /// Dropped last: writes the log lines still queued ([`LogLines::OffThread`]).
    log_writer: Option<tracing_appender::non_blocking::WorkerGuard>,
}

impl Tracing {
    /// Sends the spans still buffered (waits up to the exporter timeout) and
    /// stops the exporter thread, then writes the log lines still queued and
    /// stops the writer thread. Call it outside the runtime's worker threads
    /// while the runtime still runs; log nothing after it.
    pub fn shutdown(self) {
        if let Some(provider) = self.provider
            && let Err(e) = provider.shutdown()
        {
            eprintln!("kinserve: flushing the trace exporter failed: {e}");
        }
        drop(self.log_writer);
    }
}

/// Installs the global subscriber: log lines as `format` (level from
/// `RUST_LOG`, default `info`) written as `lines` says, and, with `config.otlp_endpoint`, the
/// OpenTelemetry layer exporting the `kinserve::trace` spans. `runtime`
/// runs the exporter's network I/O. Later calls install nothing.
pub fn init(
    format: LogFormat,
    lines: LogLines,
    config: &TraceConfig,
    runtime: Option<&tokio::runtime::Handle>,
) -> Result<Tracing, String> {
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    // Colour codes only when a person reads the terminal, never into files or pipes.
    let ansi = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let (writer, log_writer) = match lines {
        LogLines::OffThread => {
            let (w, guard) = off_thread_writer();
            (BoxMakeWriter::new(w), Some(guard))
        }
        LogLines::Direct => (BoxMakeWriter::new(std::io::stderr), None),
    };
    let fmt = tracing_subscriber::fmt::layer()
        .with_ansi(ansi)
        .with_writer(writer);
    let fmt = match format {
        LogFormat::Human => fmt.boxed(),
        LogFormat::Json => fmt.json().flatten_event(true).boxed(),
    };
    let provider = match &config.otlp_endpoint {
        Some(endpoint) => {
            let runtime = runtime.ok_or("trace export needs a tokio runtime")?;
            Some(provider(endpoint, config, runtime)?)
        }
        None => None,
    };
    let otel = provider.as_ref().map(|p| {
        tracing_opentelemetry::layer()
            .with_tracer(p.tracer("kinserve"))
            .with_location(false)
            .with_threads(false)
            .with_filter(Targets::new().with_target(TARGET, tracing::Level::DEBUG))
    });
    let installed = Registry::default()
        .with(fmt.with_filter(filter))
        .with(otel)
        .try_init()
        .is_ok();
    if !installed {
        // Another subscriber (an embedding program's) is in charge: export nothing.
        if let Some(p) = provider {
            let _ = p.shutdown();
        }
        return Ok(Tracing {
            provider: None,
            log_writer: None,
        });
    }
    EXPORTING.store(provider.is_some(), Ordering::Relaxed);
    match &config.otlp_endpoint {
        Some(endpoint) => tracing::info!(
            endpoint = %endpoint,
            protocol = ?config.otlp_protocol,
            sample_ratio = config.trace_sample_ratio,
            "trace export on: OTLP"
        ),
        None => tracing::info!("trace export off (no --otlp-endpoint)"),
    }
    Ok(Tracing {
        provider,
        log_writer,
    })
}

/// How log lines reach stderr.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogLines {
    /// Queued to a thread of their own that writes them (batched while busy,
    /// flushed when the queue is empty), so a request never waits for a
    /// `write` to stderr: the server. Each request's worker writing its own
    /// access-log line stalled every request behind a stalled stderr pipe,
    /// and the line cost 12 % of REST FK throughput and 19 % of `/healthz`'s
    /// (wrk, 64 connections, access log on against off); off the worker,
    /// about half of that came back (the line is still formatted there).
    /// Up to [`LOG_QUEUE_LINES`] lines wait; past that, lines are dropped
    /// and counted (`kinserve_log_lines_dropped_total`).
    OffThread,
    /// Written by the thread that logs (one-shot commands).
    Direct,
}

/// Log lines that may wait for the writer thread (~200 bytes each).
pub const LOG_QUEUE_LINES: usize = 65_536;

/// Lines dropped because the queue was full (see [`LogLines::OffThread`]).
static DROPPED: std::sync::OnceLock<tracing_appender::non_blocking::ErrorCounter> =
    std::sync::OnceLock::new();

/// Log lines dropped so far because the writer thread fell behind.
pub fn log_lines_dropped() -> u64 {
    DROPPED.get().map_or(0, |c| c.dropped_lines() as u64)
}

fn off_thread_writer() -> (
    tracing_appender::non_blocking::NonBlocking,
    tracing_appender::non_blocking::WorkerGuard,
) {
    let (writer, guard) = tracing_appender::non_blocking::NonBlockingBuilder::default()
        .buffered_lines_limit(LOG_QUEUE_LINES)
        .lossy(true)
        .thread_name("kinserve-log")
        .finish(std::io::BufWriter::new(std::io::stderr()));
    let _ = DROPPED.set(writer.error_counter());
    (writer, guard)
}

/// The tracer provider: the OTLP exporter behind the batch processor (its
/// queue and thread; `OTEL_BSP_*` variables tune them), the sampler, and the
/// resource (`service.name` kinserve unless `OTEL_SERVICE_NAME` says otherwise).
fn provider(
    endpoint: &str,
    config: &TraceConfig,
    runtime: &tokio::runtime::Handle,
) -> Result<SdkTracerProvider, String> {
    if !endpoint.starts_with("http://") {
        return Err(format!(
            "--otlp-endpoint {endpoint}: give an http:// URL (the exporter is built without TLS: \
             send to a collector on the same host or pod, which forwards over TLS)"
        ));
    }
    // The tonic channel spawns its worker on the runtime it is built in.
    let _entered = runtime.enter();
    let exporter = match config.otlp_protocol {
        OtlpProtocol::Grpc => opentelemetry_otlp::SpanExporter::builder()
            .with_tonic()
            .with_endpoint(endpoint)
            .build(),
        OtlpProtocol::Http => opentelemetry_otlp::SpanExporter::builder()
            .with_http()
            .with_protocol(opentelemetry_otlp::Protocol::HttpBinary)
            .with_endpoint(http_traces_url(endpoint))
            .build(),
    }
    .map_err(|e| format!("--otlp-endpoint {endpoint}: {e}"))?;
    let exporter = OnRuntime {
        inner: std::sync::Arc::new(exporter),
        runtime: runtime.clone(),
    };
    let mut resource = opentelemetry_sdk::Resource::builder();
    if std::env::var_os("OTEL_SERVICE_NAME").is_none() {
        resource = resource.with_service_name("kinserve");
    }
    Ok(SdkTracerProvider::builder()
        .with_batch_exporter(exporter)
        .with_sampler(Sampler::ParentBased(Box::new(Sampler::TraceIdRatioBased(
            config.trace_sample_ratio,
        ))))
        .with_resource(resource.build())
        .build())
}

/// The OTLP/HTTP URL of traces: `endpoint` itself when it has a path, else
/// `endpoint/v1/traces` (the collector's default).
///
/// ```
/// use kinserve::telemetry::traces::http_traces_url;
/// assert_eq!(http_traces_url("http://otel:4318"), "http://otel:4318/v1/traces");
/// assert_eq!(http_traces_url("http://otel:4318/"), "http://otel:4318/v1/traces");
/// assert_eq!(http_traces_url("https://o.example/x/traces"), "https://o.example/x/traces");
/// ```
pub fn http_traces_url(endpoint: &str) -> String {
    let after_scheme = endpoint.split_once("://").map_or(endpoint, |(_, r)| r);
    match after_scheme.find('/') {
        Some(i) if after_scheme.len() > i + 1 => endpoint.to_string(),
        _ => format!("{}/v1/traces", endpoint.trim_end_matches('/')),
    }
}

/// An exporter whose exports run as tasks on the tokio runtime: the batch
/// processor calls it from its own thread, where the HTTP client's timers
/// and sockets (and tonic's) would find no reactor.
#[derive(Debug)]
struct OnRuntime<E> {
    inner: std::sync::Arc<E>,
    runtime: tokio::runtime::Handle,
}

impl<E: SpanExporter + 'static> SpanExporter for OnRuntime<E> {
    async fn export(&self, batch: Vec<SpanData>) -> opentelemetry_sdk::error::OTelSdkResult {
        let inner = self.inner.clone();
        match self
            .runtime
            .spawn(async move { inner.export(batch).await })
            .await
        {
            Ok(result) => result,
            Err(e) => Err(opentelemetry_sdk::error::OTelSdkError::InternalFailure(
                e.to_string(),
            )),
        }
    }

    fn shutdown_with_timeout(
        &self,
        timeout: std::time::Duration,
    ) -> opentelemetry_sdk::error::OTelSdkResult {
        self.inner.shutdown_with_timeout(timeout)
    }

    fn force_flush(&self) -> opentelemetry_sdk::error::OTelSdkResult {
        self.inner.force_flush()
    }

    fn set_resource(&mut self, resource: &opentelemetry_sdk::Resource) {
        if let Some(inner) = std::sync::Arc::get_mut(&mut self.inner) {
            inner.set_resource(resource);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_ratios_outside_zero_to_one_are_refused() {
        assert_eq!(parse_ratio("0.25"), Ok(0.25));
        assert_eq!(parse_ratio("1"), Ok(1.0));
        for bad in ["-0.1", "1.5", "NaN", "half"] {
            assert!(parse_ratio(bad).is_err(), "{bad}");
        }
    }
}
