//! Durations on the command line (`250ms`, `10s`, `2m`, `1h`, or a plain
//! number of seconds such as `1.5` or `1e3`), range-checked: one parser for
//! the server's options and its tools' (`kinserve-load`). Depends on nothing.

use std::time::Duration;

/// Longest duration an option takes ([`parse_duration`]): one day. Longer
/// ones are refused at start-up, before they reach any deadline arithmetic.
pub const MAX_DURATION: Duration = Duration::from_secs(24 * 60 * 60);

/// Longest IK time limit (`serve --ik-time-limit`, `ik --time-limit`): one minute.
pub const MAX_IK_TIME_LIMIT: Duration = Duration::from_secs(60);

/// Parses `250ms`, `10s`, `2m`, `1h`, or a plain number of seconds (`1.5`,
/// `1e3`), at most [`MAX_DURATION`].
pub fn parse_duration(s: &str) -> Result<Duration, String> {
    parse_duration_at_most(s, MAX_DURATION)
}

/// [`parse_duration`] for IK time limits: at most [`MAX_IK_TIME_LIMIT`].
pub fn parse_ik_time_limit(s: &str) -> Result<Duration, String> {
    parse_duration_at_most(s, MAX_IK_TIME_LIMIT)
}

/// A duration (number and optional unit suffix) from zero to `max`.
fn parse_duration_at_most(s: &str, max: Duration) -> Result<Duration, String> {
    let s = s.trim();
    // The unit is the alphabetic suffix, so that `1e3s` is a number and a unit.
    let split = s.trim_end_matches(|c: char| c.is_ascii_alphabetic()).len();
    let (num, unit) = s.split_at(split);
    let unit = if unit.is_empty() { "s" } else { unit };
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
    match Duration::try_from_secs_f64(secs) {
        Ok(d) if d <= max => Ok(d),
        _ => Err(format!("too long: at most {}", show_duration(max))),
    }
}

/// `24h`, `60s`, `250ms`: how a maximum is named in an error.
fn show_duration(d: Duration) -> String {
    let secs = d.as_secs();
    if d.subsec_nanos() != 0 {
        format!("{}ms", d.as_millis())
    } else if secs >= 3600 && secs.is_multiple_of(3600) {
        format!("{}h", secs / 3600)
    } else {
        format!("{secs}s")
    }
}
