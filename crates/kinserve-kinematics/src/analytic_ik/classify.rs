//! Which closed form an arm admits ([`ArmClass`]), decided once from the
//! chain's joint axes at `q = 0` ([`ZeroAxes`]), with the constants the
//! solvers need ([`Geometry`]); or why it admits none ([`NotAnalytic`]).
//!
//! Tolerances: axes count as parallel when the sine of their angle is at
//! most 1e-10, and lines as meeting when they pass within 1e-10 × the chain's
//! length scale (see [`ZeroAxes::scale`]). Depends on [`super::geometry`].

use std::fmt;

use super::geometry::{Axis, V3, ZeroAxes, dot, intersection, norm, parallel, perpendicular, sub};
use crate::dh::JointKind;

/// Relative tolerance of the classification (directions: sine of the angle;
/// lengths: times the chain's length scale).
const CLASSIFY_TOL: f64 = 1e-10;
/// Relative tolerance under which a target counts as singular (a joint free).
const SINGULAR_TOL: f64 = 1e-12;

/// The closed forms [`AnalyticIk`](super::AnalyticIk) knows, for six
/// revolute joints (axes numbered 1–6 in table order, fixed rows skipped).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ArmClass {
    /// Spherical wrist (axes 4, 5, 6 meet in one point) and axes 2 ∥ 3, axis
    /// 1 not parallel to them: PUMA 560, ABB IRB 140, KUKA KR 5 and most
    /// industrial arms, with or without a shoulder offset. Up to 8 solutions.
    SphericalWristParallel23,
    /// Spherical wrist and axes 1, 2 meeting (2, 3 not parallel). Up to 8.
    SphericalWristIntersecting12,
    /// Spherical wrist and axes 2, 3 meeting (and the wrist centre off them). Up to 8.
    SphericalWristIntersecting23,
    /// Axes 2, 3, 4 parallel, axes 5 and 6 meeting, axis 1 and axis 5 not
    /// parallel to 2: the Universal Robots family, any DH offsets. Up to 8.
    ThreeParallel234,
}

impl ArmClass {
    /// A stable snake_case name (for answers and logs).
    pub fn name(self) -> &'static str {
        match self {
            ArmClass::SphericalWristParallel23 => "spherical_wrist_parallel_23",
            ArmClass::SphericalWristIntersecting12 => "spherical_wrist_intersecting_12",
            ArmClass::SphericalWristIntersecting23 => "spherical_wrist_intersecting_23",
            ArmClass::ThreeParallel234 => "three_parallel_234",
        }
    }
}

/// Why a chain has no closed form here (solve it numerically instead).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NotAnalytic {
    /// Not six movable joints (the count is given).
    JointCount(usize),
    /// A movable joint (0-based index among the movable joints) is prismatic.
    Prismatic(usize),
    /// Six revolute joints, but neither a spherical wrist with a solvable
    /// positioning part nor three parallel axes 2–4 with axes 5, 6 meeting.
    Unsupported,
}

impl fmt::Display for NotAnalytic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NotAnalytic::JointCount(n) => write!(
                f,
                "analytic IK needs exactly 6 movable joints, this chain has {n}; use the numeric solver"
            ),
            NotAnalytic::Prismatic(i) => write!(
                f,
                "analytic IK needs revolute joints only, movable joint {i} is prismatic; use the numeric solver"
            ),
            NotAnalytic::Unsupported => write!(
                f,
                "no closed form for this arm: it has neither a spherical wrist (axes 4, 5, 6 \
                 meeting) with axes 2 ∥ 3 or axes 1, 2 or 2, 3 meeting, nor axes 2, 3, 4 \
                 parallel with axes 5, 6 meeting; use the numeric solver"
            ),
        }
    }
}

impl std::error::Error for NotAnalytic {}

/// The constants of one classified arm.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Geometry {
    /// Joint axes at `q = 0` (world frame).
    pub axes: [Axis; 6],
    /// The wrist centre (spherical wrists) or where axes 5 and 6 meet (three parallel).
    pub point: V3,
    /// Where axes 1, 2 (or 2, 3) meet, for those classes; else the origin.
    pub corner: V3,
    /// A unit vector ⟂ axis 6.
    pub perp6: V3,
    /// A unit vector ⟂ axis 2.
    pub perp2: V3,
    /// `h₃·h₂` and `h₄·h₂` (±1 for the three-parallel class).
    pub signs: [f64; 2],
    /// Singularity tolerance for lengths (length unit) and directions.
    pub sing_len: f64,
    pub sing_dir: f64,
}

/// Classifies a chain from its zero-configuration axes.
pub(crate) fn classify(z: &ZeroAxes) -> Result<(ArmClass, Geometry), NotAnalytic> {
    if z.axes.len() != 6 {
        return Err(NotAnalytic::JointCount(z.axes.len()));
    }
    if let Some(i) = z.kinds.iter().position(|k| *k != JointKind::Revolute) {
        return Err(NotAnalytic::Prismatic(i));
    }
    let axes: [Axis; 6] = std::array::from_fn(|i| z.axes[i]);
    let (lt, dt) = (CLASSIFY_TOL * z.scale, CLASSIFY_TOL);
    let mut geo = Geometry {
        axes,
        point: [0.0; 3],
        corner: [0.0; 3],
        perp6: perpendicular(axes[5].h),
        perp2: perpendicular(axes[1].h),
        signs: [dot(axes[2].h, axes[1].h), dot(axes[3].h, axes[1].h)],
        sing_len: SINGULAR_TOL * z.scale,
        sing_dir: SINGULAR_TOL,
    };
    let [a1, a2, a3, a4, a5, a6] = axes;
    if let Some(w) = wrist_centre(&a4, &a5, &a6, lt, dt) {
        geo.point = w;
        let class = if parallel(a2.h, a3.h, dt)
            && !parallel(a1.h, a2.h, dt)
            && a3.distance_to(a2.p) > lt
            && a3.distance_to(w) > lt
        {
            Some(ArmClass::SphericalWristParallel23)
        } else if let Some(c) = intersection(&a1, &a2, lt, dt).filter(|_| a3.distance_to(w) > lt) {
            geo.corner = c;
            Some(ArmClass::SphericalWristIntersecting12)
        } else if let Some(c) = intersection(&a2, &a3, lt, dt).filter(|c| norm(sub(w, *c)) > lt) {
            geo.corner = c;
            (a1.distance_to(c) > lt || !parallel(a1.h, a2.h, dt))
                .then_some(ArmClass::SphericalWristIntersecting23)
        } else {
            None
        };
        if let Some(class) = class {
            return Ok((class, geo));
        }
    }
    let three_parallel = parallel(a2.h, a3.h, dt)
        && parallel(a2.h, a4.h, dt)
        && !parallel(a1.h, a2.h, dt)
        && !parallel(a5.h, a2.h, dt)
        && a3.distance_to(a2.p) > lt
        && a3.distance_to(a4.p) > lt;
    if three_parallel && let Some(p) = intersection(&a5, &a6, lt, dt) {
        geo.point = p;
        return Ok((ArmClass::ThreeParallel234, geo));
    }
    Err(NotAnalytic::Unsupported)
}

/// The point where axes 4, 5, 6 meet, if they do (4 ∦ 5, 5 ∦ 6).
fn wrist_centre(a4: &Axis, a5: &Axis, a6: &Axis, lt: f64, dt: f64) -> Option<V3> {
    let w = intersection(a4, a5, lt, dt)?;
    (a6.distance_to(w) <= lt && !parallel(a5.h, a6.h, dt)).then_some(w)
}
