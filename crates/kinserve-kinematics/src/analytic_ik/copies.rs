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

/// One joint's copies of one principal value: `(value, squared distance)`,
/// nearest first.
type Copies = Vec<(f64, f64)>;

/// The copies of `q` inside `limit` (or the nearest `r` if unlimited), at most `max`.
fn joint_copies(q: f64, r: f64, limit: Option<(f64, f64)>, max: usize) -> Copies {
    let Some((lo, hi)) = limit else {
        let v = q + TAU * ((r - q) / TAU).round();
        let d = wrap(v - r);
        return vec![(v, d * d)];
    };
    if lo.partial_cmp(&hi).is_none_or(|o| o.is_gt()) || !q.is_finite() {
        return Vec::new();
    }
    let kmin = ((lo - LIMIT_SLACK - q) / TAU).ceil();
    let kmax = ((hi + LIMIT_SLACK - q) / TAU).floor();
    if kmin > kmax {
        return Vec::new();
    }
    // The `max` nearest turns: a window around the one nearest r.
    let k0 = ((r - q) / TAU).round().clamp(kmin, kmax);
    let half = max as f64;
    let (from, to) = ((k0 - half).max(kmin), (k0 + half).min(kmax));
    let mut out: Copies = Vec::with_capacity((to - from) as usize + 1);
    let mut k = from;
    while k <= to {
        let v = (q + TAU * k).clamp(lo, hi);
        out.push((v, (v - r) * (v - r)));
        k += 1.0;
    }
    out.sort_by(|a, b| a.1.total_cmp(&b.1));
    out.truncate(max);
    out
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
    let lists: Vec<[Copies; 6]> = principal
        .iter()
        .map(|s| {
            std::array::from_fn(|j| {
                let limit = limits.get(j).copied().flatten();
                joint_copies(s.q[j], reference[j], limit, max.max(1))
            })
        })
        .collect();
    let mut heap = BinaryHeap::new();
    for (sol, l) in lists.iter().enumerate() {
        if l.iter().all(|c| !c.is_empty()) {
            let cost = l.iter().map(|c| c[0].1).sum();
            heap.push(Entry {
                cost,
                sol,
                idx: [0; 6],
                last: 0,
            });
        }
    }
    let mut out = Vec::new();
    while let Some(e) = heap.pop() {
        if out.len() == max {
            return (out, true);
        }
        let l = &lists[e.sol];
        let s = &principal[e.sol];
        out.push(AnalyticSolution {
            q: std::array::from_fn(|j| l[j][e.idx[j] as usize].0),
            branch: s.branch,
            singular: s.singular,
            distance: e.cost.max(0.0).sqrt(),
            position_error: s.position_error,
            rotation_error: s.rotation_error,
        });
        for j in e.last..6 {
            let i = e.idx[j] as usize;
            if i + 1 < l[j].len() {
                let mut idx = e.idx;
                idx[j] += 1;
                let cost = e.cost - l[j][i].1 + l[j][i + 1].1;
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

    #[test]
    fn copies_fit_the_limits_nearest_first() {
        let c = joint_copies(0.5, 0.0, Some((-7.0, 7.0)), 16);
        let values: Vec<f64> = c.iter().map(|x| x.0).collect();
        assert_eq!(values.len(), 3);
        assert!((values[0] - 0.5).abs() < 1e-15);
        assert!((values[1] - (0.5 - TAU)).abs() < 1e-12);
        assert!((values[2] - (0.5 + TAU)).abs() < 1e-12);
        assert!(joint_copies(0.5, 0.0, Some((1.0, 2.0)), 16).is_empty());
        assert!(joint_copies(0.5, 0.0, Some((f64::NAN, 2.0)), 16).is_empty());
        // Unlimited: the one copy nearest the reference.
        let u = joint_copies(0.5, 20.0, None, 16);
        assert_eq!(u.len(), 1);
        assert!((u[0].0 - 20.0).abs() <= std::f64::consts::PI);
        // Huge ranges stay bounded by `max`.
        assert_eq!(joint_copies(0.5, 0.0, Some((-1e12, 1e12)), 4).len(), 4);
    }
}
