//! How the poses of an FK answer are given (`pose_format`), the same on every
//! front door: `full` (the default: the pose object with matrix, position,
//! quaternion and roll-pitch-yaw), `matrix` (12 numbers: the top three rows of
//! the homogeneous matrix, row-major) or `position` (`[x, y, z]`).
//!
//! The compact numbers are taken straight from the [`Transform`]: no
//! quaternion or roll-pitch-yaw is computed and nothing is allocated per pose.
//! Depends on the kinematics crate and serde only.

use serde::{Deserialize, Serialize};

use kinserve_kinematics::{PackedLayout, Transform};

/// How each pose of an FK answer is given (default `full`). `matrix`: 12
/// numbers, the top three rows of the 4×4 matrix, row-major
/// (`[r11, r12, r13, x, r21, r22, r23, y, r31, r32, r33, z]`); `position`:
/// `[x, y, z]`. Frames, when asked for, follow the same format.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum PoseFormat {
    /// The pose object: matrix, position, quaternion and roll-pitch-yaw.
    #[default]
    Full,
    /// 12 numbers: the top three rows of the homogeneous matrix, row-major.
    Matrix,
    /// 3 numbers: the position `[x, y, z]`.
    Position,
}

impl PoseFormat {
    /// Numbers per pose of a compact format; `None` for [`PoseFormat::Full`].
    ///
    /// ```
    /// use kinserve_model::PoseFormat;
    /// assert_eq!(PoseFormat::Matrix.stride(), Some(12));
    /// assert_eq!(PoseFormat::Full.stride(), None);
    /// ```
    pub fn stride(self) -> Option<usize> {
        self.layout().map(PackedLayout::stride)
    }

    /// The kernel's layout of a compact format; `None` for `full`.
    pub fn layout(self) -> Option<PackedLayout> {
        match self {
            PoseFormat::Full => None,
            PoseFormat::Matrix => Some(PackedLayout::Matrix12),
            PoseFormat::Position => Some(PackedLayout::Position),
        }
    }

    /// Appends the numbers of `t` in this compact format to `out` (nothing for `full`).
    pub fn extend(self, t: &Transform, out: &mut Vec<f64>) {
        match self {
            PoseFormat::Full => {}
            PoseFormat::Matrix => out.extend_from_slice(&matrix12(t)),
            PoseFormat::Position => out.extend_from_slice(&t.translation),
        }
    }

    /// The numbers of every transform in this compact format, back to back,
    /// in one allocation (empty for `full`).
    pub fn pack<'a>(self, ts: impl ExactSizeIterator<Item = &'a Transform>) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.stride().unwrap_or(0) * ts.len());
        for t in ts {
            self.extend(t, &mut out);
        }
        out
    }
}

/// The tool poses of an FK batch in the answer's format: transforms for
/// `full` (its answer computes quaternion and roll-pitch-yaw from them), the
/// numbers of `matrix` or `position` back to back for the compact formats,
/// as the batch kernel wrote them (see [`crate::JointBatch::fk_as`]).
#[derive(Clone, Debug, PartialEq)]
pub enum BatchPoses {
    /// `full`: one transform per pose.
    Full(Vec<Transform>),
    /// `matrix`: 12 numbers per pose (see [`matrix12`]).
    Matrix(Vec<f64>),
    /// `position`: 3 numbers per pose.
    Position(Vec<f64>),
}

impl BatchPoses {
    /// The format the poses are in.
    pub fn format(&self) -> PoseFormat {
        match self {
            BatchPoses::Full(_) => PoseFormat::Full,
            BatchPoses::Matrix(_) => PoseFormat::Matrix,
            BatchPoses::Position(_) => PoseFormat::Position,
        }
    }

    /// Number of poses.
    pub fn len(&self) -> usize {
        match self {
            BatchPoses::Full(t) => t.len(),
            BatchPoses::Matrix(v) | BatchPoses::Position(v) => {
                v.len() / self.format().stride().unwrap_or(1)
            }
        }
    }

    /// Whether there is no pose.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Transforms as poses in `format`: the compact numbers packed from
    /// them ([`PoseFormat::pack`]), `full` kept as they are.
    pub fn from_transforms(format: PoseFormat, poses: Vec<Transform>) -> BatchPoses {
        match format {
            PoseFormat::Full => BatchPoses::Full(poses),
            PoseFormat::Matrix => BatchPoses::Matrix(format.pack(poses.iter())),
            PoseFormat::Position => BatchPoses::Position(format.pack(poses.iter())),
        }
    }
}

/// The top three rows of the homogeneous matrix of `t`, row-major: the same
/// numbers, bit for bit, as the first 12 of [`Transform::matrix`].
pub fn matrix12(t: &Transform) -> [f64; 12] {
    t.matrix12()
}
