//! The answers of the bidirectional FK stream: each message checked,
//! answered through the one stream step shared with the WebSocket
//! ([`Service::stream_fk`](crate::service::Service::stream_fk), and
//! [`Service::stream_step`](crate::service::Service::stream_step) on the
//! compute pool) and turned into its reply message. How a call reads its
//! messages and ends is `fk_stream`'s. Depends on the service and
//! `kinserve-api`'s conversions.

use std::future::Future;
use std::pin::Pin;

use futures_util::FutureExt;

use super::{GrpcService, pb, status};
use crate::compute::ClientId;
use crate::error::Error;
use crate::model::{AngleUnit, BatchPoses, StreamOp};
use crate::service::{RobotCache, Service, StreamAnswer};
use crate::telemetry::Protocol;
use kinserve_api::{ConfigurationBatch, packed_to_pb, pose_to_pb};

/// A stream message's answer, or where it is going to come from.
pub(super) enum Answer {
    /// Answered now (FK of one configuration, or a refusal).
    Now(pb::StreamForwardKinematicsResponse),
    /// To be answered on the compute pool (IK, paths, FK of many
    /// configurations): the future gives the reply, `Err` only for a panic.
    Later(LaterReply),
}

/// The reply of a message answered on the compute pool.
pub(super) type LaterReply =
    Pin<Box<dyn Future<Output = Result<pb::StreamForwardKinematicsResponse, Error>> + Send>>;

/// `answer` as the message `id`'s reply: the response, or the error in it.
fn reply_of(
    id: u64,
    answer: Result<pb::StreamForwardKinematicsResponse, Error>,
) -> pb::StreamForwardKinematicsResponse {
    match answer {
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
    }
}

/// A panic while answering, as the error that ends the stream (INTERNAL).
fn panicked(panic: Box<dyn std::any::Any + Send>) -> Error {
    super::super::panic_to_error(panic.as_ref(), "gRPC FK stream handler")
}

impl GrpcService {
    /// The answer to one stream message: FK (with the Jacobian and the
    /// operations on one configuration when asked for) at once; FK of many
    /// configurations, IK or a path as a future on the compute pool, under
    /// `client`'s share. `Err` only for a panic (the stream then ends INTERNAL).
    ///
    /// FK of one configuration, nearly every message of a busy stream, is
    /// answered without building or moving a future of the other operations
    /// (those moves were about 8 % of a message's instructions).
    pub(super) fn stream_answer(
        &self,
        msg: pb::StreamForwardKinematicsRequest,
        client: ClientId,
        robots: &mut RobotCache,
    ) -> Result<Answer, Error> {
        let now = std::panic::AssertUnwindSafe(|| self.stream_answer_now(msg, client, robots));
        std::panic::catch_unwind(now).map_err(panicked)
    }

    /// A message checked and converted; FK of one configuration answered,
    /// the other operations handed to a future.
    fn stream_answer_now(
        &self,
        msg: pb::StreamForwardKinematicsRequest,
        client: ClientId,
        robots: &mut RobotCache,
    ) -> Answer {
        let id = msg.id;
        let prepared = match self.prepare(msg, robots) {
            Ok(p) => p,
            Err(e) => return Answer::Now(reply_of(id, Err(e))),
        };
        match prepared.op {
            StreamOp::Fk { fk, jacobian, ops } => {
                let answer =
                    Service::stream_fk(&prepared.entry, &fk, jacobian, ops, Protocol::Grpc)
                        .map(|a| stream_response(a, prepared.unit, prepared.path_units));
                Answer::Now(reply_of(id, answer))
            }
            _ => {
                let this = self.clone();
                Answer::Later(Box::pin(async move {
                    let later = this.stream_answer_later(prepared, client);
                    let answer = std::panic::AssertUnwindSafe(later)
                        .catch_unwind()
                        .await
                        .map_err(panicked)?;
                    Ok(reply_of(id, answer))
                }))
            }
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
