//! The service methods of `kinematics.v1.KinematicsService`: admission (a
//! request permit per unary call), the message → model request conversion
//! (`kinserve-api`'s `TryFrom` impls, with REST's field paths), one service
//! call, the answer back as its message. The stream's loop is in `stream`.
//! Depends on the service, the registry's types and `kinserve-api`.

use tonic::{Request, Response, Status, Streaming};

use super::fk_stream::FkReplies;
use super::pb::kinematics_service_server::KinematicsService;
use super::{GrpcService, authorization, pb, streams};
use crate::error::Error;
use crate::model::operations;
use crate::model::{
    FkBatchSpec, FkSpec, IkBatchSpec, IkPathSpec, IkSpec, JacobianBatchSpec, JacobianSpec,
    RobotSpec, UrdfImport,
};
use crate::registry::{Condition, Entry, Origin, PutMode};
use crate::service::{FkAnswer, FkBatchCompute};
use crate::telemetry::{Protocol, StreamGuard};
use kinserve_api::{ConfigurationBatch, PbConfigOp, packed_to_pb, pose_to_pb};
use std::future::Future;
use std::pin::Pin;

/// Origin → proto enum.
fn origin_to_pb(o: Origin) -> pb::RobotSource {
    match o {
        Origin::Builtin => pb::RobotSource::Builtin,
        Origin::Registered => pb::RobotSource::Registered,
    }
}

/// The robot's name and length unit as the answers carry them.
fn names(entry: &Entry) -> (String, i32) {
    (
        entry.robot.name().to_string(),
        pb::LengthUnit::from(entry.robot.length_unit()) as i32,
    )
}

/// How a write stores its model: `replace` upserts, else creates; `etag`
/// (with `replace` only) is the version it must replace.
fn write_mode(replace: bool, etag: &str) -> Result<(PutMode, Condition), Error> {
    let mode = if replace {
        PutMode::Upsert
    } else {
        PutMode::Create
    };
    let cond = match (etag, replace) {
        ("", _) => Condition::Any,
        (_, false) => {
            return Err(Error::malformed_field(
                "etag",
                "a condition on the current version needs replace: true (replace: false already means create only)",
            ));
        }
        (tag, true) => Condition::if_match(tag, "etag")?,
    };
    Ok((mode, cond))
}

/// The answer of a write.
fn registered(entry: &Entry, created: bool) -> pb::RegisterRobotResponse {
    pb::RegisterRobotResponse {
        robot: Some(pb::Robot::from(entry.robot.spec())),
        created,
        etag: entry.etag().to_string(),
    }
}

/// Writes the gRPC method of every operation on one configuration (the
/// table [`crate::model::config_ops!`]) inside the service impl. The impl is
/// `#[tonic::async_trait]`, which leaves macro calls alone, so the methods
/// are written in the form it gives its own (a boxed `Send` future).
macro_rules! grpc_config_methods {
    ($( $(#[$doc:meta])* $name:ident: $op:ident => [$($answer:tt)+]; )*) => {
        $(
            $(#[$doc])*
            fn $name<'life0, 'async_trait>(
                &'life0 self,
                req: Request<<operations::$op as PbConfigOp>::Request>,
            ) -> Pin<Box<
                dyn Future<Output = Result<Response<<operations::$op as PbConfigOp>::Response>, Status>>
                    + Send
                    + 'async_trait,
            >>
            where
                'life0: 'async_trait,
                Self: 'async_trait,
            {
                Box::pin(std::future::ready(self.config_op::<operations::$op>(req)))
            }
        )*
    };
}

impl GrpcService {
    /// An operation on one configuration: admitted, the robot looked up, the
    /// request validated once, the answer computed on this task.
    fn config_op<Op: PbConfigOp>(
        &self,
        req: Request<Op::Request>,
    ) -> Result<Response<Op::Response>, Status> {
        let (_, _permit) = self.admit(&req)?;
        let req = req.into_inner();
        let entry = self.service.robot_at(Op::robot(&req), "robot")?;
        let spec = Op::spec(req).map_err(Error::from)?;
        let answer = self.service.config_op::<Op>(&entry.robot, &spec)?;
        let robot = entry.robot.name().to_string();
        Ok(Response::new(Op::response(
            robot,
            entry.robot.length_unit(),
            &answer,
        )))
    }
}

#[tonic::async_trait]
impl KinematicsService for GrpcService {
    crate::model::config_ops!(grpc_config_methods);

    async fn list_robots(
        &self,
        req: Request<pb::ListRobotsRequest>,
    ) -> Result<Response<pb::ListRobotsResponse>, Status> {
        let (_, _permit) = self.admit(&req)?;
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
                convention: kinserve_api::convention_to_pb(s.convention) as i32,
                length_unit: pb::LengthUnit::from(s.length_unit) as i32,
                source: origin_to_pb(s.origin) as i32,
                ik_class: s.ik_class.map(str::to_string),
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
        let (_, _permit) = self.admit(&req)?;
        let entry = self.service.robot(&req.get_ref().name)?;
        Ok(Response::new(pb::GetRobotResponse {
            robot: Some(pb::Robot::from(entry.robot.spec())),
            source: origin_to_pb(entry.origin) as i32,
            etag: entry.etag().to_string(),
        }))
    }

    async fn register_robot(
        &self,
        req: Request<pb::RegisterRobotRequest>,
    ) -> Result<Response<pb::RegisterRobotResponse>, Status> {
        self.service.authorize_header(authorization(&req)?)?;
        let (_, _permit) = self.admit(&req)?;
        let req = req.into_inner();
        let robot = req
            .robot
            .ok_or_else(|| Error::invalid_field("robot", "is required"))?;
        let spec = RobotSpec::try_from(robot).map_err(Error::from)?;
        let (mode, cond) = write_mode(req.replace, &req.etag)?;
        let (entry, created) = self.service.register(spec, mode, cond).await?;
        Ok(Response::new(registered(&entry, created)))
    }

    async fn import_urdf(
        &self,
        req: Request<pb::ImportUrdfRequest>,
    ) -> Result<Response<pb::RegisterRobotResponse>, Status> {
        self.service.authorize_header(authorization(&req)?)?;
        let (client, _permit) = self.admit(&req)?;
        let mut req = req.into_inner();
        let (mode, cond) = write_mode(req.replace, &std::mem::take(&mut req.etag))?;
        let limit = self.settings.max_document_bytes;
        if req.urdf.len() > limit {
            return Err(Error::TooLarge {
                detail: format!(
                    "the URDF document is {} bytes, over the limit of {limit} bytes (--max-body-bytes)",
                    req.urdf.len()
                ),
                field: Some("urdf".into()),
            }
            .into());
        }
        let import = UrdfImport::try_from(req).map_err(Error::from)?;
        let spec = crate::api::urdf_import::import(&self.service, client, import).await?;
        let (entry, created) = self.service.register(spec, mode, cond).await?;
        Ok(Response::new(registered(&entry, created)))
    }

    async fn delete_robot(
        &self,
        req: Request<pb::DeleteRobotRequest>,
    ) -> Result<Response<pb::DeleteRobotResponse>, Status> {
        self.service.authorize_header(authorization(&req)?)?;
        let (_, _permit) = self.admit(&req)?;
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
        let (_, _permit) = self.admit(&req)?;
        let req = req.into_inner();
        let entry = self.service.robot_at(&req.robot, "robot")?;
        let spec = FkSpec::try_from(req).map_err(Error::from)?;
        let FkAnswer { pose, frames } = self.service.fk(&entry.robot, &spec)?;
        entry.count_poses(Protocol::Grpc, 1);
        let _encode = crate::trace_span!("encode").entered();
        let frames = frames.unwrap_or_default();
        let format = spec.pose_format;
        let mut resp = pb::ForwardKinematicsResponse {
            robot: entry.robot.name().to_string(),
            length_unit: pb::LengthUnit::from(entry.robot.length_unit()) as i32,
            ..Default::default()
        };
        match packed_to_pb(format, std::iter::once(&pose)) {
            None => {
                resp.pose = Some(pose_to_pb(&pose));
                resp.frames = frames.iter().map(pose_to_pb).collect();
            }
            Some(packed) => {
                resp.packed_pose = Some(packed);
                resp.packed_frames = spec
                    .frames
                    .then(|| packed_to_pb(format, frames.iter()))
                    .flatten();
            }
        }
        Ok(Response::new(resp))
    }

    async fn forward_kinematics_batch(
        &self,
        req: Request<pb::ForwardKinematicsBatchRequest>,
    ) -> Result<Response<pb::ForwardKinematicsBatchResponse>, Status> {
        let (client, _permit) = self.admit(&req)?;
        let req = req.into_inner();
        self.service.check_batch_size(req.configuration_count())?;
        let entry = self.service.robot_at(&req.robot, "robot")?;
        req.check_joint_count(entry.robot.dof())
            .map_err(Error::from)?;
        let spec = FkBatchSpec::try_from(req).map_err(Error::from)?;
        let (poses, _) = self
            .service
            .fk_batch_on_pool(client, entry.clone(), spec, FkBatchCompute::IN_FORMAT)
            .await?;
        entry.count_poses(Protocol::Grpc, poses.len() as u64);
        let _encode = crate::trace_span!("encode").entered();
        // The builder the stream's many-configuration reply shares.
        Ok(Response::new(kinserve_api::fk_batch_to_pb(
            entry.robot.name(),
            entry.robot.length_unit(),
            poses,
        )))
    }

    type StreamForwardKinematicsStream = FkReplies;

    async fn stream_forward_kinematics(
        &self,
        req: Request<Streaming<pb::StreamForwardKinematicsRequest>>,
    ) -> Result<Response<Self::StreamForwardKinematicsStream>, Status> {
        let connection = req.extensions().get::<streams::GrpcConnInfo>().cloned();
        let client = self.client(&req);
        let permit = self
            .streams
            .try_open(connection.as_ref().map(|c| &c.streams), client)
            .map_err(|e| {
                metrics::counter!("kinserve_grpc_rejected_total", "reason" => "streams")
                    .increment(1);
                Status::from(e)
            })?;
        let inbound = req.into_inner();
        // The stream's budget slot, never a request permit: open streams do
        // not take from the requests in flight.
        let held = (permit, StreamGuard::open(Protocol::Grpc));
        Ok(Response::new(
            self.fk_replies(inbound, client, held, connection),
        ))
    }

    async fn jacobian(
        &self,
        req: Request<pb::JacobianRequest>,
    ) -> Result<Response<pb::JacobianResponse>, Status> {
        let (_, _permit) = self.admit(&req)?;
        let req = req.into_inner();
        let entry = self.service.robot_at(&req.robot, "robot")?;
        let spec = JacobianSpec::try_from(req).map_err(Error::from)?;
        let answer = self.service.jacobian(&entry.robot, &spec)?;
        entry.count_poses(Protocol::Grpc, 1);
        Ok(Response::new(pb::JacobianResponse {
            robot: entry.robot.name().to_string(),
            length_unit: pb::LengthUnit::from(entry.robot.length_unit()) as i32,
            result: Some(pb::JacobianResult::from(&answer)),
        }))
    }

    async fn jacobian_batch(
        &self,
        req: Request<pb::JacobianBatchRequest>,
    ) -> Result<Response<pb::JacobianBatchResponse>, Status> {
        let (client, _permit) = self.admit(&req)?;
        let req = req.into_inner();
        self.service.check_batch_size(req.configuration_count())?;
        let entry = self.service.robot_at(&req.robot, "robot")?;
        req.check_joint_count(entry.robot.dof())
            .map_err(Error::from)?;
        let spec = JacobianBatchSpec::try_from(req).map_err(Error::from)?;
        let answers = self
            .service
            .jacobian_batch_on_pool(client, entry.clone(), spec)
            .await?;
        entry.count_poses(Protocol::Grpc, answers.len() as u64);
        Ok(Response::new(pb::JacobianBatchResponse {
            robot: entry.robot.name().to_string(),
            length_unit: pb::LengthUnit::from(entry.robot.length_unit()) as i32,
            results: answers.iter().map(pb::JacobianResult::from).collect(),
        }))
    }

    async fn inverse_kinematics(
        &self,
        req: Request<pb::InverseKinematicsRequest>,
    ) -> Result<Response<pb::InverseKinematicsResponse>, Status> {
        let (client, _permit) = self.admit(&req)?;
        let req = req.into_inner();
        let entry = self.service.robot_at(&req.robot, "robot")?;
        let (robot, length_unit) = names(&entry);
        let spec = IkSpec::try_from(req).map_err(Error::from)?;
        let angle_unit = pb::AngleUnit::from(spec.angle_unit) as i32;
        let answer = self.service.ik_on_pool(client, entry, spec).await?;
        Ok(Response::new(pb::InverseKinematicsResponse {
            robot,
            length_unit,
            angle_unit,
            result: Some(pb::InverseKinematicsResult::from(&answer)),
        }))
    }

    async fn inverse_kinematics_batch(
        &self,
        req: Request<pb::InverseKinematicsBatchRequest>,
    ) -> Result<Response<pb::InverseKinematicsBatchResponse>, Status> {
        let (client, _permit) = self.admit(&req)?;
        let req = req.into_inner();
        let entry = self.service.robot_at(&req.robot, "robot")?;
        let (robot, length_unit) = names(&entry);
        let spec = IkBatchSpec::try_from(req).map_err(Error::from)?;
        let angle_unit = pb::AngleUnit::from(spec.angle_unit) as i32;
        let answers = self.service.ik_batch_on_pool(client, entry, spec).await?;
        Ok(Response::new(pb::InverseKinematicsBatchResponse {
            robot,
            length_unit,
            angle_unit,
            results: answers
                .iter()
                .map(pb::InverseKinematicsResult::from)
                .collect(),
        }))
    }

    async fn inverse_kinematics_path(
        &self,
        req: Request<pb::InverseKinematicsPathRequest>,
    ) -> Result<Response<pb::InverseKinematicsPathResponse>, Status> {
        let (client, _permit) = self.admit(&req)?;
        let req = req.into_inner();
        let entry = self.service.robot_at(&req.robot, "robot")?;
        let (robot, length_unit) = names(&entry);
        let spec = IkPathSpec::try_from(req).map_err(Error::from)?;
        let angle_unit = spec.angle_unit;
        let answer = self.service.ik_path_on_pool(client, entry, spec).await?;
        Ok(Response::new(kinserve_api::ik_path_to_pb(
            &answer,
            robot,
            length_unit,
            angle_unit,
        )))
    }

    async fn get_closed_form(
        &self,
        req: Request<pb::GetClosedFormRequest>,
    ) -> Result<Response<pb::GetClosedFormResponse>, Status> {
        let (client, _permit) = self.admit(&req)?;
        let cf = self
            .service
            .closed_form(client, &req.get_ref().robot)
            .await?;
        let cf = cf.as_ref().as_ref().map_err(|e| Error::from(e.clone()))?;
        Ok(Response::new(pb::GetClosedFormResponse::from(cf.clone())))
    }

    async fn get_urdf(
        &self,
        req: Request<pb::GetUrdfRequest>,
    ) -> Result<Response<pb::GetUrdfResponse>, Status> {
        let (client, _permit) = self.admit(&req)?;
        let robot = req.into_inner().robot;
        let urdf = self.service.urdf(client, &robot).await?;
        Ok(Response::new(pb::GetUrdfResponse { robot, urdf }))
    }
}
