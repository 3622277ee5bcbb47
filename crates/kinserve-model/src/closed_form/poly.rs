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

use super::budget::{Budget, Exceeded};

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
        if k != 0 {
            p.terms.insert(Vec::new(), k);
        }
        p
    }

    /// One atom.
    pub(crate) fn atom(a: Atom) -> Poly {
        let mut p = Poly::default();
        p.terms.insert(vec![a], 1);
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

    /// Number of atoms over all terms (a power counts once per factor).
    pub(crate) fn atoms(&self) -> usize {
        self.terms.keys().map(Vec::len).sum()
    }

    /// The terms in print order.
    pub(crate) fn terms(&self) -> impl Iterator<Item = (&Monomial, i64)> {
        self.terms.iter().map(|(m, k)| (m, *k))
    }

    /// Adds `k · m`, dropping the term if it cancels.
    pub(crate) fn add_term(&mut self, m: Monomial, k: i64) -> Result<(), Exceeded> {
        if k == 0 {
            return Ok(());
        }
        match self.terms.entry(m) {
            Entry::Occupied(mut e) => {
                let sum = e.get().checked_add(k).ok_or(Exceeded::Coefficient)?;
                if sum == 0 {
                    e.remove();
                } else {
                    *e.get_mut() = sum;
                }
            }
            Entry::Vacant(e) => {
                e.insert(k);
            }
        }
        Ok(())
    }

    /// `self += other`.
    pub(crate) fn add_assign(&mut self, other: &Poly) -> Result<(), Exceeded> {
        for (m, k) in other.terms() {
            self.add_term(m.clone(), k)?;
        }
        Ok(())
    }

    /// `−self`.
    pub(crate) fn neg(&self) -> Result<Poly, Exceeded> {
        let mut out = Poly::default();
        for (m, k) in self.terms() {
            out.terms
                .insert(m.clone(), k.checked_neg().ok_or(Exceeded::Coefficient)?);
        }
        Ok(out)
    }

    /// What [`Poly::mul`] of `self` and `other` costs: per pair of terms,
    /// twice the atoms of both plus one (merged, sorted, then looked up).
    pub(crate) fn mul_cost(&self, other: &Poly) -> u64 {
        let (n1, n2) = (self.len() as u64, other.len() as u64);
        let (a1, a2) = (self.atoms() as u64, other.atoms() as u64);
        let pairs = n1
            .saturating_mul(n2)
            .saturating_add(a1.saturating_mul(n2))
            .saturating_add(a2.saturating_mul(n1));
        pairs.saturating_mul(2)
    }

    /// `self · other`, expanded (the caller charges [`Poly::mul_cost`]).
    pub(crate) fn mul(&self, other: &Poly) -> Result<Poly, Exceeded> {
        let mut out = Poly::default();
        for (m1, k1) in self.terms() {
            for (m2, k2) in other.terms() {
                let k = k1.checked_mul(k2).ok_or(Exceeded::Coefficient)?;
                out.add_term(merge(m1, m2), k)?;
            }
        }
        Ok(out)
    }

    /// What one simplification pass over `self` costs: `4 + 4·len + len²`
    /// per term of `len` atoms (indexing it, then trying every pair of factors).
    fn pass_cost(&self) -> u64 {
        self.terms
            .keys()
            .map(|m| {
                let len = m.len() as u64;
                4 + 4 * len + len * len
            })
            .fold(0, u64::saturating_add)
    }

    /// Applies the trigonometric rewrites until none applies (see [`Rewrite`]),
    /// charging `budget` before each pass. Each rewrite lowers the sum of
    /// |coefficients|, so this terminates.
    pub(crate) fn simplify(
        &mut self,
        groups: &Groups,
        budget: &mut Budget,
    ) -> Result<(), Exceeded> {
        loop {
            budget.charge(self.pass_cost())?;
            let rewrites = self.find_rewrites(groups);
            if rewrites.is_empty() {
                return Ok(());
            }
            for r in rewrites {
                // |amount| ≤ i64::MAX and partner_sign is ±1: these cannot overflow.
                self.add_term(r.first, -r.amount)?;
                self.add_term(r.partner, -r.amount * r.partner_sign)?;
                self.add_term(r.result, r.amount)?;
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
                // At most both magnitudes (and i64::MAX): any such amount is a valid rewrite.
                let magnitude = k1.unsigned_abs().min(k2.unsigned_abs());
                let amount = k1.signum() * i64::try_from(magnitude).unwrap_or(i64::MAX);
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
    fn mul(a: &Poly, b: &Poly) -> Poly {
        a.mul(b).unwrap()
    }
    fn add(a: &Poly, b: &Poly) -> Poly {
        let mut out = a.clone();
        out.add_assign(b).unwrap();
        out
    }
    fn neg(a: &Poly) -> Poly {
        a.neg().unwrap()
    }
    fn simplified(mut p: Poly, groups: &Groups) -> Poly {
        p.simplify(groups, &mut Budget::new(u64::MAX)).unwrap();
        p
    }
    fn one_group(n: usize) -> Groups {
        Groups::new((0..=n).map(|r| (r > 0).then_some(0)).collect())
    }

    #[test]
    fn angle_sums_collapse_over_a_parallel_run() {
        // c1c2c3 − c1s2s3 − s1c2s3 − s1s2c3 = c123.
        let p = mul(&mul(&c(&[1]), &c(&[2])), &c(&[3]));
        let p = add(&p, &neg(&mul(&mul(&c(&[1]), &s(&[2])), &s(&[3]))));
        let p = add(&p, &neg(&mul(&mul(&s(&[1]), &c(&[2])), &s(&[3]))));
        let p = add(&p, &neg(&mul(&mul(&s(&[1]), &s(&[2])), &c(&[3]))));
        assert_eq!(simplified(p.clone(), &one_group(3)), c(&[1, 2, 3]));
        // Rows in different groups stay apart.
        let r = simplified(p, &Groups::new(vec![None, Some(0), Some(1), Some(2)]));
        assert_eq!(r.len(), 4);
    }

    #[test]
    fn sine_sums_and_pythagoras() {
        let p = add(&mul(&s(&[1]), &c(&[2])), &mul(&c(&[1]), &s(&[2])));
        assert_eq!(simplified(p, &one_group(2)), s(&[1, 2]));
        let q = add(&mul(&c(&[4]), &c(&[4])), &mul(&s(&[4]), &s(&[4])));
        assert_eq!(simplified(q, &Groups::default()), Poly::constant(1));
        // Partial: 2 c1c2 − s1s2 = c12 + c1c2.
        let r = mul(&mul(&c(&[1]), &c(&[2])), &Poly::constant(2));
        let r = add(&r, &neg(&mul(&s(&[1]), &s(&[2]))));
        let want = add(&c(&[1, 2]), &mul(&c(&[1]), &c(&[2])));
        assert_eq!(simplified(r, &one_group(2)), want);
    }

    #[test]
    fn like_terms_cancel() {
        assert!(add(&c(&[1]), &neg(&c(&[1]))).is_zero());
    }

    #[test]
    fn coefficients_past_i64_are_refused_not_wrapped() {
        let big = Poly::constant(i64::MAX);
        assert_eq!(big.mul(&Poly::constant(2)), Err(Exceeded::Coefficient));
        let mut sum = big.clone();
        assert_eq!(sum.add_assign(&big), Err(Exceeded::Coefficient));
        assert_eq!(Poly::constant(i64::MIN).neg(), Err(Exceeded::Coefficient));
    }

    #[test]
    fn a_simplification_past_the_budget_stops_before_its_pass() {
        let p = add(&mul(&s(&[1]), &c(&[2])), &mul(&c(&[1]), &s(&[2])));
        // Two terms of two atoms: a pass costs 2 · (4 + 8 + 4) = 32.
        assert_eq!(p.pass_cost(), 32);
        let mut budget = Budget::new(31);
        let mut q = p.clone();
        assert_eq!(
            q.simplify(&one_group(2), &mut budget),
            Err(Exceeded::Work { needed: 32 })
        );
        assert_eq!((q, budget.used()), (p, 0), "nothing done, nothing charged");
    }
}
