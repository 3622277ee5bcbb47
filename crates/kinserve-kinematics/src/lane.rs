//! The lane vectors the evaluators compute with, behind one small trait
//! ([`Lane`]) so that the DH step ([`crate::step`]) is written once:
//!
//! - [`Arr`]: `N` doubles as an array, element-wise loops that the compiler
//!   vectorises for whatever target features the calling function has
//!   (the batch path's 8-pose vectors; the portable single path);
//! - [`Ymm`] (x86_64): one AVX register of 4 doubles via `std::arch`, for a
//!   column of the single-pose 4×4. The arrays would do the same arithmetic,
//!   but the compiler splits a column whose fourth lane is unused into a pair
//!   and a scalar: twice the instructions on the hot path.
//!
//! `FMA` selects fused multiply-adds ([`crate::sincos::madd`]). Depends only on
//! [`crate::sincos`] and [`crate::transform`] (the poses the vectors are
//! written out as).
#![allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays in step; they vectorise as written"
)]

use std::mem::MaybeUninit;

use crate::sincos::madd;
use crate::transform::Transform;

/// A vector of doubles with the operations of a DH step.
pub(crate) trait Lane: Copy {
    /// Every lane `x`.
    fn splat(x: f64) -> Self;
    /// `self · b`, lane by lane.
    fn mul(self, b: Self) -> Self;
    /// `self · b + c`, lane by lane (fused for the FMA kernels).
    fn madd(self, b: Self, c: Self) -> Self;
    /// `c − self · b`, lane by lane (fused for the FMA kernels).
    fn nmadd(self, b: Self, c: Self) -> Self;
    /// `−self` (a sign flip, exact).
    fn neg(self) -> Self;
}

/// `N` doubles, element-wise (see the module docs).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Arr<const FMA: bool, const N: usize>(pub [f64; N]);

impl<const FMA: bool, const N: usize> Lane for Arr<FMA, N> {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Arr([x; N])
    }
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        let mut o = [0.0; N];
        for k in 0..N {
            o[k] = self.0[k] * b.0[k];
        }
        Arr(o)
    }
    #[inline(always)]
    fn madd(self, b: Self, c: Self) -> Self {
        let mut o = [0.0; N];
        for k in 0..N {
            o[k] = madd::<FMA>(self.0[k], b.0[k], c.0[k]);
        }
        Arr(o)
    }
    #[inline(always)]
    fn nmadd(self, b: Self, c: Self) -> Self {
        let mut o = [0.0; N];
        for k in 0..N {
            o[k] = madd::<FMA>(-self.0[k], b.0[k], c.0[k]);
        }
        Arr(o)
    }
    #[inline(always)]
    fn neg(self) -> Self {
        let mut o = [0.0; N];
        for k in 0..N {
            o[k] = -self.0[k];
        }
        Arr(o)
    }
}

/// An 8-lane vector of the batch path (one lane per pose): [`Lane`] plus
/// loading and storing.
pub(crate) trait Lane8: Lane {
    /// Loads eight doubles.
    ///
    /// # Safety
    /// The CPU must support the target features the type's operations use.
    unsafe fn load8(a: &[f64; 8]) -> Self;
    /// The eight doubles.
    fn store8(self) -> [f64; 8];
    /// Eight configurations of `dof` joint values each (`qb`, one after the
    /// other) as joint-major rows: `out[j][k]` is joint `j0 + j` of
    /// configuration `k`, for the joints `j0..min(j0 + 8, dof)` (the rows
    /// beyond are zero). The default reads element by element; [`Zmm`] and
    /// [`Ymm2`] transpose eight masked row loads in registers instead of a
    /// gather per joint (a gather is 8 loads and, on AMD Zen 4, many cycles).
    ///
    /// # Safety
    /// The CPU must support the target features the type's operations use.
    ///
    /// # Panics
    /// If `qb` is shorter than `8 · dof` or `j0 ≥ dof`.
    #[inline(always)]
    unsafe fn load_joints(qb: &[f64], dof: usize, j0: usize) -> [[f64; 8]; 8] {
        let mut t = [[0.0; 8]; 8];
        for j in 0..(dof - j0).min(8) {
            for k in 0..8 {
                t[j][k] = qb[k * dof + j0 + j];
            }
        }
        t
    }

    /// Writes eight poses: lane `k` of `m[r][c]` is row `r`, column `c` of
    /// pose `k`'s top three rows (column 3 the translation). Out of the
    /// vectors once, then pose by pose.
    #[inline(always)]
    fn store_poses(m: &[[Self; 4]; 3], out: &mut [Transform; 8]) {
        let e = store_state(m);
        for (k, o) in out.iter_mut().enumerate() {
            *o = Transform {
                rotation: [
                    [e[0][0][k], e[0][1][k], e[0][2][k]],
                    [e[1][0][k], e[1][1][k], e[1][2][k]],
                    [e[2][0][k], e[2][1][k], e[2][2][k]],
                ],
                translation: [e[0][3][k], e[1][3][k], e[2][3][k]],
            };
        }
    }

    /// Writes eight poses as 12 numbers each, the top three rows of the
    /// homogeneous matrix row-major (pose `k` at `out[12k..12k + 12]`; `m`
    /// as in [`Lane8::store_poses`]).
    #[inline(always)]
    fn store_matrix12(m: &[[Self; 4]; 3], out: &mut [MaybeUninit<f64>; 96]) {
        let e = store_state(m);
        for (k, o) in out.chunks_exact_mut(12).enumerate() {
            for r in 0..3 {
                for c in 0..4 {
                    o[4 * r + c].write(e[r][c][k]);
                }
            }
        }
    }
}

/// The twelve vectors of a batch block's state as arrays, by plain loops: a
/// closure (`array::map`) does not inherit the kernel's target features, so
/// its `store8` became a call per vector (the AVX2 batch took 2.3 × as long).
#[inline(always)]
fn store_state<V: Lane8>(m: &[[V; 4]; 3]) -> [[[f64; 8]; 4]; 3] {
    let mut e = [[[0.0; 8]; 4]; 3];
    for r in 0..3 {
        for c in 0..4 {
            e[r][c] = m[r][c].store8();
        }
    }
    e
}

impl<const FMA: bool> Lane8 for Arr<FMA, 8> {
    #[inline(always)]
    unsafe fn load8(a: &[f64; 8]) -> Self {
        Arr(*a)
    }
    #[inline(always)]
    fn store8(self) -> [f64; 8] {
        self.0
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use ymm::{Ymm, Ymm2};
#[cfg(target_arch = "x86_64")]
pub(crate) use zmm::Zmm;

/// `q[start..start + 8]` with the lanes past the end of `q` zero, in two
/// masked AVX loads: one instruction per half, where the clamped scalar loads
/// of the portable path become index arithmetic and a gather ahead of every
/// single pose's sine/cosine (on its critical path).
///
/// # Safety
/// The CPU must support AVX2 (only the x86_64 kernels call this, after the
/// check). Lanes past the end of `q` are masked off: the ISA neither reads
/// nor faults on them.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) unsafe fn masked_load8(q: &[f64], start: usize) -> [f64; 8] {
    use std::arch::x86_64::{
        __m256d, _mm256_cmpgt_epi64, _mm256_maskload_pd, _mm256_set_epi64x, _mm256_set1_epi64x,
    };
    // Lanes to load: 0..=8 (no overflow: a slice has at most isize::MAX elements).
    let n = q.len().saturating_sub(start).min(8) as i64;
    let base = q.as_ptr().wrapping_add(start.min(q.len()));
    // SAFETY: AVX2 is the caller's promise; each enabled lane `k` has
    // `start + k < q.len()`, so it reads inside `q`; disabled lanes are not
    // accessed (masked loads do not fault on them), and `base` is at most
    // one past the end of `q`, so `base + 4` is only formed, never read, when
    // no lane of the upper half is enabled.
    unsafe {
        let lanes = _mm256_set_epi64x(3, 2, 1, 0);
        let lo = _mm256_cmpgt_epi64(_mm256_set1_epi64x(n), lanes);
        let hi = _mm256_cmpgt_epi64(_mm256_set1_epi64x(n - 4), lanes);
        let a = _mm256_maskload_pd(base, lo);
        let b = _mm256_maskload_pd(base.wrapping_add(4), hi);
        std::mem::transmute::<[__m256d; 2], [f64; 8]>([a, b])
    }
}

#[cfg(target_arch = "x86_64")]
mod ymm {
    use super::Lane;
    #[allow(clippy::wildcard_imports)]
    use crate::transform::Transform;
    use std::arch::x86_64::{
        __m256d, _mm256_blend_pd, _mm256_fmadd_pd, _mm256_fnmadd_pd, _mm256_loadu_pd,
        _mm256_mul_pd, _mm256_permute_pd, _mm256_permute2f128_pd, _mm256_permute4x64_pd,
        _mm256_set1_pd, _mm256_setzero_pd, _mm256_storeu_pd, _mm256_unpackhi_pd,
        _mm256_unpacklo_pd, _mm256_xor_pd,
    };

    /// Four doubles in one AVX register, with fused multiply-add.
    ///
    /// Only built by [`Ymm::load`], which is `unsafe`: its caller promises the
    /// CPU has AVX2 and FMA, which is what makes every method sound.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Ymm(__m256d);

    impl Ymm {
        /// Loads four doubles.
        ///
        /// # Safety
        /// The CPU must support `avx2` and `fma` (the kernels that call this are
        /// `#[target_feature(enable = "avx2,fma")]` and are only run after the check).
        #[inline(always)]
        pub(crate) unsafe fn load(a: &[f64; 4]) -> Ymm {
            // SAFETY: `a` is 4 readable doubles; the caller guarantees AVX.
            Ymm(unsafe { _mm256_loadu_pd(a.as_ptr()) })
        }

        /// The rigid transform whose columns x, y, z, p are `cols` (lane 3
        /// unused) as its twelve row-major doubles in three registers, in
        /// memory order: `x0 y0 z0 x1 | y1 z1 x2 y2 | z2 p0 p1 p2` (a
        /// transpose in registers).
        #[inline(always)]
        fn transform_rows(cols: &[Ymm; 4]) -> [__m256d; 3] {
            let [Ymm(x), Ymm(y), Ymm(z), Ymm(p)] = *cols;
            // SAFETY: a `Ymm` exists only on a CPU with AVX2 (see `Ymm::load`).
            unsafe {
                let xy_lo = _mm256_unpacklo_pd(x, y); // x0 y0 x2 y2
                let zx = _mm256_unpacklo_pd(z, _mm256_permute_pd::<0b0101>(x)); // z0 x1 z2 x3
                let yz_hi = _mm256_unpackhi_pd(y, z); // y1 z1 y3 z3
                let p_up = _mm256_permute4x64_pd::<0b10_01_00_10>(p); // p2 p0 p1 p2
                let z2 = _mm256_permute4x64_pd::<0b10>(z); // z2 z0 z0 z0
                [
                    _mm256_permute2f128_pd::<0x20>(xy_lo, zx), // x0 y0 z0 x1
                    _mm256_blend_pd::<0b1100>(yz_hi, xy_lo),   // y1 z1 x2 y2
                    _mm256_blend_pd::<0b0001>(p_up, z2),       // z2 p0 p1 p2
                ]
            }
        }

        /// The rigid transform whose columns are `cols` (see
        /// [`Ymm::store_transform`]), returned in registers: no copy through
        /// memory, whose narrower stores read back wider stalled store
        /// forwarding (about a third of a single pose's time).
        #[inline(always)]
        pub(crate) fn transform(cols: &[Ymm; 4]) -> Transform {
            const { assert!(size_of::<Transform>() == size_of::<[__m256d; 3]>()) };
            // SAFETY: `Transform` is `repr(C)`, twelve doubles with no padding
            // (the sizes are checked above), and any bits are a valid double.
            unsafe { std::mem::transmute::<[__m256d; 3], Transform>(Self::transform_rows(cols)) }
        }

        /// Writes the rigid transform whose columns x, y, z, p are `cols`
        /// (lane 3 unused) as a row-major [`Transform`]: a 4×4 transpose in
        /// registers and three stores that do not overlap.
        ///
        /// # Safety
        /// `out` must be valid for writes of one `Transform` (it may be uninitialised).
        #[inline(always)]
        pub(crate) unsafe fn store_transform(cols: &[Ymm; 4], out: *mut Transform) {
            let base: *mut f64 = out.cast();
            let [a, b, c] = Self::transform_rows(cols);
            // SAFETY: `out` is writable (this function's contract): `Transform`
            // is `repr(C)`, 12 contiguous doubles, written as 3 × 4; a `Ymm`
            // exists only on a CPU with AVX.
            unsafe {
                _mm256_storeu_pd(base, a);
                _mm256_storeu_pd(base.add(4), b);
                _mm256_storeu_pd(base.add(8), c);
            }
        }

        /// The four doubles.
        #[inline(always)]
        pub(crate) fn store(self) -> [f64; 4] {
            let mut a = [0.0; 4];
            // SAFETY: `a` is 4 writable doubles; a `Ymm` exists only on a CPU with AVX.
            unsafe { _mm256_storeu_pd(a.as_mut_ptr(), self.0) };
            a
        }
    }

    impl Lane for Ymm {
        #[inline(always)]
        fn splat(x: f64) -> Self {
            // SAFETY: a `Ymm` is only used on a CPU with AVX2 and FMA (see `Ymm::load`).
            Ymm(unsafe { _mm256_set1_pd(x) })
        }
        #[inline(always)]
        fn mul(self, b: Self) -> Self {
            // SAFETY: as for `splat`.
            Ymm(unsafe { _mm256_mul_pd(self.0, b.0) })
        }
        #[inline(always)]
        fn madd(self, b: Self, c: Self) -> Self {
            // SAFETY: as for `splat`; FMA is part of the promise.
            Ymm(unsafe { _mm256_fmadd_pd(self.0, b.0, c.0) })
        }
        #[inline(always)]
        fn nmadd(self, b: Self, c: Self) -> Self {
            // SAFETY: as for `splat`; FMA is part of the promise.
            Ymm(unsafe { _mm256_fnmadd_pd(self.0, b.0, c.0) })
        }
        #[inline(always)]
        fn neg(self) -> Self {
            // SAFETY: as for `splat`.
            Ymm(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
        }
    }

    /// Eight doubles in two AVX registers (the AVX2 batch path), with the
    /// same promise as [`Ymm`].
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Ymm2(Ymm, Ymm);

    impl Lane for Ymm2 {
        #[inline(always)]
        fn splat(x: f64) -> Self {
            Ymm2(Ymm::splat(x), Ymm::splat(x))
        }
        #[inline(always)]
        fn mul(self, b: Self) -> Self {
            Ymm2(self.0.mul(b.0), self.1.mul(b.1))
        }
        #[inline(always)]
        fn madd(self, b: Self, c: Self) -> Self {
            Ymm2(self.0.madd(b.0, c.0), self.1.madd(b.1, c.1))
        }
        #[inline(always)]
        fn nmadd(self, b: Self, c: Self) -> Self {
            Ymm2(self.0.nmadd(b.0, c.0), self.1.nmadd(b.1, c.1))
        }
        #[inline(always)]
        fn neg(self) -> Self {
            Ymm2(self.0.neg(), self.1.neg())
        }
    }

    impl super::Lane8 for Ymm2 {
        /// Two masked AVX loads per configuration, then four 4 × 4
        /// transposes in registers (see [`super::Lane8::load_joints`]).
        #[inline(always)]
        unsafe fn load_joints(qb: &[f64], dof: usize, j0: usize) -> [[f64; 8]; 8] {
            assert!(
                j0 < dof && qb.len() >= 8 * dof,
                "eight configurations of dof values"
            );
            // SAFETY: the caller guarantees AVX2; `masked_load8` reads only
            // inside each configuration's slice.
            unsafe {
                let mut rows = [[_mm256_setzero_pd(); 2]; 8];
                for (k, row) in rows.iter_mut().enumerate() {
                    let v = super::masked_load8(&qb[k * dof..(k + 1) * dof], j0);
                    *row = std::mem::transmute::<[f64; 8], [__m256d; 2]>(v);
                }
                let mut out = [[_mm256_setzero_pd(); 2]; 8];
                for half in 0..2 {
                    // Configurations 4·half.. (lanes), joints 4·g.. (rows of `out`).
                    for g in 0..2 {
                        // (No closure: it would not inherit the target features.)
                        let b = 4 * half;
                        let r = [rows[b][g], rows[b + 1][g], rows[b + 2][g], rows[b + 3][g]];
                        let t0 = _mm256_unpacklo_pd(r[0], r[1]);
                        let t1 = _mm256_unpackhi_pd(r[0], r[1]);
                        let t2 = _mm256_unpacklo_pd(r[2], r[3]);
                        let t3 = _mm256_unpackhi_pd(r[2], r[3]);
                        out[4 * g][half] = _mm256_permute2f128_pd::<0x20>(t0, t2);
                        out[4 * g + 1][half] = _mm256_permute2f128_pd::<0x20>(t1, t3);
                        out[4 * g + 2][half] = _mm256_permute2f128_pd::<0x31>(t0, t2);
                        out[4 * g + 3][half] = _mm256_permute2f128_pd::<0x31>(t1, t3);
                    }
                }
                std::mem::transmute::<[[__m256d; 2]; 8], [[f64; 8]; 8]>(out)
            }
        }

        #[inline(always)]
        unsafe fn load8(a: &[f64; 8]) -> Self {
            let [a0, a1, a2, a3, a4, a5, a6, a7] = *a;
            // SAFETY: forwarded from this function's own contract.
            unsafe { Ymm2(Ymm::load(&[a0, a1, a2, a3]), Ymm::load(&[a4, a5, a6, a7])) }
        }
        #[inline(always)]
        fn store8(self) -> [f64; 8] {
            let [a0, a1, a2, a3] = self.0.store();
            let [a4, a5, a6, a7] = self.1.store();
            [a0, a1, a2, a3, a4, a5, a6, a7]
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod zmm {
    use super::{Lane, Lane8};
    use crate::transform::Transform;
    use std::arch::x86_64::{
        __m256d, __m512d, _mm256_setzero_pd, _mm256_storeu_pd, _mm512_castpd512_pd256,
        _mm512_extractf64x4_pd, _mm512_fmadd_pd, _mm512_fnmadd_pd, _mm512_loadu_pd, _mm512_mul_pd,
        _mm512_permutex2var_pd, _mm512_set_epi64, _mm512_set1_pd, _mm512_setzero_pd,
        _mm512_shuffle_f64x2, _mm512_storeu_pd, _mm512_unpackhi_pd, _mm512_unpacklo_pd,
        _mm512_xor_pd,
    };
    use std::mem::MaybeUninit;

    /// Eight doubles in one AVX-512 register, with fused multiply-add.
    ///
    /// Only built by [`Lane8::load8`] and [`Lane::splat`]; the kernels that use it are
    /// `#[target_feature(enable = "avx512f,avx512dq,...")]` and only run after
    /// the CPU check, which is what makes every method sound.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Zmm(__m512d);

    impl Lane for Zmm {
        #[inline(always)]
        fn splat(x: f64) -> Self {
            // SAFETY: a `Zmm` is only used on a CPU with AVX-512F and DQ (see the type docs).
            Zmm(unsafe { _mm512_set1_pd(x) })
        }
        #[inline(always)]
        fn mul(self, b: Self) -> Self {
            // SAFETY: as for `splat`.
            Zmm(unsafe { _mm512_mul_pd(self.0, b.0) })
        }
        #[inline(always)]
        fn madd(self, b: Self, c: Self) -> Self {
            // SAFETY: as for `splat`.
            Zmm(unsafe { _mm512_fmadd_pd(self.0, b.0, c.0) })
        }
        #[inline(always)]
        fn nmadd(self, b: Self, c: Self) -> Self {
            // SAFETY: as for `splat`.
            Zmm(unsafe { _mm512_fnmadd_pd(self.0, b.0, c.0) })
        }
        #[inline(always)]
        fn neg(self) -> Self {
            // SAFETY: as for `splat` (the double xor is AVX-512DQ, part of the promise).
            Zmm(unsafe { _mm512_xor_pd(self.0, _mm512_set1_pd(-0.0)) })
        }
    }

    impl Lane8 for Zmm {
        #[inline(always)]
        unsafe fn load8(a: &[f64; 8]) -> Self {
            // SAFETY: `a` is 8 readable doubles; the caller guarantees AVX-512F.
            Zmm(unsafe { _mm512_loadu_pd(a.as_ptr()) })
        }
        #[inline(always)]
        fn store8(self) -> [f64; 8] {
            let mut a = [0.0; 8];
            // SAFETY: `a` is 8 writable doubles; a `Zmm` exists only on a CPU with AVX-512F.
            unsafe { _mm512_storeu_pd(a.as_mut_ptr(), self.0) };
            a
        }

        #[inline(always)]
        unsafe fn load_joints(qb: &[f64], dof: usize, j0: usize) -> [[f64; 8]; 8] {
            use std::arch::x86_64::_mm512_maskz_loadu_pd;
            assert!(
                j0 < dof && qb.len() >= 8 * dof,
                "eight configurations of dof values"
            );
            let n = (dof - j0).min(8);
            let mask = ((1u32 << n) - 1) as u8;
            // SAFETY: the caller guarantees AVX-512F; row `k` reads lanes
            // `k·dof + j0 .. k·dof + j0 + n`, below `8·dof ≤ qb.len()` (checked
            // above); masked-off lanes are neither read nor fault.
            unsafe {
                let mut rows = [_mm512_setzero_pd(); 8];
                for (k, row) in rows.iter_mut().enumerate() {
                    *row = _mm512_maskz_loadu_pd(mask, qb.as_ptr().add(k * dof + j0));
                }
                std::mem::transmute::<[__m512d; 8], [[f64; 8]; 8]>(transpose8(rows))
            }
        }

        /// The eight poses as matrix rows, by the same transposes as
        /// [`Lane8::store_poses`], rows 0 and 1 first, then row 2.
        #[inline(always)]
        fn store_matrix12(m: &[[Self; 4]; 3], out: &mut [MaybeUninit<f64>; 96]) {
            let [[r00, r01, r02, x], [r10, r11, r12, y], [r20, r21, r22, z]] = *m;
            let head = [r00, r01, r02, x, r10, r11, r12, y].map(|v| v.0);
            // SAFETY: a `Zmm` exists only on a CPU with AVX-512F (and AVX);
            // `out` is 96 writable doubles.
            unsafe { store_twelve(head, [r20.0, r21.0, r22.0, z.0], out.as_mut_ptr().cast()) }
        }

        /// The eight poses by an in-register transpose: each pose's first
        /// eight numbers (rotation rows 0, 1 and two of row 2) as an 8 × 8
        /// block (three rounds of two-source shuffles), its last four
        /// (`r22`, the translation) as an 8 × 4 one, then one 8-double and
        /// one 4-double store per pose: 16 stores instead of 12 vector and
        /// 96 scalar ones.
        #[inline(always)]
        fn store_poses(m: &[[Self; 4]; 3], out: &mut [Transform; 8]) {
            const { assert!(size_of::<[Transform; 8]>() == 96 * size_of::<f64>()) };
            let [[r00, r01, r02, x], [r10, r11, r12, y], [r20, r21, r22, z]] = *m;
            let head = [r00, r01, r02, r10, r11, r12, r20, r21].map(|v| v.0);
            // SAFETY: a `Zmm` exists only on a CPU with AVX-512F (and AVX);
            // `Transform` is `repr(C)`, twelve doubles without padding (size
            // checked above), so `out` is 96 writable doubles.
            unsafe { store_twelve(head, [r22.0, x.0, y.0, z.0], out.as_mut_ptr().cast()) }
        }
    }

    /// Eight poses of twelve numbers each from their vectors: lane `k` of
    /// `head[j]` is number `j` of pose `k`, of `tail[j]` number `8 + j`;
    /// pose `k` goes to `base[12k..12k + 12]` (an 8 × 8 and an 8 × 4
    /// transpose, then one 8-double and one 4-double store per pose).
    ///
    /// # Safety
    /// The CPU must support AVX-512F; `base` must be valid for writes of
    /// 96 doubles.
    #[inline(always)]
    unsafe fn store_twelve(head: [__m512d; 8], tail: [__m512d; 4], base: *mut f64) {
        // SAFETY: by this function's contract every store is inside
        // `base[0..96]` and the intrinsics' features are there.
        unsafe {
            let t = transpose8(head);
            let tail = transpose8x4(tail);
            for k in 0..8 {
                _mm512_storeu_pd(base.add(12 * k), t[k]);
                _mm256_storeu_pd(base.add(12 * k + 8), tail[k]);
            }
        }
    }

    /// `a[j]` lane `k` → `out[k]` lane `j`.
    ///
    /// # Safety
    /// The CPU must support AVX-512F.
    #[inline(always)]
    unsafe fn transpose8(a: [__m512d; 8]) -> [__m512d; 8] {
        // SAFETY: by this function's contract.
        unsafe {
            // Pairs: lane pair L of `e[i]` holds (a[2i], a[2i + 1]) of pose 2L,
            // of `o[i]` the same of pose 2L + 1.
            let e = [
                _mm512_unpacklo_pd(a[0], a[1]),
                _mm512_unpacklo_pd(a[2], a[3]),
                _mm512_unpacklo_pd(a[4], a[5]),
                _mm512_unpacklo_pd(a[6], a[7]),
            ];
            let o = [
                _mm512_unpackhi_pd(a[0], a[1]),
                _mm512_unpackhi_pd(a[2], a[3]),
                _mm512_unpackhi_pd(a[4], a[5]),
                _mm512_unpackhi_pd(a[6], a[7]),
            ];
            // Quads: lane pairs 0 and 2 (0x88) or 1 and 3 (0xDD) of two
            // sources, so that a pose's four numbers of elements 0..4 (or
            // 4..8) sit in one 256-bit half; then the two halves of a pose.
            let mut out = [_mm512_setzero_pd(); 8];
            // (pairs, the pose 0x88 then gives, the pose 0xDD gives; each + 4 too)
            for (x, even, odd) in [(e, 0, 2), (o, 1, 3)] {
                let q88 = [
                    _mm512_shuffle_f64x2::<0x88>(x[0], x[1]), // poses even, even + 4: elements 0..4
                    _mm512_shuffle_f64x2::<0x88>(x[2], x[3]), // the same poses: elements 4..8
                ];
                let qdd = [
                    _mm512_shuffle_f64x2::<0xDD>(x[0], x[1]), // poses odd, odd + 4
                    _mm512_shuffle_f64x2::<0xDD>(x[2], x[3]),
                ];
                out[even] = _mm512_shuffle_f64x2::<0x88>(q88[0], q88[1]);
                out[even + 4] = _mm512_shuffle_f64x2::<0xDD>(q88[0], q88[1]);
                out[odd] = _mm512_shuffle_f64x2::<0x88>(qdd[0], qdd[1]);
                out[odd + 4] = _mm512_shuffle_f64x2::<0xDD>(qdd[0], qdd[1]);
            }
            out
        }
    }

    /// `a[j]` lane `k` → `out[k]` lane `j`, for four vectors of eight.
    ///
    /// # Safety
    /// The CPU must support AVX-512F.
    #[inline(always)]
    unsafe fn transpose8x4(a: [__m512d; 4]) -> [__m256d; 8] {
        // SAFETY: by this function's contract.
        unsafe {
            let (e0, o0) = (
                _mm512_unpacklo_pd(a[0], a[1]),
                _mm512_unpackhi_pd(a[0], a[1]),
            );
            let (e1, o1) = (
                _mm512_unpacklo_pd(a[2], a[3]),
                _mm512_unpackhi_pd(a[2], a[3]),
            );
            // Lane pair L of e0/e1 is pose 2L's (a0, a1)/(a2, a3); of o0/o1 pose 2L + 1's.
            let low = _mm512_set_epi64(11, 10, 3, 2, 9, 8, 1, 0);
            let high = _mm512_set_epi64(15, 14, 7, 6, 13, 12, 5, 4);
            let halves = [
                _mm512_permutex2var_pd(e0, low, e1),  // poses 0, 2
                _mm512_permutex2var_pd(o0, low, o1),  // poses 1, 3
                _mm512_permutex2var_pd(e0, high, e1), // poses 4, 6
                _mm512_permutex2var_pd(o0, high, o1), // poses 5, 7
            ];
            let mut out = [_mm256_setzero_pd(); 8];
            for (i, h) in halves.iter().enumerate() {
                let pose = [0, 1, 4, 5][i];
                out[pose] = _mm512_castpd512_pd256(*h);
                out[pose + 2] = _mm512_extractf64x4_pd::<1>(*h);
            }
            out
        }
    }
}
