//! The validated robot: [`Robot::from_spec`] checks a [`RobotSpec`] rule by
//! rule and compiles it into a kinematic chain. Checking joint values against
//! it ([`Robot::check_joints`]) lives one module up, in `joints.rs`, beside
//! the [`JointVector`](crate::JointVector) it makes.
//!
//! Depends on the spec, base/tool and error modules; must not depend on
//! `joints.rs`, `ik.rs`, `ik_solutions.rs` or `velocity.rs` (they build on
//! this one). It classifies the chain's closed-form IK once ([`Robot::analytic_ik`]).

use std::sync::Arc;

use kinserve_kinematics::analytic_ik::{AnalyticIk, NotAnalytic};
use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, Transform};

use crate::base_tool::{check_bounded, transform_from_spec};
use crate::error::{FieldViolation, ModelError, Result};
use crate::spec::{AngleUnit, ConventionSpec, JointType, LengthUnit, LinkSpec, RobotSpec};
use crate::{MAX_MAGNITUDE, MAX_REVOLUTE_RAD, validate_name};

/// Limits on model size, configurable at start-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModelLimits {
    /// Most movable joints a model may have (default 64).
    pub max_joints: usize,
    /// Most DH rows (movable and fixed) a model may have (default 256).
    pub max_links: usize,
}

impl ModelLimits {
    /// Default of [`ModelLimits::max_joints`]. The evaluators accept chains of
    /// any length; this bounds what a client may register.
    pub const DEFAULT_MAX_JOINTS: usize = 64;
    /// Default of [`ModelLimits::max_links`].
    pub const DEFAULT_MAX_LINKS: usize = 256;
}

impl Default for ModelLimits {
    fn default() -> Self {
        Self {
            max_joints: Self::DEFAULT_MAX_JOINTS,
            max_links: Self::DEFAULT_MAX_LINKS,
        }
    }
}

/// One movable joint of a validated robot.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// Name from the table, or `joint{i}` (1-based) when none was given.
    pub name: String,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Limits on q in internal units (rad for revolute, model length unit for prismatic).
    pub limits: Option<(f64, f64)>,
}

/// Options of an FK evaluation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FkOptions {
    /// Unit of revolute joint values in the request (default rad).
    pub angle_unit: AngleUnit,
    /// Whether values outside the joint limits are an error (default true).
    pub check_limits: bool,
}

impl FkOptions {
    /// Options from a request's optional fields; absent ones take their
    /// defaults (rad, limits checked). The one place every front door builds them.
    pub fn new(angle_unit: Option<AngleUnit>, check_limits: Option<bool>) -> FkOptions {
        FkOptions {
            angle_unit: angle_unit.unwrap_or_default(),
            check_limits: check_limits.unwrap_or(true),
        }
    }
}

impl Default for FkOptions {
    fn default() -> Self {
        Self {
            angle_unit: AngleUnit::Rad,
            check_limits: true,
        }
    }
}

/// A validated robot: the spec as registered plus its compiled chain.
/// Construct it only through [`Robot::from_spec`] (or the parsing helpers).
#[derive(Clone, Debug)]
pub struct Robot {
    spec: RobotSpec,
    chain: Chain,
    joints: Vec<Joint>,
    /// Each joint's limits (internal units), as the solvers take them.
    limits: Vec<Option<(f64, f64)>>,
    /// The closed-form IK, classified once here (or why there is none).
    analytic: Result<Arc<AnalyticIk>, NotAnalytic>,
}

impl Robot {
    /// Validates `spec` and compiles it. Every broken rule is reported, each
    /// naming its field (`links[3].alpha`).
    pub fn from_spec(spec: RobotSpec, limits: &ModelLimits) -> Result<Robot> {
        let mut v = Vec::new();
        check_header(&spec, &mut v);
        check_size(&spec, limits, &mut v)?;
        let to_rad = spec.angle_unit.to_rad();
        let mut rows = Vec::with_capacity(spec.links.len());
        let mut joints = Vec::new();
        for (i, l) in spec.links.iter().enumerate() {
            let (row, joint) = compile_row(i, l, to_rad, joints.len(), &mut v);
            rows.push(row);
            joints.extend(joint);
        }
        let base = spec
            .base
            .as_ref()
            .map(|t| transform_from_spec(t, "base", to_rad, &mut v))
            .unwrap_or(Transform::IDENTITY);
        let tool = spec
            .tool
            .as_ref()
            .map(|t| transform_from_spec(t, "tool", to_rad, &mut v));
        if spec.angle_unit == AngleUnit::Rad {
            check_not_degrees(&spec, &mut v);
        }
        if !v.is_empty() {
            return Err(ModelError::invalid(v));
        }
        let convention = match spec.convention {
            ConventionSpec::Standard => Convention::Standard,
            ConventionSpec::Modified => Convention::Modified,
        };
        let chain = Chain::new(convention, &rows, base, tool);
        let analytic = AnalyticIk::new(&chain).map(Arc::new);
        let limits = joints.iter().map(|j| j.limits).collect();
        Ok(Robot {
            spec,
            chain,
            joints,
            limits,
            analytic,
        })
    }

    /// The arm's closed-form IK (every solution; classified at
    /// registration), or why it has none: not six joints, a prismatic joint,
    /// or a geometry without a closed form here.
    pub fn analytic_ik(&self) -> std::result::Result<&AnalyticIk, NotAnalytic> {
        self.analytic.as_deref().map_err(|e| *e)
    }

    /// The closed-form class (`spherical_wrist_parallel_23`,
    /// `three_parallel_234`, …), or `None` when only the numeric solver applies.
    pub fn ik_class(&self) -> Option<&'static str> {
        self.analytic.as_ref().ok().map(|ik| ik.class().name())
    }

    /// The robot's name.
    pub fn name(&self) -> &str {
        &self.spec.name
    }

    /// Number of movable joints (length of a joint vector).
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The model exactly as registered.
    pub fn spec(&self) -> &RobotSpec {
        &self.spec
    }

    /// The compiled chain. Its evaluators are unchecked (the math layer);
    /// go through [`Robot::check_joints`] for anything a client sent.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Movable joints in table order.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Each joint's limits in internal units (rad / length unit; `None`:
    /// unlimited), in the form the IK solvers take, kept from registration.
    pub fn limits(&self) -> &[Option<(f64, f64)>] {
        &self.limits
    }

    /// Length unit of this robot's positions.
    pub fn length_unit(&self) -> LengthUnit {
        self.spec.length_unit
    }
}

/// Name, description and source.
fn check_header(spec: &RobotSpec, v: &mut Vec<FieldViolation>) {
    if let Err(m) = validate_name(&spec.name) {
        v.push(FieldViolation::new("name", m));
    }
    for (field, text) in [("description", &spec.description), ("source", &spec.source)] {
        if let Some(Err(m)) = text.as_deref().map(crate::text::check_text) {
            v.push(FieldViolation::new(field, m));
        }
    }
}

/// Row and joint counts; a table over the row limit is refused before its rows are walked.
fn check_size(spec: &RobotSpec, limits: &ModelLimits, v: &mut Vec<FieldViolation>) -> Result<()> {
    let n_links = spec.links.len();
    if n_links == 0 {
        v.push(FieldViolation::new("links", "must hold at least one row"));
    }
    if n_links > limits.max_links {
        v.push(FieldViolation::new(
            "links",
            format!(
                "at most {} rows are allowed, got {n_links}",
                limits.max_links
            ),
        ));
        return Err(ModelError::invalid(std::mem::take(v)));
    }
    let movable = spec
        .links
        .iter()
        .filter(|l| l.joint != JointType::Fixed)
        .count();
    if n_links > 0 && movable == 0 {
        v.push(FieldViolation::new(
            "links",
            "needs at least one revolute or prismatic joint",
        ));
    }
    if movable > limits.max_joints {
        v.push(FieldViolation::new(
            "links",
            format!(
                "at most {} movable joints are allowed, got {movable}",
                limits.max_joints
            ),
        ));
    }
    Ok(())
}

/// Checks row `i` and converts it to internal units; the joint, if the row is
/// movable (`index` joints came before it).
/// Largest revolute limit (rad) a radian table may have: 8 turns. Beyond it
/// (or a DH angle beyond a turn) the numbers are only plausible as degrees.
pub const MAX_PLAUSIBLE_LIMIT_RAD: f64 = 16.0 * std::f64::consts::PI;

/// A table in radians whose angles are only plausible as degrees (`alpha:
/// 90`, limits `±170`) is refused, saying how to fix it: it would otherwise
/// be read as radians and give wrong poses without a word.
fn check_not_degrees(spec: &RobotSpec, v: &mut Vec<FieldViolation>) {
    let turn = 2.0 * std::f64::consts::PI + 1e-9;
    let hint = "this table reads as degrees: add \"angle_unit\": \"deg\" to the model, or write its angles in radians";
    for (i, l) in spec.links.iter().enumerate() {
        for (name, x) in [("alpha", l.alpha), ("theta", l.theta)] {
            if x.abs() > turn && x.abs() <= MAX_MAGNITUDE {
                v.push(FieldViolation::new(
                    format!("links[{i}].{name}"),
                    format!("{x} rad is more than a full turn; {hint}"),
                ));
            }
        }
        if let (JointType::Revolute, Some([lo, hi])) = (l.joint, l.limits)
            && lo.abs().max(hi.abs()) > MAX_PLAUSIBLE_LIMIT_RAD
            && lo.abs().max(hi.abs()) <= MAX_REVOLUTE_RAD
        {
            v.push(FieldViolation::new(
                format!("links[{i}].limits"),
                format!("[{lo}, {hi}] rad is more than 8 turns; {hint}"),
            ));
        }
    }
}

fn compile_row(
    i: usize,
    l: &LinkSpec,
    to_rad: f64,
    index: usize,
    v: &mut Vec<FieldViolation>,
) -> (DhRow, Option<Joint>) {
    let f = |name: &str| format!("links[{i}].{name}");
    for (name, x) in [
        ("a", l.a),
        ("alpha", l.alpha),
        ("d", l.d),
        ("theta", l.theta),
    ] {
        check_bounded(v, || f(name), x);
    }
    if let Some(Err(m)) = l.name.as_deref().map(crate::text::check_label) {
        v.push(FieldViolation::new(f("name"), m));
    }
    let kind = match l.joint {
        JointType::Revolute => JointKind::Revolute,
        JointType::Prismatic => JointKind::Prismatic,
        JointType::Fixed => JointKind::Fixed,
    };
    let scale = if kind == JointKind::Revolute {
        to_rad
    } else {
        1.0
    };
    let limits = l
        .limits
        .and_then(|lim| check_limits(lim, kind, scale, &f("limits"), v));
    let joint = (kind != JointKind::Fixed).then(|| Joint {
        name: l
            .name
            .clone()
            .unwrap_or_else(|| format!("joint{}", index + 1)),
        kind,
        limits,
    });
    let row = DhRow {
        kind,
        a: l.a,
        alpha: l.alpha * to_rad,
        d: l.d,
        theta: l.theta * to_rad,
    };
    (row, joint)
}

/// Validates a row's `[lo, hi]` limits; in internal units if they hold.
fn check_limits(
    [lo, hi]: [f64; 2],
    kind: JointKind,
    scale: f64,
    field: &str,
    v: &mut Vec<FieldViolation>,
) -> Option<(f64, f64)> {
    let message = if kind == JointKind::Fixed {
        "a fixed row has no joint variable to limit".to_string()
    } else if !lo.is_finite() || !hi.is_finite() {
        "limits must be finite numbers".to_string()
    } else if lo > hi {
        format!("lower limit {lo} is above upper limit {hi}")
    } else if kind == JointKind::Prismatic && (lo.abs() > MAX_MAGNITUDE || hi.abs() > MAX_MAGNITUDE)
    {
        format!("prismatic limits must be within ±{MAX_MAGNITUDE:e} (model length unit)")
    } else if kind == JointKind::Revolute
        && (lo.abs() * scale > MAX_REVOLUTE_RAD || hi.abs() * scale > MAX_REVOLUTE_RAD)
    {
        format!(
            "revolute limits must be within ±{} (model angle unit; ±1e5 rad)",
            round6(MAX_REVOLUTE_RAD / scale)
        )
    } else {
        return Some((lo * scale, hi * scale));
    };
    v.push(FieldViolation::new(field, message));
    None
}

/// `x` with at most 6 significant digits, without trailing zeros (`1.91986`, `0.5`, `160`).
pub(crate) fn round6(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{}", if x == 0.0 { 0.0 } else { x });
    }
    let digits = 5 - x.abs().log10().floor() as i32;
    let s = format!("{:.*}", digits.max(0) as usize, x);
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" { "0".into() } else { s }
}

/// Unit conversions of joint values (requests and answers).
impl Robot {
    /// Joint values in `scale`·rad (revolute) → internal units.
    pub(crate) fn to_internal(&self, q: &[f64], scale: f64) -> Vec<f64> {
        q.iter()
            .zip(self.joints())
            .map(|(x, j)| match j.kind {
                JointKind::Revolute => x * scale,
                _ => *x,
            })
            .collect()
    }

    /// Internal joint values → the request's unit, nudged by an ulp where
    /// rounding would put a value at a limit just outside it (so an answer
    /// always passes [`Robot::check_joints`] in that unit).
    pub(crate) fn to_request_unit(&self, q: &[f64], unit: AngleUnit) -> Vec<f64> {
        let scale = unit.to_rad();
        q.iter()
            .zip(self.joints())
            .map(|(x, j)| {
                if j.kind != JointKind::Revolute || scale == 1.0 {
                    return *x;
                }
                let mut y = x / scale;
                if let Some((lo, hi)) = j.limits {
                    for _ in 0..4 {
                        if y * scale > hi {
                            y = y.next_down();
                        } else if y * scale < lo {
                            y = y.next_up();
                        }
                    }
                }
                y
            })
            .collect()
    }
}
