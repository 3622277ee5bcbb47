//! Cartesian paths ([`IkPathSpec`] → [`Robot::check_ik_path`] →
//! [`IkPathRequest`] → [`IkPathAnswer`]): from a start configuration through
//! waypoints along straight lines (positions interpolated linearly,
//! orientations by slerp), in steps no longer than `max_step_length` and
//! turning no more than `max_step_angle`, each step solved by IK seeded with
//! the previous one. The path stops at the first step that no IK solution
//! within the limits reaches (`unreachable`, or `joint_limits` when the
//! closed form has solutions only outside them), that would move a joint by
//! more than `max_joint_step` (`joint_jump`), that stands at a singularity
//! (`singularity`: the Jacobian's smallest singular value under
//! [`kinserve_kinematics::SINGULAR_THRESHOLD`], or the closed form's flag),
//! or when time runs out (`time_limit`). `fraction` is the share of steps
//! achieved (MoveIt's `computeCartesianPath`).
//!
//! Units: `start`, `max_joint_step` and the answer's joints in `angle_unit`
//! (revolute) or the robot's length unit (prismatic); `max_step_length` in
//! the length unit; `max_step_angle` in rad. Depends on the `ik` and
//! `ik_solutions` modules, the robot and the kinematics crate.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use kinserve_kinematics::ik::IkOptions;
use kinserve_kinematics::{JacobianFrame, JointKind, Transform};
use serde::{Deserialize, Serialize};

use crate::error::{FieldViolation, ModelError, Result};
use crate::ik::{IkTarget, IkTargetSpec, OptionFields, check_target};
use crate::ik_objectives::{AxisTolerancesSpec, ObjectiveFields, PoseAxis, PostureSpec};
use crate::ik_solutions::{IkSolutionsMode, IkSolverChoice};
use crate::robot::{FkOptions, Robot};
use crate::spec::{AngleUnit, LengthUnit, object_only};

/// Default `max_step_angle`, rad (about 2.9°).
pub const PATH_DEFAULT_STEP_ANGLE: f64 = 0.05;
/// Default `max_joint_step` in rad (20°); prismatic joints: ten length steps.
pub const PATH_DEFAULT_JOINT_STEP: f64 = 0.349_065_850_398_865_9;

/// `POST /v1/robots/{name}/ik/path`: a Cartesian path from `start` through
/// `waypoints`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields, remote = "Self")]
#[cfg_attr(feature = "openapi", schema(example = json!({
    "start": [0, -90, 90, -90, -90, 0], "angle_unit": "deg",
    "waypoints": [{"position": [0.5, 0.2, 0.4], "quaternion": {"w": 0, "x": 1, "y": 0, "z": 0}}],
    "max_step_length": 0.01
})))]
pub struct IkPathSpec {
    /// The configuration the path starts from, in `angle_unit`; within the limits.
    pub start: Vec<f64>,
    /// Poses to pass through, in order (the path is a straight line from the
    /// start's pose to the first, then from each to the next).
    pub waypoints: Vec<IkTargetSpec>,
    /// Unit of revolute values in `start`, `max_joint_step` and the answer (default `rad`).
    #[serde(default)]
    pub angle_unit: AngleUnit,
    /// Match positions only (the orientation is left free; default false).
    #[serde(default)]
    pub position_only: bool,
    /// Longest Cartesian step, robot length unit (default 0.01 m or 10 mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_step_length: Option<f64>,
    /// Largest orientation change per step, rad (default 0.05).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_step_angle: Option<f64>,
    /// Largest move of any joint between two steps, in `angle_unit`
    /// (revolute; default 20°) or the length unit (prismatic; default ten
    /// `max_step_length`). The path stops before a step that would exceed it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_joint_step: Option<f64>,
    /// IK tolerance per step (see [`crate::IkSpec::tolerance`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Solver per step (see [`crate::IkSpec::solver`]).
    #[serde(default)]
    pub solver: IkSolverChoice,
    /// Numeric iterations per attempt (see [`crate::IkSpec::max_iterations`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_iterations: Option<u32>,
    /// Numeric restarts per step (default 0 here: a step is a small move from
    /// the previous answer; restarts would jump branches).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restarts: Option<u32>,
    /// Null-space posture kept along the path (see [`crate::IkSpec::posture`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub posture: Option<PostureSpec>,
    /// Per-axis tolerances of each step (see [`crate::IkSpec::axis_tolerances`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_tolerances: Option<AxisTolerancesSpec>,
    /// Axes of each step's target frame left free (see [`crate::IkSpec::free_axes`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub free_axes: Vec<PoseAxis>,
}

object_only!(IkPathSpec);

/// Why a path stopped before its end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum PathStopReason {
    /// No IK solution within the limits and tolerance reaches the step.
    Unreachable,
    /// The closed form reaches the step only outside the joint limits.
    JointLimits,
    /// The step's solution would move a joint by more than `max_joint_step`.
    JointJump,
    /// The step's solution stands at (or the Jacobian is within rounding of) a singularity.
    Singularity,
    /// The path's time limit ran out.
    TimeLimit,
}

impl PathStopReason {
    /// The snake_case name (metrics, logs, proto mapping).
    pub fn as_str(self) -> &'static str {
        match self {
            PathStopReason::Unreachable => "unreachable",
            PathStopReason::JointLimits => "joint_limits",
            PathStopReason::JointJump => "joint_jump",
            PathStopReason::Singularity => "singularity",
            PathStopReason::TimeLimit => "time_limit",
        }
    }
}

/// Where and why a path stopped.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct PathStop {
    /// The 1-based step that was not taken (step 0 is the start).
    pub step: usize,
    /// The 0-based waypoint that step heads for.
    pub waypoint: usize,
    /// Why.
    pub reason: PathStopReason,
    /// What happened, in words (the joint and its move, the error left…).
    pub detail: String,
}

/// The answer of a path: the joints of every step taken, start first.
#[derive(Clone, Debug, PartialEq)]
pub struct IkPathAnswer {
    /// Joint values per step (the start, then each step taken), in the request's units.
    pub points: Vec<Vec<f64>>,
    /// Steps taken ÷ steps planned (1 when complete).
    pub fraction: f64,
    /// Waypoints fully reached.
    pub waypoints_reached: usize,
    /// `None` when the path is complete.
    pub stop: Option<PathStop>,
}

/// One planned step: its pose and the waypoint it heads for.
#[derive(Clone, Copy, Debug)]
struct Step {
    pose: Transform,
    waypoint: usize,
}

/// A validated path for its robot.
#[derive(Clone, Debug)]
pub struct IkPathRequest<'a> {
    robot: &'a Robot,
    /// Start, internal units.
    start: Vec<f64>,
    steps: Vec<Step>,
    oriented: bool,
    options: IkOptions,
    solver: IkSolverChoice,
    /// Per joint, internal units.
    max_joint_step: Vec<f64>,
    angle_unit: AngleUnit,
}

impl Robot {
    /// Validates a Cartesian path (field paths `start[2]`, `waypoints[1].matrix`,
    /// `max_step_length`…) and plans its steps; more than `max_steps` steps
    /// is [`ModelError::TooLarge`] on `max_step_length`.
    ///
    /// ```
    /// use kinserve_model::{IkPathSpec, IkTargetSpec, FkOptions, load_robot_file};
    ///
    /// let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots/puma560.json");
    /// let robot = load_robot_file(&path)?;
    /// let start = vec![0.1, -0.4, 0.6, 0.2, 0.5, -0.3];
    /// let mut end = robot.fk(&start, &FkOptions::default())?;
    /// end.translation[2] += 0.05; // 5 cm straight up, same orientation
    /// let [w, x, y, z] = end.quaternion();
    /// let spec = IkPathSpec {
    ///     start,
    ///     waypoints: vec![IkTargetSpec {
    ///         position: Some(end.translation),
    ///         quaternion: Some(kinserve_model::QuaternionSpec { w, x, y, z }),
    ///         matrix: None,
    ///     }],
    ///     max_step_length: Some(0.01),
    ///     ..IkPathSpec::default()
    /// };
    /// let answer = robot.check_ik_path(&spec, 10_000)?.solve(None);
    /// assert_eq!((answer.points.len(), answer.fraction), (6, 1.0)); // start + 5 steps
    /// # Ok::<(), kinserve_model::ModelError>(())
    /// ```
    pub fn check_ik_path<'a>(
        &'a self,
        spec: &IkPathSpec,
        max_steps: usize,
    ) -> Result<IkPathRequest<'a>> {
        let mut v = Vec::new();
        let unit = FkOptions::new(Some(spec.angle_unit), Some(true));
        let start = match self.check_joints_at(&spec.start, &unit, || "start".into()) {
            Ok(_) => Some(self.to_internal(&spec.start, spec.angle_unit.to_rad())),
            Err(e) => {
                v.extend(e.violations().iter().cloned());
                None
            }
        };
        if spec.waypoints.is_empty() {
            v.push(FieldViolation::new("waypoints", "give at least one pose"));
        }
        let targets: Vec<IkTarget> = spec
            .waypoints
            .iter()
            .enumerate()
            .map(|(i, t)| check_target(t, spec.position_only, &format!("waypoints[{i}]"), &mut v))
            .collect();
        let (_, options) = self.check_options(&spec.option_fields(), &mut v);
        let (length, angle) = self.check_steps(spec, &mut v);
        let max_joint_step = self.check_joint_step(spec, length, &mut v);
        if spec.solver == IkSolverChoice::Analytic {
            self.check_mode(&spec.option_fields(), &mut v);
        }
        let Some(start) = start.filter(|_| v.is_empty()) else {
            return Err(ModelError::invalid(v));
        };
        let from = self.chain().forward(&start, 1.0);
        let steps = plan(
            from,
            &targets,
            length,
            angle,
            !spec.position_only,
            max_steps,
        )?;
        Ok(IkPathRequest {
            robot: self,
            start,
            steps,
            oriented: !spec.position_only,
            options,
            solver: spec.solver,
            max_joint_step,
            angle_unit: spec.angle_unit,
        })
    }

    /// `max_step_length` (length unit) and `max_step_angle` (rad), defaulted.
    fn check_steps(&self, spec: &IkPathSpec, v: &mut Vec<FieldViolation>) -> (f64, f64) {
        let default_length = match self.length_unit() {
            LengthUnit::Mm => 10.0,
            _ => 0.01,
        };
        let length = spec.max_step_length.unwrap_or(default_length);
        let angle = spec.max_step_angle.unwrap_or(PATH_DEFAULT_STEP_ANGLE);
        for (field, x, hi) in [
            ("max_step_length", length, crate::MAX_MAGNITUDE),
            ("max_step_angle", angle, std::f64::consts::PI),
        ] {
            if !(x.is_finite() && x > 0.0 && x <= hi) {
                v.push(FieldViolation::new(
                    field,
                    format!("must be a number above 0 and at most {hi}, got {x}"),
                ));
            }
        }
        (length, angle)
    }

    /// `max_joint_step` per joint in internal units, defaulted.
    fn check_joint_step(
        &self,
        spec: &IkPathSpec,
        length: f64,
        v: &mut Vec<FieldViolation>,
    ) -> Vec<f64> {
        if let Some(x) = spec.max_joint_step
            && !(x.is_finite() && x > 0.0)
        {
            v.push(FieldViolation::new(
                "max_joint_step",
                format!("must be a number above 0, got {x}"),
            ));
        }
        let scale = spec.angle_unit.to_rad();
        self.joints()
            .iter()
            .map(|j| match (j.kind, spec.max_joint_step) {
                (JointKind::Revolute, Some(x)) => x * scale,
                (JointKind::Revolute, None) => PATH_DEFAULT_JOINT_STEP,
                (_, Some(x)) => x,
                (_, None) => 10.0 * length,
            })
            .collect()
    }
}

impl IkPathSpec {
    fn option_fields(&self) -> OptionFields<'_> {
        OptionFields {
            seed: None,
            angle_unit: self.angle_unit,
            position_only: self.position_only,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            restarts: Some(self.restarts.unwrap_or(0)),
            solver: self.solver,
            solutions: IkSolutionsMode::Best,
            max_solutions: None,
            objectives: ObjectiveFields {
                posture: self.posture.as_ref(),
                axis_tolerances: self.axis_tolerances.as_ref(),
                free_axes: &self.free_axes,
            },
        }
    }
}

/// The steps from `from` through `targets`: per segment, as many equal
/// steps as the longer of length and angle needs (at least one).
fn plan(
    from: Transform,
    targets: &[IkTarget],
    length: f64,
    angle: f64,
    oriented: bool,
    max_steps: usize,
) -> Result<Vec<Step>> {
    let mut steps = Vec::new();
    let mut a = from;
    for (w, t) in targets.iter().enumerate() {
        let b = if oriented {
            t.pose
        } else {
            Transform {
                rotation: a.rotation,
                ..t.pose
            }
        };
        let (qa, qb) = (a.quaternion(), aligned(a.quaternion(), b.quaternion()));
        let d = (0..3)
            .map(|i| (b.translation[i] - a.translation[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        let turn = 2.0 * dot4(qa, qb).clamp(-1.0, 1.0).acos();
        // A step a rounding error longer than the limit is not a step more.
        let steps_for = |x: f64| (x * (1.0 - 1e-12)).ceil();
        let n = steps_for(d / length).max(steps_for(turn / angle)).max(1.0) as usize;
        if steps.len() + n > max_steps {
            return Err(ModelError::too_large(
                "max_step_length",
                format!(
                    "the path needs more than {max_steps} steps at this step size: raise \
                     max_step_length / max_step_angle or split the path"
                ),
            ));
        }
        for k in 1..=n {
            let s = k as f64 / n as f64;
            let p = std::array::from_fn(|i| {
                a.translation[i] + s * (b.translation[i] - a.translation[i])
            });
            let pose = Transform::from_translation_quaternion(p, slerp(qa, qb, s)).unwrap_or(b);
            steps.push(Step { pose, waypoint: w });
        }
        a = b;
    }
    Ok(steps)
}

fn dot4(a: [f64; 4], b: [f64; 4]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

/// `b` or `−b`, whichever is nearer `a` (the shorter rotation).
fn aligned(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    if dot4(a, b) < 0.0 { b.map(|x| -x) } else { b }
}

/// Spherical linear interpolation of unit quaternions (`a·b ≥ 0`).
fn slerp(a: [f64; 4], b: [f64; 4], s: f64) -> [f64; 4] {
    let c = dot4(a, b).min(1.0);
    let theta = c.acos();
    if theta < 1e-9 {
        return std::array::from_fn(|i| a[i] + s * (b[i] - a[i]));
    }
    let (wa, wb) = (((1.0 - s) * theta).sin(), (s * theta).sin());
    let st = theta.sin();
    std::array::from_fn(|i| (wa * a[i] + wb * b[i]) / st)
}

impl IkPathRequest<'_> {
    /// Steps planned.
    pub fn len(&self) -> usize {
        self.steps.len()
    }

    /// Whether no step is planned (never: at least one per waypoint).
    pub fn is_empty(&self) -> bool {
        self.steps.is_empty()
    }

    /// Solves the path, each step capped at `per_step` and the whole at `deadline`.
    pub fn solve(&self, deadline: Option<Instant>) -> IkPathAnswer {
        self.solve_cancellable(Duration::MAX, deadline, &AtomicBool::new(false))
    }

    /// [`IkPathRequest::solve`] that stops (`time_limit`) once `cancel` is set.
    pub fn solve_cancellable(
        &self,
        per_step: Duration,
        deadline: Option<Instant>,
        cancel: &AtomicBool,
    ) -> IkPathAnswer {
        let r = self.robot;
        let solver = r.solver();
        let mode = crate::ik::Mode::best(self.solver);
        let mut q = self.start.clone();
        let mut points = vec![r.to_request_unit(&q, self.angle_unit)];
        let mut stop = None;
        for (k, step) in self.steps.iter().enumerate() {
            let now = Instant::now();
            if cancel.load(Ordering::Relaxed) || deadline.is_some_and(|d| now >= d) {
                stop = Some(self.stop(
                    k,
                    PathStopReason::TimeLimit,
                    "the path's time limit ran out".into(),
                ));
                break;
            }
            let opts = IkOptions {
                deadline: now
                    .checked_add(per_step)
                    .map(|t| deadline.map_or(t, |d| t.min(d)))
                    .or(deadline),
                ..self.options.clone()
            };
            let target = IkTarget {
                pose: step.pose,
                oriented: self.oriented,
            };
            let (answer, next) = r.solve_target(
                &solver,
                &target,
                Some(&q),
                &mode,
                &opts,
                cancel,
                self.angle_unit,
            );
            let Some(next) = next else {
                stop = Some(self.unreached(k, &step.pose, answer.position_error));
                break;
            };
            if let Some(why) = self.jump(&q, &next) {
                stop = Some(self.stop(k, PathStopReason::JointJump, why));
                break;
            }
            if !answer.singular.is_empty() || self.singular(&next) {
                stop = Some(self.stop(
                    k,
                    PathStopReason::Singularity,
                    "the solution stands at a singularity (the Jacobian loses rank)".into(),
                ));
                break;
            }
            q = next;
            points.push(answer.joints);
        }
        let taken = points.len() - 1;
        let waypoints_reached = match taken.checked_sub(1) {
            None => 0,
            Some(last) if taken == self.steps.len() => self.steps[last].waypoint + 1,
            Some(_) => self.steps[taken].waypoint,
        };
        IkPathAnswer {
            points,
            fraction: taken as f64 / self.steps.len() as f64,
            waypoints_reached,
            stop,
        }
    }

    fn stop(&self, k: usize, reason: PathStopReason, detail: String) -> PathStop {
        PathStop {
            step: k + 1,
            waypoint: self.steps[k].waypoint,
            reason,
            detail,
        }
    }

    /// `unreachable`, or `joint_limits` when the closed form reaches the pose
    /// only outside the limits.
    fn unreached(&self, k: usize, pose: &Transform, error: f64) -> PathStop {
        // With a partial pose the closed form (exact full poses) cannot tell.
        let outside = self.oriented
            && self.options.axis_tolerances.is_none()
            && self.robot.analytic_ik().is_ok_and(|ik| {
                let opts = kinserve_kinematics::analytic_ik::AnalyticOptions {
                    tolerance: self.options.tolerance,
                    max_solutions: 1,
                };
                ik.solve(pose, &[], None, &opts).principal > 0
            });
        if outside {
            return self.stop(
                k,
                PathStopReason::JointLimits,
                "the pose is reached only outside the joint limits".into(),
            );
        }
        let unit = self.robot.length_unit().as_str();
        self.stop(k, PathStopReason::Unreachable, format!("no IK solution within the limits and tolerance; the best attempt misses by {error:.3e} {unit}"))
    }

    /// The first joint that would move more than allowed, in words.
    fn jump(&self, q: &[f64], next: &[f64]) -> Option<String> {
        let (i, d) = q
            .iter()
            .zip(next)
            .map(|(a, b)| (b - a).abs())
            .enumerate()
            .find(|(i, d)| *d > self.max_joint_step[*i])?;
        let joint = &self.robot.joints()[i];
        let (shown, max, unit) = match joint.kind {
            JointKind::Revolute => {
                let s = self.angle_unit.to_rad();
                (d / s, self.max_joint_step[i] / s, self.angle_unit.as_str())
            }
            _ => (d, self.max_joint_step[i], self.robot.length_unit().as_str()),
        };
        Some(format!(
            "joint {i} would move {shown:.4} {unit} in one step (max_joint_step {max:.4})"
        ))
    }

    /// Whether the Jacobian at `q` (rad) is singular.
    fn singular(&self, q: &[f64]) -> bool {
        let (_, j) = self.robot.chain().jacobian(q, 1.0, JacobianFrame::Base);
        j.measures().singular
    }
}
