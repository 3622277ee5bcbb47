//! Analytic inverse kinematics (feature `ik`): every solution of a 6R arm
//! in closed form, for the arm classes of [`ArmClass`].
//!
//! Owns [`AnalyticIk`] (built once from a [`Chain`]: the chain is classified
//! and its joint axes at `q = 0` are read, in product-of-exponentials form,
//! from the DH table of either convention with its fixed rows, base and
//! tool), the per-target answers ([`Principal`] without allocation,
//! [`AnalyticAnswer`] with the 2π copies inside joint limits, nearest a seed
//! first) and their branch and singularity flags ([`Branch`], [`Singular`]).
//! The method is subproblem decomposition (Paden–Kahan subproblems 1–4 in
//! the form of Elias & Wen's IK-Geo, in `subproblems`): `spherical` solves
//! spherical wrists, `parallel` three parallel axes, `classify` decides the
//! class, `copies` adds the 2π copies, `geometry` holds the vector algebra.
//!
//! Every answer is checked by FK ([`Chain::forward`]): a candidate is kept
//! only if its position error (length unit) and the largest error of its
//! rotation matrix entries are within the tolerance; unreachable targets
//! give no solutions. Not classified — prismatic joints, fewer or more than
//! six joints, other geometries — is [`NotAnalytic`]: solve those with
//! [`crate::ik::IkSolver`].
//!
//! Units: joint values in rad; targets in the world frame in the chain's
//! length unit. Depends on the chain, DH and transform modules; must not
//! depend on serde or any other kinserve crate.

mod classify;
mod copies;
mod geometry;
mod parallel;
mod spherical;
mod subproblems;

pub use classify::{ArmClass, NotAnalytic};

use crate::chain::Chain;
use crate::transform::Transform;
use classify::Geometry;
use geometry::{ZeroAxes, wrap};

/// Default acceptance of a candidate: position error ≤ 1e-9 (length unit)
/// and every rotation-matrix entry within 1e-9.
pub const DEFAULT_TOLERANCE: f64 = 1e-9;
/// Default cap on the solutions of one answer (copies included).
pub const DEFAULT_MAX_SOLUTIONS: usize = 1024;
/// Most principal solutions a 6R arm of the classes here can have.
pub const MAX_PRINCIPAL: usize = 8;

/// Which root of each subproblem a solution took: `false` the first, `true`
/// the second, for the joints that name them — shoulder: joint 1 (or, for
/// axes 1, 2 meeting, the SP2 pair of joints 1, 2); elbow: joint 3 (the SP2
/// pair of joints 2, 3 when they meet); wrist: the SP2 pair of joints 4, 5
/// (spherical wrist) or joint 5 (three parallel axes). Along a path away from
/// singularities each solution keeps its flags, so equal flags mean no
/// shoulder, elbow or wrist flip.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Branch {
    /// Shoulder root (lefty / righty).
    pub shoulder: bool,
    /// Elbow root (up / down).
    pub elbow: bool,
    /// Wrist root (flip / no flip).
    pub wrist: bool,
}

/// Whether a solution stands for a one-parameter family: a joint was free
/// and was given its reference value (the seed's, else the middle of its
/// limits, else 0).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Singular {
    /// A positioning joint (1–3) was free: the wrist centre (or axes 5–6's
    /// meeting point) on axis 1 — a shoulder singularity.
    pub shoulder: bool,
    /// A wrist joint was free: axes 4 and 6 aligned (spherical wrist), axis 6
    /// parallel to axes 2–4 (three parallel axes) — a wrist singularity.
    pub wrist: bool,
}

impl Singular {
    /// Whether any joint was free.
    pub fn any(&self) -> bool {
        self.shoulder || self.wrist
    }
}

/// One principal solution: joint values in `(−π, π]` rad (before limits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawSolution {
    /// Joint values, rad.
    pub q: [f64; 6],
    /// Its branch.
    pub branch: Branch,
    /// Whether it represents a family.
    pub singular: Singular,
    /// `|p_target − p_FK|`, length unit.
    pub position_error: f64,
    /// Largest `|R_target − R_FK|` entry.
    pub rotation_error: f64,
}

/// The principal solutions of one target, stored inline (no allocation).
#[derive(Clone, Debug)]
pub struct Principal {
    items: [RawSolution; MAX_PRINCIPAL],
    len: usize,
}

impl Default for Principal {
    fn default() -> Self {
        Principal::new()
    }
}

impl Principal {
    /// An empty set.
    pub fn new() -> Principal {
        let blank = RawSolution {
            q: [0.0; 6],
            branch: Branch::default(),
            singular: Singular::default(),
            position_error: 0.0,
            rotation_error: 0.0,
        };
        Principal {
            items: [blank; MAX_PRINCIPAL],
            len: 0,
        }
    }

    /// The solutions, in the solver's branch order.
    pub fn as_slice(&self) -> &[RawSolution] {
        &self.items[..self.len]
    }

    /// How many.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none (target out of reach).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub(crate) fn push(&mut self, s: RawSolution) {
        if self.len < MAX_PRINCIPAL {
            self.items[self.len] = s;
            self.len += 1;
        }
    }
}

/// How to answer [`AnalyticIk::solve`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnalyticOptions {
    /// Keep a solution if FK at it is within this of the target: position
    /// (length unit) and each rotation-matrix entry.
    pub tolerance: f64,
    /// At most this many solutions (2π copies included), the nearest kept.
    pub max_solutions: usize,
}

impl Default for AnalyticOptions {
    fn default() -> Self {
        AnalyticOptions {
            tolerance: DEFAULT_TOLERANCE,
            max_solutions: DEFAULT_MAX_SOLUTIONS,
        }
    }
}

/// One solution inside the joint limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnalyticSolution {
    /// Joint values, rad, within the limits (a 2π copy of a principal solution).
    pub q: [f64; 6],
    /// Its branch (shared by all copies of one principal solution).
    pub branch: Branch,
    /// Whether it represents a family.
    pub singular: Singular,
    /// Limits-aware distance to the reference, rad (see [`AnalyticIk::solve`]).
    pub distance: f64,
    /// `|p_target − p_FK|`, length unit (of the principal solution).
    pub position_error: f64,
    /// Largest `|R_target − R_FK|` entry (of the principal solution).
    pub rotation_error: f64,
}

/// The answer of [`AnalyticIk::solve`].
#[derive(Clone, Debug, PartialEq)]
pub struct AnalyticAnswer {
    /// Every solution inside the limits, nearest the reference first.
    pub solutions: Vec<AnalyticSolution>,
    /// How many distinct principal solutions the target has (limits ignored).
    pub principal: usize,
    /// Whether more solutions fit the limits than `max_solutions`.
    pub truncated: bool,
}

impl AnalyticAnswer {
    /// Whether some solution stands for a family (singular target).
    pub fn singular(&self) -> Singular {
        self.solutions
            .iter()
            .fold(Singular::default(), |a, s| Singular {
                shoulder: a.shoulder || s.singular.shoulder,
                wrist: a.wrist || s.singular.wrist,
            })
    }
}

/// Analytic IK for one classified chain. Build once ([`AnalyticIk::new`]),
/// solve per target.
#[derive(Clone, Debug)]
pub struct AnalyticIk {
    chain: Chain,
    class: ArmClass,
    geo: Geometry,
    home_inv: Transform,
}

impl AnalyticIk {
    /// Classifies `chain` and prepares its closed form; [`NotAnalytic`] says
    /// why there is none (then use the numeric solver).
    ///
    /// ```
    /// use std::f64::consts::FRAC_PI_2;
    /// use kinserve_kinematics::analytic_ik::{AnalyticIk, AnalyticOptions, ArmClass};
    /// use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, Transform};
    ///
    /// // The PUMA 560 (standard DH, m).
    /// let r = |a, alpha, d| DhRow { kind: JointKind::Revolute, a, alpha, d, theta: 0.0 };
    /// let rows = [
    ///     r(0.0, FRAC_PI_2, 0.67183), r(0.4318, 0.0, 0.0), r(0.0203, -FRAC_PI_2, 0.15005),
    ///     r(0.0, FRAC_PI_2, 0.4318), r(0.0, -FRAC_PI_2, 0.0), r(0.0, 0.0, 0.0),
    /// ];
    /// let chain = Chain::new(Convention::Standard, &rows, Transform::IDENTITY, None);
    /// let ik = AnalyticIk::new(&chain).unwrap();
    /// assert_eq!(ik.class(), ArmClass::SphericalWristParallel23);
    ///
    /// let q = [0.3, -0.5, 0.8, 0.2, 0.7, -1.1];
    /// let answer = ik.solve(&chain.forward(&q, 1.0), &[], Some(&q), &AnalyticOptions::default());
    /// assert_eq!(answer.principal, 8);
    /// // Nearest the seed first: the configuration itself.
    /// let best = &answer.solutions[0];
    /// assert!(best.q.iter().zip(q).all(|(a, b)| (a - b).abs() < 1e-9));
    /// ```
    pub fn new(chain: &Chain) -> Result<AnalyticIk, NotAnalytic> {
        let zero = ZeroAxes::of(chain);
        let (class, geo) = classify::classify(&zero)?;
        Ok(AnalyticIk {
            chain: chain.clone(),
            class,
            geo,
            home_inv: zero.home.inverse(),
        })
    }

    /// The arm's class.
    pub fn class(&self) -> ArmClass {
        self.class
    }

    /// The chain solved for.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Every principal solution (joint values in `(−π, π]`, limits ignored)
    /// for `target` (world frame), each checked by FK within `tolerance`,
    /// distinct, into `out` (cleared first). At a singular target the free
    /// joint takes its value from `reference` (rad; missing entries are 0).
    /// Allocates nothing.
    pub fn solve_principal(
        &self,
        target: &Transform,
        reference: &[f64],
        tolerance: f64,
        out: &mut Principal,
    ) {
        out.len = 0;
        let reference: [f64; 6] = std::array::from_fn(|i| {
            reference
                .get(i)
                .copied()
                .filter(|x| x.is_finite())
                .unwrap_or(0.0)
        });
        let g = target.compose(&self.home_inv);
        match self.class {
            ArmClass::ThreeParallel234 => parallel::solve(&self.geo, &g, &reference, out),
            class => spherical::solve(class, &self.geo, &g, &reference, out),
        }
        self.check(target, tolerance, out);
    }

    /// Every solution for `target` (world frame) inside `limits` (per joint,
    /// rad; `None` or missing: unlimited), 2π copies included, sorted by the
    /// limits-aware distance to the reference: `√Σ dᵢ²` with `dᵢ = qᵢ − rᵢ`
    /// for a limited joint (travel cannot pass a limit, so each copy counts
    /// as far as it is) and the wrapped difference for an unlimited one
    /// (answered in its copy nearest `rᵢ` only). The reference is `seed`
    /// (rad) where given, else the middle of the joint's limits, else 0; it
    /// is also the value a free joint takes at a singular target.
    pub fn solve(
        &self,
        target: &Transform,
        limits: &[Option<(f64, f64)>],
        seed: Option<&[f64]>,
        opts: &AnalyticOptions,
    ) -> AnalyticAnswer {
        let reference: [f64; 6] = std::array::from_fn(|i| {
            let middle = match limits.get(i).copied().flatten() {
                Some((lo, hi)) => 0.5 * (lo + hi),
                None => 0.0,
            };
            seed.and_then(|s| s.get(i).copied())
                .filter(|x| x.is_finite())
                .unwrap_or(if middle.is_finite() { middle } else { 0.0 })
        });
        let mut principal = Principal::new();
        self.solve_principal(target, &reference, opts.tolerance, &mut principal);
        let (solutions, truncated) =
            copies::expand(principal.as_slice(), limits, &reference, opts.max_solutions);
        AnalyticAnswer {
            solutions,
            principal: principal.len(),
            truncated,
        }
    }

    /// Keeps the candidates FK confirms within `tol`, once each.
    fn check(&self, target: &Transform, tol: f64, out: &mut Principal) {
        let mut kept = 0;
        for i in 0..out.len {
            let mut s = out.items[i];
            let pose = self.chain.forward(&s.q, 1.0);
            let (p, t) = (&pose.translation, &target.translation);
            s.position_error =
                ((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2) + (p[2] - t[2]).powi(2)).sqrt();
            s.rotation_error = (0..9)
                .map(|k| (pose.rotation[k / 3][k % 3] - target.rotation[k / 3][k % 3]).abs())
                .fold(0.0, f64::max);
            let within = s.position_error <= tol && s.rotation_error <= tol;
            let seen = out.items[..kept].iter().any(|o| {
                o.q.iter()
                    .zip(&s.q)
                    .all(|(a, b)| wrap(a - b).abs() <= DUPLICATE)
            });
            if within && !seen {
                out.items[kept] = s;
                kept += 1;
            }
        }
        out.len = kept;
    }
}

/// Two principal solutions closer than this in every joint (rad) are one
/// (a double root, e.g. a stretched elbow).
const DUPLICATE: f64 = 1e-9;
