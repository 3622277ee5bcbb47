//! A fast path for JSON bodies that carry many joint configurations (or
//! poses) under one top-level key: `{"configurations": [[…], …], …}`, or one
//! joint vector: `{"joints": […], …}` ([`parse_json_values`]).
//!
//! serde_json reads a number through its general parser (correctly rounded,
//! with `float_roundtrip`), then hands it to a visitor: on a 10,000-row batch
//! that was about 40 % of the server's time for the request. Here the array
//! of arrays is read by a strict scanner of JSON's number grammar into
//! [`Configurations`] (each number correctly rounded: its digits become an
//! integer as they are scanned and [`decimal`] converts that integer and its
//! power of ten by Clinger's fast path or fast_float's Eisel–Lemire
//! algorithm, `fast-float2` the rare rest; so the value is the same bit for
//! bit as serde_json's with `float_roundtrip`),
//! and the rest of the body — with `[]` in place of the array — is parsed
//! by [`parse_json`] as before, then the rows are put in.
//!
//! Whatever the fast path does not take on (the key absent, written with an
//! escape, or twice; a row that is not an array of plain numbers; a number
//! whose exponent has more than four digits or which overflows), and any
//! error at all, falls back to [`parse_json`] on the original bytes, so
//! errors and accepted bodies are exactly those of the plain parse. Why the
//! two agree is argued at [`split_rows`]; tests compare them on random bodies.
//!
//! Depends on the json and requests modules and on `fast-float2` only
//! (and its own [`decimal`] conversion).

use serde::de::DeserializeOwned;

use crate::error::Result;
use crate::json::parse_json;
use crate::requests::Configurations;

mod decimal;

/// [`parse_json`] of a JSON object whose top-level `key` holds an array of
/// arrays of numbers, which `rows` says where to put: the same value and the
/// same errors, with the array read by the fast scanner (see the module
/// documentation).
///
/// ```
/// use kinserve_model::{Configurations, parse_json_rows};
/// #[derive(serde::Deserialize)]
/// struct Batch { configurations: Configurations, angle_unit: String }
/// let body = br#"{"configurations": [[0.5, -1e-3], [2, 0]], "angle_unit": "rad"}"#;
/// let b: Batch = parse_json_rows(body, "configurations", |b: &mut Batch| &mut b.configurations)?;
/// assert_eq!(b.configurations.values, [0.5, -1e-3, 2.0, 0.0]);
/// assert_eq!(b.configurations.lens, [2, 2]);
/// assert_eq!(b.angle_unit, "rad");
/// # Ok::<(), kinserve_model::ModelError>(())
/// ```
pub fn parse_json_rows<T: DeserializeOwned>(
    bytes: &[u8],
    key: &str,
    rows: impl FnOnce(&mut T) -> &mut Configurations,
) -> Result<T> {
    parse_split(bytes, split_rows(bytes, key), rows)
}

/// `bytes` parsed from `split` (the body with the array replaced by `[]`
/// and what the fast scanner read of it), which `put` says where to put;
/// the plain parse of `bytes` when there is no split or the rebuilt body
/// does not parse (that parse gives the error, with its field path).
fn parse_split<T: DeserializeOwned, V>(
    bytes: &[u8],
    split: Option<(Vec<u8>, V)>,
    put: impl FnOnce(&mut T) -> &mut V,
) -> Result<T> {
    if let Some((rest, found)) = split
        && let Ok(mut value) = serde_json::from_slice::<T>(&rest)
    {
        *put(&mut value) = found;
        return Ok(value);
    }
    parse_json(bytes)
}

/// The body with the array under top-level `key` replaced by `[]`, and that
/// array read; `None` when the fast path does not apply.
///
/// Why a body the caller then parses successfully means the original parses
/// to the same value with these rows: the bytes before and after the array
/// are kept as they are. The scan before it tracks strings (with escapes)
/// and brackets as JSON does, so if the rebuilt body parses, the scan's view
/// of that prefix was JSON's, and `[]` stood where the array stood: the value
/// of the top-level `key` (a second `key` would be a duplicate field, an
/// error, and back to the plain parse). The array itself is accepted only
/// when it is a valid JSON array of arrays of numbers, each number read to
/// the value serde_json gives it.
pub fn split_rows(bytes: &[u8], key: &str) -> Option<(Vec<u8>, Configurations)> {
    let start = find_value(bytes, key.as_bytes())?;
    let (rows, end) = read_rows(bytes, start)?;
    Some((without(bytes, start..end)?, rows))
}

/// [`parse_json_rows`] for a top-level `key` holding one array of numbers
/// (a joint vector), put where `values` says: the same value and the same
/// errors as [`parse_json`], each number read by the fast scanner (see
/// [`split_values`]).
///
/// ```
/// use kinserve_model::parse_json_values;
/// #[derive(serde::Deserialize)]
/// struct Fk { joints: Vec<f64>, angle_unit: String }
/// let body = br#"{"joints": [0.5, -1e-3, 2], "angle_unit": "rad"}"#;
/// let fk: Fk = parse_json_values(body, "joints", |f: &mut Fk| &mut f.joints)?;
/// assert_eq!(fk.joints, [0.5, -1e-3, 2.0]);
/// assert_eq!(fk.angle_unit, "rad");
/// # Ok::<(), kinserve_model::ModelError>(())
/// ```
pub fn parse_json_values<T: DeserializeOwned>(
    bytes: &[u8],
    key: &str,
    values: impl FnOnce(&mut T) -> &mut Vec<f64>,
) -> Result<T> {
    parse_split(bytes, split_values(bytes, key), values)
}

/// [`split_rows`] for an array of numbers: the body with the array under
/// top-level `key` replaced by `[]`, and its numbers; `None` when the fast
/// path does not apply. The argument of [`split_rows`] holds as it is.
pub fn split_values(bytes: &[u8], key: &str) -> Option<(Vec<u8>, Vec<f64>)> {
    let start = find_value(bytes, key.as_bytes())?;
    // Room for a 7-joint arm without regrowing.
    let mut values = Vec::with_capacity(8);
    let (_, end) = read_array(bytes, start, |at| {
        let (x, after) = read_number(bytes, at)?;
        values.push(x);
        Some(after)
    })?;
    Some((without(bytes, start..end)?, values))
}

/// `bytes` with `range` replaced by `[]`.
fn without(bytes: &[u8], range: std::ops::Range<usize>) -> Option<Vec<u8>> {
    let mut rest = Vec::with_capacity(bytes.len() - range.len() + 2);
    rest.extend_from_slice(bytes.get(..range.start)?);
    rest.extend_from_slice(b"[]");
    rest.extend_from_slice(bytes.get(range.end..)?);
    Some(rest)
}

/// Offset of the value of the first top-level member named `key` (written
/// without escapes); `None` if there is none or the scan meets something it
/// does not expect.
fn find_value(b: &[u8], key: &[u8]) -> Option<usize> {
    let mut i = skip_ws(b, 0);
    if b.get(i) != Some(&b'{') {
        return None;
    }
    i += 1;
    loop {
        i = skip_ws(b, i);
        let (name, after) = string_at(b, i)?;
        i = skip_ws(b, after);
        if b.get(i) != Some(&b':') {
            return None;
        }
        i = skip_ws(b, i + 1);
        if name == key {
            return Some(i);
        }
        i = skip_value(b, i)?;
        i = skip_ws(b, i);
        match b.get(i) {
            Some(b',') => i += 1,
            _ => return None,
        }
    }
}

/// The raw bytes of the string starting at `i` (between its quotes, escapes
/// left as written) and the offset after its closing quote.
fn string_at(b: &[u8], i: usize) -> Option<(&[u8], usize)> {
    if b.get(i) != Some(&b'"') {
        return None;
    }
    let mut j = i + 1;
    loop {
        match b.get(j)? {
            b'"' => return Some((b.get(i + 1..j)?, j + 1)),
            b'\\' => j += 2,
            _ => j += 1,
        }
    }
}

/// The offset after the value starting at `i`: strings and brackets are
/// tracked, anything else (numbers, literals) runs to the next delimiter.
fn skip_value(b: &[u8], mut i: usize) -> Option<usize> {
    let mut depth = 0usize;
    loop {
        match *b.get(i)? {
            b'"' => i = string_at(b, i)?.1,
            b'[' | b'{' => {
                depth += 1;
                i += 1;
            }
            b']' | b'}' => {
                depth = depth.checked_sub(1)?;
                i += 1;
            }
            _ => i += 1,
        }
        if depth == 0 && !b.get(i).is_some_and(|&c| is_scalar_byte(c)) {
            return Some(i);
        }
    }
}

/// Bytes that may continue a number or a literal (`true`, `false`, `null`).
fn is_scalar_byte(c: u8) -> bool {
    c.is_ascii_alphanumeric() || matches!(c, b'-' | b'+' | b'.')
}

/// Offset of the first byte at or after `i` that is not JSON whitespace.
fn skip_ws(b: &[u8], mut i: usize) -> usize {
    while matches!(b.get(i), Some(b' ' | b'\t' | b'\n' | b'\r')) {
        i += 1;
    }
    i
}

/// The array of arrays of numbers starting at `i`, and the offset after it.
fn read_rows(b: &[u8], i: usize) -> Option<(Configurations, usize)> {
    // About 20 bytes per number (17 digits, sign, point, comma), capped so
    // that a short array in front of a long string reserves little: a hint,
    // not a bound.
    let hint = (b.len().saturating_sub(i) / 20).min(1 << 16);
    let mut out = Configurations {
        values: Vec::with_capacity(hint),
        lens: Vec::with_capacity(hint / 6),
    };
    let (_, end) = read_array(b, i, |row| {
        let (len, after) = read_array(b, row, |at| {
            let (x, after) = read_number(b, at)?;
            out.values.push(x);
            Some(after)
        })?;
        out.lens.push(len);
        Some(after)
    })?;
    Some((out, end))
}

/// The JSON array starting at `i`, each element read by `item` (given the
/// element's first byte, it returns the offset after the element): the
/// number of elements and the offset after the array.
fn read_array(
    b: &[u8],
    i: usize,
    mut item: impl FnMut(usize) -> Option<usize>,
) -> Option<(u32, usize)> {
    if b.get(i) != Some(&b'[') {
        return None;
    }
    let mut n = 0u32;
    let mut i = skip_ws(b, i + 1);
    if b.get(i) == Some(&b']') {
        return Some((0, i + 1));
    }
    loop {
        i = skip_ws(b, item(i)?);
        n = n.checked_add(1)?;
        match b.get(i)? {
            b',' => i = skip_ws(b, i + 1),
            b']' => return Some((n, i + 1)),
            _ => return None,
        }
    }
}

/// The JSON number starting at `i` and the offset after it; `None` if it is
/// not one by JSON's grammar (`-? (0 | [1-9][0-9]*) (. [0-9]+)? ([eE] [+-]? [0-9]+)?`),
/// its exponent has more than four digits, or it is beyond `f64`'s range.
///
/// The digits are read to an integer as they are scanned (eight at a time);
/// up to 19 digits and a power of ten within [`decimal`]'s range, that
/// integer and the power give the correctly rounded value directly; anything
/// else is converted by `fast-float2` from the bytes.
fn read_number(b: &[u8], start: usize) -> Option<(f64, usize)> {
    let mut i = start;
    // Branch-free: the sign varies from number to number.
    let negative = b.get(i) == Some(&b'-');
    i += usize::from(negative);
    let int_start = i;
    let (mut mantissa, int_end) = digits(b, i, 0);
    // At least one digit, and no leading zero (`0` alone is one digit).
    if int_end == int_start || (b.get(int_start) == Some(&b'0') && int_end > int_start + 1) {
        return None;
    }
    i = int_end;
    let mut fraction = 0;
    if b.get(i) == Some(&b'.') {
        let (m, after) = fraction_digits(b, i + 1, mantissa);
        fraction = after - (i + 1);
        if fraction == 0 {
            return None;
        }
        (mantissa, i) = (m, after);
    }
    let mut exponent = 0i32;
    if matches!(b.get(i), Some(b'e' | b'E')) {
        i += 1;
        let minus = b.get(i) == Some(&b'-');
        if matches!(b.get(i), Some(b'+' | b'-')) {
            i += 1;
        }
        let (e, after) = digits(b, i, 0);
        if after == i || after - i > 4 {
            return None;
        }
        // At most four digits: below 10^4, so the cast is exact.
        exponent = if minus { -(e as i32) } else { e as i32 };
        i = after;
    }
    // Up to 19 digits the integer did not wrap (10^19 < 2^64).
    if int_end - int_start + fraction <= 19
        && let Some(x) = decimal::to_f64(mantissa, exponent - fraction as i32, negative)
    {
        return Some((x, i));
    }
    let x: f64 = fast_float2::parse(b.get(start..i)?).ok()?;
    x.is_finite().then_some((x, i))
}

/// The high nibbles of eight bytes.
const HIGH: u64 = 0xF0F0_F0F0_F0F0_F0F0;
/// Eight ASCII zeros.
const ZEROS: u64 = 0x3030_3030_3030_3030;
/// Eight sixes (a digit plus six keeps its high nibble 3).
const SIXES: u64 = 0x0606_0606_0606_0606;
/// 10^n for n digits (0 to 8).
const SCALE: [u64; 9] = [
    1,
    10,
    100,
    1_000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
];

/// The run of ASCII digits at `i`: `value` followed by them as an integer
/// (wrapping: only meaningful up to 19 digits in all) and the offset of the
/// first byte that is not a digit. Eight bytes at a time while eight remain,
/// then one by one.
#[inline(always)]
fn digits(b: &[u8], mut i: usize, mut value: u64) -> (u64, usize) {
    while let Some(Ok(eight)) = b.get(i..i + 8).map(<[u8; 8]>::try_from) {
        let x = u64::from_le_bytes(eight);
        // A byte is a digit when its high nibble is 3 and adding 6 keeps it
        // so. A carry out of a non-digit byte only disturbs the bytes after
        // it, and the first non-digit is what counts.
        let not_digit = ((x & HIGH) ^ ZEROS) | ((x.wrapping_add(SIXES) & HIGH) ^ ZEROS);
        if not_digit != 0 {
            let n = (not_digit.trailing_zeros() / 8) as usize;
            if n > 0 {
                // The n digits moved to the top, zeros (as digit values) below
                // them; a borrow from the bytes beyond them is shifted out.
                let tail = eight_digits(x.wrapping_sub(ZEROS) << (64 - 8 * n));
                value = value.wrapping_mul(SCALE[n]).wrapping_add(tail);
            }
            return (value, i + n);
        }
        value = value
            .wrapping_mul(100_000_000)
            .wrapping_add(eight_digits(x.wrapping_sub(ZEROS)));
        i += 8;
    }
    while let Some(&c @ b'0'..=b'9') = b.get(i) {
        value = value.wrapping_mul(10).wrapping_add(u64::from(c - b'0'));
        i += 1;
    }
    (value, i)
}

/// [`digits`] for the digits after a decimal point, whose count varies from
/// number to number (15 to 17 in a double's shortest spelling): the first
/// sixteen bytes are read as two words without a branch on where the run
/// ends, [`digits`] goes on only after sixteen digits.
#[inline(always)]
fn fraction_digits(b: &[u8], i: usize, value: u64) -> (u64, usize) {
    let Some(Ok(sixteen)) = b.get(i..i + 16).map(<[u8; 16]>::try_from) else {
        return digits(b, i, value);
    };
    let word = |k: usize| {
        let mut w = [0; 8];
        w.copy_from_slice(&sixteen[8 * k..8 * k + 8]);
        let x = u64::from_le_bytes(w);
        let not_digit = ((x & HIGH) ^ ZEROS) | ((x.wrapping_add(SIXES) & HIGH) ^ ZEROS);
        (
            x.wrapping_sub(ZEROS),
            (not_digit.trailing_zeros() / 8) as usize,
        )
    };
    let (x1, n1) = word(0);
    let (x2, n2) = word(1);
    let n2 = if n1 == 8 { n2 } else { 0 };
    // The n digits of a word moved to its top (see `digits`); none: 0.
    let top = |x: u64, n: usize| eight_digits(x.checked_shl(64 - 8 * n as u32).unwrap_or(0));
    let value = value.wrapping_mul(SCALE[n1]).wrapping_add(top(x1, n1));
    let value = value.wrapping_mul(SCALE[n2]).wrapping_add(top(x2, n2));
    if n1 + n2 == 16 {
        return digits(b, i + 16, value);
    }
    (value, i + n1 + n2)
}

/// Eight digit values (0–9, the first in the lowest byte) as one integer:
/// pairs, then quadruples, then the two halves (fast_float's
/// `parse_eight_digits_unrolled`).
#[inline(always)]
fn eight_digits(v: u64) -> u64 {
    const MASK: u64 = 0x0000_00FF_0000_00FF;
    const MUL1: u64 = 100 + (1_000_000 << 32);
    const MUL2: u64 = 1 + (10_000 << 32);
    let v = v.wrapping_mul(10).wrapping_add(v >> 8);
    let halves = (v & MASK)
        .wrapping_mul(MUL1)
        .wrapping_add(((v >> 16) & MASK).wrapping_mul(MUL2));
    u64::from(halves.wrapping_shr(32) as u32)
}

#[cfg(test)]
mod tests;
