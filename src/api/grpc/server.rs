//! gRPC server set-up: the HTTP/2 settings, the layers (metrics, panic
//! catching, buffered-bytes budget, timeout), health, reflection and the
//! listener's life cycle. Depends on the adapter's [`GrpcService`] and its
//! layers; answers no call itself.

use std::sync::Arc;

use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use tonic::Status;

use super::pb::kinematics_service_server::KinematicsServiceServer;
use super::{GrpcService, GrpcSettings, buffered, grpc_metrics, oversize, pb, streams};
use crate::api::budget::Budgets;
use crate::service::Service;

/// HTTP/2 receive window of one stream by default (`--grpc-stream-window`):
/// how much of a large unary request a client may send per round trip (a
/// packed 10,000-configuration batch, 480 KB, in one instead of the eight
/// that HTTP/2's 64 KiB default needs), and what it may send ahead on a
/// stream the server has stopped reading (a slow reader of the FK stream):
/// at most `--max-streams` × this, 64 MiB by default.
pub const DEFAULT_STREAM_WINDOW: u32 = 1 << 20;

/// Smallest HTTP/2 receive window of a connection (sets h2's small-frame budget to half of it).
const MIN_CONNECTION_WINDOW: u32 = 16 << 20;

/// The connection's HTTP/2 receive window for a stream window of
/// `stream_window` bytes: at least 16 MiB, and 74 stream windows.
///
/// h2 guards against floods of small DATA frames with a budget of framing
/// overhead (up to 256 bytes per frame under 256 bytes) of *unread* frames, half
/// the connection window; past it, it closes the whole connection with GOAWAY
/// ENHANCE_YOUR_CALM. A client that streams one small request at a time while
/// reading slowly fills a stalled stream's window with small frames: with
/// hyper's defaults (1 MiB stream and connection windows, budget 512 KiB) about
/// 2,700 unread ~70-byte requests killed the connection instead of blocking the
/// client. The worst case, a stream window full of the smallest gRPC frames
/// (7 bytes: the 5-byte prefix and a 2-byte message), is 249 bytes of
/// overhead per 7 bytes, 35.6 × the stream window; half of 74 windows holds
/// it, so backpressure reaches the client instead; so does a connection's
/// every stream (`--max-streams-per-connection`, 16) of FK requests of about
/// 90 bytes (166 bytes of overhead each, 1.8 × the window per stream). (The
/// connection window alone pins no memory: the server reads unary calls as
/// they arrive, and a stalled stream holds at most its own window.)
///
/// ```
/// # use kinserve::api::grpc::connection_window;
/// assert_eq!(connection_window(64 << 10), 16 << 20);
/// assert_eq!(connection_window(1 << 20), 74 << 20);
/// ```
pub fn connection_window(stream_window: u32) -> u32 {
    stream_window.saturating_mul(74).max(MIN_CONNECTION_WINDOW)
}

/// Calls (unary and streaming) open at once on one HTTP/2 connection
/// (`SETTINGS_MAX_CONCURRENT_STREAMS`); a client past it waits for one to
/// finish. tonic's default is no limit. Streaming calls have their own,
/// smaller budget per connection (`--max-streams-per-connection`).
const MAX_CALLS_PER_CONNECTION: u32 = 256;

/// The answer to a request whose handler panicked: INTERNAL (trailers-only),
/// logged; the server and the connection's other calls go on.
fn panic_response(
    err: Box<dyn std::any::Any + Send + 'static>,
) -> tonic::codegen::http::Response<tonic::body::Body> {
    Status::from(crate::api::panic_to_error(err.as_ref(), "gRPC handler")).into_http()
}

/// When the gRPC server reports NOT_SERVING and when it stops.
#[derive(Clone, Debug)]
pub struct Lifecycle {
    /// Cancelled when the drain starts: health turns NOT_SERVING, calls are still served.
    pub draining: CancellationToken,
    /// Cancelled when the listener closes (streams end, calls drain).
    pub stop: CancellationToken,
}

/// Serves gRPC (kinematics, health, reflection) on `listener` until
/// `lifecycle.stop` is cancelled; health is NOT_SERVING from `lifecycle.draining` on.
pub async fn serve(
    listener: TcpListener,
    service: Arc<Service>,
    settings: GrpcSettings,
    budgets: Budgets,
    lifecycle: Lifecycle,
    tls: Option<crate::tls::Listener>,
) -> std::io::Result<()> {
    let shutdown = lifecycle.stop;
    let (health, health_service) = tonic_health::server::health_reporter();
    health
        .set_serving::<KinematicsServiceServer<GrpcService>>()
        .await;
    health
        .set_service_status("", tonic_health::ServingStatus::Serving)
        .await;
    // Every descriptor set we serve, on both reflection versions, each of
    // which also lists the other (grpcurl and older clients use either).
    let descriptors = [
        pb::FILE_DESCRIPTOR_SET,
        tonic_health::pb::FILE_DESCRIPTOR_SET,
    ];
    let mut v1 = tonic_reflection::server::Builder::configure();
    let mut v1alpha = tonic_reflection::server::Builder::configure();
    for d in descriptors {
        v1 = v1.register_encoded_file_descriptor_set(d);
        v1alpha = v1alpha.register_encoded_file_descriptor_set(d);
    }
    v1 =
        v1.register_encoded_file_descriptor_set(tonic_reflection::pb::v1alpha::FILE_DESCRIPTOR_SET);
    v1alpha =
        v1alpha.register_encoded_file_descriptor_set(tonic_reflection::pb::v1::FILE_DESCRIPTOR_SET);
    let reflection_v1 = v1.build_v1().map_err(std::io::Error::other)?;
    let reflection_v1alpha = v1alpha.build_v1alpha().map_err(std::io::Error::other)?;
    let max_message = settings.max_message_bytes;
    let request_timeout = settings.request_timeout;
    let access_log = settings.access_log;
    let stream_window = settings.stream_window;
    let Budgets {
        permits,
        streams,
        request_bytes,
        connections,
    } = budgets;
    let buffered = buffered::BufferedBytesLayer::new(request_bytes);
    let kin = KinematicsServiceServer::new(GrpcService {
        service,
        settings: Arc::new(settings),
        permits,
        streams,
        shutdown: shutdown.clone(),
    })
    .max_decoding_message_size(max_message)
    .max_encoding_message_size(usize::MAX);
    // Oversized messages: RESOURCE_EXHAUSTED, not tonic's OUT_OF_RANGE; undecodable
    // ones INVALID_ARGUMENT, not INTERNAL; unknown methods named.
    let kin = oversize::WireErrorStatuses(kin);
    // Accepted sockets get TCP_NODELAY (tonic's own flag applies only to
    // listeners it binds) and their own count of open streams.
    let incoming = streams::incoming(listener, connections, tls);
    let health_on_stop = health.clone();
    let grpc_metrics = grpc_metrics::GrpcMetricsLayer::new(
        access_log,
        &[
            pb::FILE_DESCRIPTOR_SET,
            tonic_health::pb::FILE_DESCRIPTOR_SET,
            tonic_reflection::pb::v1::FILE_DESCRIPTOR_SET,
            tonic_reflection::pb::v1alpha::FILE_DESCRIPTOR_SET,
        ],
    );
    // Each call runs with its connection's client certificate known (for the logs).
    let client_cert = crate::tls::peer::ScopeLayer::new(|ext| {
        ext.get::<streams::GrpcConnInfo>()
            .and_then(|c| c.client_cert.clone())
    });
    tonic::transport::Server::builder()
        .layer(client_cert)
        .layer(crate::telemetry::spans::GrpcTraceLayer)
        .layer(grpc_metrics)
        .layer(tower_http::catch_panic::CatchPanicLayer::custom(
            panic_response,
        ))
        .layer(buffered)
        .timeout(request_timeout)
        .tcp_nodelay(true)
        .initial_stream_window_size(stream_window)
        .initial_connection_window_size(connection_window(stream_window))
        .max_concurrent_streams(MAX_CALLS_PER_CONNECTION)
        .http2_keepalive_interval(Some(std::time::Duration::from_secs(30)))
        .add_service(kin)
        .add_service(health_service)
        .add_service(reflection_v1)
        .add_service(reflection_v1alpha)
        .serve_with_incoming_shutdown(incoming, async move {
            tokio::select! {
                _ = lifecycle.draining.cancelled() => {}
                _ = shutdown.cancelled() => {}
            }
            health_on_stop
                .set_not_serving::<KinematicsServiceServer<GrpcService>>()
                .await;
            health_on_stop
                .set_service_status("", tonic_health::ServingStatus::NotServing)
                .await;
            shutdown.cancelled().await;
        })
        .await
        .map_err(std::io::Error::other)
}

#[cfg(test)]
mod tests {
    use tonic::codegen::http;
    use tower::{Layer, ServiceExt};

    use super::panic_response;

    /// A panicking handler behind the server's panic layer: a trailers-only
    /// INTERNAL answer with a message that does not repeat the panic.
    #[tokio::test]
    async fn a_panicking_call_is_answered_internal() {
        let svc = tower_http::catch_panic::CatchPanicLayer::custom(panic_response).layer(
            tower::service_fn(|_req: http::Request<tonic::body::Body>| async move {
                if true {
                    panic!("boom: secret detail");
                }
                Ok::<_, std::convert::Infallible>(http::Response::new(tonic::body::Body::empty()))
            }),
        );
        let resp = svc
            .oneshot(http::Request::new(tonic::body::Body::empty()))
            .await
            .unwrap();
        assert_eq!(resp.headers()["grpc-status"], "13");
        let message = resp.headers()["grpc-message"].to_str().unwrap();
        assert!(message.contains("internal"), "{message}");
        assert!(!message.contains("boom"), "{message}");
    }
}
