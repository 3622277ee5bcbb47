//! Robot models: the schema clients write ([`RobotSpec`]), its validation into
//! the only type the math accepts ([`Robot`]), units, JSON parsing with field
//! paths, and the pose representation returned to clients ([`Pose`]).

mod pose;
mod spec;

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::error::{Error, FieldViolation, Result};
use crate::kinematics::{Chain, Convention, DEFAULT_MAX_JOINTS, DhRow, JointKind, Transform};

pub use pose::{FkOutput, Pose, Quaternion};
pub use spec::{
    AngleUnit, ConventionSpec, JointType, LengthUnit, LinkSpec, QuaternionSpec, RobotSpec,
    TransformSpec,
};

/// Tolerance on `RᵀR − I` and `det R − 1` for a matrix to count as rigid.
pub const RIGID_TOLERANCE: f64 = 1e-6;
/// Longest `description` / `source` accepted (characters).
pub const MAX_TEXT_CHARS: usize = 4096;
/// Longest link name accepted (characters).
pub const MAX_LINK_NAME_CHARS: usize = 64;
/// Largest magnitude accepted for a model's DH parameters (`a`, `d`, `alpha`,
/// `theta`), base/tool translations and prismatic limits, and for prismatic
/// joint values in FK requests: 1e9 in the model's own units (m or mm, rad or
/// deg). With at most a few hundred rows every pose then stays many orders of
/// magnitude below `f64::MAX`, so FK never overflows to infinity or NaN.
pub const MAX_MAGNITUDE: f64 = 1e9;

/// Limits on model size, configurable at start-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModelLimits {
    /// Most movable joints a model may have (default 64).
    pub max_joints: usize,
    /// Most DH rows (movable and fixed) a model may have (default 256).
    pub max_links: usize,
}

impl Default for ModelLimits {
    fn default() -> Self {
        Self {
            max_joints: DEFAULT_MAX_JOINTS,
            max_links: 256,
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
}

/// Checks a robot name: 1–64 characters of `[a-z0-9_-]`, first a letter or digit.
pub fn validate_name(name: &str) -> std::result::Result<(), String> {
    if name.is_empty() {
        return Err("must not be empty".into());
    }
    if name.len() > 64 {
        return Err(format!(
            "must be at most 64 characters, got {}",
            name.chars().count()
        ));
    }
    let ok_char = |c: char| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_' || c == '-';
    if !name.chars().all(ok_char) {
        return Err("may contain only lowercase letters a-z, digits, '_' and '-'".into());
    }
    let first = name.as_bytes()[0];
    if !(first.is_ascii_lowercase() || first.is_ascii_digit()) {
        return Err("must start with a lowercase letter or a digit".into());
    }
    Ok(())
}

/// Parses JSON into `T`, turning serde errors into [`Error`]s that name the field.
/// Syntax errors, wrong types and bad values are [`Error::Malformed`]; unknown
/// and missing fields (well-formed JSON breaking the schema) are [`Error::Invalid`].
pub fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T> {
    let de = &mut serde_json::Deserializer::from_slice(bytes);
    let value: T = serde_path_to_error::deserialize(&mut *de).map_err(json_error)?;
    de.end()
        .map_err(|e| Error::malformed_field("", format!("{e}")))?;
    Ok(value)
}

/// Longest field path reported for a JSON error (characters); longer ones are cut.
const MAX_PATH_CHARS: usize = 200;
/// Longest JSON error message reported (characters); longer ones are cut.
const MAX_MESSAGE_CHARS: usize = 300;

/// `s` cut to `max` characters, with `…` when something was cut (client text
/// echoed in an error stays small however large the input was).
fn clip(s: String, max: usize) -> String {
    match s.char_indices().nth(max) {
        None => s,
        Some((i, _)) => {
            let mut cut = s;
            cut.truncate(i);
            cut.push('…');
            cut
        }
    }
}

fn json_error(e: serde_path_to_error::Error<serde_json::Error>) -> Error {
    let mut path = e.path().to_string();
    // serde_path_to_error writes `?` for a map key it could not read (e.g. a
    // single-quoted key) and `.` for the document itself: neither is a field.
    while path == "?" || path.ends_with(".?") {
        path.truncate(path.len() - 1);
        if path.ends_with('.') {
            path.pop();
        }
    }
    if path == "." {
        path.clear();
    }
    let inner = e.into_inner();
    let mut message = inner.to_string();
    // Strip serde_json's " at line L column C": the path already says where.
    if let Some(i) = message.find(" at line ") {
        message.truncate(i);
    }
    let structural = message.starts_with("unknown field") || message.starts_with("missing field");
    let names_a_field = structural || message.starts_with("duplicate field");
    if names_a_field && let Some(field) = message.split('`').nth(1) {
        let already = path.rsplit('.').next() == Some(field);
        if !already {
            path = if path.is_empty() {
                field.to_string()
            } else {
                format!("{path}.{field}")
            };
        }
    }
    let v = FieldViolation::new(clip(path, MAX_PATH_CHARS), clip(message, MAX_MESSAGE_CHARS));
    match inner.classify() {
        serde_json::error::Category::Data if structural => Error::invalid(vec![v]),
        _ => Error::Malformed {
            detail: v.to_string(),
            violations: vec![v],
        },
    }
}

/// Reads and validates a robot file (JSON, the schema of [`RobotSpec`]) with default limits.
pub fn load_robot_file(path: &Path) -> Result<Robot> {
    let bytes = std::fs::read(path).map_err(|e| Error::Malformed {
        detail: format!("cannot read {}: {e}", path.display()),
        violations: Vec::new(),
    })?;
    let spec: RobotSpec = parse_json(&bytes)?;
    Robot::from_spec(spec, &ModelLimits::default())
}

fn check_finite(v: &mut Vec<FieldViolation>, field: impl FnOnce() -> String, x: f64) {
    if !x.is_finite() {
        v.push(FieldViolation::new(field(), "must be a finite number"));
    }
}

/// Finite and at most [`MAX_MAGNITUDE`] in magnitude.
fn check_bounded(v: &mut Vec<FieldViolation>, field: impl FnOnce() -> String, x: f64) {
    if !x.is_finite() {
        v.push(FieldViolation::new(field(), "must be a finite number"));
    } else if x.abs() > MAX_MAGNITUDE {
        v.push(FieldViolation::new(field(), magnitude_message()));
    }
}

fn magnitude_message() -> String {
    format!("must be at most {MAX_MAGNITUDE:e} in magnitude (model units)")
}

/// Validates a base/tool spec and converts it (angles to rad).
fn transform_from_spec(
    t: &TransformSpec,
    field: &str,
    to_rad: f64,
    v: &mut Vec<FieldViolation>,
) -> Transform {
    let before = v.len();
    if let Some(m) = &t.matrix {
        if t.translation.is_some() || t.rpy.is_some() || t.quaternion.is_some() {
            v.push(FieldViolation::new(
                format!("{field}.matrix"),
                "give either matrix alone or translation with rpy or quaternion",
            ));
        }
        for (i, row) in m.iter().enumerate() {
            for (j, x) in row.iter().enumerate() {
                check_finite(v, || format!("{field}.matrix[{i}][{j}]"), *x);
            }
        }
        for (i, row) in m.iter().take(3).enumerate() {
            if row[3].abs() > MAX_MAGNITUDE {
                v.push(FieldViolation::new(
                    format!("{field}.matrix[{i}][3]"),
                    magnitude_message(),
                ));
            }
        }
        if v.len() > before {
            return Transform::IDENTITY;
        }
        if m[3] != [0.0, 0.0, 0.0, 1.0] {
            v.push(FieldViolation::new(
                format!("{field}.matrix[3]"),
                "last row must be [0, 0, 0, 1]",
            ));
        }
        let tr = Transform::from_matrix(m);
        let err = tr.rigidity_error();
        if err > RIGID_TOLERANCE {
            v.push(FieldViolation::new(
                format!("{field}.matrix"),
                format!(
                    "rotation part is not a rigid rotation (orthonormal with det +1 within {RIGID_TOLERANCE:e}; off by {err:.3e})"
                ),
            ));
            return tr;
        }
        // Accepted within the tolerance: use the nearest exact rotation (through
        // its unit quaternion), so that base and tool errors cannot add up to a
        // non-rigid pose.
        return Transform::from_translation_quaternion(tr.translation, tr.quaternion())
            .unwrap_or(tr);
    }
    if t.rpy.is_some() && t.quaternion.is_some() {
        v.push(FieldViolation::new(
            format!("{field}.quaternion"),
            "give rpy or quaternion, not both",
        ));
    }
    let translation = t.translation.unwrap_or([0.0; 3]);
    for (i, x) in translation.iter().enumerate() {
        check_bounded(v, || format!("{field}.translation[{i}]"), *x);
    }
    if let Some(rpy) = t.rpy {
        for (i, x) in rpy.iter().enumerate() {
            check_finite(v, || format!("{field}.rpy[{i}]"), *x);
        }
        if v.len() > before {
            return Transform::IDENTITY;
        }
        return Transform::from_translation_rpy(
            translation,
            [rpy[0] * to_rad, rpy[1] * to_rad, rpy[2] * to_rad],
        );
    }
    if let Some(q) = t.quaternion {
        for (name, x) in [("w", q.w), ("x", q.x), ("y", q.y), ("z", q.z)] {
            check_finite(v, || format!("{field}.quaternion.{name}"), x);
        }
        if v.len() > before {
            return Transform::IDENTITY;
        }
        return match Transform::from_translation_quaternion(translation, [q.w, q.x, q.y, q.z]) {
            Some(tr) => tr,
            None => {
                v.push(FieldViolation::new(
                    format!("{field}.quaternion"),
                    "must not be zero",
                ));
                Transform::IDENTITY
            }
        };
    }
    Transform::translation(translation[0], translation[1], translation[2])
}

impl Robot {
    /// Validates `spec` and compiles it. Every broken rule is reported, each
    /// naming its field (`links[3].alpha`).
    pub fn from_spec(spec: RobotSpec, limits: &ModelLimits) -> Result<Robot> {
        let mut v = Vec::new();
        if let Err(m) = validate_name(&spec.name) {
            v.push(FieldViolation::new("name", m));
        }
        for (field, text) in [("description", &spec.description), ("source", &spec.source)] {
            if let Some(t) = text
                && t.chars().count() > MAX_TEXT_CHARS
            {
                v.push(FieldViolation::new(
                    field,
                    format!("must be at most {MAX_TEXT_CHARS} characters"),
                ));
            }
        }
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
            // Do not walk a huge table.
            return Err(Error::invalid(v));
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
        let to_rad = spec.angle_unit.to_rad();
        let mut rows = Vec::with_capacity(n_links);
        let mut joints = Vec::with_capacity(movable);
        for (i, l) in spec.links.iter().enumerate() {
            let f = |name: &str| format!("links[{i}].{name}");
            for (name, x) in [
                ("a", l.a),
                ("alpha", l.alpha),
                ("d", l.d),
                ("theta", l.theta),
            ] {
                check_bounded(&mut v, || f(name), x);
            }
            if let Some(name) = &l.name
                && name.chars().count() > MAX_LINK_NAME_CHARS
            {
                v.push(FieldViolation::new(
                    f("name"),
                    format!("must be at most {MAX_LINK_NAME_CHARS} characters"),
                ));
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
            let mut lim = None;
            if let Some([lo, hi]) = l.limits {
                if kind == JointKind::Fixed {
                    v.push(FieldViolation::new(
                        f("limits"),
                        "a fixed row has no joint variable to limit",
                    ));
                } else if !lo.is_finite() || !hi.is_finite() {
                    v.push(FieldViolation::new(
                        f("limits"),
                        "limits must be finite numbers",
                    ));
                } else if lo > hi {
                    v.push(FieldViolation::new(
                        f("limits"),
                        format!("lower limit {lo} is above upper limit {hi}"),
                    ));
                } else if kind == JointKind::Prismatic
                    && (lo.abs() > MAX_MAGNITUDE || hi.abs() > MAX_MAGNITUDE)
                {
                    v.push(FieldViolation::new(
                        f("limits"),
                        format!(
                            "prismatic limits must be within ±{MAX_MAGNITUDE:e} (model length unit)"
                        ),
                    ));
                } else {
                    lim = Some((lo * scale, hi * scale));
                }
            }
            if kind != JointKind::Fixed {
                joints.push(Joint {
                    name: l
                        .name
                        .clone()
                        .unwrap_or_else(|| format!("joint{}", joints.len() + 1)),
                    kind,
                    limits: lim,
                });
            }
            rows.push(DhRow {
                kind,
                a: l.a,
                alpha: l.alpha * to_rad,
                d: l.d,
                theta: l.theta * to_rad,
            });
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
        if !v.is_empty() {
            return Err(Error::invalid(v));
        }
        let convention = match spec.convention {
            ConventionSpec::Standard => Convention::Standard,
            ConventionSpec::Modified => Convention::Modified,
        };
        let chain = Chain::new(convention, &rows, base, tool);
        Ok(Robot {
            spec,
            chain,
            joints,
        })
    }

    /// Parses a JSON model and validates it.
    pub fn from_json(bytes: &[u8], limits: &ModelLimits) -> Result<Robot> {
        let spec: RobotSpec = parse_json(bytes)?;
        Robot::from_spec(spec, limits)
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

    /// The compiled chain.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Movable joints in table order.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Length unit of this robot's positions.
    pub fn length_unit(&self) -> LengthUnit {
        self.spec.length_unit
    }

    /// Checks a joint vector: count, finiteness, prismatic values within
    /// ±[`MAX_MAGNITUDE`] and (if asked) limits.
    /// Field paths are `joints[i]`.
    pub fn check_joints(&self, q: &[f64], opts: &FkOptions) -> Result<()> {
        self.check_joints_at(q, opts, || "joints".to_string())
    }

    /// Like [`Robot::check_joints`], with the vector's field path given lazily
    /// (e.g. `configurations[17]`, giving `configurations[17][2]`).
    pub fn check_joints_at(
        &self,
        q: &[f64],
        opts: &FkOptions,
        field: impl Fn() -> String,
    ) -> Result<()> {
        if q.len() != self.joints.len() {
            return Err(Error::invalid_field(
                field(),
                format!(
                    "robot '{}' has {} movable joints, got {} values",
                    self.name(),
                    self.joints.len(),
                    q.len()
                ),
            ));
        }
        let scale = opts.angle_unit.to_rad();
        for (i, (x, j)) in q.iter().zip(&self.joints).enumerate() {
            if !x.is_finite() {
                return Err(Error::invalid_field(
                    format!("{}[{i}]", field()),
                    "must be a finite number",
                ));
            }
            if j.kind == JointKind::Prismatic && x.abs() > MAX_MAGNITUDE {
                let unit = self.spec.length_unit.as_str();
                return Err(Error::invalid_field(
                    format!("{}[{i}]", field()),
                    format!(
                        "{x} {unit} is beyond ±{MAX_MAGNITUDE:e} {unit}, the largest prismatic joint value accepted"
                    ),
                ));
            }
            if !opts.check_limits {
                continue;
            }
            if let Some((lo, hi)) = j.limits {
                let internal = if j.kind == JointKind::Revolute {
                    x * scale
                } else {
                    *x
                };
                if internal < lo || internal > hi {
                    let (unit, k) = match j.kind {
                        JointKind::Revolute => (opts.angle_unit.as_str(), 1.0 / scale),
                        _ => (self.spec.length_unit.as_str(), 1.0),
                    };
                    return Err(Error::invalid_field(
                        format!("{}[{i}]", field()),
                        format!(
                            "{x} {unit} is outside the limits [{}, {}] {unit} of joint '{}'",
                            lo * k,
                            hi * k,
                            j.name
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Checked FK: validates `q` (see [`Robot::check_joints`]) and returns the tool pose.
    pub fn fk_checked(&self, q: &[f64], opts: &FkOptions) -> Result<Transform> {
        self.check_joints(q, opts)?;
        Ok(self.chain.forward(q, opts.angle_unit.to_rad()))
    }

    /// Unchecked FK for `q` in rad (revolute) and model length unit (prismatic):
    /// no count, finiteness or limit checks (missing values count as 0).
    pub fn fk_unchecked(&self, q: &[f64]) -> Transform {
        self.chain.forward(q, 1.0)
    }

    /// Checked FK with every frame: `frames[0]` is the base frame `^world T_0`,
    /// `frames[i]` the frame after DH row `i` (the last is the flange); the tool
    /// pose is the first element of the pair.
    pub fn fk_frames_checked(
        &self,
        q: &[f64],
        opts: &FkOptions,
    ) -> Result<(Transform, Vec<Transform>)> {
        self.check_joints(q, opts)?;
        Ok(self.chain.forward_frames(q, opts.angle_unit.to_rad()))
    }
}
