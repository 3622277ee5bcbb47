//! kinserve-api: the wire contract shared by the server and its clients.
//!
//! It owns the protobuf/tonic types generated from the workspace's `proto/`
//! ([`pb`]), the encoded file descriptor set the server serves by reflection
//! ([`FILE_DESCRIPTOR_SET`]), and the conversions between those messages and
//! the model's protocol-neutral types: requests in (`TryFrom<pb::…>` for
//! [`kinserve_model::FkSpec`], [`kinserve_model::IkSpec`], …, with REST's
//! field paths in every error) and answers out (`From<&…>` for the `pb`
//! messages).
//!
//! It also owns the packed binary batch layout of REST's
//! `application/octet-stream` bodies (little-endian float64; see
//! [`configurations_from_le`] and [`poses_to_le`]) and the protobuf batch
//! answers REST's `application/x-protobuf` shares with gRPC ([`fk_batch_to_pb`]).
//!
//! It also holds the one parser of durations given on the command line
//! ([`parse_duration`]), shared by the server and `kinserve-load`.
//!
//! Depends on `kinserve-model`, `kinserve-kinematics`, prost and tonic's
//! generated-code support. Must not depend on: the server crate, axum,
//! hyper's server, tokio-postgres (a client such as `kinserve-load` links
//! this crate without the server).
//!
//! ```
//! use kinserve_api::pb;
//! use kinserve_model::{FkSpec, PoseFormat};
//!
//! let msg = pb::ForwardKinematicsRequest {
//!     robot: "puma560".into(),
//!     joints: vec![0.0; 6],
//!     options: Some(pb::FkOptions { pose_format: pb::PoseFormat::Matrix as i32, ..Default::default() }),
//! };
//! let spec = FkSpec::try_from(msg.clone()).unwrap();
//! assert_eq!(spec.pose_format, PoseFormat::Matrix);
//! assert_eq!(spec.joints.len(), 6);
//! ```

mod batch;
pub mod codec;
mod duration;
mod fk;
mod ik;
mod jacobian;
mod operations;
mod pose;
mod robot;
mod stream;
mod urdf;
mod wire;

pub use batch::{
    F64_BYTES, batch_poses_to_le, configurations_from_le, fk_batch_poses_to_pb, fk_batch_to_pb,
    jacobian_batch_to_pb, jacobian_stride, jacobians_to_le, packed_count, packed_format,
    poses_to_le,
};
pub use duration::{MAX_DURATION, MAX_IK_TIME_LIMIT, parse_duration, parse_ik_time_limit};
pub use fk::{
    ConfigurationBatch, FkOptionsExt, batch_configurations, check_joint_count, configurations,
    options_from_pb, pose_format_from_pb,
};
pub use ik::angle_unit_to_pb;
pub use ik::{ik_batch_spec_from_pb, ik_path_spec_from_pb, ik_path_to_pb, ik_spec_from_pb};
pub use jacobian::{frame_from_pb, frame_to_pb};
pub use operations::{PbConfigOp, put_stream_answers, stream_op_flag, stream_ops};
pub use pose::{packed_to_pb, pose_to_pb};
pub use robot::{convention_to_pb, length_unit_to_pb, robot_from_pb, robot_to_pb};
pub use urdf::import_convention_from_pb;

/// Generated protobuf and tonic code for `kinematics.v1`.
#[allow(missing_docs, clippy::all)]
pub mod pb {
    tonic::include_proto!("kinematics.v1");
    pub use crate::wire::{JointConfiguration, PackedConfigurations, PackedPoses};
    /// Encoded file descriptor set of `kinematics.v1` and `google.rpc` (served
    /// by reflection, so tools such as grpcurl decode the error details).
    pub const FILE_DESCRIPTOR_SET: &[u8] =
        tonic::include_file_descriptor_set!("kinematics_descriptor");
}

pub use pb::FILE_DESCRIPTOR_SET;
