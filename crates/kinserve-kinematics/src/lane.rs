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
//! [`crate::sincos`].
#![allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays in step; they vectorise as written"
)]

use crate::sincos::madd;

/// A vector of doubles with the operations of a DH step.
pub(crate) trait Lane: Copy {
    /// Every lane `x`.
    fn splat(x: f64) -> Self;
    /// `self · b`, lane by lane.
    fn mul(self, b: Self) -> Self;
    /// `self · b + c`, lane by lane (fused for the FMA kernels).
    fn madd(self, b: Self, c: Self) -> Self;
    /// `−self`.
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
    fn neg(self) -> Self {
        let mut o = [0.0; N];
        for k in 0..N {
            o[k] = -self.0[k];
        }
        Arr(o)
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use ymm::Ymm;

#[cfg(target_arch = "x86_64")]
mod ymm {
    use super::Lane;
    use std::arch::x86_64::{
        __m256d, _mm256_fmadd_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_set1_pd,
        _mm256_storeu_pd, _mm256_sub_pd, _mm256_setzero_pd,
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
        fn neg(self) -> Self {
            // SAFETY: as for `splat`.
            Ymm(unsafe { _mm256_sub_pd(_mm256_setzero_pd(), self.0) })
        }
    }
}
