//! The one step every evaluator is built from: `M ← M · Rz(θ) · Tz(q) · C` for a
//! compiled [`Step`], on a state held as `R` rows of four columns (x, y, z, p)
//! of `L` lanes each:
//!
//! - single pose and frames: `R = 1`, `L = 4`, the lanes are the matrix rows
//!   (one column fills a 4-wide vector) and the joint's `cos θ, sin θ, d` are
//!   broadcast;
//! - batch: `R = 3` matrix rows, `L = 8` poses per lane vector, each pose with
//!   its own `cos θ, sin θ, d`.
//!
//! [`apply`] dispatches once on the precompiled [`Step::kind`] to a
//! monomorphised body that does only the table's arithmetic: an aligned step
//! (`C` = `Rx(0|±90°|180°)` with translation `(a, 0, d)`) rotates two columns,
//! relabels the columns for free, and adds `x·a` and `z·d` only where `a`, `d`
//! are not zero; a general step does the full product. No other branch.
//!
//! Depends on [`crate::program`] (the step data) and [`crate::sincos::madd`].
#![allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays in step; they vectorise as written"
)]

use crate::program::{GENERAL, ROT_0, ROT_180, ROT_M90, ROT_P90, Step};
use crate::sincos::madd;

/// `R` rows of the four columns x, y, z, p, `L` lanes each.
pub(crate) type State<const L: usize, const R: usize> = [[[f64; L]; 4]; R];

/// Multiplies the state by the joint part `Rz(θ)·Tz(q)` (given as `cos θ`,
/// `sin θ` and the z translation `dz = d + q`) and the constant `C` of `step`.
#[inline(always)]
pub(crate) fn apply<const FMA: bool, const L: usize, const R: usize>(
    step: &Step,
    m: &mut State<L, R>,
    c: &[f64; L],
    s: &[f64; L],
    dz: &[f64; L],
) {
    macro_rules! aligned {
        ($rot:expr, $a:expr, $d:expr) => {
            aligned::<FMA, L, R, { $rot }, $a, $d>(m, c, s, step.c[3][0], dz)
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
            general::<FMA, L, R>(m, c, s, &step.c, dz)
        }
    }
}

/// An aligned step: `x' = x·c + y·s`, `y' = y·c − x·s`, then the columns of
/// `Rx(α)` (`ROT`) pick `±y'` / `±z`, and `p += x'·a (if A) + z·dz (if D)`.
#[inline(always)]
fn aligned<const FMA: bool, const L: usize, const R: usize, const ROT: u8, const A: bool, const D: bool>(
    m: &mut State<L, R>,
    c: &[f64; L],
    s: &[f64; L],
    a: f64,
    dz: &[f64; L],
) {
    for row in m.iter_mut() {
        let [x, y, z, p] = *row;
        let mut out = [[0.0; L]; 4];
        for k in 0..L {
            let xn = madd::<FMA>(x[k], c[k], y[k] * s[k]);
            // y' and −y' directly, so no negation is left for the relabelling.
            let yn = madd::<FMA>(y[k], c[k], -(x[k] * s[k]));
            let yneg = madd::<FMA>(x[k], s[k], -(y[k] * c[k]));
            let mut pn = p[k];
            if D {
                pn = madd::<FMA>(z[k], dz[k], pn);
            }
            if A {
                pn = madd::<FMA>(xn, a, pn);
            }
            let (c1, c2) = match ROT {
                ROT_0 => (yn, z[k]),
                ROT_P90 => (z[k], yneg),
                ROT_M90 => (-z[k], yn),
                _ => (yneg, -z[k]),
            };
            out[0][k] = xn;
            out[1][k] = c1;
            out[2][k] = c2;
            out[3][k] = pn;
        }
        *row = out;
    }
}

/// A general step: `x', y'` as above, then the full product with `C`.
#[inline(always)]
fn general<const FMA: bool, const L: usize, const R: usize>(
    m: &mut State<L, R>,
    c: &[f64; L],
    s: &[f64; L],
    k: &[[f64; 4]; 4],
    dz: &[f64; L],
) {
    for row in m.iter_mut() {
        let [x, y, z, p] = *row;
        let mut out = [[0.0; L]; 4];
        for l in 0..L {
            let xn = madd::<FMA>(x[l], c[l], y[l] * s[l]);
            let yn = madd::<FMA>(y[l], c[l], -(x[l] * s[l]));
            for j in 0..3 {
                out[j][l] = madd::<FMA>(xn, k[j][0], madd::<FMA>(yn, k[j][1], z[l] * k[j][2]));
            }
            out[3][l] = madd::<FMA>(xn, k[3][0], madd::<FMA>(yn, k[3][1], madd::<FMA>(z[l], dz[l], p[l])));
        }
        *row = out;
    }
}
