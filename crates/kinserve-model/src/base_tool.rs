//! Base and tool transforms: validation of a [`TransformSpec`] and its
//! conversion to a rigid [`Transform`], and the number checks shared with the
//! DH rows. Depends on the error and spec modules only.

use kinserve_kinematics::Transform;

use crate::error::FieldViolation;
use crate::spec::TransformSpec;
use crate::{MAX_MAGNITUDE, RIGID_TOLERANCE};

pub(crate) fn check_finite(v: &mut Vec<FieldViolation>, field: impl FnOnce() -> String, x: f64) {
    if !x.is_finite() {
        v.push(FieldViolation::new(field(), "must be a finite number"));
    }
}

/// Finite and at most [`MAX_MAGNITUDE`] in magnitude.
pub(crate) fn check_bounded(v: &mut Vec<FieldViolation>, field: impl FnOnce() -> String, x: f64) {
    if !x.is_finite() {
        v.push(FieldViolation::new(field(), "must be a finite number"));
    } else if x.abs() > MAX_MAGNITUDE {
        v.push(FieldViolation::new(field(), magnitude_message()));
    }
}

pub(crate) fn magnitude_message() -> String {
    format!("must be at most {MAX_MAGNITUDE:e} in magnitude (model units)")
}

/// Validates a base/tool spec and converts it (angles to rad).
pub(crate) fn transform_from_spec(
    t: &TransformSpec,
    field: &str,
    to_rad: f64,
    v: &mut Vec<FieldViolation>,
) -> Transform {
    let before = v.len();
    if let Some(m) = &t.matrix {
        if t.translation.is_some() || t.rpy.is_some() || t.quaternion.is_some() {
            v.push(FieldViolation::new(
                format!("{field}.matrix"),
                "give either matrix alone or translation with rpy or quaternion",
            ));
        }
        return rigid_from_matrix(m, &format!("{field}.matrix"), before, v);
    }
    if t.rpy.is_some() && t.quaternion.is_some() {
        v.push(FieldViolation::new(
            format!("{field}.quaternion"),
            "give rpy or quaternion, not both",
        ));
    }
    let translation = t.translation.unwrap_or([0.0; 3]);
    for (i, x) in translation.iter().enumerate() {
        check_bounded(v, || format!("{field}.translation[{i}]"), *x);
    }
    if let Some(rpy) = t.rpy {
        for (i, x) in rpy.iter().enumerate() {
            check_finite(v, || format!("{field}.rpy[{i}]"), *x);
        }
        if v.len() > before {
            return Transform::IDENTITY;
        }
        return Transform::from_translation_rpy(
            translation,
            [rpy[0] * to_rad, rpy[1] * to_rad, rpy[2] * to_rad],
        );
    }
    if let Some(q) = t.quaternion {
        for (name, x) in [("w", q.w), ("x", q.x), ("y", q.y), ("z", q.z)] {
            check_finite(v, || format!("{field}.quaternion.{name}"), x);
        }
        if v.len() > before {
            return Transform::IDENTITY;
        }
        return match Transform::from_translation_quaternion(translation, [q.w, q.x, q.y, q.z]) {
            Some(tr) => tr,
            None => {
                v.push(FieldViolation::new(
                    format!("{field}.quaternion"),
                    "must not be zero",
                ));
                Transform::IDENTITY
            }
        };
    }
    Transform::translation(translation[0], translation[1], translation[2])
}

/// Validates a homogeneous 4×4 matrix (row-major) under the field path
/// `field` (`base.matrix`, `target.matrix`): finite entries, translation within
/// ±[`MAX_MAGNITUDE`], last row `[0, 0, 0, 1]`, rotation rigid within
/// [`RIGID_TOLERANCE`]. Returns the transform with the nearest exact rotation.
/// The shape checks (last row, rigidity) are skipped when `v` grew past
/// `before` (number errors, or any the caller found since `before`).
pub(crate) fn rigid_from_matrix(
    m: &[[f64; 4]; 4],
    field: &str,
    before: usize,
    v: &mut Vec<FieldViolation>,
) -> Transform {
    for (i, row) in m.iter().enumerate() {
        for (j, x) in row.iter().enumerate() {
            check_finite(v, || format!("{field}[{i}][{j}]"), *x);
        }
    }
    for (i, row) in m.iter().take(3).enumerate() {
        if row[3].abs() > MAX_MAGNITUDE {
            v.push(FieldViolation::new(
                format!("{field}[{i}][3]"),
                magnitude_message(),
            ));
        }
    }
    if v.len() > before {
        return Transform::IDENTITY;
    }
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        v.push(FieldViolation::new(
            format!("{field}[3]"),
            "last row must be [0, 0, 0, 1]",
        ));
    }
    let tr = Transform::from_matrix(m);
    let err = tr.rigidity_error();
    if err > RIGID_TOLERANCE {
        v.push(FieldViolation::new(
            field,
            format!(
                "rotation part is not a rigid rotation (orthonormal with det +1 within {RIGID_TOLERANCE:e}; off by {err:.3e})"
            ),
        ));
        return tr;
    }
    // Accepted within the tolerance: use the nearest exact rotation (through
    // its unit quaternion), so that small errors cannot add up to a non-rigid pose.
    Transform::from_translation_quaternion(tr.translation, tr.quaternion()).unwrap_or(tr)
}
