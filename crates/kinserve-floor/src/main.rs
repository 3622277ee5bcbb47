//! `kinserve-floor`: the least a correct server does for the requests the
//! end-to-end benchmarks send, to measure beside kinserve in one run
//! (`scripts/bench.sh`, issue 28's "the wire as the only cost").
//!
//! Same stack as kinserve (axum on hyper, tonic on h2, prost with
//! `kinserve-api`'s codec and messages, mimalloc, a two-worker runtime on two
//! cores, the same HTTP/2 windows) and the same bytes on the wire, but
//! nothing between the socket and the work: no registry, limits, compute
//! pool, admission, metrics, tracing, access log, request IDs or CORS.
//! What it answers:
//!
//! - `GET /healthz`: `ok`;
//! - `POST /v1/robots/{name}/fk`: reads and parses the JSON body
//!   (`{"joints": [...]}`, as many as the robot has), then answers the bytes
//!   of `--fk-answer` (kinserve's answer to the benchmark's one
//!   configuration): less than any FK answer costs;
//! - gRPC `grpc.health.v1.Health/Check` (serving), `KinematicsService/GetRobot`
//!   (the load generator reads the model first), `ForwardKinematicsBatch` and
//!   `StreamForwardKinematics` (FK messages: joints checked, the pose computed
//!   by the kinematics crates, kinserve's reply messages); every other method
//!   UNIMPLEMENTED.
//!
//! A measuring instrument, not a server: it has no limits of any kind, so it
//! listens on loopback addresses only.

use std::convert::Infallible;
use std::future::Future;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};

use axum::body::Bytes;
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use clap::Parser;
use futures_util::StreamExt;
use kinserve_api::codec::ReservingCodec;
use kinserve_api::pb;
use kinserve_model::{FkBatchSpec, ModelLimits, Robot};
use tonic::{Request, Response, Status, Streaming};

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Command line of `kinserve-floor`.
#[derive(Parser, Debug)]
#[command(about = "The least a correct server does for the benchmark's requests (loopback only)")]
struct Args {
    /// The robot's JSON model (`robots/puma560.json`); every request is for it.
    #[arg(long)]
    robot_file: std::path::PathBuf,
    /// The bytes `POST /v1/robots/{name}/fk` answers (kinserve's answer to the benchmark's body).
    #[arg(long)]
    fk_answer: std::path::PathBuf,
    /// REST address (loopback).
    #[arg(long, default_value = "127.0.0.1:18090")]
    http_addr: SocketAddr,
    /// gRPC address (loopback).
    #[arg(long, default_value = "127.0.0.1:18091")]
    grpc_addr: SocketAddr,
}

/// HTTP/2 receive windows and streams per connection: kinserve's defaults
/// (`DEFAULT_STREAM_WINDOW`, `connection_window`, `MAX_CALLS_PER_CONNECTION`).
const STREAM_WINDOW: u32 = 1 << 20;
const CONNECTION_WINDOW: u32 = 74 << 20;
const MAX_CALLS_PER_CONNECTION: u32 = 256;

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    if !args.http_addr.ip().is_loopback() || !args.grpc_addr.ip().is_loopback() {
        eprintln!("kinserve-floor: listens on loopback addresses only (it has no limits)");
        return std::process::ExitCode::from(2);
    }
    let loaded = std::fs::read(&args.robot_file)
        .map_err(|e| format!("{}: {e}", args.robot_file.display()))
        .and_then(|b| {
            Robot::from_json(&b, &ModelLimits::default())
                .map_err(|e| format!("{}: {e}", args.robot_file.display()))
        })
        .and_then(|r| {
            let answer = std::fs::read(&args.fk_answer)
                .map_err(|e| format!("{}: {e}", args.fk_answer.display()))?;
            Ok((r, answer))
        });
    let (robot, answer) = match loaded {
        Ok(x) => x,
        Err(e) => {
            eprintln!("kinserve-floor: {e}");
            return std::process::ExitCode::from(2);
        }
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build();
    let served = runtime
        .map_err(|e| e.to_string())
        .and_then(|rt| rt.block_on(serve(args, Arc::new(robot), Bytes::from(answer))));
    match served {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("kinserve-floor: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Serves both front doors until one fails; says where on standard error
/// (`kinserve-floor: REST on 127.0.0.1:P, gRPC on 127.0.0.1:Q`: port 0 binds a free port).
async fn serve(args: Args, robot: Arc<Robot>, fk_answer: Bytes) -> Result<(), String> {
    let bind = |addr: SocketAddr| async move {
        let l = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|e| format!("{addr}: {e}"))?;
        let at = l.local_addr().map_err(|e| e.to_string())?;
        Ok::<_, String>((l, at))
    };
    let (http, http_at) = bind(args.http_addr).await?;
    let (grpc, grpc_at) = bind(args.grpc_addr).await?;
    let dof = robot.dof();
    let app = axum::Router::new()
        .route("/healthz", axum::routing::get(|| async { "ok" }))
        .route(
            "/v1/robots/{name}/fk",
            axum::routing::post(move |body: Bytes| rest_fk(body, dof, fk_answer.clone())),
        );
    let rest = async move {
        use axum::serve::ListenerExt;
        let http = http.tap_io(|tcp| {
            let _ = tcp.set_nodelay(true);
        });
        axum::serve(http, app).await.map_err(|e| e.to_string())
    };
    let (health, health_service) = tonic_health::server::health_reporter();
    health
        .set_service_status("", tonic_health::ServingStatus::Serving)
        .await;
    let grpc = tonic::transport::Server::builder()
        .tcp_nodelay(true)
        .initial_stream_window_size(STREAM_WINDOW)
        .initial_connection_window_size(CONNECTION_WINDOW)
        .max_concurrent_streams(MAX_CALLS_PER_CONNECTION)
        .add_service(Floor { robot })
        .add_service(health_service)
        .serve_with_incoming(
            tonic::transport::server::TcpIncoming::from(grpc).with_nodelay(Some(true)),
        );
    eprintln!("kinserve-floor: REST on {http_at}, gRPC on {grpc_at}");
    tokio::select! {
        r = rest => r,
        r = grpc => r.map_err(|e| e.to_string()),
    }
}

/// The body `POST /v1/robots/{name}/fk` reads.
#[derive(serde::Deserialize)]
struct FkBody {
    joints: Vec<f64>,
}

/// Parses the request, then answers kinserve's bytes.
async fn rest_fk(body: Bytes, dof: usize, answer: Bytes) -> axum::response::Response {
    match serde_json::from_slice::<FkBody>(&body) {
        Ok(b) if b.joints.len() == dof => {
            ([(header::CONTENT_TYPE, "application/json")], answer).into_response()
        }
        _ => (
            StatusCode::UNPROCESSABLE_ENTITY,
            "expected {\"joints\": [...]}",
        )
            .into_response(),
    }
}

/// The gRPC service: the methods the benchmarks call.
#[derive(Clone)]
struct Floor {
    robot: Arc<Robot>,
}

impl tonic::server::NamedService for Floor {
    const NAME: &'static str = "kinematics.v1.KinematicsService";
}

type BoxFuture<T> = Pin<Box<dyn Future<Output = Result<T, Infallible>> + Send>>;
type Replies = Pin<
    Box<
        dyn futures_util::Stream<Item = Result<pb::StreamForwardKinematicsResponse, Status>> + Send,
    >,
>;

impl tower::Service<http::Request<tonic::body::Body>> for Floor {
    type Response = http::Response<tonic::body::Body>;
    type Error = Infallible;
    type Future = BoxFuture<Self::Response>;

    fn poll_ready(&mut self, _: &mut Context<'_>) -> Poll<Result<(), Infallible>> {
        Poll::Ready(Ok(()))
    }

    fn call(&mut self, req: http::Request<tonic::body::Body>) -> Self::Future {
        let robot = self.robot.clone();
        match req.uri().path() {
            "/kinematics.v1.KinematicsService/GetRobot" => Box::pin(async move {
                let method = tower::service_fn(move |_: Request<pb::GetRobotRequest>| {
                    let robot = kinserve_api::robot_to_pb(robot.spec());
                    async move {
                        Ok::<_, Status>(Response::new(pb::GetRobotResponse {
                            robot: Some(robot),
                            ..Default::default()
                        }))
                    }
                });
                Ok(grpc().unary(method, req).await)
            }),
            "/kinematics.v1.KinematicsService/ForwardKinematicsBatch" => Box::pin(async move {
                let method =
                    tower::service_fn(move |r: Request<pb::ForwardKinematicsBatchRequest>| {
                        let answer = fk_batch(&robot, r.into_inner()).map(Response::new);
                        async move { answer }
                    });
                Ok(grpc().unary(method, req).await)
            }),
            "/kinematics.v1.KinematicsService/StreamForwardKinematics" => Box::pin(async move {
                let method = tower::service_fn(
                    move |r: Request<Streaming<pb::StreamForwardKinematicsRequest>>| {
                        let robot = robot.clone();
                        let replies: Replies = Box::pin(
                            r.into_inner()
                                .map(move |m| m.and_then(|m| stream_fk(&robot, m))),
                        );
                        async move { Ok::<_, Status>(Response::new(replies)) }
                    },
                );
                Ok(grpc().streaming(method, req).await)
            }),
            _ => Box::pin(async { Ok(Status::unimplemented("not in the floor").into_http()) }),
        }
    }
}

/// tonic's server side of one call with kinserve's codec.
fn grpc<T, U>() -> tonic::server::Grpc<ReservingCodec<T, U>>
where
    ReservingCodec<T, U>: tonic::codec::Codec,
{
    tonic::server::Grpc::new(ReservingCodec::default())
}

fn invalid(e: kinserve_model::ModelError) -> Status {
    Status::invalid_argument(e.to_string())
}

/// FK of a batch as kinserve answers it: the configurations checked, the
/// poses in the asked format, the same response message.
fn fk_batch(
    robot: &Robot,
    r: pb::ForwardKinematicsBatchRequest,
) -> Result<pb::ForwardKinematicsBatchResponse, Status> {
    let spec = FkBatchSpec::try_from(r).map_err(invalid)?;
    let c = &spec.configurations;
    let batch = robot
        .check_batch(&c.values, &c.lens, &spec.options)
        .map_err(invalid)?;
    Ok(kinserve_api::fk_batch_to_pb(
        robot.name(),
        robot.length_unit(),
        batch.fk_as(spec.pose_format),
    ))
}

/// FK of one stream message (`joints`) as kinserve answers it.
fn stream_fk(
    robot: &Robot,
    m: pb::StreamForwardKinematicsRequest,
) -> Result<pb::StreamForwardKinematicsResponse, Status> {
    use pb::stream_forward_kinematics_response::Result as Answer;
    let (options, _) = kinserve_api::options_from_pb(m.options.as_ref()).map_err(invalid)?;
    let format = kinserve_api::pose_format_from_pb(m.options.as_ref()).map_err(invalid)?;
    let pose = robot
        .check_joints(&m.joints, &options)
        .map_err(invalid)?
        .fk();
    let result = match kinserve_api::packed_to_pb(format, std::iter::once(&pose)) {
        Some(packed) => Answer::PackedPose(packed),
        None => Answer::Pose(Box::new(kinserve_api::pose_to_pb(&pose))),
    };
    Ok(pb::StreamForwardKinematicsResponse {
        id: m.id,
        result: Some(result),
        length_unit: kinserve_api::length_unit_to_pb(robot.length_unit()) as i32,
        ..Default::default()
    })
}
