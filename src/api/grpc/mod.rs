//! The gRPC adapter (tonic): `kinematics.v1.KinematicsService`, health and reflection.

mod buffered;
mod convert;
mod grpc_metrics;
mod oversize;
pub mod status;
mod streams;
mod velocity;

use std::pin::Pin;
use std::sync::Arc;

use futures_util::FutureExt;
use std::time::Duration;
use tokio::net::TcpListener;

use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tokio_stream::Stream;
use tokio_util::sync::CancellationToken;
use tonic::{Request, Response, Status, Streaming};

use crate::api::budget::{Budgets, StreamBudget};
use crate::error::Error;
use crate::registry::{Condition, PutMode};
use crate::service::{Configurations, Service};
use crate::telemetry::{Protocol, StreamGuard};

/// Generated protobuf and tonic code for `kinematics.v1`.
#[allow(missing_docs, clippy::all)]
pub mod pb {
    tonic::include_proto!("kinematics.v1");
    /// Encoded file descriptor set (for reflection).
    pub const FILE_DESCRIPTOR_SET: &[u8] =
        tonic::include_file_descriptor_set!("kinematics_descriptor");
}

use pb::kinematics_service_server::{KinematicsService, KinematicsServiceServer};

/// HTTP/2 receive window of one stream: what a client may send ahead on a stream
/// the server has stopped reading (a slow reader of the FK stream).
///
/// h2 guards against floods of small DATA frames with a budget of framing
/// overhead (up to 256 bytes per frame under 256 bytes) of *unread* frames, half
/// the connection window; past it, it closes the whole connection with GOAWAY
/// ENHANCE_YOUR_CALM. A client that streams one ~70-byte request at a time while
/// reading slowly fills a stalled stream's window with small frames: with
/// hyper's defaults (1 MiB stream and connection windows, budget 512 KiB) about
/// 2,700 unread requests killed the connection instead of blocking the client.
/// A 64 KiB stream window (the HTTP/2 default) and a 16 MiB connection window
/// (budget 8 MiB) keep a stalled stream's worst case (~9,400 frames of 7 bytes,
/// ~2.3 MiB of overhead) well inside the budget, so backpressure reaches the
/// client instead.
const STREAM_WINDOW: u32 = 64 << 10;

/// HTTP/2 receive window of a connection (sets h2's small-frame budget to half of it).
const CONNECTION_WINDOW: u32 = 16 << 20;

/// Calls (unary and streaming) open at once on one HTTP/2 connection
/// (`SETTINGS_MAX_CONCURRENT_STREAMS`); a client past it waits for one to
/// finish. tonic's default is no limit. Streaming calls have their own,
/// smaller budget per connection (`--max-streams-per-connection`).
const MAX_CALLS_PER_CONNECTION: u32 = 256;

/// What the gRPC adapter is configured with (start-up builds it from the
/// command line; the adapter never sees the command line itself).
#[derive(Clone, Debug)]
pub struct GrpcSettings {
    /// Largest message a client may send, in bytes.
    pub max_message_bytes: usize,
    /// Longest time a unary call may take.
    pub request_timeout: Duration,
    /// A stream that makes no progress in either direction (no message from
    /// the client, no reply taken by it) for this long is closed.
    pub stream_idle_timeout: Duration,
    /// One access-log line per call (target `kinserve::access`).
    pub access_log: bool,
}

/// The gRPC service over the shared [`Service`].
#[derive(Clone)]
pub struct GrpcService {
    service: Arc<Service>,
    settings: Arc<GrpcSettings>,
    permits: Arc<Semaphore>,
    streams: StreamBudget,
    shutdown: CancellationToken,
}

/// The `authorization` metadata value of a request, if readable.
/// Two or more values are malformed: which one counts would be a guess.
fn authorization<T>(req: &Request<T>) -> Result<Option<&str>, Error> {
    let mut all = req.metadata().get_all("authorization").iter();
    let first = all.next();
    if all.next().is_some() {
        return Err(Error::malformed_field(
            "authorization",
            "send one authorization metadata value, not several",
        ));
    }
    Ok(first.and_then(|v| v.to_str().ok()))
}

impl GrpcService {
    fn admit(&self) -> Result<OwnedSemaphorePermit, Status> {
        self.permits.clone().try_acquire_owned().map_err(|_| {
            metrics::counter!("kinserve_grpc_rejected_total", "reason" => "overloaded")
                .increment(1);
            Status::from(Error::Overloaded)
        })
    }

    fn fk_one(
        &self,
        robot: &str,
        joints: &[f64],
        options: Option<&pb::FkOptions>,
    ) -> Result<FkAnswer, Error> {
        let entry = self.service.robot_at(robot, "robot")?;
        let (opts, frames) = convert::options_from_pb(options)?;
        let format = convert::pose_format_from_pb(options)?;
        let unit = convert::length_unit_to_pb(entry.robot.length_unit());
        let (t, fr) = self
            .service
            .fk_with_frames(&entry.robot, joints, &opts, frames)?;
        entry.count_poses(Protocol::Grpc, 1);
        let fr = fr.unwrap_or_default();
        Ok(match convert::packed_to_pb(format, std::iter::once(&t)) {
            None => FkAnswer {
                pose: Some(convert::pose_to_pb(&t)),
                frames: fr.iter().map(convert::pose_to_pb).collect(),
                packed_pose: None,
                packed_frames: None,
                unit,
            },
            Some(packed) => FkAnswer {
                pose: None,
                frames: Vec::new(),
                packed_pose: Some(packed),
                packed_frames: frames
                    .then(|| convert::packed_to_pb(format, fr.iter()))
                    .flatten(),
                unit,
            },
        })
    }
}

/// One FK answer as the gRPC messages carry it: Pose messages (`full`) or
/// PackedPoses (a compact `pose_format`), and the robot's length unit.
struct FkAnswer {
    pose: Option<pb::Pose>,
    frames: Vec<pb::Pose>,
    packed_pose: Option<pb::PackedPoses>,
    packed_frames: Option<pb::PackedPoses>,
    unit: pb::LengthUnit,
}

impl GrpcService {
    /// The response to one stream message: FK (with the Jacobian when asked
    /// for) or IK. `Err` only for a panic (the stream then ends INTERNAL).
    async fn stream_reply(
        &self,
        msg: pb::StreamForwardKinematicsRequest,
    ) -> Result<pb::StreamForwardKinematicsResponse, Error> {
        let id = msg.id;
        let answer = match msg.ik {
            Some(ik) => self.stream_ik(&msg.robot, msg.joints.is_empty(), *ik).await,
            None => std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                self.stream_fk(
                    &msg.robot,
                    &msg.joints,
                    msg.options.as_ref(),
                    msg.include_jacobian,
                    msg.jacobian_frame,
                )
            }))
            .map_err(|panic| super::panic_to_error(panic.as_ref(), "gRPC FK stream handler"))?,
        };
        Ok(match answer {
            Ok(mut resp) => {
                resp.id = id;
                resp
            }
            Err(e) => pb::StreamForwardKinematicsResponse {
                id,
                result: Some(pb::stream_forward_kinematics_response::Result::Error(
                    status::to_rpc_status(&e),
                )),
                ..Default::default()
            },
        })
    }

    fn stream_fk(
        &self,
        robot: &str,
        joints: &[f64],
        options: Option<&pb::FkOptions>,
        include_jacobian: bool,
        jacobian_frame: i32,
    ) -> Result<pb::StreamForwardKinematicsResponse, Error> {
        let jacobian = if include_jacobian {
            let entry = self.service.robot_at(robot, "robot")?;
            Some(Box::new(self.jacobian_one(
                &entry,
                joints,
                options,
                jacobian_frame,
                "jacobian_frame",
            )?))
        } else {
            None
        };
        let a = self.fk_one(robot, joints, options)?;
        use pb::stream_forward_kinematics_response::Result as Answer;
        Ok(pb::StreamForwardKinematicsResponse {
            id: 0,
            result: a
                .pose
                .map(Answer::Pose)
                .or(a.packed_pose.map(Answer::PackedPose)),
            length_unit: a.unit as i32,
            frames: a.frames,
            jacobian,
            ik: None,
            packed_frames: a.packed_frames,
        })
    }

    async fn stream_ik(
        &self,
        robot: &str,
        no_joints: bool,
        ik: pb::InverseKinematicsRequest,
    ) -> Result<pb::StreamForwardKinematicsResponse, Error> {
        if !no_joints {
            return Err(Error::invalid_field(
                "joints",
                "give joints (FK) or ik, not both",
            ));
        }
        if !ik.robot.is_empty() && ik.robot != robot {
            return Err(Error::invalid_field(
                "ik.robot",
                "must be empty or the message's robot",
            ));
        }
        let entry = self.service.robot_at(robot, "robot")?;
        let unit = convert::length_unit_to_pb(entry.robot.length_unit());
        let (result, _) = self.ik_one(entry, ik).await?;
        Ok(pb::StreamForwardKinematicsResponse {
            id: 0,
            result: result
                .pose
                .clone()
                .map(pb::stream_forward_kinematics_response::Result::Pose),
            length_unit: unit as i32,
            frames: Vec::new(),
            jacobian: None,
            ik: Some(Box::new(result)),
            packed_frames: None,
        })
    }
}

impl GrpcService {
    /// Answers a stream's messages in order until it ends; returns how it ends.
    ///
    /// A stream that makes no progress in either direction for the idle
    /// timeout is closed: waiting for the client's next message and waiting
    /// for it to take a reply (its receive window closed: the reply queue
    /// stays full) both count as no progress.
    async fn pump(
        &self,
        mut inbound: Streaming<pb::StreamForwardKinematicsRequest>,
        replies: &streams::Replies<pb::StreamForwardKinematicsResponse>,
    ) -> End {
        let idle = self.settings.stream_idle_timeout;
        let idle_status = || {
            Status::deadline_exceeded(format!(
                "stream idle timeout: no message from the client and no reply taken for {idle:?}"
            ))
        };
        loop {
            if self.shutdown.is_cancelled() {
                return End::Closed(Status::unavailable("server shutting down"));
            }
            // A message already received is taken at once; only when none is
            // there does the task wait (shutdown, cancel, idle timeout). One
            // poll per message instead of three registrations.
            let ready = inbound.message().now_or_never();
            let next = match ready {
                Some(r) => Ok(r),
                None => tokio::select! {
                    _ = self.shutdown.cancelled() => return End::Closed(Status::unavailable("server shutting down")),
                    _ = replies.closed() => return End::Quiet, // client cancelled
                    r = tokio::time::timeout(idle, inbound.message()) => r,
                },
            };
            let msg = match next {
                Err(_) => return End::Closed(idle_status()),
                Ok(Ok(Some(m))) => m,
                Ok(Ok(None)) => return End::Quiet,
                // Undecodable or oversized message (or the buffered bytes
                // budget spent): report it and end (the transport state is unknown).
                Ok(Err(status)) => return End::Status(oversize::remap_status(status)),
            };
            // A bug (panic) while answering ends the stream with INTERNAL, not
            // with a clean end of stream the client would take for success.
            let resp = match self.stream_reply(msg).await {
                Ok(resp) => resp,
                Err(e) => return End::Status(Status::from(e)),
            };
            // Queued at once when there is room; else waits while the client
            // reads slowly (bounded buffering, end-to-end flow control), but
            // not longer than the idle timeout.
            let resp = match replies.try_send(resp) {
                Ok(()) => continue,
                Err(None) => return End::Quiet,
                Err(Some(resp)) => resp,
            };
            let sent = tokio::select! {
                _ = self.shutdown.cancelled() => return End::Closed(Status::unavailable("server shutting down")),
                r = tokio::time::timeout(idle, replies.send(resp)) => r,
            };
            match sent {
                Ok(true) => {}
                Ok(false) => return End::Quiet,
                Err(_) => return End::Closed(idle_status()),
            }
        }
    }
}

/// How a stream's task ended.
enum End {
    /// Cleanly, or the client went away: nothing to send.
    Quiet,
    /// With a status for the client.
    Status(Status),
    /// Closed by the server (idle timeout, shutdown) while the client may
    /// not be taking its replies.
    Closed(Status),
}

/// After the server closed a stream (idle timeout, shutdown): if its response is not done within
/// [`streams::STUCK_GRACE`] (the HTTP/2 layer still waits for the client's
/// window to send a reply or the final status), closes its connection, the
/// only way to end that stream (see `streams`). A client that reads gets
/// the final status at once and keeps its connection.
async fn close_if_stuck(done: CancellationToken, connection: Option<streams::GrpcConnInfo>) {
    let finished = tokio::time::timeout(streams::STUCK_GRACE, done.cancelled()).await;
    if finished.is_err()
        && let Some(c) = connection
    {
        tracing::info!(
            "closing a gRPC connection: a closed stream on it stays blocked on the client's receive window"
        );
        c.close.cancel();
    }
}

type FkStream = Pin<
    Box<dyn Stream<Item = Result<pb::StreamForwardKinematicsResponse, Status>> + Send + 'static>,
>;

#[tonic::async_trait]
impl KinematicsService for GrpcService {
    async fn list_robots(
        &self,
        req: Request<pb::ListRobotsRequest>,
    ) -> Result<Response<pb::ListRobotsResponse>, Status> {
        let _permit = self.admit()?;
        let req = req.into_inner();
        let size = u32::try_from(req.page_size).map_err(|_| {
            Error::malformed_field(
                "page_size",
                "must not be negative (0 means the default, 100)",
            )
        })?;
        let (page, next) = self.service.list_page(size, &req.page_token)?;
        let robots = page
            .into_iter()
            .map(|s| pb::RobotSummary {
                name: s.name,
                dof: s.dof as u32,
                convention: convert::convention_to_pb(s.convention) as i32,
                length_unit: convert::length_unit_to_pb(s.length_unit) as i32,
                source: convert::origin_to_pb(s.origin) as i32,
            })
            .collect();
        Ok(Response::new(pb::ListRobotsResponse {
            robots,
            next_page_token: next.unwrap_or_default(),
        }))
    }

    async fn get_robot(
        &self,
        req: Request<pb::GetRobotRequest>,
    ) -> Result<Response<pb::GetRobotResponse>, Status> {
        let _permit = self.admit()?;
        let entry = self.service.robot(&req.get_ref().name)?;
        Ok(Response::new(pb::GetRobotResponse {
            robot: Some(convert::robot_to_pb(entry.robot.spec())),
            source: convert::origin_to_pb(entry.origin) as i32,
            etag: entry.etag().to_string(),
        }))
    }

    async fn register_robot(
        &self,
        req: Request<pb::RegisterRobotRequest>,
    ) -> Result<Response<pb::RegisterRobotResponse>, Status> {
        self.service.authorize_header(authorization(&req)?)?;
        let _permit = self.admit()?;
        let req = req.into_inner();
        let robot = req
            .robot
            .ok_or_else(|| Error::invalid_field("robot", "is required"))?;
        let spec = convert::robot_from_pb(robot)?;
        let mode = if req.replace {
            PutMode::Upsert
        } else {
            PutMode::Create
        };
        let cond = match (req.etag.as_str(), req.replace) {
            ("", _) => Condition::Any,
            (_, false) => {
                return Err(Error::malformed_field(
                    "etag",
                    "a condition on the current version needs replace: true (replace: false already means create only)",
                )
                .into());
            }
            (tag, true) => Condition::if_match(tag, "etag")?,
        };
        let (entry, created) = self.service.register(spec, mode, cond).await?;
        Ok(Response::new(pb::RegisterRobotResponse {
            robot: Some(convert::robot_to_pb(entry.robot.spec())),
            created,
            etag: entry.etag().to_string(),
        }))
    }

    async fn delete_robot(
        &self,
        req: Request<pb::DeleteRobotRequest>,
    ) -> Result<Response<pb::DeleteRobotResponse>, Status> {
        self.service.authorize_header(authorization(&req)?)?;
        let _permit = self.admit()?;
        let req = req.into_inner();
        let cond = match req.etag.as_str() {
            "" => Condition::Any,
            tag => Condition::if_match(tag, "etag")?,
        };
        self.service.delete(&req.name, cond).await?;
        Ok(Response::new(pb::DeleteRobotResponse {}))
    }

    async fn forward_kinematics(
        &self,
        req: Request<pb::ForwardKinematicsRequest>,
    ) -> Result<Response<pb::ForwardKinematicsResponse>, Status> {
        let _permit = self.admit()?;
        let req = req.into_inner();
        let a = self.fk_one(&req.robot, &req.joints, req.options.as_ref())?;
        Ok(Response::new(pb::ForwardKinematicsResponse {
            robot: req.robot,
            length_unit: a.unit as i32,
            pose: a.pose,
            frames: a.frames,
            packed_pose: a.packed_pose,
            packed_frames: a.packed_frames,
        }))
    }

    async fn forward_kinematics_batch(
        &self,
        req: Request<pb::ForwardKinematicsBatchRequest>,
    ) -> Result<Response<pb::ForwardKinematicsBatchResponse>, Status> {
        let _permit = self.admit()?;
        let req = req.into_inner();
        self.service.check_batch_size(req.configurations.len())?;
        let entry = self.service.robot_at(&req.robot, "robot")?;
        let (opts, frames) = convert::options_from_pb(req.options.as_ref())?;
        let format = convert::pose_format_from_pb(req.options.as_ref())?;
        if frames {
            return Err(Error::malformed_field(
                "options.frames",
                "batch FK returns tool poses only: ask ForwardKinematics or the stream for frames",
            )
            .into());
        }
        let mut configs = Configurations {
            values: Vec::with_capacity(req.configurations.len() * entry.robot.dof()),
            lens: Vec::with_capacity(req.configurations.len()),
        };
        for c in &req.configurations {
            configs.push(&c.joints);
        }
        let poses = self.service.fk_batch(&entry.robot, &configs, &opts)?;
        entry.count_poses(Protocol::Grpc, poses.len() as u64);
        let packed_poses = convert::packed_to_pb(format, poses.iter());
        let poses = match packed_poses {
            Some(_) => Vec::new(),
            None => poses.iter().map(convert::pose_to_pb).collect(),
        };
        Ok(Response::new(pb::ForwardKinematicsBatchResponse {
            robot: req.robot,
            length_unit: convert::length_unit_to_pb(entry.robot.length_unit()) as i32,
            poses,
            packed_poses,
        }))
    }

    type StreamForwardKinematicsStream = FkStream;

    async fn stream_forward_kinematics(
        &self,
        req: Request<Streaming<pb::StreamForwardKinematicsRequest>>,
    ) -> Result<Response<Self::StreamForwardKinematicsStream>, Status> {
        let connection = req.extensions().get::<streams::GrpcConnInfo>().cloned();
        let permit = self
            .streams
            .try_open(connection.as_ref().map(|c| &c.streams))
            .map_err(|e| {
                metrics::counter!("kinserve_grpc_rejected_total", "reason" => "streams")
                    .increment(1);
                Status::from(e)
            })?;
        let inbound = req.into_inner();
        let (replies, outbound) = streams::channel();
        let this = self.clone();
        tokio::spawn(async move {
            // The stream's budget slot, never a request permit: open streams
            // do not take from the requests in flight.
            let stream = StreamGuard::open(Protocol::Grpc);
            let end = this.pump(inbound, &replies).await;
            drop((permit, stream));
            match end {
                End::Quiet => {}
                End::Status(status) => {
                    replies.end(status);
                }
                End::Closed(status) => {
                    let done = replies.end(status);
                    close_if_stuck(done, connection).await;
                }
            }
        });
        Ok(Response::new(Box::pin(outbound)))
    }

    async fn jacobian(
        &self,
        req: Request<pb::JacobianRequest>,
    ) -> Result<Response<pb::JacobianResponse>, Status> {
        let _permit = self.admit()?;
        Ok(Response::new(self.jacobian_call(req.into_inner())?))
    }

    async fn jacobian_batch(
        &self,
        req: Request<pb::JacobianBatchRequest>,
    ) -> Result<Response<pb::JacobianBatchResponse>, Status> {
        let _permit = self.admit()?;
        Ok(Response::new(self.jacobian_batch_call(req.into_inner())?))
    }

    async fn inverse_kinematics(
        &self,
        req: Request<pb::InverseKinematicsRequest>,
    ) -> Result<Response<pb::InverseKinematicsResponse>, Status> {
        let _permit = self.admit()?;
        Ok(Response::new(self.ik_call(req.into_inner()).await?))
    }

    async fn inverse_kinematics_batch(
        &self,
        req: Request<pb::InverseKinematicsBatchRequest>,
    ) -> Result<Response<pb::InverseKinematicsBatchResponse>, Status> {
        let _permit = self.admit()?;
        Ok(Response::new(self.ik_batch_call(req.into_inner()).await?))
    }

    async fn get_closed_form(
        &self,
        req: Request<pb::GetClosedFormRequest>,
    ) -> Result<Response<pb::GetClosedFormResponse>, Status> {
        let _permit = self.admit()?;
        let cf = self.service.closed_form(&req.get_ref().robot)?;
        Ok(Response::new(convert::closed_form_to_pb(cf)))
    }

    async fn get_urdf(
        &self,
        req: Request<pb::GetUrdfRequest>,
    ) -> Result<Response<pb::GetUrdfResponse>, Status> {
        let _permit = self.admit()?;
        let robot = req.into_inner().robot;
        let urdf = self.service.urdf(&robot)?;
        Ok(Response::new(pb::GetUrdfResponse { robot, urdf }))
    }
}

/// The answer to a request whose handler panicked: INTERNAL (trailers-only),
/// logged; the server and the connection's other calls go on.
fn panic_response(
    err: Box<dyn std::any::Any + Send + 'static>,
) -> tonic::codegen::http::Response<tonic::body::Body> {
    Status::from(super::panic_to_error(err.as_ref(), "gRPC handler")).into_http()
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
    let incoming = streams::incoming(listener, connections);
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
    tonic::transport::Server::builder()
        .layer(grpc_metrics)
        .layer(tower_http::catch_panic::CatchPanicLayer::custom(
            panic_response,
        ))
        .layer(buffered)
        .timeout(request_timeout)
        .tcp_nodelay(true)
        .initial_stream_window_size(STREAM_WINDOW)
        .initial_connection_window_size(CONNECTION_WINDOW)
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
