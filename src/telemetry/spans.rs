//! Server spans and W3C trace context at the front doors: the REST
//! middleware ([`rest_request`], WebSocket upgrades included) and the gRPC layer
//! ([`GrpcTraceLayer`]) read `traceparent`/`tracestate`, open the request's
//! server span as the caller's child, put the trace id in the request's
//! extensions for the access log, and answer the server span's
//! `traceparent` (and the caller's `tracestate`). With export off the REST
//! router leaves the middleware out (its access log reads the caller's trace
//! id itself) and the gRPC layer only reads the caller's trace id for the
//! access log (no allocation, no span).
//! Also the helpers the service uses to name the robot and the batch size on
//! the request span. Depends on `traces` and `w3c` only (not on an adapter).

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};

use axum::extract::{MatchedPath, Request};
use axum::http::{self, HeaderMap, HeaderName, HeaderValue};
use axum::middleware::Next;
use axum::response::Response;
use opentelemetry::propagation::{Extractor, TextMapPropagator};
use opentelemetry::trace::TraceContextExt;
use opentelemetry_sdk::propagation::TraceContextPropagator;
use tracing::Instrument;
use tracing::field::Empty;
use tracing_opentelemetry::OpenTelemetrySpanExt;

use super::traces::exporting;
use super::w3c::{TraceId, TraceParent};

/// `traceparent` (W3C Trace Context).
pub const TRACEPARENT: HeaderName = HeaderName::from_static("traceparent");
/// `tracestate` (W3C Trace Context).
pub const TRACESTATE: HeaderName = HeaderName::from_static("tracestate");

/// A span of the trace exporter (target `kinserve::trace`, level DEBUG):
/// disabled, and free, unless `--otlp-endpoint` is set.
#[macro_export]
#[doc(hidden)]
macro_rules! trace_span {
    ($($t:tt)*) => { ::tracing::debug_span!(target: "kinserve::trace", $($t)*) };
}

/// Names the robot on the current request span (`kinserve.robot`); nothing
/// with export off. Called once per request by the robot look-up, not per pose.
pub fn record_robot(name: &str) {
    if exporting() {
        tracing::Span::current().record("kinserve.robot", name);
    }
}

/// Records the batch size (configurations or targets) on the current request span.
pub fn record_batch_size(n: usize) {
    if exporting() {
        // Integers reach OpenTelemetry as integers only as i64.
        tracing::Span::current()
            .record("kinserve.batch_size", i64::try_from(n).unwrap_or(i64::MAX));
    }
}

/// A `HeaderMap` as the propagator reads it.
struct Headers<'a>(&'a HeaderMap);

impl Extractor for Headers<'_> {
    fn get(&self, key: &str) -> Option<&str> {
        self.0.get(key).and_then(|v| v.to_str().ok())
    }
    fn keys(&self) -> Vec<&str> {
        self.0.keys().map(HeaderName::as_str).collect()
    }
}

/// The trace context a server span answers with.
struct Answer {
    traceparent: HeaderValue,
    tracestate: Option<HeaderValue>,
}

impl Answer {
    fn write(self, headers: &mut HeaderMap) {
        headers.insert(TRACEPARENT, self.traceparent);
        if let Some(state) = self.tracestate {
            headers.insert(TRACESTATE, state);
        }
    }
}

/// Makes `span` the child of the caller's span (when `headers` carry a
/// valid `traceparent`) and starts it; its trace id and answer headers.
fn start(span: &tracing::Span, headers: &HeaderMap) -> Option<(TraceId, Answer)> {
    let parent = TraceContextPropagator::new().extract(&Headers(headers));
    let _ = span.set_parent(parent);
    let cx = span.context();
    let sc = cx.span().span_context().clone();
    if !sc.is_valid() {
        return None;
    }
    let tp = TraceParent {
        trace_id: sc.trace_id().to_bytes(),
        span_id: sc.span_id().to_bytes(),
        flags: sc.trace_flags().to_u8(),
    };
    let traceparent = HeaderValue::from_bytes(&tp.encode()).ok()?;
    let state = sc.trace_state().header();
    let tracestate = (!state.is_empty())
        .then(|| HeaderValue::from_str(&state).ok())
        .flatten();
    Some((
        TraceId(tp.trace_id),
        Answer {
            traceparent,
            tracestate,
        },
    ))
}

/// The caller's trace id, from a valid `traceparent` (export off: the access log's only source).
pub fn caller_trace_id(headers: &HeaderMap) -> Option<TraceId> {
    let v = headers.get(TRACEPARENT)?;
    TraceParent::parse(v.as_bytes()).map(|tp| TraceId(tp.trace_id))
}

/// REST middleware (innermost of the request-id layers, outside the access
/// log): the server span of the request, `POST /v1/robots/{name}/fk`.
pub async fn rest_request(mut req: Request, next: Next) -> Response {
    if !exporting() {
        return next.run(req).await;
    }
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map_or("unmatched", MatchedPath::as_str);
    let request_id = req
        .headers()
        .get("x-request-id")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    let span = crate::trace_span!(
        "request",
        otel.name = %format_args!("{} {route}", req.method()),
        otel.kind = "server",
        otel.status_code = Empty,
        http.request.method = %req.method(),
        http.route = route,
        http.response.status_code = Empty,
        request_id,
        kinserve.robot = Empty,
        kinserve.batch_size = Empty,
    );
    let answer = start(&span, req.headers()).map(|(id, answer)| {
        req.extensions_mut().insert(id);
        answer
    });
    let mut resp = next.run(req).instrument(span.clone()).await;
    let status = resp.status().as_u16();
    span.record("http.response.status_code", i64::from(status));
    if status >= 500 {
        span.record("otel.status_code", "error");
    }
    if let Some(answer) = answer {
        answer.write(resp.headers_mut());
    }
    resp
}

/// The span of a stream (WebSocket or gRPC) after its request: the
/// request span's child, ending when the stream does. One per stream,
/// none per message.
pub fn stream_span(protocol: &'static str) -> tracing::Span {
    crate::trace_span!("stream", protocol)
}

// ---------------------------------------------------------------- gRPC

/// The gRPC server layer: one server span per call (`rpc.method`), the
/// caller's context from the metadata, the server span's `traceparent` in
/// the response metadata. Place it outside the metrics layer (which writes
/// the access log).
#[derive(Clone, Copy, Debug, Default)]
pub struct GrpcTraceLayer;

impl<S> tower::Layer<S> for GrpcTraceLayer {
    type Service = GrpcTrace<S>;
    fn layer(&self, inner: S) -> GrpcTrace<S> {
        GrpcTrace { inner }
    }
}

/// The service [`GrpcTraceLayer`] wraps around the server.
#[derive(Clone, Debug)]
pub struct GrpcTrace<S> {
    inner: S,
}

type Boxed<T, E> = Pin<Box<dyn Future<Output = Result<T, E>> + Send>>;

impl<S, B, RB> tower::Service<http::Request<B>> for GrpcTrace<S>
where
    S: tower::Service<http::Request<B>, Response = http::Response<RB>>,
    S::Future: Send + 'static,
    S::Error: 'static,
    RB: 'static,
{
    type Response = S::Response;
    type Error = S::Error;
    type Future = futures_util::future::Either<S::Future, Boxed<S::Response, S::Error>>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), S::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, mut req: http::Request<B>) -> Self::Future {
        use futures_util::future::Either;
        if !exporting() {
            if let Some(id) = caller_trace_id(req.headers()) {
                req.extensions_mut().insert(id);
            }
            return Either::Left(self.inner.call(req));
        }
        let path = req.uri().path();
        let name = path.strip_prefix('/').unwrap_or(path);
        let name = name.get(..name.len().min(128)).unwrap_or("grpc");
        let (service, method) = name.split_once('/').unwrap_or((name, ""));
        let span = crate::trace_span!(
            "request",
            otel.name = name,
            otel.kind = "server",
            otel.status_code = Empty,
            rpc.system = "grpc",
            rpc.service = service,
            rpc.method = method,
            rpc.grpc.status_code = Empty,
            kinserve.robot = Empty,
            kinserve.batch_size = Empty,
        );
        let answer = start(&span, req.headers()).map(|(id, answer)| {
            req.extensions_mut().insert(id);
            answer
        });
        let fut = {
            let _entered = span.enter();
            self.inner.call(req)
        };
        Either::Right(Box::pin(async move {
            let mut result = fut.instrument(span.clone()).await;
            if let Ok(resp) = &mut result {
                // A trailers-only answer (every error) carries its status here.
                let code = resp
                    .headers()
                    .get("grpc-status")
                    .and_then(|v| v.to_str().ok())
                    .and_then(|v| v.parse::<i64>().ok())
                    .unwrap_or(0);
                span.record("rpc.grpc.status_code", code);
                if matches!(code, 2 | 4 | 12 | 13 | 14 | 15) {
                    span.record("otel.status_code", "error");
                }
                if let Some(answer) = answer {
                    answer.write(resp.headers_mut());
                }
            }
            result
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_callers_trace_id_is_read_from_a_valid_traceparent_only() {
        let mut h = HeaderMap::new();
        assert_eq!(caller_trace_id(&h), None);
        h.insert(
            TRACEPARENT,
            HeaderValue::from_static("00-4bf92f3577b34da6a3ce929d0e0e4736-00f067aa0ba902b7-01"),
        );
        assert_eq!(
            caller_trace_id(&h).map(|t| t.to_string()).as_deref(),
            Some("4bf92f3577b34da6a3ce929d0e0e4736")
        );
        h.insert(TRACEPARENT, HeaderValue::from_static("garbage"));
        assert_eq!(caller_trace_id(&h), None);
    }
}
