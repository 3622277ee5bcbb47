//! Inverse-kinematics requests as clients write them ([`IkSpec`],
//! [`IkBatchSpec`], [`IkTargetSpec`]), their validation with field paths
//! (`target.matrix[3]`, `targets[2].quaternion`, `tolerance`, `seed[1]`) into
//! [`IkRequest`] / [`IkBatch`] — the only input the solver accepts — and the
//! answers in the request's angle unit ([`IkAnswer`]).
//!
//! Units: targets in the world frame and the robot's length unit; seeds and
//! answers in the request's `angle_unit` (revolute) and the robot's length
//! unit (prismatic); `tolerance` in the length unit (position) and rad
//! (orientation). Depends on the kinematics crate (feature `ik`), serde and
//! the robot, joints and base/tool modules; nothing async, no protocol.

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use kinserve_kinematics::ik::{
    DEFAULT_MAX_ITERATIONS, DEFAULT_RESTARTS, DEFAULT_TOLERANCE, IkOptions, IkSolution, IkSolver,
};
use kinserve_kinematics::{JointKind, Transform};
use serde::{Deserialize, Serialize};

use crate::base_tool::{check_bounded, check_finite, rigid_from_matrix};
use crate::error::{FieldViolation, ModelError, Result};
use crate::robot::{FkOptions, Robot};
use crate::spec::{AngleUnit, QuaternionSpec, object_only};

/// Smallest and largest `tolerance` accepted.
pub const IK_TOLERANCE_RANGE: (f64, f64) = (1e-15, 1e3);
/// Largest `max_iterations` accepted (per attempt).
pub const IK_MAX_ITERATIONS: u32 = 10_000;
/// Largest `restarts` accepted.
pub const IK_MAX_RESTARTS: u32 = 1_000;

/// An IK target pose in the world frame: `matrix` alone, or `position` with
/// `quaternion` (the quaternion may be left out when `position_only` is set).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields, remote = "Self")]
#[cfg_attr(feature = "openapi", schema(example = json!({
    "position": [0.3161255029988693, -0.044619601375991136, 0.8782707984072009],
    "quaternion": {"w": 0.8401820867347285, "x": 0.20769568623856688, "y": -0.4940114485076959, "z": 0.08312190921349348}
})))]
pub struct IkTargetSpec {
    /// Homogeneous 4×4 matrix, row-major; must be rigid (within 1e-6, last row
    /// 0 0 0 1). Translation in the robot's length unit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matrix: Option<[[f64; 4]; 4]>,
    /// `[x, y, z]` in the robot's length unit, each at most 1e9 in magnitude.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<[f64; 3]>,
    /// Orientation (normalised; must not be zero).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quaternion: Option<QuaternionSpec>,
}

/// `POST /v1/robots/{name}/ik`: one target.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields, remote = "Self")]
#[cfg_attr(feature = "openapi", schema(example = json!({
    "target": {"position": [0.3161255029988693, -0.044619601375991136, 0.8782707984072009],
        "quaternion": {"w": 0.8401820867347285, "x": 0.20769568623856688, "y": -0.4940114485076959, "z": 0.08312190921349348}},
    "angle_unit": "deg"
})))]
pub struct IkSpec {
    /// The pose to reach.
    pub target: IkTargetSpec,
    /// Start configuration (e.g. the previous answer when tracking), in
    /// `angle_unit`; must be within the joint limits. Absent: the middle of
    /// each joint's range, then deterministic restarts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<Vec<f64>>,
    /// Unit of revolute values in `seed` and in the answer (default `rad`).
    #[serde(default)]
    pub angle_unit: AngleUnit,
    /// Match the position only (default false).
    #[serde(default)]
    pub position_only: bool,
    /// Convergence tolerance: length unit for the position, rad for the
    /// orientation (default 1e-9; 1e-15 to 1e3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Iterations per attempt (default 100; 1 to 10,000).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_iterations: Option<u32>,
    /// Restarts from new configurations after a stalled attempt (default 100; 0 to 1,000).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restarts: Option<u32>,
}

/// `POST /v1/robots/{name}/ik/batch`: many targets, solved in order, each
/// seeded with the previous converged answer (tracking a path).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields, remote = "Self")]
#[cfg_attr(feature = "openapi", schema(example = json!({
    "targets": [{"position": [0.5, 0.3, 0.0]}, {"position": [0.5, 0.32, 0.0]}],
    "position_only": true
})))]
pub struct IkBatchSpec {
    /// The poses to reach, in order.
    pub targets: Vec<IkTargetSpec>,
    /// Start configuration of the first target (see [`IkSpec::seed`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<Vec<f64>>,
    /// Unit of revolute values in `seed` and in the answers (default `rad`).
    #[serde(default)]
    pub angle_unit: AngleUnit,
    /// Match positions only (default false).
    #[serde(default)]
    pub position_only: bool,
    /// See [`IkSpec::tolerance`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// See [`IkSpec::max_iterations`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_iterations: Option<u32>,
    /// See [`IkSpec::restarts`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restarts: Option<u32>,
}

object_only!(IkTargetSpec);
object_only!(IkSpec);
object_only!(IkBatchSpec);

/// A validated target: the pose, and whether an orientation was given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkTarget {
    /// The pose (identity rotation when no orientation was given).
    pub pose: Transform,
    /// Whether the target carries an orientation.
    pub oriented: bool,
}

/// An IK request that passed validation for its robot.
#[derive(Clone, Debug)]
pub struct IkRequest<'a> {
    robot: &'a Robot,
    target: IkTarget,
    /// Seed in internal units (rad / length unit).
    seed: Option<Vec<f64>>,
    options: IkOptions,
    angle_unit: AngleUnit,
}

/// Many validated targets with shared options.
#[derive(Clone, Debug)]
pub struct IkBatch<'a> {
    robot: &'a Robot,
    targets: Vec<IkTarget>,
    seed: Option<Vec<f64>>,
    options: IkOptions,
    angle_unit: AngleUnit,
}

/// The answer to one target, in the request's units.
#[derive(Clone, Debug, PartialEq)]
pub struct IkAnswer {
    /// Joint values: revolute in the request's angle unit, prismatic in the
    /// robot's length unit; always within the joint limits.
    pub joints: Vec<f64>,
    /// Whether the errors are within the tolerance.
    pub converged: bool,
    /// Distance between the target and the reached position (length unit).
    pub position_error: f64,
    /// Angle between the target and the reached orientation (rad); `None`
    /// when the target has no orientation.
    pub orientation_error: Option<f64>,
    /// Solver iterations over all attempts.
    pub iterations: u32,
    /// Tool pose at `joints`.
    pub pose: Transform,
}

/// The shared options of single and batch requests, as written.
struct OptionFields<'a> {
    seed: Option<&'a [f64]>,
    angle_unit: AngleUnit,
    position_only: bool,
    tolerance: Option<f64>,
    max_iterations: Option<u32>,
    restarts: Option<u32>,
}

impl Robot {
    /// Validates an IK request: every broken rule is reported under its field
    /// path (`target.matrix[3]`, `tolerance`, `seed[2]`).
    ///
    /// The validated [`IkRequest`] is what the solver takes ([`IkRequest::solve`]):
    ///
    /// ```
    /// use kinserve_model::{FkOptions, IkSpec, IkTargetSpec, ModelLimits, Robot};
    ///
    /// let robot = Robot::from_json(br#"{"name": "planar", "convention": "standard", "links": [
    ///     {"joint": "revolute", "a": 0.4, "alpha": 0, "d": 0, "theta": 0},
    ///     {"joint": "revolute", "a": 0.3, "alpha": 0, "d": 0, "theta": 0, "limits": [0, 3]}
    /// ]}"#, &ModelLimits::default())?;
    ///
    /// // A position some configuration reaches, asked for without an orientation.
    /// let goal = robot.fk(&[0.3, 0.6], &FkOptions::default())?.position();
    /// let target = IkTargetSpec { position: Some(goal), ..IkTargetSpec::default() };
    /// let spec = IkSpec { target, position_only: true, ..IkSpec::default() };
    ///
    /// let request = robot.check_ik(&spec)?;
    /// let answer = request.solve(None); // no time cap
    /// assert!(answer.converged && answer.position_error <= request.options().tolerance);
    /// assert_eq!(answer.orientation_error, None);
    /// // The answer keeps the limits, and its pose is the FK of its joints.
    /// let pose = robot.fk(&answer.joints, &FkOptions::default())?;
    /// assert!(pose.max_abs_diff(&answer.pose) < 1e-12);
    ///
    /// // Without position_only a target needs its orientation too.
    /// let oriented = IkSpec { position_only: false, ..spec.clone() };
    /// let refused = robot.check_ik(&oriented).unwrap_err();
    /// assert_eq!(refused.violations()[0].field, "target.quaternion");
    /// # Ok::<(), kinserve_model::ModelError>(())
    /// ```
    pub fn check_ik<'a>(&'a self, spec: &IkSpec) -> Result<IkRequest<'a>> {
        let mut v = Vec::new();
        let target = check_target(&spec.target, spec.position_only, "target", &mut v);
        let (seed, options) = self.check_options(&spec.option_fields(), &mut v);
        if !v.is_empty() {
            return Err(ModelError::invalid(v));
        }
        Ok(IkRequest {
            robot: self,
            target,
            seed,
            options,
            angle_unit: spec.angle_unit,
        })
    }

    /// Validates a batch IK request (`targets[3].matrix[3]`, `tolerance`…).
    /// The batch size limit is the caller's.
    pub fn check_ik_batch<'a>(&'a self, spec: &IkBatchSpec) -> Result<IkBatch<'a>> {
        let mut v = Vec::new();
        let targets = spec
            .targets
            .iter()
            .enumerate()
            .map(|(i, t)| check_target(t, spec.position_only, &format!("targets[{i}]"), &mut v))
            .collect();
        let (seed, options) = self.check_options(&spec.option_fields(), &mut v);
        if !v.is_empty() {
            return Err(ModelError::invalid(v));
        }
        Ok(IkBatch {
            robot: self,
            targets,
            seed,
            options,
            angle_unit: spec.angle_unit,
        })
    }

    /// Seed (in internal units) and solver options, or violations.
    fn check_options(
        &self,
        o: &OptionFields<'_>,
        v: &mut Vec<FieldViolation>,
    ) -> (Option<Vec<f64>>, IkOptions) {
        let scale = o.angle_unit.to_rad();
        let seed = o.seed.and_then(|s| {
            let opts = FkOptions::new(Some(o.angle_unit), Some(true));
            match self.check_joints_at(s, &opts, || "seed".to_string()) {
                Ok(_) => Some(self.to_internal(s, scale)),
                Err(e) => {
                    v.extend(e.violations().iter().cloned());
                    None
                }
            }
        });
        let tolerance = o.tolerance.unwrap_or(DEFAULT_TOLERANCE);
        let (lo, hi) = IK_TOLERANCE_RANGE;
        if !(lo..=hi).contains(&tolerance) {
            v.push(FieldViolation::new(
                "tolerance",
                format!("must be a number from {lo:e} to {hi:e}, got {tolerance}"),
            ));
        }
        let max_iterations = o.max_iterations.unwrap_or(DEFAULT_MAX_ITERATIONS);
        if !(1..=IK_MAX_ITERATIONS).contains(&max_iterations) {
            v.push(FieldViolation::new(
                "max_iterations",
                format!("must be from 1 to {IK_MAX_ITERATIONS}, got {max_iterations}"),
            ));
        }
        let restarts = o.restarts.unwrap_or(DEFAULT_RESTARTS);
        if restarts > IK_MAX_RESTARTS {
            v.push(FieldViolation::new(
                "restarts",
                format!("must be from 0 to {IK_MAX_RESTARTS}, got {restarts}"),
            ));
        }
        let options = IkOptions {
            position_only: o.position_only,
            tolerance,
            max_iterations,
            restarts,
            ..IkOptions::default()
        };
        (seed, options)
    }

    /// Joint values in `scale`·rad (revolute) → internal units.
    fn to_internal(&self, q: &[f64], scale: f64) -> Vec<f64> {
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
    fn to_request_unit(&self, q: &[f64], unit: AngleUnit) -> Vec<f64> {
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

    fn solver(&self) -> IkSolver<'_> {
        let limits: Vec<Option<(f64, f64)>> = self.joints().iter().map(|j| j.limits).collect();
        IkSolver::new(self.chain(), &limits)
    }

    /// The solver's answer in the request's units; the orientation error only
    /// when the target has an orientation.
    fn answer(&self, s: IkSolution, t: &IkTarget, unit: AngleUnit) -> IkAnswer {
        IkAnswer {
            joints: self.to_request_unit(&s.q, unit),
            converged: s.converged,
            position_error: s.position_error,
            orientation_error: t.oriented.then_some(s.orientation_error),
            iterations: s.iterations,
            pose: s.pose,
        }
    }
}

impl IkSpec {
    fn option_fields(&self) -> OptionFields<'_> {
        OptionFields {
            seed: self.seed.as_deref(),
            angle_unit: self.angle_unit,
            position_only: self.position_only,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            restarts: self.restarts,
        }
    }
}

impl IkBatchSpec {
    fn option_fields(&self) -> OptionFields<'_> {
        OptionFields {
            seed: self.seed.as_deref(),
            angle_unit: self.angle_unit,
            position_only: self.position_only,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            restarts: self.restarts,
        }
    }
}

/// Validates one target under `field` (`target`, `targets[3]`).
fn check_target(
    t: &IkTargetSpec,
    position_only: bool,
    field: &str,
    v: &mut Vec<FieldViolation>,
) -> IkTarget {
    let none = IkTarget {
        pose: Transform::IDENTITY,
        oriented: false,
    };
    match (&t.matrix, &t.position) {
        (Some(m), pos) => {
            if pos.is_some() || t.quaternion.is_some() {
                v.push(FieldViolation::new(
                    format!("{field}.matrix"),
                    "give either matrix alone or position with quaternion",
                ));
            }
            let before = v.len();
            let pose = rigid_from_matrix(m, &format!("{field}.matrix"), before, v);
            IkTarget {
                pose,
                oriented: true,
            }
        }
        (None, None) => {
            v.push(FieldViolation::new(
                field,
                "give matrix, or position with quaternion",
            ));
            none
        }
        (None, Some(p)) => {
            for (i, x) in p.iter().enumerate() {
                check_bounded(v, || format!("{field}.position[{i}]"), *x);
            }
            let Some(q) = t.quaternion else {
                if !position_only {
                    v.push(FieldViolation::new(
                        format!("{field}.quaternion"),
                        "is required unless position_only is true",
                    ));
                }
                return IkTarget {
                    pose: Transform::translation(p[0], p[1], p[2]),
                    oriented: false,
                };
            };
            let before = v.len();
            for (name, x) in [("w", q.w), ("x", q.x), ("y", q.y), ("z", q.z)] {
                check_finite(v, || format!("{field}.quaternion.{name}"), x);
            }
            if v.len() > before {
                return none;
            }
            match Transform::from_translation_quaternion(*p, [q.w, q.x, q.y, q.z]) {
                Some(pose) => IkTarget {
                    pose,
                    oriented: true,
                },
                None => {
                    v.push(FieldViolation::new(
                        format!("{field}.quaternion"),
                        "must not be zero",
                    ));
                    none
                }
            }
        }
    }
}

impl IkRequest<'_> {
    /// The validated target.
    pub fn target(&self) -> &IkTarget {
        &self.target
    }

    /// The solver options (deadline unset).
    pub fn options(&self) -> &IkOptions {
        &self.options
    }

    /// Solves, giving up at `deadline` (the best attempt so far is answered).
    /// `None` means no time cap: the answer is then deterministic. See
    /// [`Robot::check_ik`] for an example.
    pub fn solve(&self, deadline: Option<Instant>) -> IkAnswer {
        self.solve_cancellable(deadline, &AtomicBool::new(false))
    }

    /// [`IkRequest::solve`] that also gives up, as at the deadline, once
    /// `cancel` is set (by another thread: the client left).
    pub fn solve_cancellable(&self, deadline: Option<Instant>, cancel: &AtomicBool) -> IkAnswer {
        let opts = IkOptions {
            deadline,
            ..self.options
        };
        let s = self.robot.solver().solve_cancellable(
            &self.target.pose,
            self.seed.as_deref(),
            &opts,
            cancel,
        );
        self.robot.answer(s, &self.target, self.angle_unit)
    }
}

impl IkBatch<'_> {
    /// Number of targets.
    pub fn len(&self) -> usize {
        self.targets.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }

    /// Solves every target in order, each seeded with the previous converged
    /// answer (the first with the request's seed). Each target may take
    /// `per_target`; the whole batch stops at `deadline`, after which the
    /// remaining targets are answered from their start configuration
    /// (not converged, 0 iterations, unless the start already fits).
    pub fn solve(&self, per_target: Duration, deadline: Instant) -> Vec<IkAnswer> {
        self.solve_cancellable(per_target, deadline, &AtomicBool::new(false))
    }

    /// [`IkBatch::solve`] that also stops, as at the deadline, once `cancel`
    /// is set: the target being solved gives up within one iteration and the
    /// rest are answered from their start configuration.
    pub fn solve_cancellable(
        &self,
        per_target: Duration,
        deadline: Instant,
        cancel: &AtomicBool,
    ) -> Vec<IkAnswer> {
        let solver = self.robot.solver();
        let mut seed = self.seed.clone();
        self.targets
            .iter()
            .map(|t| {
                let now = Instant::now();
                let opts = IkOptions {
                    deadline: Some((now + per_target).min(deadline)),
                    ..self.options
                };
                let s = solver.solve_cancellable(&t.pose, seed.as_deref(), &opts, cancel);
                if s.converged {
                    seed = Some(s.q.clone());
                }
                self.robot.answer(s, t, self.angle_unit)
            })
            .collect()
    }
}
