//! The robot model and its enums on the wire: `pb::Robot` ↔ [`RobotSpec`]
//! (field paths as REST's: `links[3].joint`, `base.matrix`), units,
//! conventions and closed forms. Depends on the model and [`crate::pb`] only.

use kinserve_model::{
    AngleUnit, ClosedForm, ConventionSpec, FieldViolation, JointType, LengthUnit, LinkSpec,
    ModelError, QuaternionSpec, Result, RobotSpec, SymbolicMatrix, TransformSpec,
};

use crate::pb;

impl TryFrom<pb::Robot> for RobotSpec {
    type Error = ModelError;
    fn try_from(r: pb::Robot) -> Result<RobotSpec> {
        robot_from_pb(r)
    }
}

impl From<&RobotSpec> for pb::Robot {
    fn from(s: &RobotSpec) -> pb::Robot {
        robot_to_pb(s)
    }
}

impl From<LengthUnit> for pb::LengthUnit {
    fn from(u: LengthUnit) -> Self {
        length_unit_to_pb(u)
    }
}

impl From<ClosedForm> for pb::GetClosedFormResponse {
    fn from(cf: ClosedForm) -> Self {
        closed_form_to_pb(cf)
    }
}

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
        let detail = kinserve_model::summary(&missing);
        return Err(ModelError::Malformed {
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
        _ => Err(ModelError::invalid(v)),
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

/// A closed form as its protobuf message.
fn closed_form_to_pb(cf: ClosedForm) -> pb::GetClosedFormResponse {
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
