//! The canonical rotation subproblems (Paden–Kahan 1–4, in the linear-algebra
//! form of Elias & Wen, "IK-Geo", arXiv 2211.05737), each on vectors through
//! the origin with unit axes:
//!
//! - [`sp1`]: `R(k, θ)·p = q` — one angle (least squares if `p`, `q` are not
//!   on one cone about `k`);
//! - [`sp2`]: `R(k₁, θ₁)·p₁ = R(k₂, θ₂)·p₂` — two angles, up to two solutions;
//! - [`sp3`]: `‖R(k, θ)·p − q‖ = d` — up to two angles (reduced to SP4);
//! - [`sp4`]: `hᵀ·R(k, θ)·p = d` — up to two angles.
//!
//! Angles come as [`Angle`] (rad with its sine and cosine, so the callers
//! rotate without calling `sin_cos` again). With no exact solution, SP2–SP4
//! answer the one least-squares root and say so; the callers check every
//! final answer by FK anyway. Depends only on [`super::geometry`].

use super::geometry::{Angle, V3, cross, dot, norm, reject, rot_a, scale};

/// Up to two roots of a one-angle subproblem.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Roots {
    /// Two roots (equal at a tangency).
    Two(Angle, Angle),
    /// No exact root: the least-squares one.
    LeastSquares(Angle),
    /// Every angle solves it, or none does: the equation does not depend on θ.
    Degenerate,
}

/// SP1: `θ` with `R(k, θ)·p = q` (least squares: the angle between the
/// projections of `p` and `q` onto the plane ⟂ `k`).
#[inline(always)]
pub(crate) fn sp1(k: V3, p: V3, q: V3) -> Angle {
    Angle::from_yx(dot(k, cross(p, q)), dot(p, q) - dot(k, p) * dot(k, q))
}

/// SP4: `θ` with `hᵀ·R(k, θ)·p = d`. `Degenerate` when the left side varies
/// by less than `tol` over a turn (`|h ⟂ k|·|p ⟂ k| ≤ tol`).
#[inline(always)]
pub(crate) fn sp4(h: V3, k: V3, p: V3, d: f64, tol: f64) -> Roots {
    // hᵀR(k,θ)p = A cos θ + B sin θ + C.
    let kp = dot(k, p);
    let hk = dot(h, k);
    let a = dot(h, p) - kp * hk;
    let b = dot(h, cross(k, p));
    let rho = (a * a + b * b).sqrt();
    if rho <= tol {
        return Roots::Degenerate;
    }
    let x = d - hk * kp;
    let (sp, cp) = (b / rho, a / rho);
    if x.abs() >= rho {
        // Nearest: θ = φ (x > 0) or φ + π.
        let sign = if x >= 0.0 { 1.0 } else { -1.0 };
        return Roots::LeastSquares(Angle::from_yx(sign * sp, sign * cp));
    }
    let sq = ((rho - x) * (rho + x)).sqrt();
    let (spsi, cpsi) = (sq / rho, x / rho);
    let plus = Angle::from_yx(sp * cpsi + cp * spsi, cp * cpsi - sp * spsi);
    let minus = Angle::from_yx(sp * cpsi - cp * spsi, cp * cpsi + sp * spsi);
    Roots::Two(plus, minus)
}

/// SP3: `θ` with `‖R(k, θ)·p − q‖ = d`, as the SP4
/// `qᵀR(k, θ)p = (‖p‖² + ‖q‖² − d²)/2`. `d2` is `d²`.
#[inline(always)]
pub(crate) fn sp3(k: V3, p: V3, q: V3, d2: f64, tol: f64) -> Roots {
    sp4(q, k, p, 0.5 * (dot(p, p) + dot(q, q) - d2), tol)
}

/// SP2's answer: up to two `(θ₁, θ₂)` pairs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Pairs {
    /// Two solutions (equal at a tangency).
    Two([(Angle, Angle); 2]),
    /// No exact solution: the least-squares one.
    LeastSquares((Angle, Angle)),
}

/// SP2: `(θ₁, θ₂)` with `R(k₁, θ₁)·p₁ = R(k₂, θ₂)·p₂`, for non-parallel unit
/// axes. The common image `x` satisfies `k₁ᵀx = k₁ᵀp₁`, `k₂ᵀx = k₂ᵀp₂` and
/// `‖x‖ = ‖p₁‖ (= ‖p₂‖)`: a line met by a sphere. The caller handles `p₁ ∥ k₁`
/// or `p₂ ∥ k₂` (an angle free) before calling.
#[inline(always)]
pub(crate) fn sp2(k1: V3, p1: V3, k2: V3, p2: V3) -> Pairs {
    let c = dot(k1, k2);
    let a1 = dot(k1, p1);
    let a2 = dot(k2, p2);
    let s2 = 1.0 - c * c;
    let alpha = (a1 - c * a2) / s2;
    let beta = (a2 - c * a1) / s2;
    let n = cross(k1, k2);
    let r2 = 0.5 * (dot(p1, p1) + dot(p2, p2));
    let g2 = (r2 - alpha * alpha - beta * beta - 2.0 * alpha * beta * c) / s2;
    let base = [
        alpha * k1[0] + beta * k2[0],
        alpha * k1[1] + beta * k2[1],
        alpha * k1[2] + beta * k2[2],
    ];
    let solve = |x: V3| (sp1(k1, p1, x), sp1(k2, p2, x));
    if g2 < 0.0 {
        return Pairs::LeastSquares(solve(base));
    }
    let g = g2.sqrt();
    let off = scale(g, n);
    let plus = [base[0] + off[0], base[1] + off[1], base[2] + off[2]];
    let minus = [base[0] - off[0], base[1] - off[1], base[2] - off[2]];
    Pairs::Two([solve(plus), solve(minus)])
}

/// Whether `v` is (nearly) along the unit vector `k`: `|v ⟂ k| ≤ tol`.
#[inline(always)]
pub(crate) fn along(v: V3, k: V3, tol: f64) -> bool {
    norm(reject(v, k)) <= tol
}

/// One root as the solvers use it: the angle, whether it is the second root
/// of its subproblem (the branch flag), and whether the angle was free (a
/// one-parameter family, answered with the reference value).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Pick {
    pub a: Angle,
    pub second: bool,
    pub free: bool,
}

/// The roots of a one-angle subproblem as [`Pick`]s (up to two, count in
/// `.1`); a degenerate one gives the angle `free` (rad), marked free.
#[inline(always)]
pub(crate) fn picks(r: Roots, free: f64) -> ([Pick; 2], usize) {
    let pick = |a, second| Pick {
        a,
        second,
        free: false,
    };
    match r {
        Roots::Two(a, b) => ([pick(a, false), pick(b, true)], 2),
        Roots::LeastSquares(a) => ([pick(a, false); 2], 1),
        Roots::Degenerate => {
            let p = Pick {
                a: Angle::new(free),
                second: false,
                free: true,
            };
            ([p; 2], 1)
        }
    }
}

/// Two successive rotations: `(θ₁, θ₂)` with `R(k₁, θ₁)·R(k₂, θ₂)·p = t`
/// (up to two, count in `.1`; the flag says the second SP2 solution). If `t ∥ k₁`
/// (within `tol`) `θ₁` is free and set to `free1`; if `p ∥ k₂`, `θ₂` is
/// free and set to `free2`; `.2` says a family was met.
#[inline(always)]
pub(crate) fn two_axes(
    k1: V3,
    t: V3,
    k2: V3,
    p: V3,
    free: (f64, f64),
    tol: f64,
) -> ([(Angle, Angle, bool); 2], usize, bool) {
    if along(t, k1, tol) {
        let t1 = Angle::new(free.0);
        let t2 = sp1(k2, p, rot_a(k1, t1.neg(), t));
        return ([(t1, t2, false); 2], 1, true);
    }
    if along(p, k2, tol) {
        let t2 = Angle::new(free.1);
        let t1 = sp1(k1, rot_a(k2, t2, p), t);
        return ([(t1, t2, false); 2], 1, true);
    }
    // R(k₁, −θ₁)·t = R(k₂, θ₂)·p.
    match sp2(k1, t, k2, p) {
        Pairs::Two([(a1, a2), (b1, b2)]) => {
            ([(a1.neg(), a2, false), (b1.neg(), b2, true)], 2, false)
        }
        Pairs::LeastSquares((a1, a2)) => ([(a1.neg(), a2, false); 2], 1, false),
    }
}

#[cfg(test)]
mod tests {
    use super::super::geometry::{rot, sub};
    use super::*;

    const K: V3 = [0.0, 0.6, 0.8];
    const K2: V3 = [1.0, 0.0, 0.0];

    fn close(a: V3, b: V3) -> bool {
        norm(sub(a, b)) < 1e-12
    }

    #[test]
    fn sp1_inverts_a_rotation() {
        let p = [0.3, -0.4, 1.1];
        let a = sp1(K, p, rot(K, 2.5, p));
        assert!((a.rad - 2.5).abs() < 1e-12);
        assert!((a.s - 2.5f64.sin()).abs() < 1e-12);
    }

    #[test]
    fn sp4_roots_satisfy_the_plane_equation() {
        let (h, p) = ([0.2, 0.9, -0.1], [0.5, 0.1, 0.3]);
        let d = dot(h, rot(K, -1.2, p));
        let Roots::Two(a, b) = sp4(h, K, p, d, 1e-12) else {
            panic!("two roots expected");
        };
        for r in [a, b] {
            assert!((dot(h, rot(K, r.rad, p)) - d).abs() < 1e-12);
        }
        assert!((a.rad + 1.2).abs() < 1e-12 || (b.rad + 1.2).abs() < 1e-12);
        assert!(matches!(sp4(h, K, p, 10.0, 1e-12), Roots::LeastSquares(_)));
        assert_eq!(sp4(K, K, p, 0.0, 1e-12), Roots::Degenerate);
    }

    #[test]
    fn sp3_roots_are_at_the_distance() {
        let (p, q) = ([0.5, 0.1, 0.3], [0.1, 0.2, 0.4]);
        let d = norm(sub(rot(K, 0.7, p), q));
        let Roots::Two(a, b) = sp3(K, p, q, d * d, 1e-12) else {
            panic!("two roots expected");
        };
        for r in [a, b] {
            assert!((norm(sub(rot(K, r.rad, p), q)) - d).abs() < 1e-12);
        }
    }

    #[test]
    fn sp2_solutions_meet() {
        let p2 = [0.3, 0.5, -0.2];
        let x = rot(K2, 0.9, p2);
        let p1 = rot(K, -0.4, x);
        let Pairs::Two(sols) = sp2(K, p1, K2, p2) else {
            panic!("two solutions expected");
        };
        for (t1, t2) in sols {
            assert!(close(rot(K, t1.rad, p1), rot(K2, t2.rad, p2)));
        }
        assert!(
            sols.iter()
                .any(|(t1, t2)| (t1.rad - 0.4).abs() < 1e-12 && (t2.rad - 0.9).abs() < 1e-12)
        );
    }
}
