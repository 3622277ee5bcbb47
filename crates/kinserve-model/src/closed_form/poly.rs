//! The term representation of the closed forms: polynomials with integer
//! coefficients over atoms (`cI`/`sI` of joint-angle sums, constant lengths
//! `aI`/`dI`, prismatic variables `dI`, cos/sin of constant angles), and the
//! simplifications the course notes apply by hand: like terms combined, zero
//! terms dropped, `cA·cB − sA·sB = c(A∪B)`, `sA·cB + cA·sB = s(A∪B)` over runs of
//! parallel revolute axes, and `c² + s² = 1`.
//!
//! Owns no knowledge of DH tables or of output formats (see `build` and
//! `render`). Depends on the standard library only.

use std::collections::btree_map::Entry;
use std::collections::{BTreeMap, HashMap, HashSet};

/// Cosine or sine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Trig {
    Cos,
    Sin,
}

/// A constant DH parameter that is a length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Length {
    A,
    D,
}

/// A constant DH parameter that is an angle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Angle {
    Alpha,
    Theta,
}

/// One factor of a product. The derived order is the order factors are
/// printed in: constants, prismatic variables, cos/sin of constant angles,
/// then `cI`/`sI` by their row sets.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Atom {
    /// A constant length `a_i` or `d_i` (index as printed: `a_{i-1}` in the modified convention).
    Length(Length, u16),
    /// The variable `d_i` of prismatic row `i` (joint value plus offset).
    Slide(u16),
    /// cos or sin of a constant angle that is not a multiple of 90°.
    Const(Trig, Angle, u16),
    /// cos or sin of the sum of the joint angles θ_j over the sorted 1-based rows `j`.
    Joint(Vec<u16>, Trig),
}

/// A product of atoms, sorted (a repeated atom is a power).
pub(crate) type Monomial = Vec<Atom>;

/// A sum of integer multiples of monomials; no zero coefficients are stored.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Poly {
    terms: BTreeMap<Monomial, i64>,
}

impl Poly {
    /// The constant `k`.
    pub(crate) fn constant(k: i64) -> Poly {
        let mut p = Poly::default();
        p.add_term(Vec::new(), k);
        p
    }

    /// One atom.
    pub(crate) fn atom(a: Atom) -> Poly {
        let mut p = Poly::default();
        p.add_term(vec![a], 1);
        p
    }

    /// Whether this is 0.
    pub(crate) fn is_zero(&self) -> bool {
        self.terms.is_empty()
    }

    /// Number of terms.
    pub(crate) fn len(&self) -> usize {
        self.terms.len()
    }

    /// The terms in print order.
    pub(crate) fn terms(&self) -> impl Iterator<Item = (&Monomial, i64)> {
        self.terms.iter().map(|(m, k)| (m, *k))
    }

    /// Adds `k · m`, dropping the term if it cancels.
    pub(crate) fn add_term(&mut self, m: Monomial, k: i64) {
        if k == 0 {
            return;
        }
        match self.terms.entry(m) {
            Entry::Occupied(mut e) => {
                *e.get_mut() += k;
                if *e.get() == 0 {
                    e.remove();
                }
            }
            Entry::Vacant(e) => {
                e.insert(k);
            }
        }
    }

    /// `self + other`.
    pub(crate) fn add(&self, other: &Poly) -> Poly {
        let mut out = self.clone();
        for (m, k) in other.terms() {
            out.add_term(m.clone(), k);
        }
        out
    }

    /// `−self`.
    pub(crate) fn neg(&self) -> Poly {
        Poly {
            terms: self.terms.iter().map(|(m, k)| (m.clone(), -k)).collect(),
        }
    }

    /// `self · other`, expanded.
    pub(crate) fn mul(&self, other: &Poly) -> Poly {
        let mut out = Poly::default();
        for (m1, k1) in self.terms() {
            for (m2, k2) in other.terms() {
                out.add_term(merge(m1, m2), k1 * k2);
            }
        }
        out
    }

    /// Applies the trigonometric rewrites until none applies (see [`Rewrite`]).
    /// Each rewrite lowers the sum of |coefficients|, so this terminates.
    pub(crate) fn simplify(&mut self, groups: &Groups) {
        loop {
            let rewrites = self.find_rewrites(groups);
            if rewrites.is_empty() {
                return;
            }
            for r in rewrites {
                self.add_term(r.first, -r.amount);
                self.add_term(r.partner, -r.amount * r.partner_sign);
                self.add_term(r.result, r.amount);
            }
        }
    }

    /// Non-overlapping rewrites for one pass: each term takes part in at most one.
    fn find_rewrites(&self, groups: &Groups) -> Vec<Rewrite> {
        let index: HashMap<&Monomial, i64> = self.terms.iter().map(|(m, k)| (m, *k)).collect();
        let mut used: HashSet<Monomial> = HashSet::new();
        let mut out = Vec::new();
        for (m1, &k1) in &self.terms {
            if used.contains(m1) {
                continue;
            }
            for cand in candidates(m1, groups) {
                let Some(&k2) = index.get(&cand.partner) else {
                    continue;
                };
                if used.contains(&cand.partner)
                    || cand.partner == *m1
                    || k2.signum() != k1.signum() * cand.partner_sign
                {
                    continue;
                }
                let amount = k1.signum() * k1.abs().min(k2.abs());
                used.insert(m1.clone());
                used.insert(cand.partner.clone());
                out.push(Rewrite {
                    first: m1.clone(),
                    amount,
                    ..cand
                });
                break;
            }
        }
        out
    }
}

/// `k·first + (partner_sign·k)·partner = k·result` for `k = amount`.
struct Rewrite {
    first: Monomial,
    partner: Monomial,
    /// +1: the partner has the same sign as `first`; −1: the opposite sign.
    partner_sign: i64,
    result: Monomial,
    amount: i64,
}

/// Which revolute rows lie on one run of parallel axes: rows `j` and `j + 1`
/// share a group when both are revolute and the twist between them is 0.
#[derive(Clone, Debug, Default)]
pub(crate) struct Groups {
    /// Group id by 1-based row (index 0 unused); `None` for non-revolute rows.
    of_row: Vec<Option<usize>>,
}

impl Groups {
    /// From each row's group id (1-based rows at positions 1..; position 0 unused).
    pub(crate) fn new(of_row: Vec<Option<usize>>) -> Groups {
        Groups { of_row }
    }

    fn group(&self, row: u16) -> Option<usize> {
        self.of_row.get(usize::from(row)).copied().flatten()
    }

    /// `A ∪ B` when the two row sets may be summed: same group, disjoint and
    /// adjacent (so every printed sum is a run like `23` or `234`).
    fn union(&self, a: &[u16], b: &[u16]) -> Option<Vec<u16>> {
        let (fa, la) = (*a.first()?, *a.last()?);
        let (fb, lb) = (*b.first()?, *b.last()?);
        let g = self.group(fa)?;
        if self.group(fb) != Some(g) {
            return None;
        }
        if la + 1 == fb {
            Some(a.iter().chain(b).copied().collect())
        } else if lb + 1 == fa {
            Some(b.iter().chain(a).copied().collect())
        } else {
            None
        }
    }
}

/// The sorted product of two sorted monomials.
fn merge(a: &[Atom], b: &[Atom]) -> Monomial {
    let mut out: Monomial = a.iter().chain(b).cloned().collect();
    out.sort();
    out
}

/// `m` without the atoms at positions `i` and `j`, plus `add`, sorted.
fn replace(m: &[Atom], i: usize, j: usize, add: &[Atom]) -> Monomial {
    let rest: Vec<Atom> = m
        .iter()
        .enumerate()
        .filter(|(p, _)| *p != i && *p != j)
        .map(|(_, a)| a.clone())
        .collect();
    merge(&rest, add)
}

/// Every rewrite `m` could start: for each pair of its factors, the partner
/// term to look for and what the pair becomes.
fn candidates(m: &[Atom], groups: &Groups) -> Vec<Rewrite> {
    let mut out = Vec::new();
    for i in 0..m.len() {
        for j in i + 1..m.len() {
            if let Some(r) = pair_rewrite(m, i, j, groups) {
                out.push(r);
            }
        }
    }
    out
}

/// The rewrite started by factors `i` and `j` of `m`, if any.
fn pair_rewrite(m: &[Atom], i: usize, j: usize, groups: &Groups) -> Option<Rewrite> {
    use Trig::{Cos, Sin};
    let rewrite = |partner: [Atom; 2], partner_sign, result: &[Atom]| Rewrite {
        first: Vec::new(),
        partner: replace(m, i, j, &partner),
        partner_sign,
        result: replace(m, i, j, result),
        amount: 0,
    };
    match (&m[i], &m[j]) {
        // c² + s² = 1, for joint sums and constant angles alike.
        (Atom::Joint(a, Cos), Atom::Joint(b, Cos)) if a == b => Some(rewrite(
            [Atom::Joint(a.clone(), Sin), Atom::Joint(a.clone(), Sin)],
            1,
            &[],
        )),
        (Atom::Const(Cos, k, n), Atom::Const(Cos, k2, n2)) if k == k2 && n == n2 => Some(rewrite(
            [Atom::Const(Sin, *k, *n), Atom::Const(Sin, *k, *n)],
            1,
            &[],
        )),
        // cA cB − sA sB = c(A∪B).
        (Atom::Joint(a, Cos), Atom::Joint(b, Cos)) => {
            let u = groups.union(a, b)?;
            Some(rewrite(
                [Atom::Joint(a.clone(), Sin), Atom::Joint(b.clone(), Sin)],
                -1,
                &[Atom::Joint(u, Cos)],
            ))
        }
        // sA cB + cA sB = s(A∪B), with the sine on either side.
        (Atom::Joint(a, Sin), Atom::Joint(b, Cos)) | (Atom::Joint(b, Cos), Atom::Joint(a, Sin)) => {
            let u = groups.union(a, b)?;
            Some(rewrite(
                [Atom::Joint(a.clone(), Cos), Atom::Joint(b.clone(), Sin)],
                1,
                &[Atom::Joint(u, Sin)],
            ))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(rows: &[u16]) -> Poly {
        Poly::atom(Atom::Joint(rows.to_vec(), Trig::Cos))
    }
    fn s(rows: &[u16]) -> Poly {
        Poly::atom(Atom::Joint(rows.to_vec(), Trig::Sin))
    }
    fn one_group(n: usize) -> Groups {
        Groups::new((0..=n).map(|r| (r > 0).then_some(0)).collect())
    }

    #[test]
    fn angle_sums_collapse_over_a_parallel_run() {
        // c1c2c3 − c1s2s3 − s1c2s3 − s1s2c3 = c123.
        let p = c(&[1]).mul(&c(&[2])).mul(&c(&[3]));
        let p = p
            .add(&c(&[1]).mul(&s(&[2])).mul(&s(&[3])).neg())
            .add(&s(&[1]).mul(&c(&[2])).mul(&s(&[3])).neg())
            .add(&s(&[1]).mul(&s(&[2])).mul(&c(&[3])).neg());
        let mut q = p.clone();
        q.simplify(&one_group(3));
        assert_eq!(q, c(&[1, 2, 3]));
        // Rows in different groups stay apart.
        let mut r = p;
        r.simplify(&Groups::new(vec![None, Some(0), Some(1), Some(2)]));
        assert_eq!(r.len(), 4);
    }

    #[test]
    fn sine_sums_and_pythagoras() {
        let mut p = s(&[1]).mul(&c(&[2])).add(&c(&[1]).mul(&s(&[2])));
        p.simplify(&one_group(2));
        assert_eq!(p, s(&[1, 2]));
        let mut q = c(&[4]).mul(&c(&[4])).add(&s(&[4]).mul(&s(&[4])));
        q.simplify(&Groups::default());
        assert_eq!(q, Poly::constant(1));
        // Partial: 2 c1c2 − s1s2 = c12 + c1c2.
        let mut r = c(&[1])
            .mul(&c(&[2]))
            .mul(&Poly::constant(2))
            .add(&s(&[1]).mul(&s(&[2])).neg());
        r.simplify(&one_group(2));
        assert_eq!(r, c(&[1, 2]).add(&c(&[1]).mul(&c(&[2]))));
    }

    #[test]
    fn like_terms_cancel() {
        let p = c(&[1]).add(&c(&[1]).neg());
        assert!(p.is_zero());
    }
}
