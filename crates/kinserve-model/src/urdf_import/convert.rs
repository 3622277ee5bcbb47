//! The exact conversion of a URDF chain into a DH table (standard or
//! modified), with the base and tool transforms that carry what the table
//! does not, and its check against the URDF's own forward kinematics.
//!
//! Geometry: at zero motion, each movable joint's axis is a line in the base
//! link's frame (its origin and its axis direction, through every origin and
//! fixed joint above it). The DH frames are built on the common normals of
//! consecutive axes — for parallel axes the normal through the previous
//! frame's origin (so that `d` is 0), for intersecting ones the cross product
//! — and each row is read off the transform between two consecutive frames.
//! Fixed joints fold into the frames (between movable joints), the base
//! (before the first) or the tool (after the last), so an imported table has
//! only movable rows. Units: metres and radians throughout.
//!
//! Owns the frame construction and the check. Depends on `parse` (the joints)
//! and the math crate's [`Transform`]; must not depend on any adapter.

use kinserve_kinematics::Transform;

use super::parse::{UrdfJoint, UrdfJointKind};
use crate::error::ModelError;
use crate::spec::{ConventionSpec, JointType};

/// Axes whose directions differ by less than this (sine of the angle) are parallel.
const PARALLEL: f64 = 1e-12;
/// Lines closer than this (times the chain's size) meet.
const MEET: f64 = 1e-12;

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V3, k: f64) -> V3 {
    [a[0] * k, a[1] * k, a[2] * k]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}
fn unit(a: V3) -> V3 {
    scale(a, 1.0 / norm(a))
}
fn rotate(t: &Transform, v: V3) -> V3 {
    let r = &t.rotation;
    [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
}

/// A movable joint's axis at zero motion, in the base link's frame.
#[derive(Clone, Debug)]
pub struct Axis {
    /// A point of the axis (the joint frame's origin), m.
    pub point: V3,
    /// Its unit direction.
    pub dir: V3,
    /// The URDF joint.
    pub joint: UrdfJoint,
}

/// The chain's movable axes at zero motion and the tip's frame.
pub fn axes(chain: &[&UrdfJoint]) -> (Vec<Axis>, Transform) {
    let mut frame = Transform::IDENTITY;
    let mut axes = Vec::new();
    for j in chain {
        frame = frame.compose(&j.origin);
        if j.kind != UrdfJointKind::Fixed {
            axes.push(Axis {
                point: frame.translation,
                dir: unit(rotate(&frame, j.axis)),
                joint: (*j).clone(),
            });
        }
    }
    (axes, frame)
}

/// A unit vector perpendicular to `u`, as close to `hint` as possible.
fn perpendicular(u: V3, hint: V3) -> V3 {
    let p = sub(hint, scale(u, dot(hint, u)));
    if norm(p) > 1e-6 {
        return unit(p);
    }
    // `hint` is along `u`: any perpendicular.
    let other = if u[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    unit(cross(u, other))
}

/// The common normal from line `a` to line `b`: its foot on `a`, its foot
/// on `b`, its unit direction. Parallel lines: the normal through `at`'s
/// projection on `a`. Meeting lines: `a × b`, turned towards `hint_x`.
/// Coincident lines: `hint_x` made perpendicular.
fn common_normal(a: (V3, V3), b: (V3, V3), at: V3, hint_x: V3, size: f64) -> (V3, V3, V3) {
    let ((pa, ua), (pb, ub)) = (a, b);
    let w = cross(ua, ub);
    let s = norm(w);
    let (fa, gb) = if s < PARALLEL {
        let fa = add(pa, scale(ua, dot(sub(at, pa), ua)));
        (fa, add(pb, scale(ub, dot(sub(fa, pb), ub))))
    } else {
        let r = sub(pb, pa);
        let ta = dot(cross(r, ub), w) / (s * s);
        let tb = dot(cross(r, ua), w) / (s * s);
        (add(pa, scale(ua, ta)), add(pb, scale(ub, tb)))
    };
    let v = sub(gb, fa);
    let n = if norm(v) > MEET * size {
        unit(v)
    } else if s < PARALLEL {
        perpendicular(ua, hint_x)
    } else {
        let n = unit(w);
        if dot(n, hint_x) < 0.0 {
            scale(n, -1.0)
        } else {
            n
        }
    };
    (fa, gb, n)
}

/// The frame with origin `o`, x axis `x` and z axis `z` (perpendicular units).
fn frame(o: V3, x: V3, z: V3) -> Transform {
    let y = cross(z, x);
    Transform {
        rotation: [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]],
        translation: o,
    }
}

/// The DH frames `F_0 … F_n` of the axes at zero motion (in the base link's
/// frame), in `convention`.
pub fn dh_frames(axes: &[Axis], convention: ConventionSpec, size: f64) -> Vec<Transform> {
    let line = |i: usize| (axes[i].point, axes[i].dir);
    let n = axes.len();
    // Normals between consecutive axes, each through the foot of the last.
    let mut normals = Vec::with_capacity(n.saturating_sub(1));
    let (mut at, mut hint) = (axes[0].point, perpendicular(axes[0].dir, [1.0, 0.0, 0.0]));
    for i in 0..n.saturating_sub(1) {
        let (f, g, x) = common_normal(line(i), line(i + 1), at, hint, size);
        normals.push((f, g, x));
        (at, hint) = (g, x);
    }
    let first_x = normals.first().map_or(hint, |n| n.2);
    let first_o = normals.first().map_or(axes[0].point, |n| n.0);
    match convention {
        ConventionSpec::Standard => {
            // F_0 on axis 1; F_i on axis i+1 with x along normal i; F_n = F_{n-1}.
            let mut frames = vec![frame(first_o, first_x, axes[0].dir)];
            for (i, (_, g, x)) in normals.iter().enumerate() {
                frames.push(frame(*g, *x, axes[i + 1].dir));
            }
            frames.push(*frames.last().expect("F_0"));
            frames
        }
        ConventionSpec::Modified => {
            // F_i on axis i with x along normal i; F_n on axis n; F_0 = F_1.
            let mut frames = vec![frame(first_o, first_x, axes[0].dir)];
            for (i, (f, _, x)) in normals.iter().enumerate() {
                frames.push(frame(*f, *x, axes[i].dir));
            }
            let (last_o, last_x) = normals.last().map_or((first_o, first_x), |n| (n.1, n.2));
            frames.push(frame(last_o, last_x, axes[n - 1].dir));
            frames[0] = frames[1];
            frames
        }
    }
}

/// One DH row's numbers (m, rad).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// `a` (modified: `a_{i-1}`).
    pub a: f64,
    /// `α` (modified: `α_{i-1}`).
    pub alpha: f64,
    /// `d` (at zero motion for a prismatic joint).
    pub d: f64,
    /// `θ` (at zero motion for a revolute joint).
    pub theta: f64,
}

/// The row that takes `from` to `to`, or the size of what the DH form
/// cannot carry (a construction fault, never expected).
pub fn row(from: &Transform, to: &Transform, convention: ConventionSpec) -> (Row, f64) {
    let m = from.inverse().compose(to);
    let (r, t) = (m.rotation, m.translation);
    match convention {
        ConventionSpec::Standard => {
            let theta = r[1][0].atan2(r[0][0]);
            let alpha = r[2][1].atan2(r[2][2]);
            let (c, s) = (theta.cos(), theta.sin());
            let off = r[2][0].abs().max((t[1] * c - t[0] * s).abs());
            (
                Row {
                    a: t[0] * c + t[1] * s,
                    alpha,
                    d: t[2],
                    theta,
                },
                off,
            )
        }
        ConventionSpec::Modified => {
            let theta = (-r[0][1]).atan2(r[0][0]);
            let alpha = (-r[1][2]).atan2(r[2][2]);
            let (c, s) = (alpha.cos(), alpha.sin());
            let off = r[0][2].abs().max((t[1] * c + t[2] * s).abs());
            (
                Row {
                    a: t[0],
                    alpha,
                    d: -t[1] * s + t[2] * c,
                    theta,
                },
                off,
            )
        }
    }
}

/// The URDF's own forward kinematics of `chain` at `q` (one value per
/// movable joint): the composition of every origin and joint motion.
pub fn urdf_fk(chain: &[&UrdfJoint], q: &[f64]) -> Transform {
    let mut t = Transform::IDENTITY;
    let mut values = q.iter();
    for j in chain {
        t = t.compose(&j.origin);
        let motion = match j.kind {
            UrdfJointKind::Fixed | UrdfJointKind::Unsupported(_) => continue,
            UrdfJointKind::Prismatic => {
                let v = values.next().copied().unwrap_or(0.0);
                let [x, y, z] = scale(j.axis, v);
                Transform::translation(x, y, z)
            }
            UrdfJointKind::Revolute | UrdfJointKind::Continuous => {
                axis_angle(j.axis, values.next().copied().unwrap_or(0.0))
            }
        };
        t = t.compose(&motion);
    }
    t
}

/// Rotation by `angle` (rad) about the unit axis `k` (Rodrigues).
fn axis_angle(k: V3, angle: f64) -> Transform {
    let (s, c) = angle.sin_cos();
    let v = 1.0 - c;
    let [x, y, z] = k;
    Transform {
        rotation: [
            [c + x * x * v, x * y * v - z * s, x * z * v + y * s],
            [y * x * v + z * s, c + y * y * v, y * z * v - x * s],
            [z * x * v - y * s, z * y * v + x * s, c + z * z * v],
        ],
        translation: [0.0; 3],
    }
}

/// The DH joint kind of a URDF joint.
pub fn joint_type(kind: UrdfJointKind) -> JointType {
    match kind {
        UrdfJointKind::Prismatic => JointType::Prismatic,
        _ => JointType::Revolute,
    }
}

/// A refusal of the converted table: its FK parts from the URDF's at `joint`.
pub fn mismatch(joint: &str, error: f64) -> ModelError {
    ModelError::invalid_field(
        "urdf",
        format!(
            "the DH table converted from this URDF does not reproduce its forward kinematics from joint '{joint}' on (off by {error:.1e}); please report the file"
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skew_lines_meet_their_common_normal_at_right_angles() {
        let a = ([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let b = ([1.0, 0.0, 5.0], unit([0.0, 1.0, 1.0]));
        let (f, g, n) = common_normal(a, b, [0.0; 3], [1.0, 0.0, 0.0], 1.0);
        assert!(dot(n, a.1).abs() < 1e-15 && dot(n, b.1).abs() < 1e-15);
        assert!(
            (norm(sub(g, f)) - 1.0).abs() < 1e-12,
            "distance 1: {f:?} {g:?}"
        );
    }

    #[test]
    fn rows_read_back_the_transform_they_come_from() {
        for convention in [ConventionSpec::Standard, ConventionSpec::Modified] {
            let (a, alpha, d, theta) = (0.3, -0.7, 0.2, 1.1);
            let m = match convention {
                ConventionSpec::Standard => Transform::rot_z(theta)
                    .compose(&Transform::translation(0.0, 0.0, d))
                    .compose(&Transform::translation(a, 0.0, 0.0))
                    .compose(&Transform::rot_x(alpha)),
                ConventionSpec::Modified => Transform::rot_x(alpha)
                    .compose(&Transform::translation(a, 0.0, 0.0))
                    .compose(&Transform::rot_z(theta))
                    .compose(&Transform::translation(0.0, 0.0, d)),
            };
            let (r, off) = row(&Transform::IDENTITY, &m, convention);
            assert!(off < 1e-15, "{convention:?}");
            for (got, want) in [(r.a, a), (r.alpha, alpha), (r.d, d), (r.theta, theta)] {
                assert!((got - want).abs() < 1e-15, "{convention:?}: {r:?}");
            }
        }
    }
}
