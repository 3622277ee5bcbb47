//! Protocol-neutral requests: one type per operation (FK, FK batch, Jacobian,
//! Jacobian batch; IK's are [`IkSpec`] and
//! [`IkBatchSpec`](crate::IkBatchSpec)), and [`StreamOp`], what one stream
//! message asks for. REST bodies, WebSocket messages and gRPC messages
//! convert into these; the server's service takes these and nothing else.
//!
//! The operations answered from one validated configuration are declared in
//! [`crate::operations`], their request is [`crate::operations::ConfigSpec`].
//!
//! Depends on the model's robot, operations, velocity, IK and pose-format modules
//! and on serde (the batch configurations are read straight into one
//! buffer); must not depend on any protocol.

use std::fmt;

use serde::de::{self, DeserializeSeed, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer};

use crate::operations::ConfigOps;
use crate::{FkOptions, IkPathSpec, IkSpec, PoseFormat, ReferenceFrame};

/// Many joint configurations stored back to back: `values` holds them all and
/// `lens[i]` is the length of configuration `i` (one allocation per request,
/// none per configuration). Deserialises from an array of arrays of numbers.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Configurations {
    /// All values, configuration after configuration.
    pub values: Vec<f64>,
    /// Length of each configuration.
    pub lens: Vec<u32>,
}

impl Configurations {
    /// Number of configurations.
    pub fn len(&self) -> usize {
        self.lens.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.lens.is_empty()
    }

    /// Appends one configuration.
    pub fn push(&mut self, q: &[f64]) {
        self.values.extend_from_slice(q);
        self.lens.push(u32::try_from(q.len()).unwrap_or(u32::MAX));
    }
}

impl<'de> Deserialize<'de> for Configurations {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_seq(Outer)
    }
}

struct Outer;

impl<'de> Visitor<'de> for Outer {
    type Value = Configurations;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an array of joint arrays")
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Configurations, A::Error> {
        let hint = seq.size_hint().unwrap_or(0).min(4096);
        let mut out = Configurations {
            values: Vec::with_capacity(hint * 6),
            lens: Vec::with_capacity(hint),
        };
        while let Some(n) = seq.next_element_seed(Row(&mut out.values))? {
            out.lens.push(n);
        }
        Ok(out)
    }
}

struct Row<'a>(&'a mut Vec<f64>);

impl<'de> DeserializeSeed<'de> for Row<'_> {
    type Value = u32;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<u32, D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for Row<'_> {
    type Value = u32;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an array of joint values")
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<u32, A::Error> {
        let mut n = 0u32;
        while let Some(x) = seq.next_element::<f64>()? {
            self.0.push(x);
            n = n
                .checked_add(1)
                .ok_or_else(|| de::Error::custom("too many values"))?;
        }
        Ok(n)
    }
}

/// FK of one configuration: the tool pose, and every frame with `frames`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FkSpec {
    /// One value per movable joint in table order: revolute in
    /// `options.angle_unit`, prismatic in the model's length unit.
    pub joints: Vec<f64>,
    /// Angle unit and limit check.
    pub options: FkOptions,
    /// Also every intermediate frame.
    pub frames: bool,
    /// How the answer's poses are given.
    pub pose_format: PoseFormat,
}

/// FK of many configurations (no frames), poses in request order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FkBatchSpec {
    /// The configurations, each like [`FkSpec::joints`].
    pub configurations: Configurations,
    /// Angle unit and limit check, for every configuration.
    pub options: FkOptions,
    /// How the answer's poses are given.
    pub pose_format: PoseFormat,
}

/// The Jacobian of one configuration, rows in `frame`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JacobianSpec {
    /// Joint values (see [`FkSpec::joints`]).
    pub joints: Vec<f64>,
    /// Angle unit and limit check.
    pub options: FkOptions,
    /// Frame of the rows.
    pub frame: ReferenceFrame,
}

/// The Jacobians of many configurations, in request order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JacobianBatchSpec {
    /// The configurations, each like [`FkSpec::joints`].
    pub configurations: Configurations,
    /// Angle unit and limit check, for every configuration.
    pub options: FkOptions,
    /// Frame of the rows.
    pub frame: ReferenceFrame,
}

/// What one stream message (WebSocket or gRPC) asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum StreamOp {
    /// FK, with the Jacobian (rows in this frame) and the operations on one
    /// configuration when asked for.
    Fk {
        /// The FK request.
        fk: FkSpec,
        /// The Jacobian too, its rows in this frame.
        jacobian: Option<ReferenceFrame>,
        /// The operations on one configuration asked for beside FK
        /// ([`crate::operations`]: one flag each).
        ops: ConfigOps,
    },
    /// Inverse kinematics.
    Ik(Box<IkSpec>),
    /// A Cartesian path.
    IkPath(Box<IkPathSpec>),
    /// FK of many configurations in one message (no frames, no Jacobian, no
    /// operations on one configuration), answered as the FK batch is.
    FkBatch(FkBatchSpec),
}
