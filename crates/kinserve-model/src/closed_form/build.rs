//! From a DH table to symbolic link matrices `A_i` and their product `⁰Tₙ`:
//! each DH parameter becomes an atom (or a folded 0/±1 for angles that are
//! multiples of 90°, or nothing for a zero length), the matrices are multiplied
//! out and simplified after every factor, within a work [`Budget`].
//!
//! Constant (fixed) rows are folded before they meet the product: an identity
//! row is skipped, and a run of adjacent fixed rows is multiplied out on its
//! own (small: constants only) and enters the product once, so neither
//! repeats the costly step of multiplying the whole product again. Matrix
//! products are associative, so the result is the same polynomial.
//!
//! Owns the link-matrix formulas of both conventions in symbolic form (the
//! numeric ones live in `kinserve-kinematics`, which the tests compare with).
//! Units: angles in rad, lengths in the table's unit. Must not depend on
//! output formats (`render`).

use std::collections::BTreeMap;
use std::f64::consts::FRAC_PI_2;

use kinserve_kinematics::{Convention, DhRow, JointKind};

use super::budget::{Budget, Exceeded, MAX_TERMS};
use super::poly::{Angle, Atom, Groups, Length, Poly, Trig};

/// A symbolic homogeneous 4×4 matrix, row-major.
pub(crate) type Matrix = [[Poly; 4]; 4];

/// Angles within this many radians of a multiple of 90° are folded to 0/±1.
const FOLD_TOLERANCE: f64 = 1e-12;

/// The symbolic form of a table.
pub(crate) struct Built {
    /// `A_1 … A_n`.
    pub(crate) links: Vec<Matrix>,
    /// Whether `A_i` is constant (a fixed row), by index.
    pub(crate) constant: Vec<bool>,
    /// Runs of parallel revolute axes.
    pub(crate) groups: Groups,
    /// Value of every constant atom that occurs (lengths in the table's unit,
    /// cos/sin of constant angles unitless).
    pub(crate) values: BTreeMap<Atom, f64>,
}

/// Builds the link matrices of `rows` (1-based row numbers in the atoms).
pub(crate) fn build(convention: Convention, rows: &[DhRow]) -> Result<Built, Exceeded> {
    let mut values = BTreeMap::new();
    let links = rows
        .iter()
        .zip(1u16..)
        .map(|(row, i)| link_matrix(convention, i, row, &mut values))
        .collect::<Result<_, _>>()?;
    Ok(Built {
        links,
        constant: rows.iter().map(|r| r.kind == JointKind::Fixed).collect(),
        groups: parallel_groups(convention, rows),
        values,
    })
}

/// `A_1 ⋯ A_n`, simplified after each factor, with identity rows skipped and
/// each run of adjacent fixed rows multiplied out on its own first. Fails once
/// the work would pass `budget` or the product [`MAX_TERMS`].
pub(crate) fn product(built: &Built, budget: &mut Budget) -> Result<Matrix, Exceeded> {
    let mut t = identity();
    // The product of the current run of fixed rows, not yet in `t`.
    let mut run: Option<Matrix> = None;
    for (a, &constant) in built.links.iter().zip(&built.constant) {
        if constant {
            if !is_identity(a) {
                run = Some(match run {
                    None => a.clone(),
                    Some(c) => fold(c, a, &built.groups, budget)?,
                });
            }
            continue;
        }
        if let Some(c) = run.take() {
            t = fold(t, &c, &built.groups, budget)?;
        }
        t = fold(t, a, &built.groups, budget)?;
    }
    match run {
        Some(c) => fold(t, &c, &built.groups, budget),
        None => Ok(t),
    }
}

/// `t · a`, skipping the multiplication when either is the identity.
fn fold(t: Matrix, a: &Matrix, groups: &Groups, budget: &mut Budget) -> Result<Matrix, Exceeded> {
    if is_identity(a) {
        Ok(t)
    } else if is_identity(&t) {
        Ok(a.clone())
    } else {
        step(&t, a, groups, budget)
    }
}

/// `t · a`, simplified; fails past the budget or [`MAX_TERMS`].
fn step(t: &Matrix, a: &Matrix, groups: &Groups, budget: &mut Budget) -> Result<Matrix, Exceeded> {
    let mut p = mat_mul(t, a, budget)?;
    let mut terms = 0;
    for entry in p.iter_mut().flatten() {
        entry.simplify(groups, budget)?;
        terms += entry.len();
    }
    if terms > MAX_TERMS {
        return Err(Exceeded::Terms { terms });
    }
    Ok(p)
}

/// The number of quarter turns (0–3) of `x` if it is a multiple of 90°.
pub(crate) fn quarter_turns(x: f64) -> Option<u8> {
    let k = (x / FRAC_PI_2).round();
    ((x - k * FRAC_PI_2).abs() <= FOLD_TOLERANCE).then(|| (k.rem_euclid(4.0)) as u8)
}

fn identity() -> Matrix {
    std::array::from_fn(|i| std::array::from_fn(|j| Poly::constant(i64::from(i == j))))
}

fn is_identity(m: &Matrix) -> bool {
    *m == identity()
}

/// `a · b`, charging the term products to `budget` before any is made.
fn mat_mul(a: &Matrix, b: &Matrix, budget: &mut Budget) -> Result<Matrix, Exceeded> {
    let cost = (0..4)
        .flat_map(|i| (0..4).flat_map(move |j| (0..4).map(move |k| (i, j, k))))
        .map(|(i, j, k)| a[i][k].mul_cost(&b[k][j]))
        .fold(0, u64::saturating_add);
    budget.charge(cost)?;
    let mut out: Matrix = Default::default();
    for (i, row) in out.iter_mut().enumerate() {
        for (j, entry) in row.iter_mut().enumerate() {
            for k in 0..4 {
                if !a[i][k].is_zero() && !b[k][j].is_zero() {
                    entry.add_assign(&a[i][k].mul(&b[k][j])?)?;
                }
            }
        }
    }
    Ok(out)
}

/// (cos, sin) of a constant angle: folded when a multiple of 90°, else atoms.
fn const_trig(x: f64, angle: Angle, index: u16, values: &mut BTreeMap<Atom, f64>) -> (Poly, Poly) {
    match quarter_turns(x) {
        Some(0) => (Poly::constant(1), Poly::default()),
        Some(1) => (Poly::default(), Poly::constant(1)),
        Some(2) => (Poly::constant(-1), Poly::default()),
        Some(_) => (Poly::default(), Poly::constant(-1)),
        None => {
            let c = Atom::Const(Trig::Cos, angle, index);
            let s = Atom::Const(Trig::Sin, angle, index);
            values.insert(c.clone(), x.cos());
            values.insert(s.clone(), x.sin());
            (Poly::atom(c), Poly::atom(s))
        }
    }
}

/// A constant length: nothing when zero, else an atom.
fn length(x: f64, which: Length, index: u16, values: &mut BTreeMap<Atom, f64>) -> Poly {
    if x == 0.0 {
        return Poly::default();
    }
    let a = Atom::Length(which, index);
    values.insert(a.clone(), x);
    Poly::atom(a)
}

/// `A_i` of row `i` (1-based) in symbolic form.
fn link_matrix(
    convention: Convention,
    i: u16,
    row: &DhRow,
    values: &mut BTreeMap<Atom, f64>,
) -> Result<Matrix, Exceeded> {
    // Row i holds a_{i-1}, α_{i-1} in the modified convention.
    let prev = match convention {
        Convention::Standard => i,
        Convention::Modified => i - 1,
    };
    let (ct, st) = match row.kind {
        JointKind::Revolute => (
            Poly::atom(Atom::Joint(vec![i], Trig::Cos)),
            Poly::atom(Atom::Joint(vec![i], Trig::Sin)),
        ),
        _ => const_trig(row.theta, Angle::Theta, i, values),
    };
    let (ca, sa) = const_trig(row.alpha, Angle::Alpha, prev, values);
    let a = length(row.a, Length::A, prev, values);
    let d = match row.kind {
        JointKind::Prismatic => Poly::atom(Atom::Slide(i)),
        _ => length(row.d, Length::D, i, values),
    };
    let (zero, one) = (Poly::default(), Poly::constant(1));
    Ok(match convention {
        Convention::Standard => [
            [ct.clone(), st.mul(&ca)?.neg()?, st.mul(&sa)?, a.mul(&ct)?],
            [st.clone(), ct.mul(&ca)?, ct.mul(&sa)?.neg()?, a.mul(&st)?],
            [zero.clone(), sa, ca, d],
            [zero.clone(), zero.clone(), zero, one],
        ],
        Convention::Modified => [
            [ct.clone(), st.neg()?, zero.clone(), a],
            [st.mul(&ca)?, ct.mul(&ca)?, sa.neg()?, sa.mul(&d)?.neg()?],
            [st.mul(&sa)?, ct.mul(&sa)?, ca.clone(), ca.mul(&d)?],
            [zero.clone(), zero.clone(), zero, one],
        ],
    })
}

/// Rows `j` and `j + 1` share a group when both are revolute and the twist
/// between their axes (α_j: row `j` standard, row `j + 1` modified) is 0.
fn parallel_groups(convention: Convention, rows: &[DhRow]) -> Groups {
    let mut of_row = vec![None; rows.len() + 1];
    let mut next = 0;
    for (j, row) in rows.iter().enumerate() {
        if row.kind != JointKind::Revolute {
            continue;
        }
        let joins_previous = j > 0
            && rows[j - 1].kind == JointKind::Revolute
            && quarter_turns(match convention {
                Convention::Standard => rows[j - 1].alpha,
                Convention::Modified => row.alpha,
            }) == Some(0);
        if !joins_previous {
            next += 1;
        }
        of_row[j + 1] = Some(next);
    }
    Groups::new(of_row)
}
