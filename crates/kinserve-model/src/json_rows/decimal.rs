//! Decimal to `f64`, correctly rounded, for what the numbers in kinserve's
//! bodies almost always are: at most 19 significant digits (an exact `u64`
//! mantissa) times a power of ten in [[`MIN_POWER`], [`MAX_POWER`]].
//!
//! Clinger's fast path when the mantissa and the power of ten are both exact
//! doubles (one rounding); otherwise the Eisel–Lemire algorithm (D. Lemire,
//! "Number Parsing at a Gigabyte per Second", Software: Practice and
//! Experience 51(8), 2021), transcribed from fast-float2 0.2.4
//! (`binary::compute_float`, MIT OR Apache-2.0) with its table of truncated
//! 128-bit powers of five cut to the powers above and computed at compile
//! time from the table's own definition (entries checked against the
//! published ones in the tests). The powers here keep every result a normal
//! double, so the subnormal and infinite branches of the original are not
//! needed. `None` only outside those powers: the caller then converts the
//! bytes with fast-float2 itself.
//!
//! Depends on nothing else in the crate.

/// Smallest power of ten handled here.
pub(super) const MIN_POWER: i32 = -27;
/// Largest power of ten handled here (5^27 is the largest power of five in a `u64`).
pub(super) const MAX_POWER: i32 = 27;

/// `mantissa · 10^power`, correctly rounded (ties to even), negated when
/// `negative`; `None` when `power` is outside [`MIN_POWER`]..=[`MAX_POWER`].
#[inline(always)]
pub(super) fn to_f64(mantissa: u64, power: i32, negative: bool) -> Option<f64> {
    let x = if mantissa <= 1 << 53 && (-22..=22).contains(&power) {
        // Both operands exact, so one correctly rounded operation.
        let m = mantissa as f64;
        if power < 0 {
            m / POW10[power.unsigned_abs() as usize]
        } else {
            m * POW10[power as usize]
        }
    } else {
        eisel_lemire(mantissa, power)?
    };
    // The sign bit set without a branch (x is not negative).
    Some(f64::from_bits(x.to_bits() | u64::from(negative) << 63))
}

/// 10^0 … 10^22, every one an exact `f64`.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Explicit mantissa bits of `f64`.
const MANTISSA_BITS: i32 = 52;

/// fast-float2's `compute_float::<f64>(q, w)` for `q` in [`MIN_POWER`]..=[`MAX_POWER`].
fn eisel_lemire(mut w: u64, q: i32) -> Option<f64> {
    if !(MIN_POWER..=MAX_POWER).contains(&q) {
        return None;
    }
    if w == 0 {
        return Some(0.0);
    }
    let lz = w.leading_zeros() as i32;
    w <<= lz;
    // The original gives up when `lo` is all ones and q is outside
    // [-27, 55]; every q here is inside, so the product is always decisive.
    let (lo, hi) = product_approx(q, w);
    let upperbit = (hi >> 63) as i32;
    let shift = upperbit + 64 - MANTISSA_BITS - 3;
    let mut mantissa = hi >> shift;
    // 1023: f64's exponent bias (`-MINIMUM_EXPONENT`).
    let mut power2 = power(q) + upperbit - lz + 1023;
    if power2 <= 0 {
        return None; // subnormal: not reached for these powers (≥ 1e-27)
    }
    // A tie can only be exact for these powers of ten (round to even).
    if lo <= 1 && (-4..=23).contains(&q) && mantissa & 3 == 1 && (mantissa << shift) == hi {
        mantissa &= !1;
    }
    mantissa += mantissa & 1;
    mantissa >>= 1;
    if mantissa >= 2 << MANTISSA_BITS {
        mantissa = 1 << MANTISSA_BITS;
        power2 += 1;
    }
    mantissa &= !(1 << MANTISSA_BITS);
    if power2 >= 0x7FF {
        return None; // infinite: not reached for these powers (< 2e46)
    }
    Some(f64::from_bits(mantissa | (power2 as u64) << MANTISSA_BITS))
}

/// `floor(log2(10^q)) + 63`, by the original's fixed-point formula.
fn power(q: i32) -> i32 {
    (q.wrapping_mul(152_170 + 65_536) >> 16) + 63
}

/// The high 128 bits of `w · 5^q` (truncated table entry), refined by the
/// entry's low word only when the first product's bits below the mantissa
/// and its round bit are all ones (`precision` 55 in the original).
fn product_approx(q: i32, w: u64) -> (u64, u64) {
    const MASK: u64 = u64::MAX >> (MANTISSA_BITS + 3);
    let (hi5, lo5) = POW5[(q - MIN_POWER) as usize];
    let (mut first_lo, mut first_hi) = full_mul(w, hi5);
    if first_hi & MASK == MASK {
        let (_, second_hi) = full_mul(w, lo5);
        first_lo = first_lo.wrapping_add(second_hi);
        if second_hi > first_lo {
            first_hi += 1;
        }
    }
    (first_lo, first_hi)
}

/// `a · b` as (low, high) words.
fn full_mul(a: u64, b: u64) -> (u64, u64) {
    let r = u128::from(a) * u128::from(b);
    (r as u64, (r >> 64) as u64)
}

/// Entries of fast_float's `power_of_five_128` for q = [`MIN_POWER`]..=[`MAX_POWER`],
/// as (high, low) words.
pub(super) const POW5: [(u64, u64); (MAX_POWER - MIN_POWER + 1) as usize] = pow5_table();

/// The table's definition: for q ≥ 0, 5^q shifted up until bit 127 is set;
/// for q < 0 (q ≥ -27), `floor(2^(z + 127) / 5^-q) + 1` with `2^z` the
/// smallest power of two above `5^-q` (already in [2^127, 2^128)).
const fn pow5_table() -> [(u64, u64); (MAX_POWER - MIN_POWER + 1) as usize] {
    let mut table = [(0, 0); (MAX_POWER - MIN_POWER + 1) as usize];
    let mut i = 0;
    while i < table.len() {
        let q = MIN_POWER + i as i32;
        let c: u128 = if q >= 0 {
            let p = pow5(q as u32) as u128;
            p << p.leading_zeros()
        } else {
            let p = pow5(q.unsigned_abs());
            let z = 64 - p.leading_zeros();
            div_pow2(z + 127, p) + 1
        };
        table[i] = ((c >> 64) as u64, c as u64);
        i += 1;
    }
    table
}

/// 5^k (k ≤ 27).
const fn pow5(k: u32) -> u64 {
    let mut p = 1u64;
    let mut i = 0;
    while i < k {
        p *= 5;
        i += 1;
    }
    p
}

/// `floor(2^b / d)` for a quotient below 2^128, one bit at a time.
const fn div_pow2(b: u32, d: u64) -> u128 {
    let d = d as u128;
    let (mut rem, mut quo) = (0u128, 0u128);
    let mut i = b as i64;
    while i >= 0 {
        rem = (rem << 1) | (i == b as i64) as u128;
        quo <<= 1;
        if rem >= d {
            rem -= d;
            quo |= 1;
        }
        i -= 1;
    }
    quo
}

#[cfg(test)]
mod tests {
    use kinserve_testkit::SplitMix64;

    use super::{MAX_POWER, MIN_POWER, POW5, to_f64};

    /// Entries of fast_float's published `power_of_five_128` (as fast-float2
    /// 0.2.4's `table.rs` prints them).
    #[test]
    fn the_table_is_fast_floats() {
        let published = [
            (-27, 0x9e74_d1b7_91e0_7e48, 0x775e_a264_cf55_347e),
            (-22, 0xf1c9_0080_baf7_2cb1, 0x5324_c68b_12dd_6339),
            (-1, 0xcccc_cccc_cccc_cccc, 0xcccc_cccc_cccc_cccd),
            (0, 0x8000_0000_0000_0000, 0),
            (1, 0xa000_0000_0000_0000, 0),
            (22, 0x8786_7832_6eac_9000, 0),
            (27, 0xcecb_8f27_f420_0f3a, 0),
        ];
        for (q, hi, lo) in published {
            assert_eq!(POW5[(q - MIN_POWER) as usize], (hi, lo), "5^{q}");
        }
    }

    /// A mantissa of 1 to 64 bits (below 10^19), as clients' numbers have.
    fn mantissa(r: &mut SplitMix64) -> u64 {
        let bits = 1 + r.below(64);
        (r.next_u64() >> (64 - bits)) % 10_000_000_000_000_000_000
    }

    #[test]
    fn agrees_with_fast_float_bit_for_bit() {
        let mut r = SplitMix64(0x5eed_dec1);
        for n in 0..400_000 {
            let m = match n % 4 {
                // Shortest spellings of doubles in [-4, 4): 15 to 17 digits.
                0 => 10_000_000_000_000_000 + r.next_u64() % 90_000_000_000_000_000,
                1 => 1_000_000_000_000_000 + r.next_u64() % 9_000_000_000_000_000,
                _ => mantissa(&mut r),
            };
            let q = MIN_POWER + r.below((MAX_POWER - MIN_POWER + 1) as usize) as i32;
            let negative = r.below(2) == 0;
            let text = format!("{}{m}e{q}", if negative { "-" } else { "" });
            let want: f64 = fast_float2::parse(&text).unwrap_or(f64::NAN);
            let got = to_f64(m, q, negative).map(f64::to_bits);
            assert_eq!(got, Some(want.to_bits()), "{text}");
        }
        assert_eq!(to_f64(1, MIN_POWER - 1, false), None);
        assert_eq!(to_f64(1, MAX_POWER + 1, false), None);
    }

    /// Exact midpoints between two doubles, written with up to 19 digits, go
    /// to the even one; one unit in the last digit off goes to the nearer.
    #[test]
    fn ties_round_to_even() {
        let mut r = SplitMix64(0x71e5);
        for _ in 0..50_000 {
            let m = (1u64 << 52) + (r.next_u64() >> 12);
            let even = if m.is_multiple_of(2) { m } else { m + 1 };
            // (2m + 1)·2^s, halfway between m·2^(s+1) and (m + 1)·2^(s+1).
            let s = r.below(10) as i32;
            let tie = (2 * m + 1) << s;
            let scale = 2f64.powi(s + 1);
            assert_eq!(to_f64(tie, 0, false), Some(even as f64 * scale), "{tie}");
            assert_eq!(
                to_f64(tie - 1, 0, false),
                Some(m as f64 * scale),
                "{tie} - 1"
            );
            assert_eq!(
                to_f64(tie + 1, 0, false),
                Some((m + 1) as f64 * scale),
                "{tie} + 1"
            );
            // (2m + 1)·2^-n = (2m + 1)·5^n / 10^n, n ≤ 4 to stay below 2^64.
            let n = 1 + r.below(4) as i32;
            let tie = (2 * m + 1) * 5u64.pow(n as u32);
            let scale = 2f64.powi(1 - n);
            assert_eq!(
                to_f64(tie, -n, false),
                Some(even as f64 * scale),
                "{tie}e-{n}"
            );
            assert_eq!(
                to_f64(tie - 1, -n, false),
                Some(m as f64 * scale),
                "{tie}e-{n} - 1"
            );
            assert_eq!(
                to_f64(tie + 1, -n, true),
                Some(-((m + 1) as f64) * scale),
                "-{tie}e-{n} + 1"
            );
        }
    }
}
