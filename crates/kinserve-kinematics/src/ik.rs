//! Numerical inverse kinematics (feature `ik`): which joint values put the
//! tool at a target pose.
//!
//! Owns [`IkSolver`], its [`IkOptions`] and the [`IkSolution`] it returns.
//! Damped least squares with Levenberg–Marquardt damping on the geometric
//! Jacobian ([`Chain::jacobian_into`]): each step solves
//! `(J Jᵀ + λ I) y = e`, `Δq = Jᵀ y` with nalgebra's Cholesky factorisation
//! (6×6, or 3×3 in position-only mode, whatever the number of joints), and is
//! kept only if it lowers the error (λ shrinks tenfold after a kept step and
//! grows tenfold after a refused one).
//!
//! An attempt has two phases. First the limits are ignored: unconstrained
//! steps do not stall against a limit, and a solution they reach that lies
//! outside the limits may still fit them after whole turns of revolute
//! joints. If that does not give an in-limit solution, the second phase
//! continues from the clamped configuration with every step projected onto
//! the limits — on every other attempt with an active set (joints at a limit
//! that the step would push further are taken out of the step), which
//! reaches other solutions than plain clamping near the limits. A phase is
//! abandoned as soon as it stalls: λ too large to move, several kept steps in
//! a row that each remove less than a tenth of the squared error, or the
//! squared error down by less than ¾ over the last six iterations while
//! still farther than 1000 × the tolerance from the target (the progress test
//! that keeps failing attempts short). Then the
//! solver restarts from a pseudo-random in-limit configuration drawn from a
//! fixed seed, so every answer is deterministic (unless the time cap cuts a
//! solve short); by default, past [`FAR_RESTARTS`] restarts it goes on only
//! while its best attempt is close to the target. Every answer, converged or
//! not, is within the joint limits.
//!
//! Two optional objectives ([`IkOptions`]): per-axis tolerances (position
//! along and rotation about the target frame's x, y, z axes, `f64::INFINITY`
//! for a free axis; an error component within its tolerance counts as zero,
//! as TRAC-IK's bounds), and a null-space [`Posture`] for redundant arms: once
//! a solution is found, steps `Δq = z + J⁺(e − J z)` with
//! `z = W (q_posture − q)` move it towards the posture while every kept step
//! stays within the tolerance.
//!
//! Units: joint values in rad (revolute) and the chain's length unit
//! (prismatic); targets in the world frame in the chain's length unit;
//! position error in that unit, orientation error in rad (the angle of
//! `R_target · Rᵀ`). Depends on the chain and transform modules and nalgebra;
//! must not depend on serde or any other kinserve crate.

use std::f64::consts::PI;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

use crate::chain::Chain;
use crate::dh::JointKind;
use crate::jacobian::JacobianFrame;
use crate::transform::Transform;

/// Default convergence tolerance: 1e-9 in the chain's length unit for the
/// position and 1e-9 rad for the orientation.
pub const DEFAULT_TOLERANCE: f64 = 1e-9;
/// Default iterations per attempt.
pub const DEFAULT_MAX_ITERATIONS: u32 = 100;
/// Default number of restarts after the first attempt. Past
/// [`FAR_RESTARTS`] of them a solve goes on only while its best attempt is
/// close to the target ([`IkOptions::far_restarts`]), so an unreachable
/// target costs 100 restarts, not 1000.
pub const DEFAULT_RESTARTS: u32 = 1000;
/// Default of [`IkOptions::far_restarts`]: restarts after which a solve whose
/// best attempt is not close to the target (farther than [`CLOSE_ERROR`], or
/// 1000 × the tolerance if larger) gives up as unreachable. A reachable target
/// that 100 restarts miss lies next to a singularity or a limit (seen on the
/// Panda: about 1 in 20,000 random reachable targets at 1e-6, its best
/// attempt within 2e-4), and the further restarts find it.
pub const FAR_RESTARTS: u32 = 100;
/// Error (length unit for the position, rad for the orientation) within which
/// the best attempt counts as close (see [`FAR_RESTARTS`]).
pub const CLOSE_ERROR: f64 = 1e-3;
/// Seed of the restart configurations (any fixed value keeps answers deterministic).
pub const DEFAULT_RNG_SEED: u64 = 0x6b69_6e73_6572_7665;

/// Initial and smallest damping (relative to the mean diagonal of `J Jᵀ`).
const LAMBDA_START: f64 = 1e-3;
const LAMBDA_MIN: f64 = 1e-12;
/// Damping past which an attempt is given up (the error cannot go down).
const LAMBDA_MAX: f64 = 1e8;
/// Kept steps in a row that each remove less than [`SLOW_RATIO`] of the
/// error before an attempt counts as stalled.
const SLOW_STEPS: u32 = 8;
const SLOW_RATIO: f64 = 0.1;
/// The progress test: a phase is abandoned when its cost (squared error) is
/// above [`PROGRESS_RATIO`] times the cost [`PROGRESS_WINDOW`] iterations
/// earlier, unless the error is already within [`NEAR_FACTOR`] × the
/// tolerance (close to a solution, convergence may be linear: let it run).
const PROGRESS_WINDOW: usize = 6;
const PROGRESS_RATIO: f64 = 0.25;
const NEAR_FACTOR: f64 = 1e3;
/// Undamped steps back onto the target after each null-space posture step
/// (the null space is tangent to the self-motion, which is curved).
const POSTURE_CORRECTIONS: usize = 4;

/// How a phase of an attempt treats the joint limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Limits {
    /// Ignored (the configuration is brought into the limits afterwards).
    Ignored,
    /// Each trial configuration clamped into the limits.
    Clamped,
    /// Clamped, and joints at a limit that the step pushes further are
    /// taken out of the step (an active set).
    ActiveSet,
}

/// A preferred configuration for a redundant arm (the null-space objective
/// of [`IkOptions::posture`]).
///
/// ```
/// use kinserve_kinematics::ik::{IkOptions, IkSolver, Posture};
/// use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, Transform};
///
/// // A planar 3R arm reaching a point: one joint to spare.
/// let row = |a| DhRow { kind: JointKind::Revolute, a, alpha: 0.0, d: 0.0, theta: 0.0 };
/// let rows = [row(1.0), row(1.0), row(1.0)];
/// let chain = Chain::new(Convention::Standard, &rows, Transform::IDENTITY, None);
/// let solver = IkSolver::new(&chain, &[]);
/// let target = chain.forward(&[0.3, 0.4, 0.5], 1.0);
/// let preferred = vec![0.0, 0.0, 1.5];
/// let opts = |weight| IkOptions {
///     position_only: true,
///     posture: Some(Posture { joints: preferred.clone(), weights: vec![weight; 3] }),
///     ..IkOptions::default()
/// };
/// let plain = solver.solve(&target, None, &opts(0.0)); // same start, no pull
/// let pulled = solver.solve(&target, None, &opts(1.0));
/// assert!(plain.converged && pulled.converged);
/// let dist = |q: &[f64]| q.iter().zip(&preferred).map(|(a, b)| (a - b).powi(2)).sum::<f64>();
/// assert!(dist(&pulled.q) < dist(&plain.q));
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Posture {
    /// Preferred joint values, one per joint (rad / length unit; missing
    /// entries: no preference).
    pub joints: Vec<f64>,
    /// Weight per joint, unit-free: the fraction of the way to the preferred
    /// value asked for per refinement step, used within `[0, 1]` (0 or
    /// missing: no preference; larger values count as 1, negative or
    /// non-finite ones as 0).
    pub weights: Vec<f64>,
}

/// How to solve.
#[derive(Clone, Debug, PartialEq)]
pub struct IkOptions {
    /// Match the position only (orientation free): for arms with fewer than
    /// 6 joints or when orientation does not matter.
    pub position_only: bool,
    /// Converged when the position error ≤ `tolerance` (length unit) and,
    /// unless `position_only`, the orientation error ≤ `tolerance` (rad).
    pub tolerance: f64,
    /// Iterations per attempt.
    pub max_iterations: u32,
    /// Attempts after the first, each from a new start configuration.
    pub restarts: u32,
    /// Past this many restarts, go on only while the best attempt is close to
    /// the target ([`FAR_RESTARTS`], the default); `None`: every restart
    /// [`IkOptions::restarts`] allows runs (a caller that asked for them).
    pub far_restarts: Option<u32>,
    /// Give up (answering the best attempt so far) at this instant.
    pub deadline: Option<Instant>,
    /// Seed of the restart configurations.
    pub rng_seed: u64,
    /// Null-space posture objective: after a solution is found, it is moved
    /// towards [`Posture::joints`] along the self-motion of the arm (only a
    /// redundant arm, or a free axis, leaves room) while the pose stays
    /// within the tolerance. Without a seed the first attempt starts from
    /// the posture (clamped into the limits), and whole turns are chosen
    /// near it.
    pub posture: Option<Posture>,
    /// Per-axis tolerances `[x, y, z, rx, ry, rz]`: position along (length
    /// unit) and rotation about (rad) the target frame's axes, replacing
    /// `tolerance` when set. `f64::INFINITY` leaves an axis free; an error
    /// component within its tolerance counts as zero. `position_only` frees
    /// the rotations whatever is set here. The solution's `converged` is
    /// this test; its errors are still the full norms.
    pub axis_tolerances: Option<[f64; 6]>,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            position_only: false,
            tolerance: DEFAULT_TOLERANCE,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            restarts: DEFAULT_RESTARTS,
            far_restarts: Some(FAR_RESTARTS),
            deadline: None,
            rng_seed: DEFAULT_RNG_SEED,
            posture: None,
            axis_tolerances: None,
        }
    }
}

/// The answer of a solve: the solution, or the best attempt if none converged.
#[derive(Clone, Debug, PartialEq)]
pub struct IkSolution {
    /// Joint values (rad / length unit), always within the joint limits.
    pub q: Vec<f64>,
    /// Whether both errors are within the tolerance (position only: the
    /// position error; with [`IkOptions::axis_tolerances`]: every component).
    pub converged: bool,
    /// `|p_target − p|`, length unit.
    pub position_error: f64,
    /// Angle of `R_target · Rᵀ`, rad (reported in position-only mode too).
    pub orientation_error: f64,
    /// Iterations over all attempts.
    pub iterations: u32,
    /// Attempts made (1 + restarts used).
    pub attempts: u32,
    /// Tool pose at `q`.
    pub pose: Transform,
}

/// Where a joint may go.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Bound {
    /// Within `[lo, hi]` (rad or length unit).
    Limited(f64, f64),
    /// An unlimited revolute joint (any angle; answers near the reference).
    FreeAngle,
    /// An unlimited prismatic joint (restarts draw from ±the chain's reach).
    FreeLength,
}

/// An IK solver for one chain and its joint limits.
#[derive(Clone, Debug)]
pub struct IkSolver<'a> {
    chain: &'a Chain,
    bounds: Vec<Bound>,
    reach: f64,
}

/// The buffers of one solve, allocated once.
#[derive(Clone, Debug)]
struct Work {
    q: Vec<f64>,
    trial_q: Vec<f64>,
    step: Vec<f64>,
    locked: Vec<bool>,
    start: Vec<f64>,
    cur: Eval,
    trial: Eval,
}

impl Work {
    fn new(n: usize) -> Work {
        let eval = || Eval {
            columns: vec![[0.0; 6]; n],
            error: [0.0; 6],
            raw: [0.0; 6],
            cost: f64::INFINITY,
        };
        Work {
            q: vec![0.0; n],
            trial_q: vec![0.0; n],
            step: vec![0.0; n],
            locked: vec![false; n],
            start: vec![0.0; n],
            cur: eval(),
            trial: eval(),
        }
    }
}

/// One evaluated configuration.
#[derive(Clone, Debug)]
struct Eval {
    columns: Vec<[f64; 6]>,
    /// `[p_target − p; ω]` with `exp(ω) = R_target Rᵀ` (in the target frame
    /// with per-axis tolerances), components within their tolerance zeroed.
    error: [f64; 6],
    /// The same before zeroing (what convergence is tested on).
    raw: [f64; 6],
    /// The squared norm minimised (position rows only in position-only mode).
    cost: f64,
}

/// Deterministic pseudo-random numbers in [0, 1) (SplitMix64).
#[derive(Clone, Debug)]
struct Rng(u64);

impl Rng {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The rotation vector `ω` (axis × angle, rad) of `R_target · Rᵀ`, exact for
/// every angle: through the unit quaternion (Shepperd's method) and `atan2`.
pub fn rotation_error(target: &Transform, pose: &Transform) -> [f64; 3] {
    let (a, b) = (&target.rotation, &pose.rotation);
    let m = Transform {
        rotation: std::array::from_fn(|i| {
            std::array::from_fn(|j| a[i][0] * b[j][0] + a[i][1] * b[j][1] + a[i][2] * b[j][2])
        }),
        translation: [0.0; 3],
    };
    let [w, x, y, z] = m.quaternion();
    let s = (x * x + y * y + z * z).sqrt();
    if s == 0.0 {
        return [0.0; 3];
    }
    let k = 2.0 * s.atan2(w) / s;
    [x * k, y * k, z * k]
}

/// Whether a solve must give up now: its deadline passed or it was cancelled.
fn stopped(opts: &IkOptions, cancel: &AtomicBool) -> bool {
    cancel.load(Ordering::Relaxed) || opts.deadline.is_some_and(|d| Instant::now() >= d)
}

fn norm3(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

impl<'a> IkSolver<'a> {
    /// A solver for `chain` with `limits` per movable joint (`None`: no limit;
    /// internal units). Missing entries count as unlimited.
    pub fn new(chain: &'a Chain, limits: &[Option<(f64, f64)>]) -> IkSolver<'a> {
        let bounds = chain
            .joint_kinds()
            .enumerate()
            .map(|(i, kind)| match (limits.get(i).copied().flatten(), kind) {
                (Some((lo, hi)), _) => Bound::Limited(lo, hi),
                (None, JointKind::Prismatic) => Bound::FreeLength,
                (None, _) => Bound::FreeAngle,
            })
            .collect();
        let reach = chain
            .dh_rows()
            .map(|r| r.a.abs() + r.d.abs())
            .sum::<f64>()
            .max(1.0);
        IkSolver {
            chain,
            bounds,
            reach,
        }
    }

    /// Number of joints solved for.
    pub fn dof(&self) -> usize {
        self.bounds.len()
    }

    /// Solves for `target` (world frame), starting from `seed` if given
    /// (clamped into the limits), else from the posture if one is set, else
    /// from the middle of each joint's range (0 where unlimited), then
    /// restarting as [`IkOptions::restarts`] allows. Returns the first
    /// converged attempt (moved towards the posture if one is set), or the
    /// attempt with the lowest error. Unlimited revolute joints are answered
    /// within π of that start (seed, posture, or 0); limited joints whose
    /// range spans more than a turn, as close to it as their limits allow.
    pub fn solve(&self, target: &Transform, seed: Option<&[f64]>, opts: &IkOptions) -> IkSolution {
        static NEVER: AtomicBool = AtomicBool::new(false);
        self.solve_cancellable(target, seed, opts, &NEVER)
    }

    /// [`IkSolver::solve`] that also gives up (answering the best attempt so
    /// far, as at the deadline) once `cancel` is set — by another thread, for
    /// a client that left. Checked once per iteration (a few µs).
    ///
    /// ```
    /// use std::sync::atomic::AtomicBool;
    /// use kinserve_kinematics::ik::{IkOptions, IkSolver};
    /// use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, Transform};
    ///
    /// let row = |a| DhRow { kind: JointKind::Revolute, a, alpha: 0.0, d: 0.0, theta: 0.0 };
    /// let chain = Chain::new(Convention::Standard, &[row(1.0), row(1.0)], Transform::IDENTITY, None);
    /// let solver = IkSolver::new(&chain, &[]);
    /// let target = chain.forward(&[0.3, 0.4], 1.0);
    /// let opts = IkOptions { position_only: true, ..IkOptions::default() };
    /// let cancelled = AtomicBool::new(true);
    /// let s = solver.solve_cancellable(&target, None, &opts, &cancelled);
    /// assert_eq!(s.attempts, 1, "a cancelled solve makes no restarts");
    /// ```
    pub fn solve_cancellable(
        &self,
        target: &Transform,
        seed: Option<&[f64]>,
        opts: &IkOptions,
        cancel: &AtomicBool,
    ) -> IkSolution {
        let n = self.dof();
        let reference: Vec<f64> = match (seed, &opts.posture) {
            (Some(s), _) => (0..n).map(|i| s.get(i).copied().unwrap_or(0.0)).collect(),
            (None, Some(p)) => (0..n)
                .map(|i| {
                    let x = p.joints.get(i).copied().filter(|x| x.is_finite());
                    x.unwrap_or(self.middle(self.bounds[i]))
                })
                .collect(),
            (None, None) => self.bounds.iter().map(|b| self.middle(*b)).collect(),
        };
        let mut rng = Rng(opts.rng_seed);
        let mut w = Work::new(n);
        w.q.copy_from_slice(&reference);
        self.clamp(&mut w.q);
        let mut best: Option<(Vec<f64>, f64)> = None;
        let mut iterations = 0;
        let mut attempts = 0;
        let close = CLOSE_ERROR.max(NEAR_FACTOR * Self::tolerance(opts)).powi(2);
        loop {
            attempts += 1;
            let active_set = attempts % 2 == 0;
            let (done, cost) =
                self.attempt(target, &mut w, opts, cancel, &mut iterations, active_set);
            // A converged attempt wins over any lower-cost unconverged one.
            let cost = if done { f64::NEG_INFINITY } else { cost };
            if best.as_ref().is_none_or(|(_, c)| cost < *c) {
                best = Some((w.q.clone(), cost));
            }
            let out_of_time = stopped(opts, cancel);
            let far = best.as_ref().is_some_and(|(_, c)| *c > close);
            let given_up = far && opts.far_restarts.is_some_and(|n| attempts > n);
            if done || attempts > opts.restarts || out_of_time || given_up {
                break;
            }
            self.random_start(&mut w.q, &mut rng);
        }
        let (mut q, cost) = best.unwrap_or((reference.clone(), f64::INFINITY));
        self.near_reference(&mut q, &reference);
        if let (Some(p), true) = (&opts.posture, cost == f64::NEG_INFINITY) {
            w.q.copy_from_slice(&q);
            self.refine_posture(target, &mut w, opts, cancel, p, &mut iterations);
            q.copy_from_slice(&w.q);
        }
        let pose = self.chain.forward(&q, 1.0);
        let position_error = norm3(&sub3(target.translation, pose.translation));
        let orientation_error = norm3(&rotation_error(target, &pose));
        self.eval(target, &q, opts, &mut w.cur);
        let converged = self.converged(&w.cur, opts);
        IkSolution {
            q,
            converged,
            position_error,
            orientation_error,
            iterations,
            attempts,
            pose,
        }
    }

    /// One attempt from `w.q` (within the limits; updated in place to the best
    /// in-limit configuration it reached): the unconstrained phase, then, unless
    /// it gave an in-limit solution, the limited phase from the clamped result,
    /// both within `opts.max_iterations` iterations together. Never answers
    /// worse than its start. Returns whether it converged and its cost.
    fn attempt(
        &self,
        target: &Transform,
        w: &mut Work,
        opts: &IkOptions,
        cancel: &AtomicBool,
        iterations: &mut u32,
        active_set: bool,
    ) -> (bool, f64) {
        w.start.copy_from_slice(&w.q);
        self.eval(target, &w.q, opts, &mut w.cur);
        let start_cost = w.cur.cost;
        let budget = opts.max_iterations;
        let (done, used) = self.run(target, w, opts, cancel, iterations, budget, Limits::Ignored);
        if done && self.wrap_into_limits(&mut w.q) {
            self.eval(target, &w.q, opts, &mut w.cur);
            if self.converged(&w.cur, opts) {
                return (true, w.cur.cost);
            }
        }
        self.clamp(&mut w.q);
        self.eval(target, &w.q, opts, &mut w.cur);
        let limits = if active_set {
            Limits::ActiveSet
        } else {
            Limits::Clamped
        };
        let (done, _) = self.run(target, w, opts, cancel, iterations, budget - used, limits);
        if !done && w.cur.cost > start_cost {
            w.q.copy_from_slice(&w.start);
            self.eval(target, &w.q, opts, &mut w.cur);
        }
        (done, w.cur.cost)
    }

    /// One damped-least-squares phase from `w.q` (evaluated in `w.cur`), at
    /// most `budget` iterations. Returns whether it converged and the
    /// iterations it used.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &self,
        target: &Transform,
        w: &mut Work,
        opts: &IkOptions,
        cancel: &AtomicBool,
        iterations: &mut u32,
        budget: u32,
        limits: Limits,
    ) -> (bool, u32) {
        let mut lambda = LAMBDA_START;
        let mut slow = 0;
        let mut history = [f64::INFINITY; PROGRESS_WINDOW];
        let near = (NEAR_FACTOR * Self::tolerance(opts).min(1.0)).powi(2);
        for it in 0..budget {
            if self.converged(&w.cur, opts) {
                return (true, it);
            }
            let slot = it as usize % PROGRESS_WINDOW;
            let stalled = w.cur.cost > near && w.cur.cost > PROGRESS_RATIO * history[slot];
            if stopped(opts, cancel) || stalled {
                return (false, it);
            }
            history[slot] = w.cur.cost;
            *iterations += 1;
            let moved = if limits == Limits::ActiveSet {
                self.limited_step(
                    &w.q,
                    &w.cur,
                    lambda,
                    opts.position_only,
                    &mut w.step,
                    &mut w.locked,
                )
            } else {
                self.step(&w.cur, lambda, opts.position_only, &mut w.step, &[])
            };
            if moved {
                for ((t, x), d) in w.trial_q.iter_mut().zip(&w.q).zip(&w.step) {
                    *t = x + d;
                }
                if limits != Limits::Ignored {
                    self.clamp(&mut w.trial_q);
                }
                self.eval(target, &w.trial_q, opts, &mut w.trial);
            }
            if moved && w.trial.cost < w.cur.cost {
                let slow_step = w.trial.cost > SLOW_RATIO.mul_add(-w.cur.cost, w.cur.cost);
                slow = if slow_step { slow + 1 } else { 0 };
                std::mem::swap(&mut w.q, &mut w.trial_q);
                std::mem::swap(&mut w.cur, &mut w.trial);
                lambda = (lambda / 10.0).max(LAMBDA_MIN);
                if slow >= SLOW_STEPS {
                    return (self.converged(&w.cur, opts), it + 1);
                }
            } else {
                lambda *= 10.0;
                if lambda > LAMBDA_MAX {
                    return (false, it + 1);
                }
            }
        }
        (self.converged(&w.cur, opts), budget)
    }

    /// [`IkSolver::step`] with the joints that stand at a limit and would be
    /// pushed past it taken out of the step (an active set, re-solved until
    /// no such joint remains, at most three passes).
    fn limited_step(
        &self,
        q: &[f64],
        e: &Eval,
        lambda: f64,
        position_only: bool,
        out: &mut [f64],
        locked: &mut [bool],
    ) -> bool {
        locked.iter_mut().for_each(|l| *l = false);
        for _ in 0..3 {
            if !self.step(e, lambda, position_only, out, locked) {
                return false;
            }
            let mut more = false;
            for (i, b) in self.bounds.iter().enumerate() {
                if let Bound::Limited(lo, hi) = *b {
                    let push = (q[i] >= hi && out[i] > 0.0) || (q[i] <= lo && out[i] < 0.0);
                    if push && !locked[i] {
                        locked[i] = true;
                        more = true;
                    }
                }
            }
            if !more {
                break;
            }
        }
        true
    }

    /// Moves revolute joints outside their limits by whole turns into them
    /// where a turn fits (the pose does not change). Whether every joint is
    /// then within its limits.
    fn wrap_into_limits(&self, q: &mut [f64]) -> bool {
        let mut inside = true;
        for ((x, b), kind) in q.iter_mut().zip(&self.bounds).zip(self.chain.joint_kinds()) {
            let Bound::Limited(lo, hi) = *b else {
                continue;
            };
            if kind == JointKind::Revolute && !(lo..=hi).contains(x) {
                let turns = ((0.5 * (lo + hi) - *x) / (2.0 * PI)).round();
                let moved = *x + turns * 2.0 * PI;
                if (lo..=hi).contains(&moved) {
                    *x = moved;
                }
            }
            inside &= (lo..=hi).contains(x);
        }
        inside
    }

    /// The tightest tolerance asked for: `tolerance`, or the smallest
    /// per-axis tolerance.
    fn tolerance(opts: &IkOptions) -> f64 {
        opts.axis_tolerances.map_or(opts.tolerance, |t| {
            t.iter().copied().fold(f64::INFINITY, f64::min)
        })
    }

    fn converged(&self, e: &Eval, opts: &IkOptions) -> bool {
        match opts.axis_tolerances {
            Some(t) => {
                let rows = if opts.position_only { 3 } else { 6 };
                e.raw[..rows].iter().zip(&t).all(|(x, t)| x.abs() <= *t)
            }
            None => {
                norm3(&e.raw[..3]) <= opts.tolerance
                    && (opts.position_only || norm3(&e.raw[3..]) <= opts.tolerance)
            }
        }
    }

    /// The posture cost `Σ wᵢ (qᵢ − pᵢ)²` (weights within `[0, 1]`).
    fn posture_cost(q: &[f64], p: &Posture) -> f64 {
        q.iter()
            .zip(&p.joints)
            .zip(&p.weights)
            .map(|((x, p), w)| posture_weight(*w) * (x - p).powi(2))
            .filter(|c| c.is_finite())
            .sum()
    }

    /// From a converged `w.q`, null-space steps towards the posture (each
    /// followed by up to [`POSTURE_CORRECTIONS`] plain steps back onto the
    /// target), each kept only if the pose is within the tolerance and the posture cost
    /// falls (the step is halved after a refused one, doubled back after a
    /// kept one), until the steps get negligible or `max_iterations` ran out.
    fn refine_posture(
        &self,
        target: &Transform,
        w: &mut Work,
        opts: &IkOptions,
        cancel: &AtomicBool,
        p: &Posture,
        iterations: &mut u32,
    ) {
        self.eval(target, &w.q, opts, &mut w.cur);
        let mut cost = Self::posture_cost(&w.q, p);
        let mut z = vec![0.0; self.dof()];
        let mut scale = 1.0;
        for _ in 0..opts.max_iterations {
            if stopped(opts, cancel) || scale < 1e-3 {
                break;
            }
            for (i, zi) in z.iter_mut().enumerate() {
                let (pi, wi) = (p.joints.get(i), p.weights.get(i));
                let pull = match (pi, wi) {
                    (Some(pi), Some(wi)) => posture_weight(*wi) * (pi - w.q[i]),
                    _ => 0.0,
                };
                *zi = if pull.is_finite() {
                    (scale * pull).clamp(-0.5, 0.5)
                } else {
                    0.0
                };
            }
            if z.iter().all(|x| x.abs() < 1e-12) {
                break;
            }
            *iterations += 1;
            if !self.step_z(&w.cur, 1e-9, opts.position_only, &mut w.step, &[], Some(&z)) {
                break;
            }
            for ((t, x), d) in w.trial_q.iter_mut().zip(&w.q).zip(&w.step) {
                *t = x + d;
            }
            self.clamp(&mut w.trial_q);
            self.eval(target, &w.trial_q, opts, &mut w.trial);
            // Corrector: a few undamped steps back onto the target.
            for _ in 0..POSTURE_CORRECTIONS {
                if self.converged(&w.trial, opts)
                    || !self.step(&w.trial, 1e-9, opts.position_only, &mut w.step, &[])
                {
                    break;
                }
                *iterations += 1;
                for (t, d) in w.trial_q.iter_mut().zip(&w.step) {
                    *t += d;
                }
                self.clamp(&mut w.trial_q);
                self.eval(target, &w.trial_q, opts, &mut w.trial);
            }
            let trial_cost = Self::posture_cost(&w.trial_q, p);
            if self.converged(&w.trial, opts) && trial_cost < cost {
                let gain = cost - trial_cost;
                std::mem::swap(&mut w.q, &mut w.trial_q);
                std::mem::swap(&mut w.cur, &mut w.trial);
                cost = trial_cost;
                scale = (scale * 2.0).min(1.0);
                if gain <= 1e-12 * (1.0 + cost) {
                    break;
                }
            } else {
                scale *= 0.5;
            }
        }
    }

    /// The damped step `Δq = Jᵀ (J Jᵀ + λ·s·I)⁻¹ e` into `out`, with `s` the
    /// mean diagonal of `J Jᵀ` (so λ is unit-free), over the joints not
    /// `locked` (the others get 0; missing entries count as not locked).
    /// False if the system is not positive definite (only for a zero
    /// Jacobian and tiny λ).
    fn step(
        &self,
        e: &Eval,
        lambda: f64,
        position_only: bool,
        out: &mut [f64],
        locked: &[bool],
    ) -> bool {
        self.step_z(e, lambda, position_only, out, locked, None)
    }

    /// [`IkSolver::step`] plus `z` projected onto the null space of `J`:
    /// `Δq = z + Jᵀ (J Jᵀ + λ·s·I)⁻¹ (e − J z)` (`None`: `z = 0`).
    fn step_z(
        &self,
        e: &Eval,
        lambda: f64,
        position_only: bool,
        out: &mut [f64],
        locked: &[bool],
        z: Option<&[f64]>,
    ) -> bool {
        let cols = &e.columns;
        let free = |i: usize| !locked.get(i).copied().unwrap_or(false);
        let mut rhs = e.error;
        if let Some(z) = z {
            for (c, zi) in cols.iter().zip(z) {
                for (r, j) in rhs.iter_mut().zip(c) {
                    *r -= j * zi;
                }
            }
        }
        let mut y = [0.0; 6];
        if position_only {
            let mut a = Matrix3::<f64>::zeros();
            for (_, c) in cols.iter().enumerate().filter(|(i, _)| free(*i)) {
                let v = Vector3::new(c[0], c[1], c[2]);
                a += v * v.transpose();
            }
            let s = (a.trace() / 3.0).max(f64::MIN_POSITIVE);
            a += Matrix3::identity() * (lambda * s);
            let b = Vector3::new(rhs[0], rhs[1], rhs[2]);
            let Some(chol) = a.cholesky() else {
                return false;
            };
            y[..3].copy_from_slice(chol.solve(&b).as_slice());
        } else {
            let mut a = Matrix6::<f64>::zeros();
            for (_, c) in cols.iter().enumerate().filter(|(i, _)| free(*i)) {
                let v = Vector6::from_row_slice(c);
                a += v * v.transpose();
            }
            let s = (a.trace() / 6.0).max(f64::MIN_POSITIVE);
            a += Matrix6::identity() * (lambda * s);
            let b = Vector6::from_row_slice(&rhs);
            let Some(chol) = a.cholesky() else {
                return false;
            };
            y.copy_from_slice(chol.solve(&b).as_slice());
        }
        for (i, (o, c)) in out.iter_mut().zip(cols).enumerate() {
            let zi = z.and_then(|z| z.get(i)).copied().unwrap_or(0.0);
            *o = if free(i) {
                zi + c.iter().zip(&y).map(|(j, y)| j * y).sum::<f64>()
            } else {
                0.0
            };
        }
        true
    }

    /// Pose, Jacobian and error at `q` into `out`. With per-axis tolerances
    /// the error and the Jacobian's rows are expressed in the target frame,
    /// components within their tolerance count as zero and the rows of free
    /// axes as zero too (the step then leaves them alone).
    fn eval(&self, target: &Transform, q: &[f64], opts: &IkOptions, out: &mut Eval) {
        let pose = self
            .chain
            .jacobian_into(q, 1.0, JacobianFrame::Base, &mut out.columns);
        let p = sub3(target.translation, pose.translation);
        let w = rotation_error(target, &pose);
        out.raw = [p[0], p[1], p[2], w[0], w[1], w[2]];
        out.error = out.raw;
        if let Some(tol) = opts.axis_tolerances {
            let r = &target.rotation;
            // Rᵀ v for the target rotation R, on each 3-vector half.
            let to_target = |v: &mut [f64]| {
                let x = [v[0], v[1], v[2]];
                for (k, o) in v.iter_mut().enumerate().take(3) {
                    *o = r[0][k] * x[0] + r[1][k] * x[1] + r[2][k] * x[2];
                }
            };
            to_target(&mut out.raw[..3]);
            to_target(&mut out.raw[3..]);
            for c in out.columns.iter_mut() {
                to_target(&mut c[..3]);
                to_target(&mut c[3..]);
                for (x, t) in c.iter_mut().zip(&tol) {
                    if t.is_infinite() {
                        *x = 0.0;
                    }
                }
            }
            for ((e, x), t) in out.error.iter_mut().zip(&out.raw).zip(&tol) {
                *e = if x.abs() <= *t { 0.0 } else { *x };
            }
        }
        let rows = if opts.position_only { 3 } else { 6 };
        out.cost = out.error[..rows].iter().map(|x| x * x).sum();
    }

    fn middle(&self, b: Bound) -> f64 {
        match b {
            Bound::Limited(lo, hi) => 0.5 * (lo + hi),
            _ => 0.0,
        }
    }

    fn clamp(&self, q: &mut [f64]) {
        for (x, b) in q.iter_mut().zip(&self.bounds) {
            if let Bound::Limited(lo, hi) = *b {
                *x = x.clamp(lo, hi);
            }
        }
    }

    fn random_start(&self, q: &mut [f64], rng: &mut Rng) {
        for (x, b) in q.iter_mut().zip(&self.bounds) {
            let u = rng.next_f64();
            *x = match *b {
                Bound::Limited(lo, hi) => lo + (hi - lo) * u,
                Bound::FreeAngle => PI * (2.0 * u - 1.0),
                Bound::FreeLength => self.reach * (2.0 * u - 1.0),
            };
        }
    }

    /// Moves each revolute joint by whole turns as close to `reference` as
    /// its limits allow (the pose does not change).
    fn near_reference(&self, q: &mut [f64], reference: &[f64]) {
        let kinds = self.chain.joint_kinds();
        for (((x, b), r), kind) in q.iter_mut().zip(&self.bounds).zip(reference).zip(kinds) {
            if kind != JointKind::Revolute {
                continue;
            }
            let turns = ((*r - *x) / (2.0 * PI)).round();
            if turns == 0.0 {
                continue;
            }
            let moved = *x + turns * 2.0 * PI;
            let inside = match *b {
                Bound::Limited(lo, hi) => (lo..=hi).contains(&moved),
                _ => true,
            };
            if inside {
                *x = moved;
            }
        }
    }
}

/// A posture weight as used: within `[0, 1]`, 0 for a negative or non-finite one.
fn posture_weight(w: f64) -> f64 {
    if w.is_finite() {
        w.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
