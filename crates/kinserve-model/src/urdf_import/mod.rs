//! Robots from URDF: the chain between two links of a URDF document turned
//! into an exact DH table (standard or modified), checked against the URDF's
//! own forward kinematics before it is answered.
//!
//! `parse` reads the document and finds the chain; `convert` builds the DH
//! frames on the joint axes and reads the rows off them. Owns
//! [`UrdfImport`] and [`import_urdf`]. Depends on the schema and the math
//! crate; must not depend on any server crate.

mod convert;
mod parse;

use kinserve_kinematics::Transform;

use crate::error::{ModelError, Result};
use crate::robot::{ModelLimits, Robot};
use crate::spec::{AngleUnit, ConventionSpec, LengthUnit, LinkSpec, RobotSpec, TransformSpec};
use parse::{UrdfJoint, UrdfJointKind, list};

/// Configurations at which an import is checked against the URDF.
pub const CHECKS: usize = 300;

/// Relative agreement required between the table and the URDF (of the
/// chain's size: the sum of its origin offsets, at least 1 m).
pub const TOLERANCE: f64 = 1e-12;

/// What to import: a URDF document, the chain's ends and the convention.
#[derive(Clone, Debug, PartialEq)]
pub struct UrdfImport {
    /// The robot's name in kinserve.
    pub name: String,
    /// The URDF document (XML).
    pub urdf: String,
    /// The chain's first link (default: the URDF's root, when it has one).
    pub base_link: Option<String>,
    /// The chain's last link (default: the only leaf below the base).
    pub tip_link: Option<String>,
    /// The DH convention of the table.
    pub convention: ConventionSpec,
}

/// Converts the chain of `req` into a robot model (metres, radians; one row
/// per movable joint, named after it, with its limits; fixed joints folded
/// into the frames, the base and the tool). The table is checked against the
/// URDF's forward kinematics at 300 configurations to 1e-12 of the chain's size.
///
/// ```
/// use kinserve_model::{ConventionSpec, ModelLimits, Robot, UrdfImport, import_urdf};
/// let urdf = r#"<robot name="r">
///   <link name="base"/><link name="l1"/><link name="tip"/>
///   <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
///     <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><limit lower="-2" upper="2"/></joint>
///   <joint name="j2" type="continuous"><parent link="l1"/><child link="tip"/>
///     <origin xyz="0.5 0 0" rpy="1.5707963267948966 0 0"/><axis xyz="0 0 -1"/></joint>
/// </robot>"#;
/// let req = UrdfImport { name: "two".into(), urdf: urdf.into(), base_link: None,
///     tip_link: None, convention: ConventionSpec::Standard };
/// let spec = import_urdf(&req).unwrap();
/// assert_eq!(spec.links.len(), 2);
/// assert_eq!(spec.links[0].limits, Some([-2.0, 2.0]));
/// let robot = Robot::from_spec(spec, &ModelLimits::default()).unwrap();
/// assert_eq!(robot.dof(), 2);
/// ```
pub fn import_urdf(req: &UrdfImport) -> Result<RobotSpec> {
    import_urdf_with(req, &ModelLimits::default())
}

/// [`import_urdf`] under `limits`: a chain with more movable joints or joints
/// in all than a model may have is refused before it is converted.
pub fn import_urdf_with(req: &UrdfImport, limits: &ModelLimits) -> Result<RobotSpec> {
    let urdf = parse::parse(&req.urdf)?;
    if let Some(base) = &req.base_link
        && !urdf.links.contains(base)
    {
        return Err(ModelError::invalid_field(
            "base_link",
            format!(
                "no link '{base}' in the URDF (its links: {})",
                list(urdf.links.iter().map(String::as_str))
            ),
        ));
    }
    let base = match &req.base_link {
        Some(b) => b.clone(),
        None => only("base_link", "root", urdf.roots())?,
    };
    let tip = match &req.tip_link {
        Some(t) => t.clone(),
        None => only("tip_link", "leaf", leaves_below(&urdf, &base))?,
    };
    let chain = urdf.chain(&base, &tip)?;
    let movable = chain
        .iter()
        .filter(|j| j.kind != UrdfJointKind::Fixed)
        .count();
    if movable > limits.max_joints || movable > limits.max_links {
        return Err(ModelError::invalid_field(
            "tip_link",
            format!(
                "the chain from '{base}' to '{tip}' has {movable} movable joints, more than a model may have ({}): choose a tip link nearer the base",
                limits.max_joints.min(limits.max_links)
            ),
        ));
    }
    supported(&chain)?;
    let (axes, tip_frame) = convert::axes(&chain);
    if axes.is_empty() {
        return Err(ModelError::invalid_field(
            "tip_link",
            format!("no movable joint between '{base}' and '{tip}': choose a tip further down"),
        ));
    }
    let size = chain
        .iter()
        .map(|j| {
            j.origin
                .translation
                .iter()
                .map(|v| v * v)
                .sum::<f64>()
                .sqrt()
        })
        .sum::<f64>()
        .max(1.0);
    let frames = convert::dh_frames(&axes, req.convention, size);
    let spec = table(req, &urdf.name, (&base, &tip), &axes, &frames, tip_frame)?;
    check(&spec, &chain, &axes, size)?;
    Ok(spec)
}

/// The one candidate, or a refusal listing them.
fn only(field: &str, what: &str, candidates: Vec<&str>) -> Result<String> {
    match candidates.as_slice() {
        [one] => Ok((*one).to_string()),
        [] => Err(ModelError::invalid_field(
            field,
            format!("the URDF has no {what} link: name the {field}"),
        )),
        many => Err(ModelError::invalid_field(
            field,
            format!(
                "the URDF has {} {what} links, name the {field}: one of {}",
                many.len(),
                list(many.iter().copied())
            ),
        )),
    }
}

/// The leaves of the tree under `base`.
fn leaves_below<'a>(urdf: &'a parse::Urdf, base: &str) -> Vec<&'a str> {
    urdf.leaves()
        .into_iter()
        .filter(|l| urdf.chain(base, l).is_ok())
        .collect()
}

/// Refuses joints a DH table cannot hold, naming them.
fn supported(chain: &[&UrdfJoint]) -> Result<()> {
    for j in chain {
        if let UrdfJointKind::Unsupported(kind) = j.kind {
            return Err(ModelError::invalid_field(
                "urdf",
                format!(
                    "joint '{}' is {kind} (more than one degree of freedom): choose a base link below it or a tip link above it",
                    j.name
                ),
            ));
        }
        if let Some(m) = &j.mimic {
            return Err(ModelError::invalid_field(
                "urdf",
                format!(
                    "joint '{}' mimics '{m}': choose a tip link above it",
                    j.name
                ),
            ));
        }
    }
    Ok(())
}

fn matrix_spec(t: &Transform) -> Option<TransformSpec> {
    (t.max_abs_diff(&Transform::IDENTITY) > 0.0).then(|| TransformSpec {
        matrix: Some(t.matrix()),
        ..TransformSpec::default()
    })
}

/// The model: one row per axis, the base `F_0` and the tool `F_n⁻¹ · tip`.
fn table(
    req: &UrdfImport,
    robot: &str,
    (base, tip): (&str, &str),
    axes: &[convert::Axis],
    frames: &[Transform],
    tip_frame: Transform,
) -> Result<RobotSpec> {
    let mut links = Vec::with_capacity(axes.len());
    for (i, axis) in axes.iter().enumerate() {
        let (r, off) = convert::row(&frames[i], &frames[i + 1], req.convention);
        if off > 1e-9 {
            return Err(convert::mismatch(&axis.joint.name, off));
        }
        // `+ 0.0` turns a negative zero into zero (it printed as `-0.0`).
        links.push(LinkSpec {
            name: Some(axis.joint.name.clone()),
            joint: convert::joint_type(axis.joint.kind),
            a: r.a + 0.0,
            alpha: r.alpha + 0.0,
            d: r.d + 0.0,
            theta: r.theta + 0.0,
            limits: axis.joint.limits.map(|(lo, hi)| [lo, hi]),
        });
    }
    let last = frames.last().expect("n + 1 frames");
    Ok(RobotSpec {
        name: req.name.clone(),
        // Names the model may not carry in its text are left out of it.
        description: Some(format!(
            "Imported from the URDF robot '{robot}', links '{base}' to '{tip}'"
        ))
        .filter(|d| crate::text::check_text(d).is_ok())
        .or_else(|| Some("Imported from a URDF".into())),
        source: Some("URDF import (kinserve)".into()),
        convention: req.convention,
        angle_unit: AngleUnit::Rad,
        length_unit: LengthUnit::M,
        base: matrix_spec(&frames[0]),
        tool: matrix_spec(&last.inverse().compose(&tip_frame)),
        links,
    })
}

/// Checks the table against the URDF's forward kinematics at [`CHECKS`]
/// configurations (within the limits; ±π or ±1 m without); on a mismatch,
/// names the first joint from which they part.
fn check(spec: &RobotSpec, chain: &[&UrdfJoint], axes: &[convert::Axis], size: f64) -> Result<()> {
    let limits = ModelLimits {
        max_joints: axes.len().max(ModelLimits::default().max_joints),
        max_links: axes.len().max(ModelLimits::default().max_links),
    };
    let robot = Robot::from_spec(spec.clone(), &limits)?;
    let mut rng = 0x2545_f491_4f6c_dd1d_u64;
    let mut sample = |lo: f64, hi: f64| {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        lo + (hi - lo) * (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let range = |a: &convert::Axis| match (a.joint.limits, a.joint.kind) {
        (Some(l), _) => l,
        (None, UrdfJointKind::Prismatic) => (-1.0, 1.0),
        (None, _) => (-std::f64::consts::PI, std::f64::consts::PI),
    };
    let off = |q: &[f64]| {
        robot
            .chain()
            .forward(q, 1.0)
            .max_abs_diff(&convert::urdf_fk(chain, q))
    };
    for _ in 0..CHECKS {
        let q: Vec<f64> = axes
            .iter()
            .map(|a| {
                let (lo, hi) = range(a);
                sample(lo, hi)
            })
            .collect();
        let e = off(&q);
        if e > TOLERANCE * size {
            // Move one joint more at a time: the first that parts is named.
            for (k, axis) in axes.iter().enumerate() {
                let partial: Vec<f64> = q
                    .iter()
                    .enumerate()
                    .map(|(i, v)| if i <= k { *v } else { 0.0 })
                    .collect();
                let e = off(&partial);
                if e > TOLERANCE * size {
                    return Err(convert::mismatch(&axis.joint.name, e));
                }
            }
            return Err(convert::mismatch(&axes[0].joint.name, e));
        }
    }
    Ok(())
}
