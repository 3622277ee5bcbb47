//! A gRPC stream message → the robot it names and the [`StreamOp`] it asks
//! for (the same operation a WebSocket message converts into): FK of one
//! configuration (`joints`), of many (`configurations` or
//! `packed_configurations`, answered as the FK batch), IK or a Cartesian
//! path. Depends on the model, [`crate::fk`], [`crate::jacobian`],
//! [`crate::operations`] and [`crate::pb`].

use kinserve_model::{FkBatchSpec, FkSpec, IkPathSpec, IkSpec, ModelError, Result, StreamOp};

use crate::fk::{FkOptionsExt, batch_configurations};
use crate::jacobian::frame_from_pb;
use crate::pb;

impl TryFrom<pb::StreamForwardKinematicsRequest> for StreamOp {
    type Error = ModelError;
    /// FK of one configuration (with the Jacobian and the operations on one
    /// configuration when asked for), FK of many, IK or a path: exactly one
    /// of `joints`, `configurations` (or `packed_configurations`), `ik`,
    /// `ik_path`; an `ik.robot` other than the message's is refused.
    fn try_from(msg: pb::StreamForwardKinematicsRequest) -> Result<StreamOp> {
        if !msg.configurations.is_empty() || msg.packed_configurations.is_some() {
            return fk_batch(msg);
        }
        if let Some(path) = msg.ik_path {
            if !msg.joints.is_empty() || msg.ik.is_some() {
                return Err(ModelError::invalid_field(
                    "joints",
                    "give joints (FK), ik or ik_path, one of them",
                ));
            }
            if !path.robot.is_empty() && path.robot != msg.robot {
                return Err(ModelError::invalid_field(
                    "ik_path.robot",
                    "must be empty or the message's robot",
                ));
            }
            return Ok(StreamOp::IkPath(Box::new(IkPathSpec::try_from(*path)?)));
        }
        if let Some(ik) = msg.ik {
            if !msg.joints.is_empty() {
                return Err(ModelError::invalid_field(
                    "joints",
                    "give joints (FK) or ik, not both",
                ));
            }
            if !ik.robot.is_empty() && ik.robot != msg.robot {
                return Err(ModelError::invalid_field(
                    "ik.robot",
                    "must be empty or the message's robot",
                ));
            }
            return Ok(StreamOp::Ik(Box::new(IkSpec::try_from(*ik)?)));
        }
        let jacobian = if msg.include_jacobian {
            Some(frame_from_pb(msg.jacobian_frame, "jacobian_frame")?)
        } else {
            None
        };
        let ops = crate::operations::stream_ops(&msg);
        let (options, frames, pose_format) = msg.options.read()?;
        Ok(StreamOp::Fk {
            fk: FkSpec {
                joints: msg.joints,
                options,
                frames,
                pose_format,
            },
            jacobian,
            ops,
        })
    }
}

/// A message with `configurations`: FK of each, as `ForwardKinematicsBatch`
/// computes it. With `joints`, `ik` or `ik_path` it is refused naming
/// `configurations`; frames, the Jacobian and the operations on one
/// configuration are refused naming their field.
fn fk_batch(msg: pb::StreamForwardKinematicsRequest) -> Result<StreamOp> {
    if !msg.joints.is_empty() || msg.ik.is_some() || msg.ik_path.is_some() {
        let field = if msg.configurations.is_empty() {
            "packed_configurations"
        } else {
            "configurations"
        };
        return Err(ModelError::invalid_field(
            field,
            "give joints (FK), configurations or packed_configurations (FK of many), ik or \
             ik_path, one of them",
        ));
    }
    if msg.include_jacobian {
        return Err(ModelError::invalid_field(
            "include_jacobian",
            "the Jacobian is for one configuration: send joints, or use JacobianBatch",
        ));
    }
    if let Some(flag) = crate::operations::stream_op_flag(&msg) {
        return Err(ModelError::invalid_field(
            flag,
            "operations on one configuration need joints, not configurations",
        ));
    }
    let (options, frames, pose_format) = msg.options.read()?;
    if frames {
        return Err(ModelError::malformed_field(
            "options.frames",
            "FK of many configurations returns tool poses only: send joints for frames",
        ));
    }
    let packed = msg.packed_configurations.map(|p| *p);
    Ok(StreamOp::FkBatch(FkBatchSpec {
        configurations: batch_configurations(&msg.configurations, packed)?,
        options,
        pose_format,
    }))
}

#[cfg(test)]
mod tests {
    use crate::pb;

    /// A stream's messages and replies are moved several times each on the
    /// way through the stream's queues, so the large or rarely set parts are
    /// boxed (`build.rs`): what is moved stays a few cache lines.
    #[test]
    fn stream_messages_are_small() {
        let reply = size_of::<pb::StreamForwardKinematicsResponse>();
        let request = size_of::<pb::StreamForwardKinematicsRequest>();
        eprintln!("reply {reply} bytes, request {request} bytes");
        assert!(reply <= 192, "a reply is {reply} bytes");
        assert!(request <= 192, "a request is {request} bytes");
    }
}
