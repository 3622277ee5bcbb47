//! Arms with a spherical wrist (Pieper's decomposition in subproblem form):
//! the wrist centre `w` is moved only by joints 1–3, so `e₁e₂e₃·w = G·w`
//! with `G = T·home⁻¹` fixes them (up to 4 ways), then the wrist rotation
//! `R₄R₅R₆ = (R₁R₂R₃)ᵀ·R_G` fixes joints 4–6 (2 ways each): SP2 for 4 and 5
//! on axis 6's direction, SP1 for 6.
//!
//! Positioning, by class: axes 2 ∥ 3 — SP4 for q₁ (the component of the
//! wrist centre along axis 2 does not change with q₂, q₃), SP3 for q₃, SP1
//! for q₂; axes 1, 2 meeting at `c` — SP3 for q₃ (`|w − c|` does not change
//! with q₁, q₂), then SP2 for q₁, q₂; axes 2, 3 meeting at `c` — SP3 for q₁,
//! then SP2 for q₂, q₃. Units: rad, the chain's length unit. Depends on the
//! geometry, subproblem and classification modules.

use super::classify::{ArmClass, Geometry};
use super::geometry::{Angle, V3, add, dot, mul_mv, point, rot_a, sub};
use super::subproblems::{picks, sp1, sp3, sp4, two_axes};
use super::{Branch, Principal, RawSolution, Singular};
use crate::transform::Transform;

/// Joints 1–3 of one solution, with their branch flags.
#[derive(Clone, Copy, Debug)]
struct Arm {
    q: [Angle; 3],
    shoulder: bool,
    elbow: bool,
    free: bool,
}

/// At most four positioning solutions.
struct Arms {
    items: [Arm; 4],
    len: usize,
}

impl Arms {
    fn push(&mut self, arm: Arm) {
        if self.len < self.items.len() {
            self.items[self.len] = arm;
            self.len += 1;
        }
    }
}

/// Every candidate for `g = T·home⁻¹` into `out` (unchecked; the caller runs FK).
pub(super) fn solve(
    class: ArmClass,
    geo: &Geometry,
    g: &Transform,
    reference: &[f64; 6],
    out: &mut Principal,
) {
    let y = point(g, geo.point);
    let blank = Arm {
        q: [Angle::ZERO; 3],
        shoulder: false,
        elbow: false,
        free: false,
    };
    let mut arms = Arms {
        items: [blank; 4],
        len: 0,
    };
    match class {
        ArmClass::SphericalWristParallel23 => parallel23(geo, y, reference, &mut arms),
        ArmClass::SphericalWristIntersecting12 => meeting12(geo, y, reference, &mut arms),
        ArmClass::SphericalWristIntersecting23 => meeting23(geo, y, reference, &mut arms),
        ArmClass::ThreeParallel234 => {}
    }
    let rg6 = mul_mv(&g.rotation, geo.axes[5].h);
    let rgp = mul_mv(&g.rotation, geo.perp6);
    for arm in &arms.items[..arms.len] {
        wrist(geo, arm, rg6, rgp, reference, out);
    }
}

/// Axes 2 ∥ 3: SP4 (q₁), SP3 (q₃), SP1 (q₂).
fn parallel23(geo: &Geometry, y: V3, reference: &[f64; 6], arms: &mut Arms) {
    let [a1, a2, a3, ..] = &geo.axes;
    let w = geo.point;
    let yp = sub(y, a1.p);
    // h₂ᵀ·R(h₁, −q₁)·(y − p₁) = h₂ᵀ·(w − p₁).
    let roots = sp4(a2.h, a1.h, yp, dot(a2.h, sub(w, a1.p)), geo.sing_len);
    let (q1s, n1) = picks(roots, -reference[0]);
    let u3 = sub(w, a3.p);
    let v3 = sub(a2.p, a3.p);
    for t1 in &q1s[..n1] {
        let zd = sub(add(a1.p, rot_a(a1.h, t1.a, yp)), a2.p);
        let (q3s, n3) = picks(sp3(a3.h, u3, v3, dot(zd, zd), geo.sing_len), reference[2]);
        for t3 in &q3s[..n3] {
            let x = sub(add(a3.p, rot_a(a3.h, t3.a, u3)), a2.p);
            arms.push(Arm {
                q: [t1.a.neg(), sp1(a2.h, x, zd), t3.a],
                shoulder: t1.second,
                elbow: t3.second,
                free: t1.free || t3.free,
            });
        }
    }
}

/// Axes 1, 2 meeting at `c`: SP3 (q₃), then SP2 (q₁, q₂).
fn meeting12(geo: &Geometry, y: V3, reference: &[f64; 6], arms: &mut Arms) {
    let [a1, a2, a3, ..] = &geo.axes;
    let c = geo.corner;
    let yc = sub(y, c);
    let u3 = sub(geo.point, a3.p);
    let (q3s, n3) = picks(
        sp3(a3.h, u3, sub(c, a3.p), dot(yc, yc), geo.sing_len),
        reference[2],
    );
    for t3 in &q3s[..n3] {
        let xc = sub(add(a3.p, rot_a(a3.h, t3.a, u3)), c);
        let free = (reference[0], reference[1]);
        let (pairs, n, fam) = two_axes(a1.h, yc, a2.h, xc, free, geo.sing_len);
        for (q1, q2, second) in &pairs[..n] {
            arms.push(Arm {
                q: [*q1, *q2, t3.a],
                shoulder: *second,
                elbow: t3.second,
                free: fam || t3.free,
            });
        }
    }
}

/// Axes 2, 3 meeting at `c`: SP3 (q₁), then SP2 (q₂, q₃).
fn meeting23(geo: &Geometry, y: V3, reference: &[f64; 6], arms: &mut Arms) {
    let [a1, a2, a3, ..] = &geo.axes;
    let c = geo.corner;
    let yp = sub(y, a1.p);
    let wc = sub(geo.point, c);
    // |R(h₁, −q₁)·(y − p₁) − (c − p₁)| = |w − c|.
    let (q1s, n1) = picks(
        sp3(a1.h, yp, sub(c, a1.p), dot(wc, wc), geo.sing_len),
        -reference[0],
    );
    for t1 in &q1s[..n1] {
        let zc = sub(add(a1.p, rot_a(a1.h, t1.a, yp)), c);
        let free = (reference[1], reference[2]);
        let (pairs, n, fam) = two_axes(a2.h, zc, a3.h, wc, free, geo.sing_len);
        for (q2, q3, second) in &pairs[..n] {
            arms.push(Arm {
                q: [t1.a.neg(), *q2, *q3],
                shoulder: t1.second,
                elbow: *second,
                free: fam || t1.free,
            });
        }
    }
}

/// Joints 4–6 for one positioning solution: `R₄R₅·h₆ = v` (SP2, or q₄ free
/// at a wrist singularity) and `R₆·perp₆ = R₅ᵀR₄ᵀ·(R₁R₂R₃)ᵀR_G·perp₆` (SP1).
fn wrist(geo: &Geometry, arm: &Arm, rg6: V3, rgp: V3, reference: &[f64; 6], out: &mut Principal) {
    let [a1, a2, a3, a4, a5, a6] = &geo.axes;
    let [q1, q2, q3] = arm.q;
    let back = |v| {
        rot_a(
            a3.h,
            q3.neg(),
            rot_a(a2.h, q2.neg(), rot_a(a1.h, q1.neg(), v)),
        )
    };
    let v = back(rg6);
    let wv = back(rgp);
    let free = (reference[3], reference[4]);
    let (pairs, n, fam) = two_axes(a4.h, v, a5.h, a6.h, free, geo.sing_dir);
    for (q4, q5, second) in &pairs[..n] {
        let u = rot_a(a5.h, q5.neg(), rot_a(a4.h, q4.neg(), wv));
        let q6 = sp1(a6.h, geo.perp6, u);
        out.push(RawSolution {
            q: [q1.rad, q2.rad, q3.rad, q4.rad, q5.rad, q6.rad],
            branch: Branch {
                shoulder: arm.shoulder,
                elbow: arm.elbow,
                wrist: *second,
            },
            singular: Singular {
                shoulder: arm.free,
                wrist: fam,
            },
            position_error: f64::NAN,
            rotation_error: f64::NAN,
        });
    }
}
