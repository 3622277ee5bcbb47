//! A gRPC stream message → the robot it names and the [`StreamOp`] it asks
//! for (the same operation a WebSocket message converts into). Depends on the
//! model, [`crate::fk`], [`crate::jacobian`], [`crate::operations`] and
//! [`crate::pb`].

use kinserve_model::{FkSpec, IkPathSpec, IkSpec, ModelError, Result, StreamOp};

use crate::fk::FkOptionsExt;
use crate::jacobian::frame_from_pb;
use crate::pb;

impl TryFrom<pb::StreamForwardKinematicsRequest> for StreamOp {
    type Error = ModelError;
    /// FK (with the Jacobian and the operations on one configuration when asked for) or IK; `ik`
    /// with joints, or an `ik.robot` other than the message's, is refused.
    fn try_from(msg: pb::StreamForwardKinematicsRequest) -> Result<StreamOp> {
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
            return Ok(StreamOp::IkPath(Box::new(IkPathSpec::try_from(path)?)));
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
