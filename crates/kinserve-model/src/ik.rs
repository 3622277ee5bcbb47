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

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use kinserve_kinematics::Transform;
use kinserve_kinematics::analytic_ik::AnalyticIk;
use kinserve_kinematics::ik::{
    DEFAULT_MAX_ITERATIONS, DEFAULT_RESTARTS, DEFAULT_TOLERANCE, FAR_RESTARTS, IkOptions,
    IkSolution, IkSolver,
};
use serde::{Deserialize, Serialize};

use crate::base_tool::{check_bounded, check_finite, rigid_from_matrix};
use crate::error::{FieldViolation, ModelError, Result};
use crate::ik_objectives::{AxisTolerancesSpec, ObjectiveFields, PoseAxis, PostureSpec};
use crate::ik_solutions::{
    IK_DEFAULT_MAX_SOLUTIONS, IK_MAX_BATCH_SOLUTIONS, IK_MAX_SOLUTIONS, IkBranch, IkSolutionItem,
    IkSolutionsMode, IkSolverChoice, IkSolverUsed, Singularity, analytic_solutions, pose_errors,
};
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
    /// Restarts from new configurations after a stalled attempt (0 to 1,000;
    /// all run when given). Absent: up to 1,000, past 100 only while the best
    /// attempt is within 1e-3 (or 1,000 × the tolerance) of the target, so a
    /// target out of reach costs 100 restarts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restarts: Option<u32>,
    /// Which solver runs (default `auto`: the arm's closed form where it has
    /// one and the target has an orientation, else numeric).
    #[serde(default)]
    pub solver: IkSolverChoice,
    /// `best` (default): one answer; `all`: every solution inside the limits
    /// in `solutions`, nearest the seed first (needs the closed form).
    #[serde(default)]
    pub solutions: IkSolutionsMode,
    /// With `solutions: "all"`, at most this many (default 64; 1 to 1,024);
    /// `truncated` says when more fit the limits.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_solutions: Option<u32>,
    /// Null-space posture for redundant arms: the solution moves towards
    /// these joints while the pose stays within the tolerance (numeric
    /// solver only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub posture: Option<PostureSpec>,
    /// Per-axis tolerances in the target frame, replacing `tolerance` on the
    /// axes given (numeric solver only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_tolerances: Option<AxisTolerancesSpec>,
    /// Axes of the target frame left free, e.g. `["rz"]` for a tool that
    /// may spin about its axis (numeric solver only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub free_axes: Vec<PoseAxis>,
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
    /// See [`IkSpec::solver`].
    #[serde(default)]
    pub solver: IkSolverChoice,
    /// See [`IkSpec::solutions`] (per target).
    #[serde(default)]
    pub solutions: IkSolutionsMode,
    /// See [`IkSpec::max_solutions`] (per target; `targets × max_solutions`
    /// at most 100,000).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_solutions: Option<u32>,
    /// See [`IkSpec::posture`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub posture: Option<PostureSpec>,
    /// See [`IkSpec::axis_tolerances`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_tolerances: Option<AxisTolerancesSpec>,
    /// See [`IkSpec::free_axes`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub free_axes: Vec<PoseAxis>,
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
    mode: Mode,
    angle_unit: AngleUnit,
}

/// Many validated targets with shared options.
#[derive(Clone, Debug)]
pub struct IkBatch<'a> {
    robot: &'a Robot,
    targets: Vec<IkTarget>,
    seed: Option<Vec<f64>>,
    options: IkOptions,
    mode: Mode,
    angle_unit: AngleUnit,
}

/// How a validated request is solved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Mode {
    solver: IkSolverChoice,
    /// `solutions: "all"`.
    all: bool,
    /// `max_solutions`.
    max: usize,
}

impl Mode {
    /// One answer from `solver`.
    pub(crate) fn best(solver: IkSolverChoice) -> Mode {
        Mode {
            solver,
            all: false,
            max: 1,
        }
    }
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
    /// The solver that produced `joints`.
    pub solver: IkSolverUsed,
    /// The closed-form branch of `joints` (`None` from the numeric solver).
    pub branch: Option<IkBranch>,
    /// Singularities `joints` stands at (closed form only).
    pub singular: Vec<Singularity>,
    /// With `solutions: "all"`: every solution, nearest the seed first
    /// (`joints` is the first); empty when none fits.
    pub solutions: Option<Vec<IkSolutionItem>>,
    /// Whether more solutions fit the limits than `max_solutions`.
    pub truncated: bool,
}

/// The shared options of single, batch and path requests, as written.
pub(crate) struct OptionFields<'a> {
    pub seed: Option<&'a [f64]>,
    pub angle_unit: AngleUnit,
    pub position_only: bool,
    pub tolerance: Option<f64>,
    pub max_iterations: Option<u32>,
    pub restarts: Option<u32>,
    pub solver: IkSolverChoice,
    pub solutions: IkSolutionsMode,
    pub max_solutions: Option<u32>,
    pub objectives: ObjectiveFields<'a>,
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
        let mode = self.check_mode(&spec.option_fields(), &mut v);
        if !v.is_empty() {
            return Err(ModelError::invalid(v));
        }
        Ok(IkRequest {
            robot: self,
            target,
            seed,
            options,
            mode,
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
        let mode = self.check_mode(&spec.option_fields(), &mut v);
        if !v.is_empty() {
            return Err(ModelError::invalid(v));
        }
        let answered = spec.targets.len() as u64 * mode.max as u64;
        if mode.all && answered > IK_MAX_BATCH_SOLUTIONS {
            return Err(ModelError::too_large(
                "max_solutions",
                format!(
                    "a batch with solutions \"all\" answers at most {IK_MAX_BATCH_SOLUTIONS} \
                     solutions (targets × max_solutions), this one up to {answered}: lower \
                     max_solutions or split the batch"
                ),
            ));
        }
        Ok(IkBatch {
            robot: self,
            targets,
            seed,
            options,
            mode,
            angle_unit: spec.angle_unit,
        })
    }

    /// Seed (in internal units) and solver options, or violations.
    pub(crate) fn check_options(
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
        let (posture, axis_tolerances) =
            self.check_objectives(&o.objectives, tolerance, o.angle_unit, o.position_only, v);
        let options = IkOptions {
            position_only: o.position_only,
            tolerance,
            max_iterations,
            restarts,
            // Restarts asked for all run; the default gives up early on a
            // target no attempt came close to.
            far_restarts: o.restarts.map_or(Some(FAR_RESTARTS), |_| None),
            posture,
            axis_tolerances,
            ..IkOptions::default()
        };
        (seed, options)
    }

    /// The solver and solution count asked for, or violations naming
    /// `solver`, `solutions` or `max_solutions`.
    pub(crate) fn check_mode(&self, o: &OptionFields<'_>, v: &mut Vec<FieldViolation>) -> Mode {
        let all = o.solutions == IkSolutionsMode::All;
        let max = o.max_solutions.unwrap_or(IK_DEFAULT_MAX_SOLUTIONS);
        if !(1..=IK_MAX_SOLUTIONS).contains(&max) {
            v.push(FieldViolation::new(
                "max_solutions",
                format!("must be from 1 to {IK_MAX_SOLUTIONS}, got {max}"),
            ));
        } else if o.max_solutions.is_some() && !all {
            v.push(FieldViolation::new(
                "max_solutions",
                "applies to solutions \"all\" only: add \"solutions\": \"all\" or leave it out",
            ));
        }
        let why_not = match self.analytic_ik() {
            Err(e) => Some(e.to_string()),
            Ok(_) if o.objectives.numeric_only().is_some() => Some(format!(
                "the closed form solves exact full poses and has no null space, and {} is set; \
                 use the numeric solver",
                o.objectives.numeric_only().unwrap_or_default()
            )),
            Ok(_) if o.position_only => Some(
                "the closed form solves full poses and position_only is true; \
                 use the numeric solver"
                    .to_string(),
            ),
            Ok(_) => None,
        };
        match (&why_not, o.solver) {
            (Some(why), IkSolverChoice::Analytic) => {
                v.push(FieldViolation::new(
                    "solver",
                    format!("{why} (\"auto\" or \"numeric\")"),
                ));
            }
            (_, IkSolverChoice::Numeric) if all => v.push(FieldViolation::new(
                "solutions",
                "\"all\" comes from the closed form: use solver \"auto\" or \"analytic\", \
                 or solutions \"best\" with the numeric solver",
            )),
            (Some(why), _) if all => v.push(FieldViolation::new(
                "solutions",
                format!("\"all\" needs the closed form, and {why} with solutions \"best\""),
            )),
            _ => {}
        }
        Mode {
            solver: o.solver,
            all,
            max: max.clamp(1, IK_MAX_SOLUTIONS) as usize,
        }
    }

    /// The closed form's answer: the solution nearest `seed` (rad; `None`:
    /// the middle of the limits), every one with `solutions: "all"`; none
    /// inside the limits answers the reference configuration, not converged.
    /// Also the converged joints in internal units (to seed the next target).
    fn analytic_answer(
        &self,
        ik: &AnalyticIk,
        t: &IkTarget,
        seed: Option<&[f64]>,
        mode: &Mode,
        tolerance: f64,
        unit: AngleUnit,
    ) -> (IkAnswer, Option<Vec<f64>>) {
        let max = if mode.all { mode.max } else { 1 };
        let (hits, truncated) = analytic_solutions(self, ik, &t.pose, seed, tolerance, max, unit);
        let solutions = mode
            .all
            .then(|| hits.iter().map(|h| h.item.clone()).collect());
        let Some(best) = hits.first() else {
            let q = self.reference(seed);
            let pose = self.chain().forward(&q, 1.0);
            let (position_error, orientation_error) = pose_errors(&t.pose, &pose);
            let answer = IkAnswer {
                joints: self.to_request_unit(&q, unit),
                converged: false,
                position_error,
                orientation_error: Some(orientation_error),
                iterations: 0,
                pose,
                solver: IkSolverUsed::Analytic,
                branch: None,
                singular: Vec::new(),
                solutions,
                truncated: false,
            };
            return (answer, None);
        };
        let answer = IkAnswer {
            joints: best.item.joints.clone(),
            converged: true,
            position_error: best.item.position_error,
            orientation_error: Some(best.item.orientation_error),
            iterations: 0,
            pose: best.pose,
            solver: IkSolverUsed::Analytic,
            branch: best.item.branch,
            singular: best.item.singular.clone(),
            solutions,
            truncated: mode.all && truncated,
        };
        (answer, Some(best.q.to_vec()))
    }

    /// `seed` (internal units), else the middle of each joint's limits (0
    /// when unlimited).
    fn reference(&self, seed: Option<&[f64]>) -> Vec<f64> {
        match seed {
            Some(s) => s.to_vec(),
            None => self
                .joints()
                .iter()
                .map(|j| j.limits.map_or(0.0, |(lo, hi)| 0.5 * (lo + hi)))
                .collect(),
        }
    }

    /// Solves one validated target: the closed form where the request and
    /// the arm allow it, else (or when it finds nothing and the solver was
    /// not forced) numerically. Also the converged joints in internal units.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn solve_target(
        &self,
        solver: &IkSolver<'_>,
        t: &IkTarget,
        seed: Option<&[f64]>,
        mode: &Mode,
        opts: &IkOptions,
        cancel: &AtomicBool,
        unit: AngleUnit,
    ) -> (IkAnswer, Option<Vec<f64>>) {
        // Past the deadline (or cancelled) nothing is solved, as numerically.
        let in_time =
            !cancel.load(Ordering::Relaxed) && opts.deadline.is_none_or(|d| Instant::now() < d);
        let closed_form = (in_time
            && mode.solver != IkSolverChoice::Numeric
            && t.oriented
            && !opts.position_only
            && opts.posture.is_none()
            && opts.axis_tolerances.is_none())
        .then(|| self.analytic_ik().ok())
        .flatten();
        if let Some(ik) = closed_form {
            let (answer, q) = self.analytic_answer(ik, t, seed, mode, opts.tolerance, unit);
            if answer.converged || mode.solver == IkSolverChoice::Analytic {
                return (answer, q);
            }
        }
        let s = solver.solve_cancellable(&t.pose, seed, opts, cancel);
        let q = s.converged.then(|| s.q.clone());
        let reference = self.reference(seed);
        (self.answer(s, t, unit, mode, &reference), q)
    }

    pub(crate) fn solver(&self) -> IkSolver<'_> {
        IkSolver::new(self.chain(), self.limits())
    }

    /// The numeric solver's answer in the request's units; the orientation
    /// error only when the target has an orientation. With `solutions:
    /// "all"` (the closed form found nothing) the converged answer is the one
    /// solution, its distance the plain one to `reference` (rad).
    fn answer(
        &self,
        s: IkSolution,
        t: &IkTarget,
        unit: AngleUnit,
        mode: &Mode,
        reference: &[f64],
    ) -> IkAnswer {
        let joints = self.to_request_unit(&s.q, unit);
        let solutions = mode.all.then(|| {
            let item = IkSolutionItem {
                joints: joints.clone(),
                branch: None,
                singular: Vec::new(),
                distance: s
                    .q
                    .iter()
                    .zip(reference)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
                    .sqrt(),
                position_error: s.position_error,
                orientation_error: s.orientation_error,
            };
            s.converged.then_some(item).into_iter().collect()
        });
        IkAnswer {
            joints,
            converged: s.converged,
            position_error: s.position_error,
            orientation_error: t.oriented.then_some(s.orientation_error),
            iterations: s.iterations,
            pose: s.pose,
            solver: IkSolverUsed::Numeric,
            branch: None,
            singular: Vec::new(),
            solutions,
            truncated: false,
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
            solver: self.solver,
            solutions: self.solutions,
            max_solutions: self.max_solutions,
            objectives: ObjectiveFields {
                posture: self.posture.as_ref(),
                axis_tolerances: self.axis_tolerances.as_ref(),
                free_axes: &self.free_axes,
            },
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
            solver: self.solver,
            solutions: self.solutions,
            max_solutions: self.max_solutions,
            objectives: ObjectiveFields {
                posture: self.posture.as_ref(),
                axis_tolerances: self.axis_tolerances.as_ref(),
                free_axes: &self.free_axes,
            },
        }
    }
}

/// Validates one target under `field` (`target`, `targets[3]`).
pub(crate) fn check_target(
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
            ..self.options.clone()
        };
        let solver = self.robot.solver();
        let (answer, _) = self.robot.solve_target(
            &solver,
            &self.target,
            self.seed.as_deref(),
            &self.mode,
            &opts,
            cancel,
            self.angle_unit,
        );
        answer
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
                    ..self.options.clone()
                };
                let (answer, q) = self.robot.solve_target(
                    &solver,
                    t,
                    seed.as_deref(),
                    &self.mode,
                    &opts,
                    cancel,
                    self.angle_unit,
                );
                if q.is_some() {
                    seed = q;
                }
                answer
            })
            .collect()
    }
}
