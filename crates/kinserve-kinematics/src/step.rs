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
        ($rot:expr, $a:expr, $d:expr) => {
            aligned::<V, R, { $rot }, $a, $d>(m, c, s, V::splat(step.c[3][0]), dz)
        };
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
            general::<V, R>(m, c, s, &step.c, dz)
        }
    }
}

/// An aligned step: `x' = x·c + y·s`, `y' = y·c − x·s`, then the columns of
/// `Rx(α)` (`ROT`) pick `±y'` / `±z`, and `p += x'·a (if A) + z·dz (if D)`.
#[inline(always)]
fn aligned<V: Lane, const R: usize, const ROT: u8, const A: bool, const D: bool>(
    m: &mut State<V, R>,
    c: V,
    s: V,
    a: V,
    dz: V,
) {
    for row in m.iter_mut() {
        let [x, y, z, p] = *row;
        let xn = x.madd(c, y.mul(s));
        // y' and −y' directly, so no negation is left for the relabelling
        // (the compiler drops whichever this ROT does not use).
        let yn = y.madd(c, x.mul(s).neg());
        let yneg = x.madd(s, y.mul(c).neg());
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
        *row = [xn, c1, c2, pn];
    }
}

/// A general step: `x', y'` as above, then the full product with `C`
/// (column-major `k`; its z translation is in `dz`).
#[inline(always)]
fn general<V: Lane, const R: usize>(m: &mut State<V, R>, c: V, s: V, k: &[[f64; 4]; 4], dz: V) {
    let e = |j: usize, i: usize| V::splat(k[j][i]);
    for row in m.iter_mut() {
        let [x, y, z, p] = *row;
        let xn = x.madd(c, y.mul(s));
        let yn = y.madd(c, x.mul(s).neg());
        let col = |j: usize| xn.madd(e(j, 0), yn.madd(e(j, 1), z.mul(e(j, 2))));
        let pn = xn.madd(e(3, 0), yn.madd(e(3, 1), z.madd(dz, p)));
        *row = [col(0), col(1), col(2), pn];
    }
}
