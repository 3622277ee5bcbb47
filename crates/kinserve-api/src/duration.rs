//! Durations on the command line (`250ms`, `10s`, `2m`, `1h`, or a plain
//! number of seconds): one parser for the server's options and its tools'
//! (`kinserve-load`). Depends on nothing.

use std::time::Duration;

/// Parses `250ms`, `10s`, `2m`, or a plain number of seconds.
pub fn parse_duration(s: &str) -> Result<Duration, String> {
    let s = s.trim();
    let (num, unit) = match s.find(|c: char| c.is_ascii_alphabetic()) {
        Some(i) => (&s[..i], &s[i..]),
        None => (s, "s"),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("not a duration: '{s}'"))?;
    if !v.is_finite() || v < 0.0 {
        return Err(format!("not a duration: '{s}'"));
    }
    let secs = match unit {
        "ms" => v / 1000.0,
        "s" => v,
        "m" | "min" => v * 60.0,
        "h" => v * 3600.0,
        _ => return Err(format!("unknown unit in '{s}' (use ms, s, m or h)")),
    };
    Ok(Duration::from_secs_f64(secs))
}
