//! The bidirectional FK stream: the task that reads a stream's messages in
//! order, answers each through the one stream step shared with the WebSocket
//! ([`Service::stream_step`](crate::service::Service::stream_step)) and queues
//! its reply with bounded buffering, and how the stream ends (idle timeout,
//! shutdown, a stuck client window). Depends on the service, `streams` and
//! `kinserve-api`'s conversions.

use std::pin::Pin;

use futures_util::FutureExt;
use tokio_stream::Stream;
use tokio_util::sync::CancellationToken;
use tonic::{Status, Streaming};

use super::{GrpcService, oversize, pb, status, streams};
use crate::compute::ClientId;
use crate::error::Error;
use crate::model::{AngleUnit, BatchPoses, StreamOp};
use crate::service::{RobotCache, Service, StreamAnswer};
use crate::telemetry::Protocol;
use kinserve_api::{ConfigurationBatch, packed_to_pb, pose_to_pb};

impl GrpcService {
    /// The response to one stream message: FK (with the Jacobian and the
    /// operations on one configuration when asked for), FK of many
    /// configurations, IK or a path. `Err` only for a panic (the stream then
    /// ends INTERNAL).
    ///
    /// FK of one configuration, nearly every message of a busy stream, is
    /// answered at once: no future of the other operations is built or
    /// moved for it (those moves were about 8 % of a message's instructions).
    async fn stream_reply(
        &self,
        msg: pb::StreamForwardKinematicsRequest,
        client: ClientId,
        robots: &mut RobotCache,
    ) -> Result<pb::StreamForwardKinematicsResponse, Error> {
        let id = msg.id;
        let panicked = |panic: Box<dyn std::any::Any + Send>| {
            super::super::panic_to_error(panic.as_ref(), "gRPC FK stream handler")
        };
        let now = std::panic::AssertUnwindSafe(|| self.stream_answer_now(msg, robots));
        let answer = match std::panic::catch_unwind(now).map_err(panicked)? {
            Now::Answered(answer) => answer,
            Now::Later(prepared) => {
                std::panic::AssertUnwindSafe(self.stream_answer_later(*prepared, client))
                    .catch_unwind()
                    .await
                    .map_err(panicked)?
            }
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

    /// A message checked and converted; FK of one configuration answered.
    fn stream_answer_now(
        &self,
        msg: pb::StreamForwardKinematicsRequest,
        robots: &mut RobotCache,
    ) -> Now {
        let prepared = match self.prepare(msg, robots) {
            Ok(p) => p,
            Err(e) => return Now::Answered(Err(e)),
        };
        match prepared.op {
            StreamOp::Fk { fk, jacobian, ops } => Now::Answered(
                Service::stream_fk(&prepared.entry, &fk, jacobian, ops, Protocol::Grpc)
                    .map(|a| stream_response(a, prepared.unit, prepared.path_units)),
            ),
            _ => Now::Later(Box::new(prepared)),
        }
    }

    fn prepare(
        &self,
        msg: pb::StreamForwardKinematicsRequest,
        robots: &mut RobotCache,
    ) -> Result<Prepared, Error> {
        // Many configurations: refused over the batch limit before they are
        // copied, as ForwardKinematicsBatch refuses them.
        if !msg.configurations.is_empty() || msg.packed_configurations.is_some() {
            self.service.check_batch_size(msg.configuration_count())?;
        }
        let entry = self.service.robot_cached(robots, &msg.robot, "robot")?;
        msg.check_joint_count(entry.robot.dof())?;
        let op = StreamOp::try_from(msg)?;
        let unit = pb::LengthUnit::from(entry.robot.length_unit()) as i32;
        // A path answer names its units like InverseKinematicsPath's.
        let path_units = match &op {
            StreamOp::IkPath(p) => (entry.robot.name().to_string(), p.angle_unit),
            _ => (String::new(), AngleUnit::Rad),
        };
        Ok(Prepared {
            entry,
            op,
            unit,
            path_units,
        })
    }

    /// The operations that run on the compute pool (IK, paths, FK of many
    /// configurations), under `client`'s share.
    async fn stream_answer_later(
        &self,
        p: Prepared,
        client: ClientId,
    ) -> Result<pb::StreamForwardKinematicsResponse, Error> {
        let answer = self
            .service
            .stream_step(p.entry, p.op, Protocol::Grpc, client)
            .await?;
        Ok(stream_response(answer, p.unit, p.path_units))
    }
}

/// A stream message ready to answer: its robot, operation and units.
struct Prepared {
    entry: std::sync::Arc<crate::registry::Entry>,
    op: StreamOp,
    unit: i32,
    path_units: (String, AngleUnit),
}

/// What [`GrpcService::stream_answer_now`] did with a message.
enum Now {
    /// Answered (or refused).
    Answered(Result<pb::StreamForwardKinematicsResponse, Error>),
    /// To be answered on the compute pool.
    Later(Box<Prepared>),
}

/// A stream answer as its message (Pose messages for `full`, PackedPoses for
/// a compact `pose_format`; a path as InverseKinematicsPath answers it; many
/// configurations as ForwardKinematicsBatch answers them, with the same builder).
fn stream_response(
    answer: StreamAnswer,
    unit: i32,
    (robot, angle_unit): (String, AngleUnit),
) -> pb::StreamForwardKinematicsResponse {
    use pb::stream_forward_kinematics_response::Result as Answer;
    match answer {
        StreamAnswer::FkBatch { poses, pose_format } => {
            let _encode = crate::trace_span!("encode").entered();
            let (poses, packed_poses) =
                kinserve_api::fk_batch_poses_to_pb(BatchPoses::from_transforms(pose_format, poses));
            pb::StreamForwardKinematicsResponse {
                length_unit: unit,
                poses,
                packed_poses: packed_poses.map(Box::new),
                ..Default::default()
            }
        }
        StreamAnswer::IkPath(a) => pb::StreamForwardKinematicsResponse {
            length_unit: unit,
            ik_path: Some(Box::new(kinserve_api::ik_path_to_pb(
                &a, robot, unit, angle_unit,
            ))),
            ..Default::default()
        },
        StreamAnswer::Ik(a) => {
            let result = pb::InverseKinematicsResult::from(&a);
            pb::StreamForwardKinematicsResponse {
                result: result.pose.clone().map(|p| Answer::Pose(Box::new(p))),
                length_unit: unit,
                ik: Some(Box::new(result)),
                ..Default::default()
            }
        }
        StreamAnswer::Fk {
            fk,
            pose_format,
            jacobian,
            ops,
        } => {
            let frames = fk.frames.unwrap_or_default();
            let (result, frames, packed_frames) =
                match packed_to_pb(pose_format, std::iter::once(&fk.pose)) {
                    None => (
                        Answer::Pose(Box::new(pose_to_pb(&fk.pose))),
                        frames.iter().map(pose_to_pb).collect(),
                        None,
                    ),
                    Some(packed) => (
                        Answer::PackedPose(packed),
                        Vec::new(),
                        packed_to_pb(pose_format, frames.iter()).filter(|p| !p.values.is_empty()),
                    ),
                };
            let mut reply = pb::StreamForwardKinematicsResponse {
                id: 0,
                result: Some(result),
                length_unit: unit,
                frames,
                jacobian: jacobian.map(|j| Box::new(pb::JacobianResult::from(&j))),
                packed_frames: packed_frames.map(Box::new),
                ..Default::default()
            };
            kinserve_api::put_stream_answers(&ops, &mut reply);
            reply
        }
    }
}

impl GrpcService {
    /// Answers a stream's messages in order until it ends; returns how it ends.
    ///
    /// A stream that makes no progress in either direction for the idle
    /// timeout is closed: waiting for the client's next message and waiting
    /// for it to take a reply (its receive window closed: the reply queue
    /// stays full) both count as no progress.
    pub(super) async fn pump(
        &self,
        mut inbound: Streaming<pb::StreamForwardKinematicsRequest>,
        replies: &streams::Replies<pb::StreamForwardKinematicsResponse>,
        client: ClientId,
    ) -> End {
        let idle = self.settings.stream_idle_timeout;
        let idle_status = || {
            Status::from(Error::RequestTimeout {
                detail: format!(
                    "stream idle timeout: no message from the client and no reply taken for {idle:?}"
                ),
            })
        };
        let closing = || {
            Status::from(Error::Unavailable {
                detail: "server shutting down".into(),
            })
        };
        // Until the first message, the (shorter) first-message timeout.
        let mut wait = idle.min(self.settings.stream_first_message_timeout);
        // The stream's own token, cancelled with the server's: checking it
        // per message locks only this stream's node, where the server's
        // token is one mutex every stream of every worker would take per
        // message.
        let shutdown = self.shutdown.child_token();
        let mut robots = RobotCache::default();
        loop {
            if shutdown.is_cancelled() {
                return End::Closed(closing());
            }
            // A message already received is taken at once; only when none is
            // there does the task wait (shutdown, cancel, idle timeout). One
            // poll per message instead of three registrations.
            let ready = inbound.message().now_or_never();
            let next = match ready {
                Some(r) => Ok(r),
                None => tokio::select! {
                    _ = shutdown.cancelled() => return End::Closed(closing()),
                    _ = replies.closed() => return End::Quiet, // client cancelled
                    r = tokio::time::timeout(wait, inbound.message()) => r,
                },
            };
            wait = idle;
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
            let resp = match self.stream_reply(msg, client, &mut robots).await {
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
                _ = shutdown.cancelled() => return End::Closed(closing()),
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
pub(super) enum End {
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
pub(super) async fn close_if_stuck(
    done: CancellationToken,
    connection: Option<streams::GrpcConnInfo>,
) {
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

pub(super) type FkStream = Pin<
    Box<dyn Stream<Item = Result<pb::StreamForwardKinematicsResponse, Status>> + Send + 'static>,
>;
