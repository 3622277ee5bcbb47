//! The two optional IK objectives as clients write them and their
//! validation: a null-space posture for redundant arms ([`PostureSpec`]:
//! `posture.joints`, `posture.weights`) and partial poses
//! ([`AxisTolerancesSpec`]: `axis_tolerances.x` … `.rz`, and
//! [`PoseAxis`] values in `free_axes`), checked into the kinematics crate's
//! [`Posture`] and per-axis tolerance array by [`Robot::check_objectives`].
//!
//! Units: posture joints in the request's `angle_unit` (revolute) and the
//! robot's length unit (prismatic); weights unit-free in `[0, 1]`; axis
//! tolerances along the target frame's x, y, z in the length unit and about
//! them in rad. Depends on the kinematics crate (`ik::Posture`), serde and
//! the robot and joints modules; must not depend on the `ik` module (which
//! uses this one).

use kinserve_kinematics::ik::Posture;
use serde::{Deserialize, Serialize};

use crate::error::FieldViolation;
use crate::robot::{FkOptions, Robot};
use crate::spec::{AngleUnit, object_only};

/// Smallest and largest axis tolerance accepted (as `tolerance`).
const RANGE: (f64, f64) = (1e-15, 1e3);

/// A preferred configuration: once the target is reached, the solver moves
/// the arm towards it along its self-motion (only a redundant arm, or a free
/// axis, leaves room) while the pose stays within the tolerance.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields, remote = "Self")]
#[cfg_attr(feature = "openapi", schema(example = json!({
    "joints": [0, 0, 0, -90, 0, 90, 45], "weights": [0, 0, 1, 0, 0, 0, 0]
})))]
pub struct PostureSpec {
    /// One value per joint, in `angle_unit` (revolute) and the robot's
    /// length unit (prismatic), within the joint limits.
    pub joints: Vec<f64>,
    /// One weight per joint from 0 (no preference) to 1 (default: 1 for
    /// every joint): the share of the way to the preferred value asked for
    /// per refinement step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights: Option<Vec<f64>>,
}

/// Tolerances per axis of the target frame, replacing `tolerance` on the
/// axes given (the others keep `tolerance`): `x`, `y`, `z` along the axes
/// (length unit), `rx`, `ry`, `rz` about them (rad).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields, remote = "Self")]
#[cfg_attr(feature = "openapi", schema(example = json!({"x": 1e-4, "y": 1e-4, "rz": 0.01})))]
pub struct AxisTolerancesSpec {
    /// Along the target frame's x axis (length unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x: Option<f64>,
    /// Along its y axis (length unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub y: Option<f64>,
    /// Along its z axis (length unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub z: Option<f64>,
    /// About its x axis (rad).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rx: Option<f64>,
    /// About its y axis (rad).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ry: Option<f64>,
    /// About its z axis (rad).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rz: Option<f64>,
}

object_only!(PostureSpec);
object_only!(AxisTolerancesSpec);

/// An axis of the target frame: position along it or rotation about it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum PoseAxis {
    /// Position along x.
    X,
    /// Position along y.
    Y,
    /// Position along z.
    Z,
    /// Rotation about x.
    Rx,
    /// Rotation about y.
    Ry,
    /// Rotation about z (a free spin of the tool about its axis).
    Rz,
}

impl PoseAxis {
    /// Every axis, in the order of the tolerance array.
    pub const ALL: [PoseAxis; 6] = [
        PoseAxis::X,
        PoseAxis::Y,
        PoseAxis::Z,
        PoseAxis::Rx,
        PoseAxis::Ry,
        PoseAxis::Rz,
    ];

    /// `"x"` … `"rz"`, as in JSON.
    pub fn as_str(self) -> &'static str {
        ["x", "y", "z", "rx", "ry", "rz"][self as usize]
    }
}

impl AxisTolerancesSpec {
    fn values(&self) -> [Option<f64>; 6] {
        [self.x, self.y, self.z, self.rx, self.ry, self.rz]
    }
}

/// The objectives of a request as written.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct ObjectiveFields<'a> {
    pub posture: Option<&'a PostureSpec>,
    pub axis_tolerances: Option<&'a AxisTolerancesSpec>,
    pub free_axes: &'a [PoseAxis],
}

impl ObjectiveFields<'_> {
    /// The field that keeps the closed form out (it solves exact full
    /// poses and has no null space), if any.
    pub(crate) fn numeric_only(&self) -> Option<&'static str> {
        if self.posture.is_some() {
            Some("posture")
        } else if self.axis_tolerances.is_some() {
            Some("axis_tolerances")
        } else if !self.free_axes.is_empty() {
            Some("free_axes")
        } else {
            None
        }
    }
}

impl Robot {
    /// The posture (internal units) and per-axis tolerances `[x, y, z, rx,
    /// ry, rz]` (`f64::INFINITY` for a free axis; `None` when neither
    /// `axis_tolerances` nor `free_axes` is given) of a request, or
    /// violations under `posture.joints[2]`, `axis_tolerances.rz`,
    /// `free_axes`.
    pub(crate) fn check_objectives(
        &self,
        o: &ObjectiveFields<'_>,
        tolerance: f64,
        angle_unit: AngleUnit,
        position_only: bool,
        v: &mut Vec<FieldViolation>,
    ) -> (Option<Posture>, Option<[f64; 6]>) {
        let posture = o.posture.and_then(|p| self.check_posture(p, angle_unit, v));
        if o.axis_tolerances.is_none() && o.free_axes.is_empty() {
            return (posture, None);
        }
        let given = o.axis_tolerances.map(|a| a.values()).unwrap_or_default();
        let mut axes = [tolerance; 6];
        for ((axis, slot), x) in PoseAxis::ALL.iter().zip(&mut axes).zip(given) {
            let Some(x) = x else { continue };
            let (lo, hi) = RANGE;
            if !(lo..=hi).contains(&x) {
                v.push(FieldViolation::new(
                    format!("axis_tolerances.{}", axis.as_str()),
                    format!("must be a number from {lo:e} to {hi:e}, got {x}"),
                ));
            }
            *slot = x;
        }
        for axis in o.free_axes {
            axes[*axis as usize] = f64::INFINITY;
        }
        let matched = if position_only { &axes[..3] } else { &axes[..] };
        if matched.iter().all(|t| t.is_infinite()) {
            v.push(FieldViolation::new(
                "free_axes",
                "leaves no axis to match: keep at least one (position_only already frees rx, ry, rz)",
            ));
        }
        (posture, Some(axes))
    }

    fn check_posture(
        &self,
        p: &PostureSpec,
        angle_unit: AngleUnit,
        v: &mut Vec<FieldViolation>,
    ) -> Option<Posture> {
        let before = v.len();
        let opts = FkOptions::new(Some(angle_unit), Some(true));
        if let Err(e) = self.check_joints_at(&p.joints, &opts, || "posture.joints".into()) {
            v.extend(e.violations().iter().cloned());
        }
        let weights = p.weights.clone().unwrap_or_else(|| vec![1.0; self.dof()]);
        if weights.len() != self.dof() {
            v.push(FieldViolation::new(
                "posture.weights",
                format!(
                    "robot '{}' has {} movable joints, got {} weights",
                    self.name(),
                    self.dof(),
                    weights.len()
                ),
            ));
        }
        for (i, w) in weights.iter().enumerate() {
            if !(0.0..=1.0).contains(w) {
                v.push(FieldViolation::new(
                    format!("posture.weights[{i}]"),
                    format!("must be a number from 0 to 1, got {w}"),
                ));
            }
        }
        (v.len() == before).then(|| Posture {
            joints: self.to_internal(&p.joints, angle_unit.to_rad()),
            weights,
        })
    }
}
