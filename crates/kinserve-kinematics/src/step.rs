//! The one step every evaluator is built from: `M ← M · Rz(θ) · Tz(q) · C` for a
//! compiled [`Step`], on a state held as `R` rows of four columns (x, y, z, p),
//! each entry a lane vector `V` ([`crate::lane`]):
//!
//! - single pose and frames: `R = 1`, `V` holds the 3 matrix rows of one column
//!   (4 lanes, one unused) and the joint's `cos θ, sin θ, d` are broadcast;
//! - batch: `R = 3` matrix rows, `V` holds 8 poses, each with its own
//!   `cos θ, sin θ, d`.
//!
//! [`apply`] dispatches once on the precompiled [`Step::kind`] to a
//! monomorphised body that does only the table's arithmetic: an aligned step
//! (`C` = `Rx(0|±90°|180°)` with translation `(a, 0, d)`) rotates two columns,
//! relabels the columns for free, and adds `x·a` and `z·d` only where `a`, `d`
//! are not zero; a general step does the full product. No other branch.
//!
//! Depends on [`crate::program`] (the step data) and [`crate::lane`].

use crate::lane::Lane;
use crate::program::{GENERAL, ROT_0, ROT_180, ROT_M90, ROT_P90, Step};

/// `R` rows of the four columns x, y, z, p.
pub(crate) type State<V, const R: usize> = [[V; 4]; R];

/// Multiplies the state by the joint part `Rz(θ)·Tz(q)` (given as `cos θ`,
/// `sin θ` and the z translation `dz = d + q`) and the constant `C` of `step`.
#[inline(always)]
pub(crate) fn apply<V: Lane, const R: usize>(step: &Step, m: &mut State<V, R>, c: V, s: V, dz: V) {
    macro_rules! aligned {
        ($rot:expr, $a:expr, $d:expr) => {{
            let a = V::splat(step.c[3][0]);
            for row in m.iter_mut() {
                *row = aligned::<V, { $rot }, $a, $d>(*row, c, s, a, dz);
            }
        }};
    }
    match step.kind {
        0 => aligned!(ROT_0, false, false),
        1 => aligned!(ROT_0, false, true),
        2 => aligned!(ROT_0, true, false),
        3 => aligned!(ROT_0, true, true),
        4 => aligned!(ROT_P90, false, false),
        5 => aligned!(ROT_P90, false, true),
        6 => aligned!(ROT_P90, true, false),
        7 => aligned!(ROT_P90, true, true),
        8 => aligned!(ROT_M90, false, false),
        9 => aligned!(ROT_M90, false, true),
        10 => aligned!(ROT_M90, true, false),
        11 => aligned!(ROT_M90, true, true),
        12 => aligned!(ROT_180, false, false),
        13 => aligned!(ROT_180, false, true),
        14 => aligned!(ROT_180, true, false),
        15 => aligned!(ROT_180, true, true),
        _ => {
            debug_assert_eq!(step.kind, GENERAL);
            for row in m.iter_mut() {
                *row = general::<V>(*row, c, s, &step.c, dz);
            }
        }
    }
}

/// An aligned step on one row: `x' = x·c + y·s`, `y' = y·c − x·s`, then the
/// columns of `Rx(α)` (`ROT`) pick `±y'` / `±z`, and `p += x'·a (if A) + z·dz (if D)`.
#[inline(always)]
fn aligned<V: Lane, const ROT: u8, const A: bool, const D: bool>(
    [x, y, z, p]: [V; 4],
    c: V,
    s: V,
    a: V,
    dz: V,
) -> [V; 4] {
    let xn = x.madd(c, y.mul(s));
    // y' and −y' directly, so no negation is left for the relabelling
    // (the compiler drops whichever this ROT does not use).
    let yn = x.nmadd(s, y.mul(c));
    let yneg = y.nmadd(c, x.mul(s));
    let mut pn = p;
    if D {
        pn = z.madd(dz, pn);
    }
    if A {
        pn = xn.madd(a, pn);
    }
    let (c1, c2) = match ROT {
        ROT_0 => (yn, z),
        ROT_P90 => (z, yneg),
        ROT_M90 => (z.neg(), yn),
        _ => (yneg, z.neg()),
    };
    [xn, c1, c2, pn]
}

/// A general step: `x', y'` as above, then the full product with `C`
/// (column-major `k`; its z translation is in `dz`).
#[inline(always)]
fn general<V: Lane>([x, y, z, p]: [V; 4], c: V, s: V, k: &[[f64; 4]; 4], dz: V) -> [V; 4] {
    // No closures here or anywhere on these paths: a closure does not inherit
    // the caller's target features, so it would not inline into the kernels.
    let xn = x.madd(c, y.mul(s));
    let yn = x.nmadd(s, y.mul(c));
    let mut out = [z; 4];
    for j in 0..3 {
        let [k0, k1, k2, _] = k[j];
        out[j] = xn.madd(V::splat(k0), yn.madd(V::splat(k1), z.mul(V::splat(k2))));
    }
    let [t0, t1, _, _] = k[3];
    out[3] = xn.madd(V::splat(t0), yn.madd(V::splat(t1), z.madd(dz, p)));
    out
}
