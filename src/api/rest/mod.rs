//! The REST adapter (axum): routes, middleware, OpenAPI document and docs page.

mod binary;
pub mod body_budget;
mod buffered;
pub mod conn;
mod dto;
mod export;
mod extract;
mod handlers;
mod ik;
mod import;
mod jacobian;
mod openapi;
pub mod ops;
mod playground;
pub mod problem;
mod routes;
mod streamed;
mod strict;
mod ws;

use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::Router;
use axum::extract::{MatchedPath, Request, State};
use axum::http::{HeaderValue, Method, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use metrics::SharedString;
use metrics_exporter_prometheus::PrometheusHandle;
use tokio_util::sync::CancellationToken;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::cors::{AllowOrigin, Any, CorsLayer};
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::trace::TraceLayer;
use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::{Modify, OpenApi};
use utoipa_swagger_ui::SwaggerUi;

pub use body_budget::{ByteBudget, Reservation, RestBudgets};
pub use conn::ConnActivity;
pub use dto::{
    FkBatchRequest, FkRequest, JacobianBatchRequest, JacobianRequest, JointsRequest, RobotList,
    RobotSummaryDto, WsRequest,
};
pub use export::{PLANAR_CLOSED_FORM_EXAMPLE, PLANAR_URDF_EXAMPLE};
pub use extract::{Client, PeerAddr};
pub use problem::{ApiError, Problem, ProblemField};

use crate::compute::{ClientId, FairBudget, share_of};
use crate::error::Error;
use crate::service::Service;
use crate::telemetry::w3c::TraceId;

/// What every handler can reach; cloning it is one reference-count increment.
#[derive(Clone)]
pub struct AppState(Arc<Shared>);

struct Shared {
    inner: AppInner,
    budgets: RestBudgets,
}

impl AppState {
    /// Wraps the shared parts; the byte budgets are sized by its settings.
    pub fn new(inner: AppInner) -> AppState {
        let budgets = RestBudgets {
            request: inner.request_bytes.clone(),
            response: ByteBudget::new(inner.settings.max_buffered_response_bytes),
            batch_slots: FairBudget::new(
                "batch requests under way",
                "--max-concurrent-batches",
                inner.settings.max_concurrent_batches,
                share_of(
                    inner.settings.max_concurrent_batches,
                    inner.settings.client_share_percent,
                ),
            ),
        };
        AppState(Arc::new(Shared { inner, budgets }))
    }

    /// The request and response byte budgets.
    pub fn budgets(&self) -> &RestBudgets {
        &self.0.budgets
    }
}

impl std::ops::Deref for AppState {
    type Target = AppInner;
    fn deref(&self) -> &AppInner {
        &self.0.inner
    }
}

/// What the REST adapter is configured with (start-up builds it from the
/// command line; the adapter never sees the command line itself).
#[derive(Clone, Debug)]
pub struct RestSettings {
    /// Largest request body in bytes (all routes but batch); also the largest WebSocket message.
    pub max_body_bytes: usize,
    /// Largest batch request body in bytes.
    pub max_batch_body_bytes: usize,
    /// Longest time a request may take.
    pub request_timeout: Duration,
    /// Longest wait for the next piece of a request body (408 past it).
    pub body_timeout: Duration,
    /// Most bytes of (large) answers waiting to be written at once (503 past it).
    pub max_buffered_response_bytes: usize,
    /// Most batch requests (`…/batch`) under way at once; more wait their
    /// turn, except that a client holding its share is refused at once.
    pub max_concurrent_batches: usize,
    /// Percent of every budget one client may hold.
    pub client_share_percent: u8,
    /// Whether the last `X-Forwarded-For` address names the client (the
    /// peer is the operator's proxy).
    pub trust_forwarded_for: bool,
    /// A WebSocket that makes no progress in either direction (no data
    /// message from the client, no reply taken by it) for this long is closed.
    pub stream_idle_timeout: Duration,
    /// A WebSocket whose client has sent no data message this long after
    /// the upgrade is closed (at most the idle timeout).
    pub stream_first_message_timeout: Duration,
    /// Allowed CORS origins; empty: any origin.
    pub cors_origins: Vec<String>,
    /// One access-log line per request (target `kinserve::access`).
    pub access_log: bool,
}

/// The parts of [`AppState`].
pub struct AppInner {
    /// The shared service.
    pub service: Arc<Service>,
    /// Limits, timeouts and CORS.
    pub settings: RestSettings,
    /// Cancelled when shutdown starts (streams close).
    pub shutdown: CancellationToken,
    /// Prometheus exposition.
    pub metrics: PrometheusHandle,
    /// Admission control: one permit per request in flight, a share per client.
    pub permits: FairBudget,
    /// Open WebSockets (shared with gRPC streams); a WebSocket holds a slot, not a request permit.
    pub streams: crate::api::budget::StreamBudget,
    /// Request bytes buffered at once (bodies read before a permit), one
    /// budget with the gRPC adapter's undecoded messages.
    pub request_bytes: ByteBudget,
}

struct SecurityAddon;

impl Modify for SecurityAddon {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
        );
    }
}

/// The parts of the OpenAPI 3.1 document that no route declares: its info,
/// the WebSocket message schemas and the security scheme. The paths come
/// from the routes (see [`routes`]); [`openapi`] is the whole document.
#[derive(OpenApi)]
#[openapi(
    info(title = "kinserve", description = "Forward, velocity and inverse kinematics of serial robots (Denavit–Hartenberg tables)."),
    components(schemas(WsRequest, dto::WsReply, dto::WsJacobian, dto::WsIk)),
    modifiers(&SecurityAddon)
)]
struct ApiDoc;

/// The OpenAPI 3.1 document of the REST API, as `/openapi.json` serves it.
pub fn openapi() -> utoipa::openapi::OpenApi {
    routes::document()
}

/// Prometheus metrics in text exposition format.
#[utoipa::path(get, path = "/metrics", tag = "operations", responses((status = 200,
    description = "Prometheus text exposition format: every family has # HELP and # TYPE lines",
    content_type = "text/plain",
    example = "# HELP kinserve_robots Robots in the registry, by source.\n# TYPE kinserve_robots gauge\nkinserve_robots{source=\"builtin\"} 19\n")))]
async fn metrics_text(State(state): State<AppState>) -> Response {
    crate::telemetry::update_process_metrics();
    let store = state.service.registry().store_health();
    crate::telemetry::record_store_health(store.kind, store.up, store.snapshot_age);
    (
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("text/plain; version=0.0.4"),
        )],
        state.metrics.render(),
    )
        .into_response()
}

/// Whether a request announces a body (which an early refusal leaves unread).
pub(crate) fn has_body(headers: &header::HeaderMap) -> bool {
    headers.contains_key(header::TRANSFER_ENCODING)
        || headers
            .get(header::CONTENT_LENGTH)
            .is_some_and(|v| v.as_bytes() != b"0")
}

/// An answer given before the request body was read: the connection is closed
/// after it (`Connection: close`), since the unread rest of the body cannot be
/// told apart from a next request; the client learns not to reuse it instead
/// of failing its next request on a connection the server is closing.
pub(crate) fn refuse_unread(body_unread: bool, mut resp: Response) -> Response {
    if body_unread {
        resp.headers_mut()
            .insert(header::CONNECTION, HeaderValue::from_static("close"));
    }
    resp
}

/// Requires the bearer token on mutating methods (when one is configured).
async fn require_token(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let mutating = matches!(
        *req.method(),
        Method::POST | Method::PUT | Method::DELETE | Method::PATCH
    );
    if !mutating {
        return next.run(req).await;
    }
    let unread = has_body(req.headers());
    if let Err(e) = check_origin(req.headers(), &state.settings.cors_origins, true)
        .and_then(|()| authorization(req.headers()))
        .and_then(|token| state.service.authorize_header(token))
    {
        return refuse_unread(unread, ApiError(e).into_response());
    }
    next.run(req).await
}

/// The one `Authorization` header of a request (two or more are malformed:
/// which one counts would be a guess).
fn authorization(headers: &header::HeaderMap) -> Result<Option<&str>, Error> {
    let mut all = headers.get_all(header::AUTHORIZATION).iter();
    let first = all.next();
    if all.next().is_some() {
        return Err(Error::malformed_field(
            "authorization",
            "send one Authorization header, not several",
        ));
    }
    Ok(first.and_then(|v| v.to_str().ok()))
}

/// Secure by default: a browser request from another origin (its `Origin`
/// header is neither this server nor one of `--cors-origin`) may not write
/// to the registry (`write`), and, once `--cors-origin` is set, may not open
/// a WebSocket either. Requests without `Origin` (non-browser clients) pass.
pub(crate) fn check_origin(
    headers: &header::HeaderMap,
    allowed: &[String],
    write: bool,
) -> Result<(), Error> {
    let Some(origin) = headers.get(header::ORIGIN).and_then(|v| v.to_str().ok()) else {
        return Ok(());
    };
    let host = headers
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    let same = origin
        .split_once("://")
        .is_some_and(|(_, rest)| !host.is_empty() && rest == host);
    if same || allowed.iter().any(|a| a == origin) || (!write && allowed.is_empty()) {
        return Ok(());
    }
    let what = if write {
        "registry writes"
    } else {
        "WebSocket streams"
    };
    Err(Error::Forbidden {
        detail: format!(
            "{what} from the web origin '{origin}' are refused: start the server with --cors-origin {origin} to allow it"
        ),
    })
}

/// How a route is admitted, set where it is declared (see [`routes`]) and
/// left in the request's extensions for the body extractor.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Admission {
    /// One request: the body limit (`--max-body-bytes`).
    #[default]
    Single,
    /// A batch: the batch body limit (`--max-batch-body-bytes`), then one of
    /// the batch slots (`--max-concurrent-batches`).
    Batch,
}

/// Admission control and request timeout. The request body is read first,
/// without a permit (see [`buffered::read_body`]); then, past the concurrency
/// limit, a request is answered 503 at once instead of queueing; a request
/// over the time limit gets 503. Batch requests then wait for one of the
/// batch slots (within the request timeout). A large answer is counted against the
/// response byte budget (see [`buffered::hold_response`]).
async fn admit(
    State((state, admission)): State<(AppState, Admission)>,
    mut req: Request,
    next: Next,
) -> Response {
    // Deadlines count from the request's arrival, body read included.
    let deadline = tokio::time::Instant::now() + state.settings.request_timeout;
    let client = client_of(&req, state.settings.trust_forwarded_for);
    req.extensions_mut().insert(admission);
    req.extensions_mut().insert(client);
    let conn = req.extensions().get::<Arc<ConnActivity>>().cloned();
    let (req, body_bytes) = match buffered::read_body(req, &state, admission).await {
        Ok(read) => read,
        Err(refusal) => return refusal,
    };
    let _permit = match state.permits.try_acquire(client) {
        Ok(permit) => permit,
        Err(refusal) => {
            metrics::counter!("kinserve_http_rejected_total", "reason" => "overloaded")
                .increment(1);
            // A body read ahead is not left unread: the connection can be kept.
            return refuse_unread(
                body_bytes.is_none() && has_body(req.headers()),
                ApiError(refusal).into_response(),
            );
        }
    };
    let _body_bytes = body_bytes;
    let run = async {
        let _slot = match admission {
            Admission::Batch => match state.budgets().batch_slots.acquire(client).await {
                Ok(slot) => Some(slot),
                Err(e) => return ApiError(e).into_response(),
            },
            Admission::Single => None,
        };
        next.run(req).await
    };
    // Past the deadline the handler is dropped: work on the compute pool sees
    // its cancel flag and stops.
    let resp = match tokio::time::timeout_at(deadline, run).await {
        Ok(resp) => resp,
        Err(_) => ApiError(Error::Unavailable {
            detail: "request timed out".into(),
        })
        .into_response(),
    };
    buffered::hold_response(resp, &state, conn)
}

/// The client of a request: its connection's peer, or the last
/// `X-Forwarded-For` address when the peer is a trusted proxy.
fn client_of(req: &Request, trust_forwarded_for: bool) -> ClientId {
    let peer = req.extensions().get::<PeerAddr>().map(|p| p.0.ip());
    let forwarded = req
        .headers()
        .get_all("x-forwarded-for")
        .iter()
        .next_back()
        .and_then(|v| v.to_str().ok());
    ClientId::resolve(peer, forwarded, trust_forwarded_for)
}

/// The route label of a request: the template of the route it matched
/// (`/v1/robots/{name}/fk`), `unmatched` when none did. Only declared
/// templates are labels, so their number is bounded by the router's routes.
fn route_label(path: Option<&MatchedPath>) -> &'static str {
    match path {
        None => "unmatched",
        Some(m) => intern(m.as_str()),
    }
}

/// `template` as a `&'static str`, kept the first time it is seen, so a
/// request's label costs no allocation. Only route templates come here:
/// what is kept is bounded by the routes the process declares.
fn intern(template: &str) -> &'static str {
    use std::collections::BTreeSet;
    use std::sync::{PoisonError, RwLock};
    static TEMPLATES: RwLock<BTreeSet<&'static str>> = RwLock::new(BTreeSet::new());
    let seen = TEMPLATES.read().unwrap_or_else(PoisonError::into_inner);
    if let Some(kept) = seen.get(template) {
        return kept;
    }
    drop(seen);
    let mut all = TEMPLATES.write().unwrap_or_else(PoisonError::into_inner);
    if let Some(kept) = all.get(template) {
        return kept;
    }
    let kept: &'static str = Box::leak(template.into());
    all.insert(kept);
    kept
}

fn method_label(m: &Method) -> &'static str {
    match *m {
        Method::GET => "GET",
        Method::POST => "POST",
        Method::PUT => "PUT",
        Method::DELETE => "DELETE",
        Method::OPTIONS => "OPTIONS",
        Method::HEAD => "HEAD",
        Method::PATCH => "PATCH",
        _ => "OTHER",
    }
}

fn status_label(code: u16) -> SharedString {
    const CODES: &[(u16, &str)] = &[
        (101, "101"),
        (200, "200"),
        (201, "201"),
        (204, "204"),
        (400, "400"),
        (401, "401"),
        (404, "404"),
        (405, "405"),
        (408, "408"),
        (409, "409"),
        (412, "412"),
        (413, "413"),
        (415, "415"),
        (422, "422"),
        (500, "500"),
        (501, "501"),
        (503, "503"),
        (507, "507"),
    ];
    match CODES.iter().find(|(c, _)| *c == code) {
        Some((_, s)) => SharedString::const_str(s),
        None => SharedString::from(code.to_string()),
    }
}

/// Counts requests by route and status and records their latency.
async fn record_metrics(State(access_log): State<bool>, req: Request, next: Next) -> Response {
    let start = Instant::now();
    let route = route_label(req.extensions().get::<MatchedPath>());
    let method = method_label(req.method());
    let request_id = access_log.then(|| {
        req.headers()
            .get("x-request-id")
            .and_then(|v| v.to_str().ok())
            .unwrap_or("")
            .to_string()
    });
    // Export on: the server span's trace (set by the span middleware); off:
    // the caller's `traceparent`, read only for the access log.
    let trace_id = req.extensions().get::<TraceId>().copied().or_else(|| {
        access_log
            .then(|| crate::telemetry::spans::caller_trace_id(req.headers()))
            .flatten()
    });
    let resp = next.run(req).await;
    if let Some(request_id) = request_id {
        tracing::info!(
            target: "kinserve::access",
            protocol = "http",
            method = %method,
            route = %route,
            status = resp.status().as_u16(),
            duration_ms = start.elapsed().as_secs_f64() * 1e3,
            request_id = %request_id,
            trace_id = trace_id.map(tracing::field::display),
            client_cert = crate::tls::peer::current_subject().as_deref(),
            "request"
        );
    }
    let metrics = RouteMetrics::of(method, route, resp.status().as_u16());
    metrics.requests.increment(1);
    metrics.duration.record(start.elapsed().as_secs_f64());
    resp
}

/// The request counter and latency histogram of one method, route and
/// status, registered with the recorder on their first request and kept:
/// later requests add to them without building, hashing and looking up
/// their label set (about 2,000 instructions, a twentieth of a `/healthz`).
/// Bounded as the labels are: methods, declared routes, status codes.
#[derive(Clone)]
struct RouteMetrics {
    requests: metrics::Counter,
    duration: metrics::Histogram,
}

impl RouteMetrics {
    fn of(method: &'static str, route: &'static str, status: u16) -> RouteMetrics {
        use std::collections::HashMap;
        use std::sync::{LazyLock, PoisonError, RwLock};
        type Labels = (&'static str, &'static str, u16);
        static KEPT: LazyLock<RwLock<HashMap<Labels, RouteMetrics>>> = LazyLock::new(|| {
            // Handles taken before the recorder is installed would count nowhere;
            // it expires no idle metric (no `idle_timeout`), so kept ones stay live.
            let _ = crate::telemetry::metrics_handle();
            RwLock::default()
        });
        let labels = (method, route, status);
        if let Some(kept) = KEPT
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .get(&labels)
        {
            return kept.clone();
        }
        let made = RouteMetrics {
            requests: metrics::counter!("kinserve_http_requests_total", "method" => method, "route" => route, "status" => status_label(status)),
            duration: metrics::histogram!("kinserve_http_request_duration_seconds", "method" => method, "route" => route),
        };
        let mut all = KEPT.write().unwrap_or_else(PoisonError::into_inner);
        all.entry(labels).or_insert(made).clone()
    }
}

/// A 5xx answer or a failed response body: overload answers (503, 507) at
/// WARN and rate-limited ([`crate::telemetry::log_overload`]: a loop of them
/// must not flood the log), anything else at ERROR as tower-http would.
fn log_failure(
    class: tower_http::classify::ServerErrorsFailureClass,
    latency: std::time::Duration,
    _span: &tracing::Span,
) {
    use crate::telemetry::{Overload, log_overload};
    use tower_http::classify::ServerErrorsFailureClass as Class;
    match class {
        Class::StatusCode(axum::http::StatusCode::SERVICE_UNAVAILABLE) => {
            log_overload(Overload::Http503)
        }
        Class::StatusCode(axum::http::StatusCode::INSUFFICIENT_STORAGE) => {
            log_overload(Overload::Http507)
        }
        class => tracing::error!(
            classification = %class,
            latency_ms = latency.as_secs_f64() * 1e3,
            "response failed"
        ),
    }
}

fn panic_response(err: Box<dyn std::any::Any + Send + 'static>) -> Response {
    ApiError(super::panic_to_error(err.as_ref(), "REST handler")).into_response()
}

fn cors(origins: &[String]) -> CorsLayer {
    let layer = CorsLayer::new()
        .allow_methods([
            Method::GET,
            Method::POST,
            Method::PUT,
            Method::DELETE,
            Method::OPTIONS,
        ])
        .allow_headers([
            header::CONTENT_TYPE,
            header::AUTHORIZATION,
            header::IF_MATCH,
            header::IF_NONE_MATCH,
            header::HeaderName::from_static("x-request-id"),
            crate::telemetry::spans::TRACEPARENT,
            crate::telemetry::spans::TRACESTATE,
        ])
        .expose_headers([
            header::LOCATION,
            header::ETAG,
            header::LAST_MODIFIED,
            header::HeaderName::from_static("x-request-id"),
            header::RETRY_AFTER,
            crate::telemetry::spans::TRACEPARENT,
            crate::telemetry::spans::TRACESTATE,
        ]);
    if origins.is_empty() {
        // Any web page may read and compute FK; registry writes (PUT, DELETE,
        // and POST /v1/robots, refused by `check_origin`) need --cors-origin.
        layer
            .allow_origin(Any)
            .allow_methods([Method::GET, Method::POST, Method::OPTIONS])
    } else {
        let origins: Vec<HeaderValue> = origins
            .iter()
            .filter_map(|o| HeaderValue::from_str(o).ok())
            .collect();
        layer.allow_origin(AllowOrigin::list(origins))
    }
}

/// `Allow` without `CONNECT`: the HTTP/2 WebSocket handshake (RFC 8441) is
/// how `GET …/fk/stream` travels over HTTP/2, not an operation of its own
/// (OpenAPI has no CONNECT), so it is not advertised. Applied by the server
/// to every answer of the router (axum adds `Allow` outside any route layer).
pub fn hide_connect<B>(mut resp: axum::http::Response<B>) -> axum::http::Response<B> {
    let Some(allow) = resp
        .headers()
        .get(header::ALLOW)
        .and_then(|v| v.to_str().ok())
    else {
        return resp;
    };
    let kept: Vec<&str> = allow
        .split(',')
        .map(str::trim)
        .filter(|m| !m.eq_ignore_ascii_case("CONNECT"))
        .collect();
    if let Ok(v) = HeaderValue::from_str(&kept.join(",")) {
        resp.headers_mut().insert(header::ALLOW, v);
    }
    resp
}

/// The complete REST router.
pub fn router(state: AppState) -> Router {
    router_with(state, Router::new())
}

/// The REST router with `extra` routes served beside the API ones, under the
/// same admission control and middleware (panic catching, metrics, request
/// ids, CORS). For tests of that wiring (e.g. a route that panics); the server
/// itself uses [`router`].
pub fn router_with(state: AppState, extra: Router<AppState>) -> Router {
    let (api, doc) = routes::api(&state, extra);
    let cors = cors(&state.settings.cors_origins);
    let access_log = state.settings.access_log;
    // validatorUrl "none": Swagger UI must not send the spec's URL to the public validator.
    let swagger = SwaggerUi::new("/docs")
        .url("/openapi.json", doc)
        .config(utoipa_swagger_ui::Config::new(["/openapi.json"]).validator_url("none"));
    // Every layer as one: `Router::layer` wraps every route (and fallback)
    // in a boxed service, cloned and dropped per request, so eight layers
    // added one by one cost eight boxes per request (about a fifth of a
    // `/healthz` request's instructions); composed, the same layers in the
    // same order, still applied after routing (the metrics and spans read the
    // matched route, and `Allow` is added outside them), cost one.
    // Outermost first.
    let layers = tower::ServiceBuilder::new()
        .layer(cors)
        .layer(SetRequestIdLayer::x_request_id(MakeRequestUuid))
        .layer(PropagateRequestIdLayer::x_request_id())
        // Server spans only when they are exported: with export off the
        // layer is not there at all.
        .option_layer(
            crate::telemetry::traces::exporting()
                .then(|| middleware::from_fn(crate::telemetry::spans::rest_request)),
        )
        // One body type under the optional layer (both of its sides answer it).
        .map_response(IntoResponse::into_response)
        .layer(
            TraceLayer::new_for_http()
                .make_span_with(|req: &Request| {
                    let id = req.headers().get("x-request-id").and_then(|v| v.to_str().ok()).unwrap_or("");
                    tracing::debug_span!("http", method = %req.method(), path = %req.uri().path(), request_id = %id)
                })
                .on_failure(log_failure),
        )
        .layer(CatchPanicLayer::custom(panic_response))
        .layer(middleware::from_fn_with_state(access_log, record_metrics))
        .layer(middleware::from_fn(strict::check_message));
    api.merge(swagger)
        .fallback(handlers::not_found)
        .method_not_allowed_fallback(handlers::method_not_allowed)
        .with_state(state)
        .layer(layers)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The value of `name{…}` whose labels include every one of `labels`.
    fn sample(text: &str, name: &str, labels: &[&str]) -> Option<f64> {
        text.lines()
            .filter(|l| l.starts_with(name) && labels.iter().all(|w| l.contains(w)))
            .find_map(|l| l.rsplit(' ').next()?.parse().ok())
    }

    #[test]
    fn kept_route_metrics_count_every_request_under_their_own_labels() {
        let handle = crate::telemetry::metrics_handle();
        let route = "/t/kept-route-metrics";
        for status in [200, 200, 200, 404] {
            let m = RouteMetrics::of("POST", route, status);
            m.requests.increment(1);
            m.duration.record(0.001);
        }
        let text = handle.render();
        let count = |status: &str| {
            sample(
                &text,
                "kinserve_http_requests_total",
                &[
                    &format!("route=\"{route}\""),
                    &format!("status=\"{status}\""),
                    "method=\"POST\"",
                ],
            )
        };
        assert_eq!(count("200"), Some(3.0), "{text}");
        assert_eq!(count("404"), Some(1.0), "{text}");
        let seconds = sample(
            &text,
            "kinserve_http_request_duration_seconds_count",
            &[&format!("route=\"{route}\"")],
        );
        assert_eq!(seconds, Some(4.0), "{text}");
    }
}
