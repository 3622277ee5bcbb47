//! Conversions between protobuf messages and the model / service types.

use super::pb;
use crate::api::pose_format::PoseFormat;
use crate::error::{Error, FieldViolation, Result};
use crate::kinematics::Transform;
use crate::model::{
    AngleUnit, ConventionSpec, FkOptions, JointType, LengthUnit, LinkSpec, QuaternionSpec,
    RobotSpec, TransformSpec,
};
use crate::model::{ClosedForm, SymbolicMatrix};
use crate::registry::Origin;

/// Proto → model robot. Field paths match REST (`links[3].joint`, `base.matrix`).
pub fn robot_from_pb(r: pb::Robot) -> Result<RobotSpec> {
    let mut v = Vec::new();
    let convention = match pb::Convention::try_from(r.convention) {
        Ok(pb::Convention::Standard) => Some(ConventionSpec::Standard),
        Ok(pb::Convention::Modified) => Some(ConventionSpec::Modified),
        _ => {
            v.push(FieldViolation::new(
                "convention",
                "must be CONVENTION_STANDARD or CONVENTION_MODIFIED",
            ));
            None
        }
    };
    let angle_unit = match pb::AngleUnit::try_from(r.angle_unit) {
        Ok(pb::AngleUnit::Unspecified | pb::AngleUnit::Rad) => AngleUnit::Rad,
        Ok(pb::AngleUnit::Deg) => AngleUnit::Deg,
        Err(_) => {
            v.push(FieldViolation::new("angle_unit", "unknown angle unit"));
            AngleUnit::Rad
        }
    };
    let length_unit = match pb::LengthUnit::try_from(r.length_unit) {
        Ok(pb::LengthUnit::Unspecified | pb::LengthUnit::M) => LengthUnit::M,
        Ok(pb::LengthUnit::Mm) => LengthUnit::Mm,
        Err(_) => {
            v.push(FieldViolation::new("length_unit", "unknown length unit"));
            LengthUnit::M
        }
    };
    let mut links = Vec::with_capacity(r.links.len());
    // Missing values are parse errors (400-class), like a missing JSON field.
    let mut missing = Vec::new();
    for (i, l) in r.links.into_iter().enumerate() {
        let joint = match pb::JointType::try_from(l.joint) {
            Ok(pb::JointType::Revolute) => JointType::Revolute,
            Ok(pb::JointType::Prismatic) => JointType::Prismatic,
            Ok(pb::JointType::Fixed) => JointType::Fixed,
            _ => {
                v.push(FieldViolation::new(
                    format!("links[{i}].joint"),
                    "must be JOINT_TYPE_REVOLUTE, JOINT_TYPE_PRISMATIC or JOINT_TYPE_FIXED",
                ));
                JointType::Fixed
            }
        };
        let mut required = |name: &str, x: Option<f64>| {
            x.unwrap_or_else(|| {
                missing.push(FieldViolation::new(
                    format!("links[{i}].{name}"),
                    format!("missing field `{name}`"),
                ));
                0.0
            })
        };
        let (a, alpha, d, theta) = (
            required("a", l.a),
            required("alpha", l.alpha),
            required("d", l.d),
            required("theta", l.theta),
        );
        links.push(LinkSpec {
            name: l.name,
            joint,
            a,
            alpha,
            d,
            theta,
            limits: l.limits.map(|x| [x.lo, x.hi]),
        });
    }
    if !missing.is_empty() {
        let detail = crate::model::summary(&missing);
        return Err(Error::Malformed {
            detail,
            violations: missing,
        });
    }
    let base = r.base.map(|t| transform_from_pb(t, "base", &mut v));
    let tool = r.tool.map(|t| transform_from_pb(t, "tool", &mut v));
    match convention {
        Some(convention) if v.is_empty() => Ok(RobotSpec {
            name: r.name,
            description: r.description,
            source: r.source,
            convention,
            angle_unit,
            length_unit,
            base,
            tool,
            links,
        }),
        _ => Err(Error::invalid(v)),
    }
}

fn transform_from_pb(
    t: pb::FixedTransform,
    field: &str,
    v: &mut Vec<FieldViolation>,
) -> TransformSpec {
    let mut out = TransformSpec {
        translation: t.translation.map(|p| [p.x, p.y, p.z]),
        ..Default::default()
    };
    match t.rotation {
        None => {}
        Some(pb::fixed_transform::Rotation::Rpy(r)) => out.rpy = Some([r.roll, r.pitch, r.yaw]),
        Some(pb::fixed_transform::Rotation::Quaternion(q)) => {
            out.quaternion = Some(QuaternionSpec {
                w: q.w,
                x: q.x,
                y: q.y,
                z: q.z,
            })
        }
        Some(pb::fixed_transform::Rotation::Matrix(m)) => {
            if m.values.len() != 16 {
                v.push(FieldViolation::new(
                    format!("{field}.matrix"),
                    format!(
                        "must hold 16 values (row-major 4x4), got {}",
                        m.values.len()
                    ),
                ));
            } else {
                let mut mm = [[0.0; 4]; 4];
                for (slot, x) in mm.iter_mut().flatten().zip(&m.values) {
                    *slot = *x;
                }
                out.matrix = Some(mm);
            }
        }
    }
    out
}

fn transform_to_pb(t: &TransformSpec) -> pb::FixedTransform {
    let rotation = if let Some(m) = &t.matrix {
        Some(pb::fixed_transform::Rotation::Matrix(pb::Matrix4 {
            values: m.iter().flat_map(|r| r.iter().copied()).collect(),
        }))
    } else if let Some(r) = t.rpy {
        Some(pb::fixed_transform::Rotation::Rpy(pb::Rpy {
            roll: r[0],
            pitch: r[1],
            yaw: r[2],
        }))
    } else {
        t.quaternion.map(|q| {
            pb::fixed_transform::Rotation::Quaternion(pb::Quaternion {
                w: q.w,
                x: q.x,
                y: q.y,
                z: q.z,
            })
        })
    };
    pb::FixedTransform {
        translation: t.translation.map(|p| pb::Vector3 {
            x: p[0],
            y: p[1],
            z: p[2],
        }),
        rotation,
    }
}

/// Model → proto robot.
pub fn robot_to_pb(s: &RobotSpec) -> pb::Robot {
    pb::Robot {
        name: s.name.clone(),
        description: s.description.clone(),
        source: s.source.clone(),
        convention: convention_to_pb(s.convention) as i32,
        angle_unit: match s.angle_unit {
            AngleUnit::Rad => pb::AngleUnit::Rad,
            AngleUnit::Deg => pb::AngleUnit::Deg,
        } as i32,
        length_unit: length_unit_to_pb(s.length_unit) as i32,
        base: s.base.as_ref().map(transform_to_pb),
        tool: s.tool.as_ref().map(transform_to_pb),
        links: s
            .links
            .iter()
            .map(|l| pb::Link {
                name: l.name.clone(),
                joint: match l.joint {
                    JointType::Revolute => pb::JointType::Revolute,
                    JointType::Prismatic => pb::JointType::Prismatic,
                    JointType::Fixed => pb::JointType::Fixed,
                } as i32,
                a: Some(l.a),
                alpha: Some(l.alpha),
                d: Some(l.d),
                theta: Some(l.theta),
                limits: l.limits.map(|[lo, hi]| pb::Limits { lo, hi }),
            })
            .collect(),
    }
}

/// Convention → proto enum.
pub fn convention_to_pb(c: ConventionSpec) -> pb::Convention {
    match c {
        ConventionSpec::Standard => pb::Convention::Standard,
        ConventionSpec::Modified => pb::Convention::Modified,
    }
}

/// Length unit → proto enum.
pub fn length_unit_to_pb(u: LengthUnit) -> pb::LengthUnit {
    match u {
        LengthUnit::M => pb::LengthUnit::M,
        LengthUnit::Mm => pb::LengthUnit::Mm,
    }
}

/// Origin → proto enum.
pub fn origin_to_pb(o: Origin) -> pb::RobotSource {
    match o {
        Origin::Builtin => pb::RobotSource::Builtin,
        Origin::Registered => pb::RobotSource::Registered,
    }
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
            return Err(Error::malformed_field(
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
        Some(v) if old != default && v != old => Err(Error::malformed_field(
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
        Err(_) => Err(Error::malformed_field(
            "options.pose_format",
            "unknown pose format: use POSE_FORMAT_FULL, POSE_FORMAT_MATRIX or POSE_FORMAT_POSITION",
        )),
    }
}

/// Poses in a compact format as one packed message (one pre-sized vector of
/// numbers, nothing per pose); `None` for `full`, which answers with Pose messages.
pub fn packed_to_pb<'a>(
    format: PoseFormat,
    poses: impl ExactSizeIterator<Item = &'a Transform>,
) -> Option<pb::PackedPoses> {
    let format_pb = match format {
        PoseFormat::Full => return None,
        PoseFormat::Matrix => pb::PoseFormat::Matrix,
        PoseFormat::Position => pb::PoseFormat::Position,
    };
    Some(pb::PackedPoses {
        format: format_pb as i32,
        values: format.pack(poses),
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

/// A closed form as its protobuf message.
pub fn closed_form_to_pb(cf: ClosedForm) -> pb::GetClosedFormResponse {
    let matrix = |m: SymbolicMatrix| pb::SymbolicMatrix {
        text: m.text.into_iter().flatten().collect(),
        latex: m.latex,
        mathml: m.mathml,
    };
    let numbers = |m: [[f64; 4]; 4]| pb::Matrix4 {
        values: m.iter().flatten().copied().collect(),
    };
    pb::GetClosedFormResponse {
        robot: cf.robot,
        convention: convention_to_pb(cf.convention) as i32,
        length_unit: length_unit_to_pb(cf.length_unit) as i32,
        variables: cf
            .variables
            .into_iter()
            .map(|v| pb::JointVariable {
                name: v.name,
                row: u32::try_from(v.row).unwrap_or(u32::MAX),
                joint: v.joint,
                kind: match v.kind {
                    JointType::Revolute => pb::JointType::Revolute,
                    JointType::Prismatic => pb::JointType::Prismatic,
                    JointType::Fixed => pb::JointType::Fixed,
                } as i32,
                offset: v.offset,
            })
            .collect(),
        symbols: cf.symbols.into_iter().collect(),
        link_transforms: cf.link_transforms.into_iter().map(matrix).collect(),
        transform: Some(matrix(cf.transform)),
        base: Some(numbers(cf.base)),
        tool: cf.tool.map(numbers),
    }
}
