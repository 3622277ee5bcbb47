//! Per-call gRPC metrics as a tower layer around the tonic server:
//! `kinserve_grpc_requests_total{method, code}` and
//! `kinserve_grpc_request_duration_seconds{method}`. The method label is one
//! of the RPCs the server serves (read from the descriptor sets once), or
//! `other`, so a client cannot grow the label set. The code is the
//! `grpc-status` of a trailers-only answer (every error and every refusal)
//! and `OK` otherwise.

use std::collections::HashSet;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Instant;

use prost::Message;
use tonic::codegen::http;
use tower::{Layer, Service};

/// The layer; build it with [`GrpcMetricsLayer::new`].
#[derive(Clone, Debug)]
pub struct GrpcMetricsLayer {
    methods: Arc<HashSet<String>>,
    access_log: bool,
}

impl GrpcMetricsLayer {
    /// Labels the methods of the services in `descriptor_sets` (encoded
    /// `FileDescriptorSet`s) by name; with `access_log`, also writes one
    /// access-log line per call (target `kinserve::access`).
    pub fn new(access_log: bool, descriptor_sets: &[&[u8]]) -> GrpcMetricsLayer {
        let mut methods = HashSet::new();
        for bytes in descriptor_sets {
            let Ok(set) = prost_types::FileDescriptorSet::decode(*bytes) else {
                continue;
            };
            for file in &set.file {
                for service in &file.service {
                    for m in &service.method {
                        methods.insert(format!(
                            "/{}.{}/{}",
                            file.package(),
                            service.name(),
                            m.name()
                        ));
                    }
                }
            }
        }
        GrpcMetricsLayer {
            methods: Arc::new(methods),
            access_log,
        }
    }
}

impl<S> Layer<S> for GrpcMetricsLayer {
    type Service = GrpcMetrics<S>;
    fn layer(&self, inner: S) -> GrpcMetrics<S> {
        GrpcMetrics {
            inner,
            methods: self.methods.clone(),
            access_log: self.access_log,
        }
    }
}

/// The service the layer wraps around the server.
#[derive(Clone, Debug)]
pub struct GrpcMetrics<S> {
    inner: S,
    methods: Arc<HashSet<String>>,
    access_log: bool,
}

type BoxFuture<T, E> = Pin<Box<dyn Future<Output = Result<T, E>> + Send>>;

impl<S, B, RB> Service<http::Request<B>> for GrpcMetrics<S>
where
    S: Service<http::Request<B>, Response = http::Response<RB>>,
    S::Future: Send + 'static,
    S::Error: 'static,
    RB: 'static,
{
    type Response = S::Response;
    type Error = S::Error;
    type Future = BoxFuture<S::Response, S::Error>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), S::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, req: http::Request<B>) -> Self::Future {
        let path = req.uri().path();
        let method = if self.methods.contains(path) {
            path.rsplit('/').next().unwrap_or("other").to_string()
        } else {
            "other".to_string()
        };
        let start = Instant::now();
        let access_log = self.access_log;
        let trace_id = req
            .extensions()
            .get::<crate::telemetry::w3c::TraceId>()
            .copied();
        let fut = self.inner.call(req);
        Box::pin(async move {
            let result = fut.await;
            if let Ok(resp) = &result {
                let code = resp
                    .headers()
                    .get("grpc-status")
                    .and_then(|v| v.to_str().ok())
                    .and_then(|v| v.parse::<i32>().ok())
                    .unwrap_or(0);
                if code == 8 {
                    crate::telemetry::log_overload(
                        crate::telemetry::Overload::GrpcResourceExhausted,
                    );
                }
                let code = code_name(code);
                if access_log {
                    tracing::info!(
                        target: "kinserve::access",
                        protocol = "grpc",
                        method = %method,
                        code,
                        duration_ms = start.elapsed().as_secs_f64() * 1e3,
                        trace_id = trace_id.map(tracing::field::display),
                        client_cert = crate::tls::peer::current_subject().as_deref(),
                        "call"
                    );
                }
                metrics::counter!("kinserve_grpc_requests_total", "method" => method.clone(), "code" => code)
                    .increment(1);
                metrics::histogram!("kinserve_grpc_request_duration_seconds", "method" => method)
                    .record(start.elapsed().as_secs_f64());
            }
            result
        })
    }
}

/// The canonical name of a gRPC status code (`OK`, `INVALID_ARGUMENT`, ...).
fn code_name(code: i32) -> &'static str {
    const NAMES: [&str; 17] = [
        "OK",
        "CANCELLED",
        "UNKNOWN",
        "INVALID_ARGUMENT",
        "DEADLINE_EXCEEDED",
        "NOT_FOUND",
        "ALREADY_EXISTS",
        "PERMISSION_DENIED",
        "RESOURCE_EXHAUSTED",
        "FAILED_PRECONDITION",
        "ABORTED",
        "OUT_OF_RANGE",
        "UNIMPLEMENTED",
        "INTERNAL",
        "UNAVAILABLE",
        "DATA_LOSS",
        "UNAUTHENTICATED",
    ];
    usize::try_from(code)
        .ok()
        .and_then(|i| NAMES.get(i))
        .copied()
        .unwrap_or("UNKNOWN")
}
