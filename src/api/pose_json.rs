//! Poses written as JSON text straight into a byte buffer, for the answers
//! that carry them on the hot paths (REST `fk`, REST batch answers).
//!
//! The bytes are exactly serde_json's compact output of the same shapes
//! ([`crate::api::pose_format`]'s [`AsPose`], [`AsMatrix`], [`AsPosition`],
//! which stay the reference and the path of every other answer): numbers by
//! the same shortest round-trip formatter (`zmij`, which serde_json calls),
//! non-finite numbers as `null`, no spaces. Only the serde machinery between
//! the numbers is left out: a `full` pose costs about half the instructions
//! it costs through serde. Tested byte for byte against serde_json below and
//! through every REST test that reads a pose.
//!
//! Depends on the kinematics crate and [`crate::api::pose_format`] only.
//!
//! [`AsPose`]: crate::api::pose_format::AsPose
//! [`AsMatrix`]: crate::api::pose_format::AsMatrix
//! [`AsPosition`]: crate::api::pose_format::AsPosition

use crate::api::pose_format::{PoseFormat, matrix12};
use crate::kinematics::Transform;

/// Appends `x` as serde_json writes an `f64`: shortest round-trip digits,
/// `null` when not finite.
pub fn number(out: &mut Vec<u8>, x: f64) {
    if x.is_finite() {
        let mut buf = zmij::Buffer::new();
        out.extend_from_slice(buf.format_finite(x).as_bytes());
    } else {
        out.extend_from_slice(b"null");
    }
}

/// Appends `xs` as a JSON array of numbers.
pub fn numbers(out: &mut Vec<u8>, xs: &[f64]) {
    out.push(b'[');
    for (i, &x) in xs.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        number(out, x);
    }
    out.push(b']');
}

/// Appends `t` in `format`: the `Pose` object (`full`), 12 numbers
/// (`matrix`) or `[x, y, z]` (`position`).
pub fn pose(out: &mut Vec<u8>, format: PoseFormat, t: &Transform) {
    match format {
        PoseFormat::Full => full(out, t),
        PoseFormat::Matrix => numbers(out, &matrix12(t)),
        PoseFormat::Position => numbers(out, &t.translation),
    }
}

/// Appends `ts` in `format` as a JSON array.
pub fn poses(out: &mut Vec<u8>, format: PoseFormat, ts: &[Transform]) {
    out.push(b'[');
    items(out, format, ts);
    out.push(b']');
}

/// Appends `ts` in `format`, separated by commas: an array's items, for a
/// caller that wrote its `[` already.
pub fn items(out: &mut Vec<u8>, format: PoseFormat, ts: &[Transform]) {
    for (i, t) in ts.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        pose(out, format, t);
    }
}

/// The `Pose` object: `matrix` (4 rows), `position`, `quaternion`
/// (`w`, `x`, `y`, `z`), `rpy`, in the order the struct declares them.
fn full(out: &mut Vec<u8>, t: &Transform) {
    out.extend_from_slice(b"{\"matrix\":[");
    for (i, row) in t.matrix().iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        numbers(out, row);
    }
    out.extend_from_slice(b"],\"position\":");
    numbers(out, &t.position());
    let [w, x, y, z] = t.quaternion();
    out.extend_from_slice(b",\"quaternion\":{\"w\":");
    number(out, w);
    out.extend_from_slice(b",\"x\":");
    number(out, x);
    out.extend_from_slice(b",\"y\":");
    number(out, y);
    out.extend_from_slice(b",\"z\":");
    number(out, z);
    out.extend_from_slice(b"},\"rpy\":");
    numbers(out, &t.rpy());
    out.push(b'}');
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::pose_format::{Many, serde_reference};

    /// Transforms whose numbers take every shape the formatter writes:
    /// exact zeros of both signs, integers, short and 17-digit decimals,
    /// tiny, huge and subnormal translations, and non-finite ones.
    fn transforms() -> Vec<Transform> {
        let mut ts = Vec::new();
        let offsets = [
            [0.0, -0.0, 1.0],
            [0.3, -0.2, 1.0 / 3.0],
            [1e-300, -5e-324, 1e300],
            [123456.789, -1e-7, 2.5e15],
            [f64::NAN, f64::INFINITY, f64::NEG_INFINITY],
        ];
        for (k, o) in offsets.iter().enumerate() {
            for a in [0.0, 0.6, -2.9, std::f64::consts::PI] {
                let r = Transform::rot_z(a).compose(&Transform::rot_x(a * 0.5 + k as f64));
                ts.push(r.compose(&Transform::translation(o[0], o[1], o[2])));
            }
            ts.push(Transform::translation(o[0], o[1], o[2]));
        }
        ts
    }

    #[test]
    fn every_format_is_serde_json_byte_for_byte() {
        for format in [PoseFormat::Full, PoseFormat::Matrix, PoseFormat::Position] {
            for t in transforms() {
                let mut fast = Vec::new();
                pose(&mut fast, format, &t);
                let reference = serde_reference(format, t);
                assert_eq!(
                    String::from_utf8(fast).unwrap(),
                    String::from_utf8(reference).unwrap(),
                    "{format:?}"
                );
            }
        }
    }

    #[test]
    fn lists_are_serde_json_byte_for_byte() {
        use crate::api::pose_format::{AsMatrix, AsPose, AsPosition};
        let ts = transforms();
        for n in [0, 1, 2, ts.len()] {
            let part = &ts[..n];
            let mut fast = Vec::new();
            for (format, reference) in [
                (
                    PoseFormat::Full,
                    serde_json::to_vec(&Many::<AsPose>::new(part)),
                ),
                (
                    PoseFormat::Matrix,
                    serde_json::to_vec(&Many::<AsMatrix>::new(part)),
                ),
                (
                    PoseFormat::Position,
                    serde_json::to_vec(&Many::<AsPosition>::new(part)),
                ),
            ] {
                fast.clear();
                poses(&mut fast, format, part);
                assert_eq!(fast, reference.unwrap(), "{format:?} × {n}");
            }
        }
    }
}
