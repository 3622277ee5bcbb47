//! The packed binary batch layout (REST `application/octet-stream`) and the
//! protobuf batch answers shared by REST and gRPC.
//!
//! **Packed layout.** Every number is an IEEE 754 float64, little-endian,
//! with nothing else in the body (no header, no length prefix):
//!
//! - a request is `n` configurations of `dof` joint values each, row-major
//!   (configuration after configuration), so its length is `n × dof × 8`
//!   bytes ([`configurations_from_le`]);
//! - an FK answer is `n` poses of `k` numbers each, in request order
//!   ([`poses_to_le`], [`batch_poses_to_le`]): `k = 12` for the `matrix` pose format (the top three
//!   rows of the homogeneous 4×4 matrix, row-major: `r11 r12 r13 x r21 r22
//!   r23 y r31 r32 r33 z`, the numbers of REST's `matrices` and of
//!   `PackedPoses` in `POSE_FORMAT_MATRIX`), `k = 3` for `position`
//!   (`x y z`). `full` has no packed form and is written as `matrix`
//!   ([`packed_format`]);
//! - a Jacobian answer is `n` results of `6 × dof + 15` numbers each
//!   ([`jacobians_to_le`]): the Jacobian's 6 rows (`vx vy vz ωx ωy ωz`) of
//!   `dof` values each, row-major as JSON's `jacobian`; then
//!   `manipulability`; `condition_number` (+∞ where JSON has `null`);
//!   `singular` (1.0 or 0.0); then the tool pose's 12 `matrix` numbers.
//!
//! Every number is the bit pattern the server computed: the same doubles as
//! the JSON answer (which serde_json prints so that they read back exactly)
//! and the protobuf one.
//!
//! Depends on the model, the kinematics crate and [`crate::pb`] only.

use kinserve_kinematics::Transform;
use kinserve_model::{
    BatchPoses, Configurations, JacobianAnswer, LengthUnit, ModelError, PoseFormat, Result,
};

use crate::pb;
use crate::pose::{packed_poses, pose_to_pb};

/// Bytes of one packed number.
pub const F64_BYTES: usize = 8;

/// The configurations of a packed request body: `n × dof` little-endian
/// float64, row-major. A body whose length is not a whole number of
/// configurations (`dof × 8` bytes each) is malformed, naming `body`.
///
/// ```
/// let body: Vec<u8> = [0.5f64, 0.1, 0.0, 0.0].iter().flat_map(|x| x.to_le_bytes()).collect();
/// let c = kinserve_api::configurations_from_le(&body, 2).unwrap();
/// assert_eq!((c.len(), c.values.as_slice()), (2, [0.5, 0.1, 0.0, 0.0].as_slice()));
/// assert!(kinserve_api::configurations_from_le(&body[..12], 2).is_err());
/// ```
pub fn configurations_from_le(bytes: &[u8], dof: usize) -> Result<Configurations> {
    let row = dof.saturating_mul(F64_BYTES);
    // With no joints, only an empty body is whole (`n.is_multiple_of(0)` is `n == 0`).
    if !bytes.len().is_multiple_of(row) {
        return Err(ModelError::malformed_field(
            "body",
            format!(
                "{} bytes is not a whole number of configurations: the robot has {dof} joints, \
                 so the body must be n × {row} bytes ({dof} little-endian float64 per configuration)",
                bytes.len()
            ),
        ));
    }
    let n = bytes.len().checked_div(row).unwrap_or(0);
    let values = bytes
        .chunks_exact(F64_BYTES)
        .filter_map(|c| c.first_chunk::<F64_BYTES>())
        .map(|b| f64::from_le_bytes(*b))
        .collect();
    let len = u32::try_from(dof).unwrap_or(u32::MAX);
    Ok(Configurations {
        values,
        lens: vec![len; n],
    })
}

/// The number of configurations a packed body of `bytes` holds for a robot
/// of `dof` joints (rounded down; [`configurations_from_le`] refuses a
/// remainder).
pub fn packed_count(bytes: usize, dof: usize) -> usize {
    bytes
        .checked_div(dof.saturating_mul(F64_BYTES))
        .unwrap_or(0)
}

/// The pose format a packed answer is written in: `full` (no packed form)
/// as `matrix`, the compact formats as themselves.
pub fn packed_format(format: PoseFormat) -> PoseFormat {
    match format {
        PoseFormat::Full => PoseFormat::Matrix,
        compact => compact,
    }
}

/// The poses as a packed answer: in [`packed_format`]`(format)`, `k` numbers
/// per pose (12 or 3), little-endian float64, in one allocation.
///
/// ```
/// use kinserve_kinematics::Transform;
/// use kinserve_model::PoseFormat;
/// let t = Transform::translation(1.0, 2.0, 3.0);
/// let bytes = kinserve_api::poses_to_le(PoseFormat::Position, [t].iter());
/// let xyz: Vec<f64> = bytes.chunks(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
/// assert_eq!(xyz, [1.0, 2.0, 3.0]);
/// assert_eq!(kinserve_api::poses_to_le(PoseFormat::Full, [t].iter()).len(), 12 * 8);
/// ```
pub fn poses_to_le<'a>(
    format: PoseFormat,
    poses: impl ExactSizeIterator<Item = &'a Transform>,
) -> Vec<u8> {
    let format = packed_format(format);
    let stride = format.stride().unwrap_or(12);
    let mut out = Vec::with_capacity(poses.len() * stride * F64_BYTES);
    for t in poses {
        match format {
            PoseFormat::Position => push_le(&mut out, &t.translation),
            _ => push_le(&mut out, &kinserve_model::matrix12(t)),
        }
    }
    out
}

/// The poses of a batch as a packed answer: the compact formats' numbers
/// as they are (one copy into bytes), `full` written as `matrix` (see
/// [`poses_to_le`]).
pub fn batch_poses_to_le(poses: &BatchPoses) -> Vec<u8> {
    match poses {
        BatchPoses::Full(t) => poses_to_le(PoseFormat::Full, t.iter()),
        BatchPoses::Matrix(v) | BatchPoses::Position(v) => {
            let mut out = Vec::new();
            push_le(&mut out, v);
            out
        }
    }
}

/// Appends `values` as little-endian float64 (sized once, then one
/// fixed-size copy per value, which compiles to a block copy).
fn push_le(out: &mut Vec<u8>, values: &[f64]) {
    let start = out.len();
    out.resize(start + values.len() * F64_BYTES, 0);
    for (bytes, v) in out[start..].chunks_exact_mut(F64_BYTES).zip(values) {
        bytes.copy_from_slice(&v.to_le_bytes());
    }
}

/// The answer of an FK batch as its message: `poses` for `full`, one
/// `packed_poses` for the compact formats (what `ForwardKinematicsBatch`
/// answers, and REST's `application/x-protobuf` answer).
pub fn fk_batch_to_pb(
    robot: &str,
    length_unit: LengthUnit,
    poses: BatchPoses,
) -> pb::ForwardKinematicsBatchResponse {
    let (poses, packed_poses) = fk_batch_poses_to_pb(poses);
    pb::ForwardKinematicsBatchResponse {
        robot: robot.to_string(),
        length_unit: pb::LengthUnit::from(length_unit) as i32,
        poses,
        packed_poses,
    }
}

/// The poses of an FK batch as its two fields: `poses` (Pose messages) for
/// `full`, else one `packed_poses` holding the batch's vector of numbers
/// as it is (moved, not copied). [`fk_batch_to_pb`] and the gRPC stream's
/// many-configuration reply both write them, so their numbers are the same.
pub fn fk_batch_poses_to_pb(poses: BatchPoses) -> (Vec<pb::Pose>, Option<pb::PackedPoses>) {
    let format = poses.format();
    match poses {
        BatchPoses::Full(t) => (t.iter().map(pose_to_pb).collect(), None),
        BatchPoses::Matrix(v) | BatchPoses::Position(v) => (Vec::new(), packed_poses(format, v)),
    }
}

/// Numbers per result of a packed Jacobian answer for `dof` joints.
pub fn jacobian_stride(dof: usize) -> usize {
    6 * dof + 15
}

/// Jacobian answers as a packed answer (see the module documentation):
/// per result the 6 × dof rows, manipulability, condition number (+∞ when
/// JSON has `null`), singular (1 or 0) and the 12 `matrix` numbers of the pose.
pub fn jacobians_to_le(answers: &[JacobianAnswer]) -> Vec<u8> {
    let dof = answers.first().map_or(0, |a| a.jacobian.dof());
    let mut out = Vec::with_capacity(answers.len() * jacobian_stride(dof) * F64_BYTES);
    for a in answers {
        for row in 0..6 {
            for column in a.jacobian.columns() {
                let v = column.get(row).copied().unwrap_or(f64::NAN);
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        let c = a.measures.condition_number;
        let singular = if a.measures.singular { 1.0 } else { 0.0 };
        let c = if c.is_finite() { c } else { f64::INFINITY };
        push_le(&mut out, &[a.measures.manipulability, c, singular]);
        push_le(&mut out, &kinserve_model::matrix12(&a.pose));
    }
    out
}

/// The answer of a Jacobian batch as its message (what `JacobianBatch` answers).
pub fn jacobian_batch_to_pb(
    robot: &str,
    length_unit: LengthUnit,
    answers: &[JacobianAnswer],
) -> pb::JacobianBatchResponse {
    pb::JacobianBatchResponse {
        robot: robot.to_string(),
        length_unit: pb::LengthUnit::from(length_unit) as i32,
        results: answers.iter().map(pb::JacobianResult::from).collect(),
    }
}
