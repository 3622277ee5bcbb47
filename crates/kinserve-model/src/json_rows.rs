//! A fast path for JSON bodies that carry many joint configurations (or
//! poses) under one top-level key: `{"configurations": [[…], …], …}`.
//!
//! serde_json reads a number through its general parser (correctly rounded,
//! with `float_roundtrip`), then hands it to a visitor: on a 10,000-row batch
//! that was about 40 % of the server's time for the request. Here the array
//! of arrays is read by a strict scanner of JSON's number grammar into
//! [`Configurations`] (each number converted by `fast-float2`, a port of
//! fast_float's correctly rounded Eisel–Lemire conversion, so the value is the
//! same bit for bit as serde_json's with `float_roundtrip`),
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
//! Depends on the json and requests modules and on `fast-float2` only.

use serde::de::DeserializeOwned;

use crate::error::Result;
use crate::json::parse_json;
use crate::requests::Configurations;

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
    // The rebuilt body by serde alone: a failure here goes to the plain
    // parse of the original, which gives the error (with its field path).
    if let Some((rest, found)) = split_rows(bytes, key)
        && let Ok(mut value) = serde_json::from_slice::<T>(&rest)
    {
        *rows(&mut value) = found;
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
    let mut rest = Vec::with_capacity(bytes.len() - (end - start) + 2);
    rest.extend_from_slice(bytes.get(..start)?);
    rest.extend_from_slice(b"[]");
    rest.extend_from_slice(bytes.get(end..)?);
    Some((rest, rows))
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
fn read_number(b: &[u8], start: usize) -> Option<(f64, usize)> {
    let mut i = start;
    if b.get(i) == Some(&b'-') {
        i += 1;
    }
    match b.get(i)? {
        b'0' => i += 1,
        b'1'..=b'9' => i = digits(b, i + 1),
        _ => return None,
    }
    if b.get(i) == Some(&b'.') {
        let after = digits(b, i + 1);
        if after == i + 1 {
            return None;
        }
        i = after;
    }
    if matches!(b.get(i), Some(b'e' | b'E')) {
        i += 1;
        if matches!(b.get(i), Some(b'+' | b'-')) {
            i += 1;
        }
        let after = digits(b, i);
        if after == i || after - i > 4 {
            return None;
        }
        i = after;
    }
    let x: f64 = fast_float2::parse(b.get(start..i)?).ok()?;
    x.is_finite().then_some((x, i))
}

/// Offset of the first byte at or after `i` that is not an ASCII digit:
/// eight bytes at a time while eight remain, then one by one.
fn digits(b: &[u8], mut i: usize) -> usize {
    const HIGH: u64 = 0xF0F0_F0F0_F0F0_F0F0;
    const ZEROS: u64 = 0x3030_3030_3030_3030;
    const SIXES: u64 = 0x0606_0606_0606_0606;
    while let Some(Ok(eight)) = b.get(i..i + 8).map(<[u8; 8]>::try_from) {
        let x = u64::from_le_bytes(eight);
        // A byte is a digit when its high nibble is 3 and adding 6 keeps it
        // so. A carry out of a non-digit byte only disturbs the bytes after
        // it, and the first non-digit is what counts.
        let not_digit = ((x & HIGH) ^ ZEROS) | ((x.wrapping_add(SIXES) & HIGH) ^ ZEROS);
        if not_digit != 0 {
            return i + (not_digit.trailing_zeros() / 8) as usize;
        }
        i += 8;
    }
    while matches!(b.get(i), Some(b'0'..=b'9')) {
        i += 1;
    }
    i
}

#[cfg(test)]
mod tests;
