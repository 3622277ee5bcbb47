//! Sine and cosine of many angles at once: a branch-free polynomial that the
//! compiler vectorises (AVX-512 or AVX2 with FMA when the CPU has them, plain
//! SSE2 otherwise).
//!
//! Method: Cody–Waite reduction by π/2 in three parts (two fused ones with
//! FMA), then the Cephes minimax polynomials for sin and cos on `[-π/4, π/4]`
//! (by Estrin's scheme), then a quadrant swap.
//! For `|x| ≤ POLY_LIMIT` the result is within 2 ulp-ish of `f64::sin_cos`
//! (the test `matches_std_over_range` bounds the absolute error by 4e-16);
//! larger or non-finite inputs fall back to `f64::sin_cos` itself, so the
//! function is exact-as-std everywhere else.

//!
//! Depends only on the crate's kernel choice ([`Kernel`]).

// The constants below are published ones, kept digit for digit as printed (fdlibm, Cephes).
#![allow(clippy::excessive_precision)]
#![allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays in step; they vectorise as written"
)]

use crate::kernel::Kernel;

/// Inputs with magnitude above this (rad) use `f64::sin_cos`.
pub const POLY_LIMIT: f64 = 1.0e5;

// π/2 split in three: PIO2_1 has 33 significant bits so `j * PIO2_1` is exact for
// |j| < 2^20 (fdlibm's e_rem_pio2.c constants).
const PIO2_1: f64 = 1.570_796_326_734_125_614_17e+00;
const PIO2_2: f64 = 6.077_100_506_303_965_976_6e-11;
const PIO2_3: f64 = 2.022_266_248_711_166_455_8e-21;
const FRAC_2_PI: f64 = std::f64::consts::FRAC_2_PI;
/// 1.5 · 2^52: adding it rounds to an integer and leaves that integer in the low mantissa bits.
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;

// Cephes sin.c coefficients, highest power first.
const S0: f64 = 1.589_623_015_765_465_680_60e-10;
const S1: f64 = -2.505_074_776_285_780_728_66e-8;
const S2: f64 = 2.755_731_362_138_572_452_13e-6;
const S3: f64 = -1.984_126_982_958_953_859_96e-4;
const S4: f64 = 8.333_333_333_322_118_588_78e-3;
const S5: f64 = -1.666_666_666_666_663_072_95e-1;
const C0: f64 = -1.135_853_652_138_768_173_00e-11;
const C1: f64 = 2.087_570_084_197_473_167_78e-9;
const C2: f64 = -2.755_731_417_929_673_881_12e-7;
const C3: f64 = 2.480_158_728_885_170_453_48e-5;
const C4: f64 = -1.388_888_888_887_305_641_16e-3;
const C5: f64 = 4.166_666_666_666_659_292_18e-2;

/// `a·b + c`, fused (one rounding) when `FMA` is set. Only instantiate `FMA = true`
/// inside functions compiled with the `fma` target feature: elsewhere
/// `f64::mul_add` becomes a slow library call.
#[inline(always)]
pub fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

/// π/2 in two parts for the fused reduction: the double nearest π/2 and the
/// rest (with one rounding, `x − j·PIO2_HI` is exact before it is rounded,
/// so two parts reach what three reach unfused; the neglected third part is
/// below 6.2e-33 · |j|).
const PIO2_HI: f64 = std::f64::consts::FRAC_PI_2;
const PIO2_LO: f64 = 6.123_233_995_736_766_036_43e-17;

/// The polynomial `k0·z⁵ + … + k5` by Estrin's scheme: three pairs at once,
/// then `z²` and `z⁴` (shared by sine and cosine): three dependent steps
/// where Horner's takes five, for one more multiplication. The single-pose
/// paths wait on the result (a tenth less time for a pose with every frame;
/// a single pose's fastest samples did not move); the batch, bound by
/// throughput, pays about 1 %. One scheme everywhere, so a pose is the same
/// to the last bit from every path.
#[inline(always)]
fn poly5<const FMA: bool>(k: [f64; 6], z: f64, z2: f64, z4: f64) -> f64 {
    let q0 = madd::<FMA>(k[0], z, k[1]);
    let q1 = madd::<FMA>(k[2], z, k[3]);
    let q2 = madd::<FMA>(k[4], z, k[5]);
    madd::<FMA>(q0, z4, madd::<FMA>(q1, z2, q2))
}

/// Sine and cosine of one angle (rad) by the polynomial; valid for `|x| ≤ POLY_LIMIT`.
/// Branch-free so that loops over it vectorise; fused multiply-adds when `FMA` (see [`madd`]),
/// and then the reduction by π/2 takes two fused steps (the double nearest π/2, then
/// the rest) instead of three.
#[inline(always)]
pub fn sincos_poly_impl<const FMA: bool>(x: f64) -> (f64, f64) {
    let t = madd::<FMA>(x, FRAC_2_PI, ROUND_MAGIC);
    let quadrant = t.to_bits();
    let j = t - ROUND_MAGIC;
    let r = if FMA {
        madd::<FMA>(-j, PIO2_LO, madd::<FMA>(-j, PIO2_HI, x))
    } else {
        madd::<FMA>(
            -j,
            PIO2_3,
            madd::<FMA>(-j, PIO2_2, madd::<FMA>(-j, PIO2_1, x)),
        )
    };
    let z = r * r;
    let z2 = z * z;
    let z4 = z2 * z2;
    let sp = poly5::<FMA>([S0, S1, S2, S3, S4, S5], z, z2, z4);
    let s = madd::<FMA>(r * z, sp, r);
    let cp = poly5::<FMA>([C0, C1, C2, C3, C4, C5], z, z2, z4);
    let c = madd::<FMA>(z2, cp, madd::<FMA>(-0.5, z, 1.0));
    let swap = quadrant & 1 != 0;
    let (s1, c1) = if swap { (c, s) } else { (s, c) };
    // quadrant 0: ( s,  c)  1: ( c, -s)  2: (-s, -c)  3: (-c,  s)
    let sin_neg = (quadrant & 2) << 62;
    let cos_neg = ((quadrant + 1) & 2) << 62;
    (
        f64::from_bits(s1.to_bits() ^ sin_neg),
        f64::from_bits(c1.to_bits() ^ cos_neg),
    )
}

/// Whether `x` needs the `std` fallback (huge or not finite). One comparison,
/// so that it vectorises: NaN compares false.
#[inline(always)]
#[allow(
    clippy::neg_cmp_op_on_partial_ord,
    reason = "NaN must count as needing std; one comparison keeps it vectorisable"
)]
pub fn needs_std(x: f64) -> bool {
    !(x.abs() <= POLY_LIMIT)
}

/// The polynomial sine and cosine of `L` angles (rad) as whole vectors, and
/// whether any lane [needs `std`](needs_std) (its values are then wrong). No
/// call, so vector state around it stays in registers.
#[inline(always)]
pub(crate) fn sincos_poly_lanes<const FMA: bool, const L: usize>(
    x: &[f64; L],
) -> ([f64; L], [f64; L], bool) {
    let mut s = [0.0; L];
    let mut c = [0.0; L];
    for k in 0..L {
        (s[k], c[k]) = sincos_poly_impl::<FMA>(x[k]);
    }
    (s, c, x.iter().fold(false, |any, &v| any | needs_std(v)))
}

/// Sine and cosine of `L` angles (rad) as whole vectors: the polynomial on every
/// lane, then `std` for the lanes that need it (see [`needs_std`]) only when one does.
#[inline(always)]
pub(crate) fn sincos_lanes<const FMA: bool, const L: usize>(x: &[f64; L]) -> ([f64; L], [f64; L]) {
    // Not through `sincos_poly_lanes`: the frames path took 10 % longer so.
    let mut s = [0.0; L];
    let mut c = [0.0; L];
    for k in 0..L {
        (s[k], c[k]) = sincos_poly_impl::<FMA>(x[k]);
    }
    let any = x.iter().fold(false, |any, &v| any | needs_std(v));
    if any {
        for k in 0..L {
            if needs_std(x[k]) {
                (s[k], c[k]) = x[k].sin_cos();
            }
        }
    }
    (s, c)
}

#[inline(always)]
fn sincos_slice_generic<const FMA: bool>(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    for ((xi, si), ci) in x.iter().zip(sin.iter_mut()).zip(cos.iter_mut()) {
        let (s, c) = sincos_poly_impl::<FMA>(*xi);
        *si = s;
        *ci = c;
    }
    // Rare: huge or non-finite angles take the exact std path.
    for ((xi, si), ci) in x.iter().zip(sin.iter_mut()).zip(cos.iter_mut()) {
        if needs_std(*xi) {
            let (s, c) = xi.sin_cos();
            *si = s;
            *ci = c;
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn sincos_slice_avx2(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    sincos_slice_generic::<true>(x, sin, cos)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx2,fma")]
fn sincos_slice_avx512(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    sincos_slice_generic::<true>(x, sin, cos)
}

/// Fills `sin[i], cos[i]` with the sine and cosine of `x[i]` (rad) for every `i`
/// up to the shortest of the three slices, on the [best kernel](Kernel::best).
pub fn sincos_slice(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    sincos_slice_with(Kernel::best(), x, sin, cos)
}

/// [`sincos_slice`] on a given kernel (the portable one if the CPU lacks it).
pub fn sincos_slice_with(kernel: Kernel, x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    match kernel.or_portable() {
        Kernel::Portable => sincos_slice_generic::<false>(x, sin, cos),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `or_portable` returned Avx2Fma, so the CPU supports avx2 and fma.
        Kernel::Avx2Fma => unsafe { sincos_slice_avx2(x, sin, cos) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `or_portable` returned Avx512, so the CPU supports every feature enabled.
        Kernel::Avx512 => unsafe { sincos_slice_avx512(x, sin, cos) },
        #[cfg(not(target_arch = "x86_64"))]
        Kernel::Avx2Fma | Kernel::Avx512 => sincos_slice_generic::<false>(x, sin, cos),
    }
}
