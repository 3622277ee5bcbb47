//! Poses on the wire: a [`Transform`] as a `pb::Pose` message, or many in a
//! compact format as one `pb::PackedPoses` (one pre-sized vector, nothing per
//! pose). Depends on the model, the kinematics crate and
//! [`crate::pb`] only.

use kinserve_kinematics::Transform;
use kinserve_model::PoseFormat;

use crate::pb;

impl From<&Transform> for pb::Pose {
    fn from(t: &Transform) -> Self {
        pose_to_pb(t)
    }
}

/// Poses in a compact format as one packed message (one pre-sized vector of
/// numbers, nothing per pose); `None` for `full`, which answers with Pose messages.
pub fn packed_to_pb<'a>(
    format: PoseFormat,
    poses: impl ExactSizeIterator<Item = &'a Transform>,
) -> Option<pb::PackedPoses> {
    packed_poses(format, format.pack(poses))
}

/// `values` (numbers of poses in `format`, back to back) as the packed
/// message; `None` for `full`.
pub(crate) fn packed_poses(format: PoseFormat, values: Vec<f64>) -> Option<pb::PackedPoses> {
    let format_pb = match format {
        PoseFormat::Full => return None,
        PoseFormat::Matrix => pb::PoseFormat::Matrix,
        PoseFormat::Position => pb::PoseFormat::Position,
    };
    Some(pb::PackedPoses {
        format: format_pb as i32,
        values,
    })
}

/// Transform → proto pose.
pub fn pose_to_pb(t: &Transform) -> pb::Pose {
    let m = t.matrix();
    let [w, x, y, z] = t.quaternion();
    let [roll, pitch, yaw] = t.rpy();
    let p = t.position();
    pb::Pose {
        matrix: m.iter().flat_map(|r| r.iter().copied()).collect(),
        position: Some(pb::Vector3 {
            x: p[0],
            y: p[1],
            z: p[2],
        }),
        #[allow(deprecated, reason = "still filled for older clients")]
        orientation: Some(pb::Quaternion { w, x, y, z }),
        rpy: Some(pb::Rpy { roll, pitch, yaw }),
        quaternion: Some(pb::Quaternion { w, x, y, z }),
    }
}
