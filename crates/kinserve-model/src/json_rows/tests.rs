//! The fast path against the plain parse: the same value bit for bit, or the
//! same error, on random bodies, their random corruptions and the edge cases
//! of JSON's number grammar.

use kinserve_testkit::SplitMix64;
use serde::Deserialize;

use super::{parse_json_rows, parse_json_values, split_rows, split_values};
use crate::json::parse_json;
use crate::requests::Configurations;

/// A batch body (`configurations`) or one with a joint vector (`joints`, as
/// the WebSocket messages have), with other members around the array.
#[derive(Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct Body {
    #[serde(default)]
    configurations: Option<Configurations>,
    #[serde(default)]
    joints: Option<Vec<f64>>,
    #[serde(default)]
    angle_unit: Option<String>,
    #[serde(default)]
    check_limits: Option<bool>,
    #[serde(default)]
    extra: Option<serde_json::Value>,
}

/// One of `items`, chosen by `r`.
fn pick<'a>(r: &mut SplitMix64, items: &[&'a str]) -> &'a str {
    items[r.below(items.len())]
}

/// Parses `bytes` both ways (as a batch body, or as a joint vector body when
/// it names `joints`) and checks they agree; true if both succeeded.
fn agree(bytes: &[u8]) -> bool {
    let fast = if bytes.windows(8).any(|w| w == b"\"joints\"") {
        parse_json_values(bytes, "joints", |b: &mut Body| {
            b.joints.get_or_insert_with(Vec::new)
        })
    } else {
        parse_json_rows(bytes, "configurations", |b: &mut Body| {
            b.configurations.get_or_insert_with(Configurations::default)
        })
    };
    let plain = parse_json::<Body>(bytes);
    let text = String::from_utf8_lossy(bytes);
    match (fast, plain) {
        (Ok(f), Ok(p)) => {
            let bits = |b: &Body| {
                let rows = b.configurations.iter().flat_map(|c| &c.values);
                rows.chain(b.joints.iter().flatten())
                    .map(|x| x.to_bits())
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&f), bits(&p), "values of {text}");
            assert_eq!(f, p, "{text}");
            true
        }
        (Err(f), Err(p)) => {
            assert_eq!(f, p, "errors of {text}");
            false
        }
        (f, p) => panic!("fast {f:?} but plain {p:?} for {text}"),
    }
}

const WS: &[&str] = &["", "", " ", "\n", "\t ", "\r\n  "];

/// A number in one of the spellings clients use (all inside the fast path).
fn number(r: &mut SplitMix64) -> String {
    let x = match r.below(3) {
        0 => (r.next_u64() as f64 / u64::MAX as f64 - 0.5) * 20.0,
        1 => f64::from_bits(r.next_u64()),
        _ => (r.next_u64() % 2000) as f64 - 1000.0,
    };
    let x = if x.is_finite() { x } else { 0.5 };
    match r.below(9) {
        0 => format!("{x}"),
        1 => format!("{x:e}"),
        2 => format!("{x:E}"),
        3 => format!("{x:.3}"),
        4 => serde_json::to_string(&x).unwrap_or_default(),
        5 => format!("{}", r.next_u64() as i64),
        6 => format!("{}", r.next_u64()),
        7 => pick(
            r,
            &[
                "-0", "0", "-0.0", "0e0", "1E+2", "1e-0002", "-12e3", "4.9e-324", "1e-400",
            ],
        )
        .to_string(),
        _ => format!("{x:.17e}"),
    }
}

/// An array of numbers.
fn row(r: &mut SplitMix64) -> String {
    let mut s = "[".to_string();
    for j in 0..r.below(9) {
        if j > 0 {
            s += &format!("{},{}", pick(r, WS), pick(r, WS));
        }
        s += &number(r);
    }
    s + pick(r, WS) + "]"
}

fn rows(r: &mut SplitMix64) -> String {
    let mut s = format!("[{}", pick(r, WS));
    for i in 0..r.below(7) {
        if i > 0 {
            s += &format!("{},{}", pick(r, WS), pick(r, WS));
        }
        s += &row(r);
    }
    s + pick(r, WS) + "]"
}

/// A valid body: the members in random order, tricky strings and nesting
/// around the array.
fn body(r: &mut SplitMix64) -> String {
    body_with(r, "configurations", rows)
}

/// A valid body with `key` holding what `array` writes, members as [`body`]'s.
fn body_with(r: &mut SplitMix64, key: &str, array: fn(&mut SplitMix64) -> String) -> String {
    let mut members = vec![format!(
        "\"{key}\"{}:{}{}",
        pick(r, WS),
        pick(r, WS),
        array(r)
    )];
    if r.below(2) == 0 {
        let unit = pick(
            r,
            &["\"rad\"", "\"deg\"", "\"r\\u0061d\"", "\"a\\\"],}{\\\\\""],
        );
        members.push(format!("\"angle_unit\":{unit}"));
    }
    if r.below(2) == 0 {
        members.push(format!("\"check_limits\":{}", pick(r, &["true", "false"])));
    }
    if r.below(2) == 0 {
        let extra = pick(
            r,
            &[
                "{\"a\":[1,{\"b\":\"]}\\\"\"}],\"configurations\":[[1]]}",
                "[[0.5],[],\"x,\"]",
                "null",
                "-1.5e3",
                "\"\\\\\"",
            ],
        );
        members.push(format!("\"extra\":{}{extra}", pick(r, WS)));
    }
    let n = members.len();
    for i in 0..n {
        members.swap(i, i + r.below(n - i));
    }
    format!(
        "{}{{{}}}{}",
        pick(r, WS),
        members.join(&format!("{},{}", pick(r, WS), pick(r, WS))),
        pick(r, WS)
    )
}

#[test]
fn random_bodies_read_the_same_and_take_the_fast_path() {
    let mut r = SplitMix64(7);
    for _ in 0..5000 {
        let b = body(&mut r);
        assert!(
            split_rows(b.as_bytes(), "configurations").is_some(),
            "not taken: {b}"
        );
        assert!(agree(b.as_bytes()), "refused: {b}");
        let b = body_with(&mut r, "joints", row);
        assert!(
            split_values(b.as_bytes(), "joints").is_some(),
            "not taken: {b}"
        );
        assert!(agree(b.as_bytes()), "refused: {b}");
    }
}

#[test]
fn corrupted_bodies_give_the_same_value_or_the_same_error() {
    const BYTES: &[u8] = b"\",][}{0-.eE+\\a 1:n";
    let mut r = SplitMix64(11);
    let (mut ok, mut err) = (0, 0);
    for n in 0..40_000 {
        let mut b = if n % 2 == 0 {
            body(&mut r)
        } else {
            body_with(&mut r, "joints", row)
        }
        .into_bytes();
        for _ in 0..1 + r.below(2) {
            let at = r.below(b.len());
            let c = BYTES[r.below(BYTES.len())];
            match r.below(3) {
                0 => {
                    b.remove(at);
                }
                1 => b.insert(at, c),
                _ => b[at] = c,
            }
        }
        if agree(&b) { ok += 1 } else { err += 1 }
    }
    // Both outcomes occur, so both branches of `agree` were exercised.
    assert!(ok > 1000 && err > 1000, "ok {ok}, err {err}");
}

#[test]
fn edge_numbers_read_as_serde_reads_them() {
    let numbers = [
        "-0",
        "0",
        "-0.0",
        "0.0",
        "1e-400",
        "-1e-400",
        "4.9e-324",
        "2.4e-324",
        "2.2250738585072011e-308",
        "1.7976931348623157e308",
        "1.7976931348623159e308",
        "1e308",
        "1e309",
        "-1e309",
        "18446744073709551615",
        "18446744073709551616",
        "-9223372036854775808",
        "-9223372036854775809",
        "123456789012345678901234567890",
        "0.1e99999",
        "1e00005",
        "1e9999",
        "0e9999",
        "01",
        "-01",
        "1.",
        ".5",
        "+1",
        "1e",
        "1e+",
        "--1",
        "-",
        "NaN",
        "Infinity",
        "-Infinity",
        "1E+2",
        "1e-0002",
        "0x10",
        "1_000",
        "1.5.5",
        "9007199254740993",
        "0.30000000000000004",
        "1e-7",
        "true",
        "\"1\"",
        "null",
    ];
    for n in numbers {
        for row in [format!("[{n}]"), format!("[1,{n},2]"), format!("[[{n}]]")] {
            agree(format!("{{\"configurations\":[{row}]}}").as_bytes());
            agree(format!("{{\"configurations\":{row}}}").as_bytes());
            agree(format!("{{\"joints\":{row}}}").as_bytes());
        }
    }
}

#[test]
fn what_the_fast_path_leaves_to_the_plain_parse() {
    let none = |b: &str| split_rows(b.as_bytes(), "configurations").is_none();
    // Absent, escaped key, not an array of arrays, exponent of five digits,
    // overflow, a top-level array.
    assert!(none(r#"{"joints":[[1]]}"#));
    assert!(none(r#"{"configur\u0061tions":[[1]]}"#));
    assert!(none(r#"{"configurations":[1,2]}"#));
    assert!(none(r#"{"configurations":[[1e00005]]}"#));
    assert!(none(r#"{"configurations":[[1e999]]}"#));
    assert!(none(r#"[{"configurations":[[1]]}]"#));
    // A joint vector: an array of numbers, nothing else.
    let no_values = |b: &str| split_values(b.as_bytes(), "joints").is_none();
    assert!(no_values(r#"{"joints":[[1]]}"#));
    assert!(no_values(r#"{"joints":1}"#));
    assert!(no_values(r#"{"joints":null}"#));
    assert!(no_values(r#"{"joints":[1,"2"]}"#));
    let (rest, values) =
        split_values(br#"{"id":"[","joints": [1, -0, 2.5e-3]}"#, "joints").unwrap_or_default();
    assert_eq!(rest, br#"{"id":"[","joints": []}"#);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&values), bits(&[1.0, -0.0, 2.5e-3]));
    // Taken: the array is replaced by `[]`, the rest kept byte for byte.
    let (rest, rows) = split_rows(
        br#" { "a" : "x\"]" , "configurations" : [ [1, -2.5e-3] , [] ] , "b":0}"#,
        "configurations",
    )
    .unwrap_or_default();
    assert_eq!(rest, br#" { "a" : "x\"]" , "configurations" : [] , "b":0}"#);
    assert_eq!(rows.values, [1.0, -2.5e-3]);
    assert_eq!(rows.lens, [2, 0]);
}

#[test]
fn digits_stop_at_the_first_non_digit_eight_at_a_time_or_one_by_one() {
    // Every byte value at every offset of runs of digits of several lengths
    // (shorter and longer than the two words the fraction is read in): where
    // the run stops, and the run read as an integer after a value already
    // read, by both readers.
    for len in [7, 10, 16, 17, 20, 26] {
        let run = &b"31415926535897932384626433"[..len];
        for at in 0..len {
            for c in 0..=255u8 {
                let mut b = run.to_vec();
                b[at] = c;
                let end = if c.is_ascii_digit() { len } else { at };
                let value = b[..end].iter().fold(7u64, |v, d| {
                    v.wrapping_mul(10).wrapping_add(u64::from(d - b'0'))
                });
                let want = (value, end);
                assert_eq!(super::digits(&b, 0, 7), want, "byte {c} at {at} of {len}");
                assert_eq!(
                    super::fraction_digits(&b, 0, 7),
                    want,
                    "fraction: byte {c} at {at} of {len}"
                );
            }
        }
    }
}
