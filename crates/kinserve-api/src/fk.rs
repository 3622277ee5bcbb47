//! FK on the wire: `pb::FkOptions` and the FK requests → [`FkSpec`] /
//! [`FkBatchSpec`] (field paths as REST's: `options.angle_unit`,
//! `options.pose_format`, `configurations[3][1]` after validation), and the
//! configurations of the batch messages, repeated or packed
//! ([`batch_configurations`], [`ConfigurationBatch`]). Depends on
//! the model and [`crate::pb`] only.

use kinserve_model::{
    AngleUnit, Configurations, FkBatchSpec, FkOptions, FkSpec, ModelError, PoseFormat, Result,
};

use crate::pb;

/// What the FK requests' `options` say, read once.
pub trait FkOptionsExt {
    /// Evaluation options, whether frames were asked for, and the pose format.
    fn read(&self) -> Result<(FkOptions, bool, PoseFormat)>;
}

impl FkOptionsExt for Option<pb::FkOptions> {
    fn read(&self) -> Result<(FkOptions, bool, PoseFormat)> {
        let (options, frames) = options_from_pb(self.as_ref())?;
        Ok((options, frames, pose_format_from_pb(self.as_ref())?))
    }
}

impl TryFrom<pb::ForwardKinematicsRequest> for FkSpec {
    type Error = ModelError;
    fn try_from(r: pb::ForwardKinematicsRequest) -> Result<FkSpec> {
        let (options, frames, pose_format) = r.options.read()?;
        Ok(FkSpec {
            joints: r.joints,
            options,
            frames,
            pose_format,
        })
    }
}

impl TryFrom<pb::ForwardKinematicsBatchRequest> for FkBatchSpec {
    type Error = ModelError;
    fn try_from(r: pb::ForwardKinematicsBatchRequest) -> Result<FkBatchSpec> {
        let (options, frames, pose_format) = r.options.read()?;
        if frames {
            return Err(ModelError::malformed_field(
                "options.frames",
                "batch FK returns tool poses only: ask ForwardKinematics or the stream for frames",
            ));
        }
        Ok(FkBatchSpec {
            configurations: batch_configurations(&r.configurations, r.packed_configurations)?,
            options,
            pose_format,
        })
    }
}

/// A batch request whose configurations come as the repeated
/// `configurations` or as `packed_configurations`.
pub trait ConfigurationBatch {
    /// How many configurations it holds, before any check: packed values
    /// are counted per `joint_count` (per value when that is 0), so that a
    /// batch limit applies to a message whose count is wrong too.
    fn configuration_count(&self) -> usize;

    /// The packed configurations' `joint_count` against the robot's `dof`,
    /// once the robot is known; invalid, naming
    /// `packed_configurations.joint_count`, when they differ.
    fn check_joint_count(&self, dof: usize) -> Result<()>;
}

macro_rules! configuration_batch {
    ($message:ty, $packed:ident) => {
        impl ConfigurationBatch for $message {
            fn configuration_count(&self) -> usize {
                count(&self.configurations, self.packed_configurations.$packed())
            }
            fn check_joint_count(&self, dof: usize) -> Result<()> {
                joint_count_is(self.packed_configurations.$packed(), dof)
            }
        }
    };
}

configuration_batch!(pb::ForwardKinematicsBatchRequest, as_ref);
configuration_batch!(pb::JacobianBatchRequest, as_ref);
// Boxed in the stream message (`build.rs`).
configuration_batch!(pb::StreamForwardKinematicsRequest, as_deref);

fn count(rows: &[pb::JointConfiguration], packed: Option<&pb::PackedConfigurations>) -> usize {
    let packed = packed.map_or(0, |p| p.values.len() / (p.joint_count as usize).max(1));
    rows.len().saturating_add(packed)
}

fn joint_count_is(packed: Option<&pb::PackedConfigurations>, dof: usize) -> Result<()> {
    match packed {
        Some(p) if !p.values.is_empty() => {
            check_joint_count("packed_configurations.joint_count", p.joint_count, dof)
        }
        _ => Ok(()),
    }
}

/// A packed batch's declared values per configuration against the robot's
/// joint count: a batch of the wrong width whose length happens to be a
/// multiple of the robot's (42 values: 6 of 7 joints, or 7 of 6) is refused
/// instead of read as other configurations. Invalid, naming `field` (gRPC's
/// `packed_configurations.joint_count`, REST's `joint_count` query
/// parameter), with the same text on both.
///
/// ```
/// let e = kinserve_api::check_joint_count("joint_count", 3, 2).unwrap_err();
/// assert_eq!(
///     e.to_string(),
///     "invalid input: joint_count: 3 values per configuration, but the robot has 2 joints: \
///      set joint_count to 2 and pack 2 values per configuration"
/// );
/// assert!(kinserve_api::check_joint_count("joint_count", 2, 2).is_ok());
/// ```
pub fn check_joint_count(field: &str, declared: u32, dof: usize) -> Result<()> {
    if declared as usize == dof {
        return Ok(());
    }
    Err(ModelError::invalid_field(
        field,
        format!(
            "{declared} values per configuration, but the robot has {dof} joints: set \
             joint_count to {dof} and pack {dof} values per configuration"
        ),
    ))
}

/// The configurations of a batch message in one buffer: the repeated
/// `configurations` copied back to back, or `packed_configurations` as they
/// are (not both: malformed, naming `packed_configurations`; values that
/// are not a whole number of `joint_count` ones: malformed, naming
/// `packed_configurations.values`).
///
/// ```
/// use kinserve_api::{batch_configurations, pb};
/// let packed = pb::PackedConfigurations { joint_count: 2, values: vec![0.1, 0.2, 0.3, 0.4] };
/// let c = batch_configurations(&[], Some(packed)).unwrap();
/// assert_eq!((c.len(), c.lens.as_slice()), (2, [2, 2].as_slice()));
/// let odd = pb::PackedConfigurations { joint_count: 3, values: vec![0.1, 0.2, 0.3, 0.4] };
/// assert!(batch_configurations(&[], Some(odd)).is_err());
/// ```
pub fn batch_configurations(
    rows: &[pb::JointConfiguration],
    packed: Option<pb::PackedConfigurations>,
) -> Result<Configurations> {
    let Some(p) = packed else {
        return Ok(configurations(rows));
    };
    if !rows.is_empty() {
        return Err(ModelError::malformed_field(
            "packed_configurations",
            "give the configurations either as `configurations` or as `packed_configurations`, \
             not both",
        ));
    }
    let k = p.joint_count as usize;
    if !p.values.len().is_multiple_of(k.max(1)) || (k == 0 && !p.values.is_empty()) {
        return Err(ModelError::malformed_field(
            "packed_configurations.values",
            format!(
                "{} values is not a whole number of configurations of joint_count = {k} values \
                 (set joint_count to the robot's number of joints)",
                p.values.len()
            ),
        ));
    }
    let n = p.values.len().checked_div(k).unwrap_or(0);
    Ok(Configurations {
        values: p.values,
        lens: vec![p.joint_count; n],
    })
}

/// The configurations of a batch message, back to back in one buffer.
pub fn configurations(rows: &[pb::JointConfiguration]) -> Configurations {
    let mut out = Configurations {
        values: Vec::with_capacity(rows.iter().map(|c| c.joints.len()).sum()),
        lens: Vec::with_capacity(rows.len()),
    };
    for c in rows {
        out.push(&c.joints);
    }
    out
}

/// Request options → evaluation options and whether frames were asked for.
/// Absent options: radians, no frames, limits checked. The deprecated
/// `include_frames` / `skip_limit_check` count when their new twins are
/// absent; twins that disagree are refused.
pub fn options_from_pb(o: Option<&pb::FkOptions>) -> Result<(FkOptions, bool)> {
    let Some(o) = o else {
        return Ok((FkOptions::default(), false));
    };
    let angle_unit = match pb::AngleUnit::try_from(o.angle_unit) {
        Ok(pb::AngleUnit::Unspecified | pb::AngleUnit::Rad) => AngleUnit::Rad,
        Ok(pb::AngleUnit::Deg) => AngleUnit::Deg,
        Err(_) => {
            return Err(ModelError::malformed_field(
                "options.angle_unit",
                "unknown angle unit: use ANGLE_UNIT_RAD or ANGLE_UNIT_DEG",
            ));
        }
    };
    #[allow(deprecated, reason = "the old names are still honoured")]
    let (old_frames, old_check) = (o.include_frames, !o.skip_limit_check);
    let frames = twin(
        "options.frames",
        "include_frames",
        o.frames,
        old_frames,
        false,
    )?;
    let check = twin(
        "options.check_limits",
        "skip_limit_check",
        o.check_limits,
        old_check,
        true,
    )?;
    Ok((FkOptions::new(Some(angle_unit), Some(check)), frames))
}

/// A new option and its deprecated twin: the new one when present (it must
/// not contradict an old one that was set away from its default), else the old.
fn twin(field: &str, old_name: &str, new: Option<bool>, old: bool, default: bool) -> Result<bool> {
    match new {
        Some(v) if old != default && v != old => Err(ModelError::malformed_field(
            field,
            format!("contradicts the deprecated `{old_name}`: give only the new field"),
        )),
        Some(v) => Ok(v),
        None => Ok(old),
    }
}

/// `options.pose_format` → pose format (absent options or unspecified: full).
/// A value out of range is malformed, naming `options.pose_format` (like an
/// unknown `angle_unit`).
pub fn pose_format_from_pb(o: Option<&pb::FkOptions>) -> Result<PoseFormat> {
    let Some(o) = o else {
        return Ok(PoseFormat::Full);
    };
    match pb::PoseFormat::try_from(o.pose_format) {
        Ok(pb::PoseFormat::Unspecified | pb::PoseFormat::Full) => Ok(PoseFormat::Full),
        Ok(pb::PoseFormat::Matrix) => Ok(PoseFormat::Matrix),
        Ok(pb::PoseFormat::Position) => Ok(PoseFormat::Position),
        Err(_) => Err(ModelError::malformed_field(
            "options.pose_format",
            "unknown pose format: use POSE_FORMAT_FULL, POSE_FORMAT_MATRIX or POSE_FORMAT_POSITION",
        )),
    }
}
