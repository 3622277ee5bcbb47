//! Small 3-vector and rotation algebra for the analytic solvers, and the
//! product-of-exponentials form of a chain at its zero configuration
//! ([`ZeroAxes`]): each revolute joint's unit axis and a point on it in the
//! world frame, and the tool pose at `q = 0`, read from the DH table (either
//! convention, fixed rows, base and tool included).
//!
//! Units: lengths in the chain's length unit, angles in rad. Depends on the
//! chain, DH and transform modules only.

use crate::chain::Chain;
use crate::dh::{Convention, JointKind, link_transform};
use crate::transform::Transform;

/// A 3-vector (length unit, or unitless for directions).
pub(crate) type V3 = [f64; 3];
/// A 3×3 matrix, row-major.
pub(crate) type M3 = [[f64; 3]; 3];

#[inline(always)]
pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
pub(crate) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline(always)]
pub(crate) fn scale(s: f64, a: V3) -> V3 {
    [s * a[0], s * a[1], s * a[2]]
}

#[inline(always)]
pub(crate) fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

/// `a` without its component along the unit vector `k`.
#[inline(always)]
pub(crate) fn reject(a: V3, k: V3) -> V3 {
    sub(a, scale(dot(k, a), k))
}

/// `R(k, θ)·v` for a unit axis `k` given `sin θ`, `cos θ` (Rodrigues).
#[inline(always)]
pub(crate) fn rot_sc(k: V3, s: f64, c: f64, v: V3) -> V3 {
    let kv = cross(k, v);
    let along = dot(k, v) * (1.0 - c);
    [
        v[0] * c + kv[0] * s + k[0] * along,
        v[1] * c + kv[1] * s + k[1] * along,
        v[2] * c + kv[2] * s + k[2] * along,
    ]
}

/// `R(k, θ)·v` for a unit axis `k`, `θ` in rad.
#[cfg(test)]
pub(crate) fn rot(k: V3, theta: f64, v: V3) -> V3 {
    let (s, c) = theta.sin_cos();
    rot_sc(k, s, c, v)
}

/// An angle (rad) with its sine and cosine, so rotations by it need no
/// further `sin_cos`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Angle {
    pub rad: f64,
    pub s: f64,
    pub c: f64,
}

impl Angle {
    pub const ZERO: Angle = Angle {
        rad: 0.0,
        s: 0.0,
        c: 1.0,
    };

    /// From an angle in rad.
    pub fn new(rad: f64) -> Angle {
        let (s, c) = rad.sin_cos();
        Angle { rad, s, c }
    }

    /// From `(y, x)` proportional to `(sin, cos)` (rad in `(−π, π]`); zero
    /// if both are 0.
    #[inline(always)]
    pub fn from_yx(y: f64, x: f64) -> Angle {
        let n = (y * y + x * x).sqrt();
        if n == 0.0 {
            return Angle::ZERO;
        }
        Angle {
            rad: y.atan2(x),
            s: y / n,
            c: x / n,
        }
    }

    /// `−θ`.
    #[inline(always)]
    pub fn neg(self) -> Angle {
        Angle {
            rad: -self.rad,
            s: -self.s,
            c: self.c,
        }
    }
}

/// `R(k, θ)·v` for a unit axis `k`.
#[inline(always)]
pub(crate) fn rot_a(k: V3, a: Angle, v: V3) -> V3 {
    rot_sc(k, a.s, a.c, v)
}

/// `G·x` for the point `x` (rotation then translation).
#[inline(always)]
pub(crate) fn point(g: &Transform, x: V3) -> V3 {
    add(mul_mv(&g.rotation, x), g.translation)
}

/// `M·v`.
#[inline(always)]
pub(crate) fn mul_mv(m: &M3, v: V3) -> V3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// `Mᵀ·v`.
#[inline(always)]
pub(crate) fn mul_mtv(m: &M3, v: V3) -> V3 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

/// A unit vector perpendicular to the unit vector `k`.
pub(crate) fn perpendicular(k: V3) -> V3 {
    let e = if k[0].abs() <= k[1].abs() && k[0].abs() <= k[2].abs() {
        [1.0, 0.0, 0.0]
    } else if k[1].abs() <= k[2].abs() {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let p = reject(e, k);
    scale(1.0 / norm(p), p)
}

/// Angle wrapped into `(−π, π]`, rad.
#[inline(always)]
pub(crate) fn wrap(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let w = a - TAU * (a / TAU).round();
    if w <= -PI { w + TAU } else { w }
}

/// A joint axis at the zero configuration: unit direction `h` and a point `p`
/// on it (world frame, length unit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Axis {
    pub h: V3,
    pub p: V3,
}

impl Axis {
    /// `exp(ξ θ)·x`: the point `x` rotated by the [`Angle`] `a` about this axis.
    #[inline(always)]
    pub fn apply_a(&self, a: Angle, x: V3) -> V3 {
        add(self.p, rot_a(self.h, a, sub(x, self.p)))
    }

    /// Distance from the point `x` to this axis line (length unit).
    pub fn distance_to(&self, x: V3) -> f64 {
        norm(cross(sub(x, self.p), self.h))
    }
}

/// Whether two unit directions are parallel or anti-parallel within `tol`.
pub(crate) fn parallel(a: V3, b: V3, tol: f64) -> bool {
    norm(cross(a, b)) <= tol
}

/// Where two non-parallel axis lines meet (the midpoint of their closest
/// points) if they pass within `tol` (length unit) of each other.
pub(crate) fn intersection(a: &Axis, b: &Axis, tol: f64, dir_tol: f64) -> Option<V3> {
    let n = cross(a.h, b.h);
    let nn = dot(n, n);
    if nn.sqrt() <= dir_tol {
        return None;
    }
    let d = sub(b.p, a.p);
    if dot(d, n).abs() / nn.sqrt() > tol {
        return None;
    }
    let ta = dot(cross(d, b.h), n) / nn;
    let tb = dot(cross(d, a.h), n) / nn;
    let pa = add(a.p, scale(ta, a.h));
    let pb = add(b.p, scale(tb, b.h));
    Some(scale(0.5, add(pa, pb)))
}

/// A chain in product-of-exponentials form: `T(q) = e₁(q₁)⋯eₙ(qₙ)·home`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ZeroAxes {
    /// Each movable joint's axis at `q = 0`, in order.
    pub axes: Vec<Axis>,
    /// Each movable joint's kind, in order.
    pub kinds: Vec<JointKind>,
    /// Tool pose at `q = 0` (world frame).
    pub home: Transform,
    /// A length scale of the chain: the largest distance of a joint point or
    /// the tool from the world origin, at least 1e-3 (length unit).
    pub scale: f64,
}

impl ZeroAxes {
    /// Reads the joint axes of `chain` at its zero configuration. A joint
    /// rotates about (or slides along) the z axis of the frame where its
    /// `Rz(θ)` acts: frame `i−1` in standard DH, frame `i−1` moved by
    /// `Rx(α)·Tx(a)` in modified DH.
    pub fn of(chain: &Chain) -> ZeroAxes {
        let convention = chain.convention();
        let mut frame = *chain.base();
        let mut axes = Vec::with_capacity(chain.dof());
        let mut kinds = Vec::with_capacity(chain.dof());
        for row in chain.dh_rows() {
            if row.kind != JointKind::Fixed {
                let at = match convention {
                    Convention::Standard => frame,
                    Convention::Modified => {
                        frame
                            * Transform::rot_x(row.alpha)
                            * Transform::translation(row.a, 0.0, 0.0)
                    }
                };
                let r = &at.rotation;
                axes.push(Axis {
                    h: [r[0][2], r[1][2], r[2][2]],
                    p: at.translation,
                });
                kinds.push(row.kind);
            }
            frame = frame * link_transform(convention, &row, 0.0);
        }
        let home = match chain.tool() {
            Some(tool) => frame * *tool,
            None => frame,
        };
        let scale = axes
            .iter()
            .map(|a| norm(a.p))
            .fold(norm(home.translation), f64::max)
            .max(1e-3);
        ZeroAxes {
            axes,
            kinds,
            home,
            scale,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_is_half_open() {
        use std::f64::consts::PI;
        assert_eq!(wrap(PI), PI);
        assert!((wrap(-PI) - PI).abs() < 1e-15);
        assert!((wrap(3.0 * PI + 0.5) - (-PI + 0.5)).abs() < 1e-12);
        assert!((wrap(0.25) - 0.25).abs() < 1e-15);
    }

    #[test]
    fn rotation_matches_transform() {
        let v = [0.3, -0.2, 0.9];
        let r = Transform::rot_z(0.7);
        let expect = mul_mv(&r.rotation, v);
        let got = rot([0.0, 0.0, 1.0], 0.7, v);
        for i in 0..3 {
            assert!((got[i] - expect[i]).abs() < 1e-15);
        }
        assert!(dot(perpendicular([0.0, 0.6, 0.8]), [0.0, 0.6, 0.8]).abs() < 1e-15);
    }
}
