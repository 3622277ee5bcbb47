//! Arms with three parallel axes 2, 3, 4 (direction `h`) and axes 5, 6
//! meeting at `p₅₆`: the Universal Robots family, Hawkins' closed form in
//! subproblem form, for any DH offsets. With `G = T·home⁻¹`:
//!
//! - q₁ (SP4): rotations about axes ∥ `h` keep a point's component along
//!   `h`, and e₅, e₆ fix `p₅₆`, so `hᵀ·e₁⁻¹(G·p₅₆) = hᵀ·p₅₆`;
//! - q₅ (SP4): `hᵀ·R₁ᵀR_G·h₆ = hᵀ·R₅·h₆` (R₂R₃R₄ is a rotation about `h`);
//! - q₆ (SP1): `R₆·(R_GᵀR₁·h) = R₅ᵀ·h` — free when axis 6 is ∥ `h` (wrist
//!   singularity), then answered with the reference value;
//! - q₂ + q₃ + q₄ (SP1): `R(h, θ₂₃₄) = R₁ᵀR_G R₆ᵀR₅ᵀ`;
//! - q₃ (SP3) and q₂ (SP1): the planar two-link problem `e₂e₃·p₄ = H·p₄`
//!   with `H = e₁⁻¹ G e₆⁻¹ e₅⁻¹`; q₄ from θ₂₃₄.
//!
//! Units: rad, the chain's length unit. Depends on the geometry, subproblem
//! and classification modules.

use super::classify::Geometry;
use super::geometry::{Angle, add, dot, mul_mtv, mul_mv, point, rot_a, sub, wrap};
use super::subproblems::{Pick, along, picks, sp1, sp3, sp4};
use super::{Branch, Principal, RawSolution, Singular};
use crate::transform::Transform;

/// Every candidate for `g = T·home⁻¹` into `out` (unchecked; the caller runs FK).
pub(super) fn solve(geo: &Geometry, g: &Transform, reference: &[f64; 6], out: &mut Principal) {
    let [a1, a2, _, _, a5, a6] = &geo.axes;
    let h = a2.h;
    let yp = sub(point(g, geo.point), a1.p);
    let rg6 = mul_mv(&g.rotation, a6.h);
    // hᵀ·R(h₁, −q₁)·(y − p₁) = hᵀ·(p₅₆ − p₁).
    let roots = sp4(h, a1.h, yp, dot(h, sub(geo.point, a1.p)), geo.sing_len);
    let (q1s, n1) = picks(roots, -reference[0]);
    for t1 in &q1s[..n1] {
        let m = rot_a(a1.h, t1.a, rg6);
        let (q5s, n5) = picks(sp4(h, a5.h, a6.h, dot(h, m), geo.sing_dir), reference[4]);
        for t5 in &q5s[..n5] {
            lower(geo, g, t1, t5, reference, out);
        }
    }
}

/// Joints 6, then 2, 3, 4 for one choice of q₁ (`t1` holds −q₁) and q₅.
fn lower(
    geo: &Geometry,
    g: &Transform,
    t1: &Pick,
    t5: &Pick,
    reference: &[f64; 6],
    out: &mut Principal,
) {
    let [a1, a2, a3, a4, a5, a6] = &geo.axes;
    let h = a2.h;
    let (m1, q1) = (t1.a, t1.a.neg());
    let q5 = t5.a;
    let pv = mul_mtv(&g.rotation, rot_a(a1.h, q1, h));
    let wrist_free = along(pv, a6.h, geo.sing_dir);
    let q6 = if wrist_free {
        Angle::new(reference[5])
    } else {
        sp1(a6.h, pv, rot_a(a5.h, q5.neg(), h))
    };
    let back65 = |v| rot_a(a6.h, q6.neg(), rot_a(a5.h, q5.neg(), v));
    let mw = rot_a(a1.h, m1, mul_mv(&g.rotation, back65(geo.perp2)));
    let t234 = sp1(h, geo.perp2, mw).rad;
    // H·p₄ = e₁⁻¹·G·e₆⁻¹·e₅⁻¹·p₄.
    let q4p = a6.apply_a(q6.neg(), a5.apply_a(q5.neg(), a4.p));
    let hd = sub(a1.apply_a(m1, point(g, q4p)), a2.p);
    let u3 = sub(a4.p, a3.p);
    let (q3s, n3) = picks(
        sp3(a3.h, u3, sub(a2.p, a3.p), dot(hd, hd), geo.sing_len),
        reference[2],
    );
    let [s3, s4] = geo.signs;
    for t3 in &q3s[..n3] {
        let x = sub(add(a3.p, rot_a(a3.h, t3.a, u3)), a2.p);
        let q2 = sp1(h, x, hd).rad;
        let q4 = wrap(s4 * (t234 - q2 - s3 * t3.a.rad));
        out.push(RawSolution {
            q: [q1.rad, q2, t3.a.rad, q4, q5.rad, q6.rad],
            branch: Branch {
                shoulder: t1.second,
                elbow: t3.second,
                wrist: t5.second,
            },
            singular: Singular {
                shoulder: t1.free || t3.free,
                wrist: wrist_free,
            },
            position_error: f64::NAN,
            rotation_error: f64::NAN,
        });
    }
}
