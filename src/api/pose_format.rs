//! Compact pose formats (`pose_format`), the same on every front door: `full`
//! (the default: the [`Pose`] object), `matrix` (12 numbers: the top three
//! rows of the homogeneous matrix, row-major) or `position` (`[x, y, z]`).
//!
//! Each format has its own answer fields with their own type (one type per
//! field, so that generated clients can read them): a single pose is `pose`,
//! `matrix` or `position`; several are `poses`/`frames`, `matrices`/
//! `frame_matrices` or `positions`/`frame_positions`. [`one`] and [`many`]
//! fill exactly the field of the format ([`ByFormat`]), and [`One`] and
//! [`Many`] write a pose in their shape ([`AsPose`], [`AsMatrix`],
//! [`AsPosition`]).
//!
//! The compact formats are written straight from the [`Transform`]: no
//! quaternion or roll-pitch-yaw is computed and nothing is allocated per pose
//! (JSON numbers are written by serde_json's shortest round-trip formatter;
//! gRPC gets one pre-sized `Vec<f64>` per reply). Depends on the kinematics
//! crate and [`crate::api::pose`] only.

use std::marker::PhantomData;

use serde::ser::SerializeSeq;
use serde::{Serialize, Serializer};

use crate::api::pose::Pose;
use crate::kinematics::Transform;

pub use crate::model::{PoseFormat, matrix12};

/// How one pose is written in JSON.
pub trait Shape {
    /// Writes `t` in this shape.
    fn write<S: Serializer>(t: &Transform, s: S) -> Result<S::Ok, S::Error>;
}

/// The [`Pose`] object (`full`).
#[derive(Clone, Copy, Debug)]
pub enum AsPose {}

/// 12 numbers (`matrix`): see [`matrix12`].
#[derive(Clone, Copy, Debug)]
pub enum AsMatrix {}

/// `[x, y, z]` (`position`).
#[derive(Clone, Copy, Debug)]
pub enum AsPosition {}

impl Shape for AsPose {
    fn write<S: Serializer>(t: &Transform, s: S) -> Result<S::Ok, S::Error> {
        Pose::from(t).serialize(s)
    }
}

impl Shape for AsMatrix {
    fn write<S: Serializer>(t: &Transform, s: S) -> Result<S::Ok, S::Error> {
        matrix12(t).serialize(s)
    }
}

impl Shape for AsPosition {
    fn write<S: Serializer>(t: &Transform, s: S) -> Result<S::Ok, S::Error> {
        t.translation.serialize(s)
    }
}

/// One pose, written in shape `F`.
#[derive(Clone, Copy, Debug)]
pub struct One<F>(pub Transform, PhantomData<F>);

impl<F> One<F> {
    /// `t`, to be written in shape `F`.
    pub fn new(t: Transform) -> One<F> {
        One(t, PhantomData)
    }
}

impl<F: Shape> Serialize for One<F> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        F::write(&self.0, s)
    }
}

/// Many poses, written in shape `F` as an array, without building them in
/// memory first.
#[derive(Clone, Copy, Debug)]
pub struct Many<'a, F>(pub &'a [Transform], PhantomData<F>);

impl<'a, F> Many<'a, F> {
    /// `ts`, to be written in shape `F`.
    pub fn new(ts: &'a [Transform]) -> Many<'a, F> {
        Many(ts, PhantomData)
    }
}

/// One element of a [`Many`].
struct Element<'a, F>(&'a Transform, PhantomData<F>);

impl<F: Shape> Serialize for Element<'_, F> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        F::write(self.0, s)
    }
}

impl<F: Shape> Serialize for Many<'_, F> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut seq = s.serialize_seq(Some(self.0.len()))?;
        for t in self.0 {
            seq.serialize_element(&Element::<F>(t, PhantomData))?;
        }
        seq.end()
    }
}

/// The answer fields of a pose (or of a list of poses), one per format:
/// exactly the one of the request's format is `Some` (none when there is
/// nothing to give, as frames not asked for).
#[derive(Clone, Copy, Debug)]
pub struct ByFormat<A, B, C> {
    /// `full`: `pose`, `poses` or `frames`.
    pub full: Option<A>,
    /// `matrix`: `matrix`, `matrices` or `frame_matrices`.
    pub matrix: Option<B>,
    /// `position`: `position`, `positions` or `frame_positions`.
    pub position: Option<C>,
}

/// The fields of one pose.
pub type OneByFormat = ByFormat<One<AsPose>, One<AsMatrix>, One<AsPosition>>;

/// The fields of a list of poses.
pub type ManyByFormat<'a> = ByFormat<Many<'a, AsPose>, Many<'a, AsMatrix>, Many<'a, AsPosition>>;

impl<A, B, C> ByFormat<A, B, C> {
    const NONE: Self = ByFormat {
        full: None,
        matrix: None,
        position: None,
    };
}

/// `t` in the field of `format`.
pub fn one(format: PoseFormat, t: Transform) -> OneByFormat {
    match format {
        PoseFormat::Full => ByFormat {
            full: Some(One::new(t)),
            ..ByFormat::NONE
        },
        PoseFormat::Matrix => ByFormat {
            matrix: Some(One::new(t)),
            ..ByFormat::NONE
        },
        PoseFormat::Position => ByFormat {
            position: Some(One::new(t)),
            ..ByFormat::NONE
        },
    }
}

/// `ts` (when given) in the field of `format`.
pub fn many(format: PoseFormat, ts: Option<&[Transform]>) -> ManyByFormat<'_> {
    let Some(ts) = ts else {
        return ByFormat::NONE;
    };
    match format {
        PoseFormat::Full => ByFormat {
            full: Some(Many::new(ts)),
            ..ByFormat::NONE
        },
        PoseFormat::Matrix => ByFormat {
            matrix: Some(Many::new(ts)),
            ..ByFormat::NONE
        },
        PoseFormat::Position => ByFormat {
            position: Some(Many::new(ts)),
            ..ByFormat::NONE
        },
    }
}

/// `t` in `format` as serde_json writes it through this module's shapes: the
/// reference [`crate::api::pose_json`] is tested against.
#[cfg(test)]
pub(crate) fn serde_reference(format: PoseFormat, t: Transform) -> Vec<u8> {
    let o = one(format, t);
    match format {
        PoseFormat::Full => serde_json::to_vec(&o.full),
        PoseFormat::Matrix => serde_json::to_vec(&o.matrix),
        PoseFormat::Position => serde_json::to_vec(&o.position),
    }
    .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Transform {
        Transform::rot_z(0.6).compose(&Transform::translation(0.3, -0.2, 0.1))
    }

    #[test]
    fn matrix12_is_the_top_of_matrix_bit_for_bit() {
        let t = sample();
        let full: Vec<f64> = t.matrix().iter().flatten().copied().take(12).collect();
        assert_eq!(
            matrix12(&t).map(f64::to_bits).to_vec(),
            full.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }

    #[test]
    fn compact_json_is_a_flat_array_and_full_is_the_pose_object() {
        let t = sample();
        let json = |f| serde_json::from_slice::<serde_json::Value>(&serde_reference(f, t)).unwrap();
        assert_eq!(
            json(PoseFormat::Full),
            serde_json::to_value(Pose::from(&t)).unwrap()
        );
        assert_eq!(json(PoseFormat::Matrix).as_array().unwrap().len(), 12);
        assert_eq!(json(PoseFormat::Position), serde_json::json!(t.translation));
        let packed = PoseFormat::Matrix.pack([t, t].iter());
        assert_eq!(packed.len(), 24);
        assert!(PoseFormat::Full.pack([t].iter()).is_empty());
    }

    #[test]
    fn exactly_the_field_of_the_format_is_filled() {
        let t = sample();
        let ts = [t, t];
        for format in [PoseFormat::Full, PoseFormat::Matrix, PoseFormat::Position] {
            let o = one(format, t);
            let filled = [o.full.is_some(), o.matrix.is_some(), o.position.is_some()];
            let m = many(format, Some(&ts));
            let listed = [m.full.is_some(), m.matrix.is_some(), m.position.is_some()];
            let want = [
                format == PoseFormat::Full,
                format == PoseFormat::Matrix,
                format == PoseFormat::Position,
            ];
            assert_eq!(filled, want, "{format:?}");
            assert_eq!(listed, want, "{format:?}");
            let none = many(format, None);
            assert!(none.full.is_none() && none.matrix.is_none() && none.position.is_none());
        }
        let m = many(PoseFormat::Matrix, Some(&ts)).matrix.unwrap();
        let each: serde_json::Value =
            serde_json::from_slice(&serde_reference(PoseFormat::Matrix, t)).unwrap();
        assert_eq!(
            serde_json::to_value(m).unwrap(),
            serde_json::json!([each, each])
        );
        let p = one(PoseFormat::Position, t).position.unwrap();
        assert_eq!(
            serde_json::to_value(p).unwrap(),
            serde_json::json!(t.translation)
        );
    }
}
