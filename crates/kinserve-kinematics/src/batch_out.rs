//! Where the poses of a batch go: whole [`Transform`]s, or the numbers of a
//! compact layout ([`PackedLayout`]) written straight from the kernel's
//! registers into the caller's slice of doubles, so that an answer in that
//! layout is not first built as transforms and then copied into it.
//!
//! Owns [`PackedLayout`] and the [`BatchOut`] destinations; depends on
//! [`crate::lane`] (how eight poses leave the registers) and
//! [`crate::transform`] only, not on the evaluators that fill them.

use std::mem::MaybeUninit;

use crate::lane::Lane8;
use crate::transform::Transform;

/// How each pose of a packed batch ([`crate::Chain::forward_batch_packed`])
/// is laid out, back to back in one slice of doubles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PackedLayout {
    /// 12 numbers: the top three rows of the homogeneous matrix, row-major
    /// (`[r11, r12, r13, x, r21, r22, r23, y, r31, r32, r33, z]`), lengths in
    /// the chain's unit.
    Matrix12,
    /// 3 numbers: the position `[x, y, z]`.
    Position,
}

impl PackedLayout {
    /// Numbers per pose.
    ///
    /// ```
    /// use kinserve_kinematics::PackedLayout;
    /// assert_eq!(PackedLayout::Matrix12.stride(), 12);
    /// assert_eq!(PackedLayout::Position.stride(), 3);
    /// ```
    pub const fn stride(self) -> usize {
        match self {
            PackedLayout::Matrix12 => 12,
            PackedLayout::Position => 3,
        }
    }
}

/// A destination of batch poses: one at a time (the tail of a batch, poses
/// redone by the exact path, a chain without joints) or eight at once from
/// the kernel's registers.
pub(crate) trait BatchOut {
    /// Poses it holds.
    fn count(&self) -> usize;
    /// Writes pose `i` (`i < count()`).
    fn put(&mut self, i: usize, t: &Transform);
    /// Writes poses `first..first + 8` (`first + 8 <= count()`): lane `k`
    /// of `m[r][c]` is row `r`, column `c` of pose `first + k`.
    fn put8<V: Lane8>(&mut self, first: usize, m: &[[V; 4]; 3]);
}

impl BatchOut for [Transform] {
    fn count(&self) -> usize {
        self.len()
    }

    fn put(&mut self, i: usize, t: &Transform) {
        self[i] = *t;
    }

    #[inline(always)]
    fn put8<V: Lane8>(&mut self, first: usize, m: &[[V; 4]; 3]) {
        if let Some(out) = self[first..].first_chunk_mut::<8>() {
            V::store_poses(m, out);
        }
    }
}

/// Writes `values` to the front of `out`.
fn put_all(out: &mut [MaybeUninit<f64>], values: &[f64]) {
    for (o, v) in out.iter_mut().zip(values) {
        o.write(*v);
    }
}

/// Poses as [`PackedLayout::Matrix12`] numbers, into memory that need not
/// be initialised (the answer's vector before its length is set): every
/// pose written is written whole.
pub(crate) struct Matrix12Out<'a>(pub(crate) &'a mut [MaybeUninit<f64>]);

impl BatchOut for Matrix12Out<'_> {
    fn count(&self) -> usize {
        self.0.len() / 12
    }

    fn put(&mut self, i: usize, t: &Transform) {
        put_all(&mut self.0[12 * i..12 * i + 12], &t.matrix12());
    }

    #[inline(always)]
    fn put8<V: Lane8>(&mut self, first: usize, m: &[[V; 4]; 3]) {
        if let Some(out) = self.0[12 * first..].first_chunk_mut::<96>() {
            V::store_matrix12(m, out);
        }
    }
}

/// Poses as [`PackedLayout::Position`] numbers (memory as for [`Matrix12Out`]).
pub(crate) struct PositionOut<'a>(pub(crate) &'a mut [MaybeUninit<f64>]);

impl BatchOut for PositionOut<'_> {
    fn count(&self) -> usize {
        self.0.len() / 3
    }

    fn put(&mut self, i: usize, t: &Transform) {
        put_all(&mut self.0[3 * i..3 * i + 3], &t.translation);
    }

    #[inline(always)]
    fn put8<V: Lane8>(&mut self, first: usize, m: &[[V; 4]; 3]) {
        if let Some(out) = self.0[3 * first..].first_chunk_mut::<24>() {
            let [x, y, z] = [m[0][3], m[1][3], m[2][3]].map(V::store8);
            for k in 0..8 {
                put_all(&mut out[3 * k..3 * k + 3], &[x[k], y[k], z[k]]);
            }
        }
    }
}
