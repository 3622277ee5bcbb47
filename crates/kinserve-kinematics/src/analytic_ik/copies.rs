//! The 2π copies of principal solutions that fit the joint limits, nearest a
//! reference first ([`expand`]).
//!
//! Distance (limits-aware): `√Σᵢ dᵢ²` over the joints, where `dᵢ = qᵢ − rᵢ`
//! for a limited joint (it cannot pass its limits, so a copy a turn away is
//! a turn of travel away) and the wrapped difference (within π) for an
//! unlimited one, which is answered only in its copy nearest `rᵢ`. rad.
//!
//! The nearest `max` tuples of copies are enumerated best first (a heap over
//! per-joint lists sorted by distance; a tuple's successors raise one index at
//! or after the last raised one, so each tuple is reached once), so wide limits
//! (many turns) cost `O(max · log max)`, never the full product. Depends on
//! [`super::geometry`] and the solution types of [`super`].

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::f64::consts::TAU;

use super::geometry::wrap;
use super::{AnalyticSolution, RawSolution};

/// Slack (rad) within which a copy just outside a limit is clamped onto it.
const LIMIT_SLACK: f64 = 1e-12;

/// Appends the copies of `q` inside `limit` (or the one nearest `r` if
/// unlimited), at most `max`, to `out` as `(value, squared distance)`,
/// nearest first; returns how many.
fn joint_copies(
    q: f64,
    r: f64,
    limit: Option<(f64, f64)>,
    max: usize,
    out: &mut Vec<(f64, f64)>,
) -> usize {
    let Some((lo, hi)) = limit else {
        let v = q + TAU * ((r - q) / TAU).round();
        let d = wrap(v - r);
        out.push((v, d * d));
        return 1;
    };
    if lo.partial_cmp(&hi).is_none_or(|o| o.is_gt()) || !q.is_finite() {
        return 0;
    }
    let kmin = ((lo - LIMIT_SLACK - q) / TAU).ceil();
    let kmax = ((hi + LIMIT_SLACK - q) / TAU).floor();
    if kmin > kmax {
        return 0;
    }
    // The `max` nearest turns: a window around the one nearest r.
    let k0 = ((r - q) / TAU).round().clamp(kmin, kmax);
    let half = max as f64;
    let (from, to) = ((k0 - half).max(kmin), (k0 + half).min(kmax));
    let start = out.len();
    let mut k = from;
    while k <= to {
        let v = (q + TAU * k).clamp(lo, hi);
        out.push((v, (v - r) * (v - r)));
        k += 1.0;
    }
    out[start..].sort_by(|a, b| a.1.total_cmp(&b.1));
    out.truncate(start + max);
    out.len() - start
}

/// Each principal solution's copies per joint: `(start, len)` into a flat store.
struct Lists {
    store: Vec<(f64, f64)>,
    ranges: Vec<[(usize, usize); 6]>,
}

impl Lists {
    fn get(&self, sol: usize, joint: usize, i: usize) -> (f64, f64) {
        let (start, _) = self.ranges[sol][joint];
        self.store[start + i]
    }

    fn len(&self, sol: usize, joint: usize) -> usize {
        self.ranges[sol][joint].1
    }
}

/// A heap entry: total squared distance, which principal solution, the copy
/// index per joint and the last joint raised.
#[derive(Clone, Debug)]
struct Entry {
    cost: f64,
    sol: usize,
    idx: [u32; 6],
    last: usize,
}

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Entry {
    /// Reversed, so the std max-heap pops the smallest cost first.
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .cost
            .total_cmp(&self.cost)
            .then(other.sol.cmp(&self.sol))
            .then(other.idx.cmp(&self.idx))
    }
}

/// Every copy of `principal` inside `limits`, nearest `reference` first, at
/// most `max`; the flag says more fitted than `max`.
pub(super) fn expand(
    principal: &[RawSolution],
    limits: &[Option<(f64, f64)>],
    reference: &[f64; 6],
    max: usize,
) -> (Vec<AnalyticSolution>, bool) {
    let mut lists = Lists {
        store: Vec::with_capacity(principal.len() * 6),
        ranges: Vec::with_capacity(principal.len()),
    };
    for s in principal {
        let mut ranges = [(0, 0); 6];
        for (j, range) in ranges.iter_mut().enumerate() {
            let start = lists.store.len();
            let limit = limits.get(j).copied().flatten();
            let n = joint_copies(s.q[j], reference[j], limit, max.max(1), &mut lists.store);
            *range = (start, n);
        }
        lists.ranges.push(ranges);
    }
    let total = (0..principal.len()).fold(0usize, |acc, sol| {
        let product = (0..6).fold(1usize, |p, j| p.saturating_mul(lists.len(sol, j)));
        acc.saturating_add(product)
    });
    if total <= max {
        return (every_copy(principal, &lists, total), false);
    }
    nearest_copies(principal, &lists, max)
}

fn solution(
    s: &RawSolution,
    lists: &Lists,
    sol: usize,
    idx: &[u32; 6],
    cost: f64,
) -> AnalyticSolution {
    AnalyticSolution {
        q: std::array::from_fn(|j| lists.get(sol, j, idx[j] as usize).0),
        branch: s.branch,
        singular: s.singular,
        distance: cost.max(0.0).sqrt(),
        position_error: s.position_error,
        rotation_error: s.rotation_error,
    }
}

/// All `total` copies, sorted (the product is small).
fn every_copy(principal: &[RawSolution], lists: &Lists, total: usize) -> Vec<AnalyticSolution> {
    let mut out = Vec::with_capacity(total);
    for (sol, s) in principal.iter().enumerate() {
        if (0..6).any(|j| lists.len(sol, j) == 0) {
            continue;
        }
        let mut idx = [0u32; 6];
        loop {
            let cost = (0..6).map(|j| lists.get(sol, j, idx[j] as usize).1).sum();
            out.push(solution(s, lists, sol, &idx, cost));
            // Odometer over the six copy indices.
            let mut j = 0;
            while j < 6 {
                idx[j] += 1;
                if (idx[j] as usize) < lists.len(sol, j) {
                    break;
                }
                idx[j] = 0;
                j += 1;
            }
            if j == 6 {
                break;
            }
        }
    }
    out.sort_by(|a, b| a.distance.total_cmp(&b.distance));
    out
}

/// The `max` nearest copies, best first from a heap.
fn nearest_copies(
    principal: &[RawSolution],
    lists: &Lists,
    max: usize,
) -> (Vec<AnalyticSolution>, bool) {
    let mut heap = BinaryHeap::new();
    for sol in 0..principal.len() {
        if (0..6).all(|j| lists.len(sol, j) > 0) {
            let cost = (0..6).map(|j| lists.get(sol, j, 0).1).sum();
            heap.push(Entry {
                cost,
                sol,
                idx: [0; 6],
                last: 0,
            });
        }
    }
    let mut out = Vec::with_capacity(max.min(4096));
    while let Some(e) = heap.pop() {
        if out.len() == max {
            return (out, true);
        }
        out.push(solution(&principal[e.sol], lists, e.sol, &e.idx, e.cost));
        for j in e.last..6 {
            let i = e.idx[j] as usize;
            if i + 1 < lists.len(e.sol, j) {
                let mut idx = e.idx;
                idx[j] += 1;
                let cost = e.cost - lists.get(e.sol, j, i).1 + lists.get(e.sol, j, i + 1).1;
                heap.push(Entry {
                    cost,
                    sol: e.sol,
                    idx,
                    last: j,
                });
            }
        }
    }
    (out, false)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn copies(q: f64, r: f64, limit: Option<(f64, f64)>, max: usize) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        let n = joint_copies(q, r, limit, max, &mut out);
        assert_eq!(n, out.len());
        out
    }

    #[test]
    fn copies_fit_the_limits_nearest_first() {
        let c = copies(0.5, 0.0, Some((-7.0, 7.0)), 16);
        let values: Vec<f64> = c.iter().map(|x| x.0).collect();
        assert_eq!(values.len(), 3);
        assert!((values[0] - 0.5).abs() < 1e-15);
        assert!((values[1] - (0.5 - TAU)).abs() < 1e-12);
        assert!((values[2] - (0.5 + TAU)).abs() < 1e-12);
        assert!(copies(0.5, 0.0, Some((1.0, 2.0)), 16).is_empty());
        assert!(copies(0.5, 0.0, Some((f64::NAN, 2.0)), 16).is_empty());
        // Unlimited: the one copy nearest the reference.
        let u = copies(0.5, 20.0, None, 16);
        assert_eq!(u.len(), 1);
        assert!((u[0].0 - 20.0).abs() <= std::f64::consts::PI);
        // Huge ranges stay bounded by `max`.
        assert_eq!(copies(0.5, 0.0, Some((-1e12, 1e12)), 4).len(), 4);
    }
}
