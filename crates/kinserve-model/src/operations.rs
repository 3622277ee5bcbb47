//! Operations answered from one validated configuration, declared once.
//!
//! Each such operation is one line of [`config_ops!`](crate::config_ops) and
//! one [`ConfigOp`] impl (its answer, computed from a [`JointVector`]). The
//! line is the whole declaration: every front door expands the table with a
//! macro of its own, so the line alone gives the operation its flag in a
//! stream message ([`ConfigOps`]) and its field in the stream reply
//! ([`ConfigAnswers`]) here, its gRPC method and stream fields in
//! `kinserve-api`, and its REST route, WebSocket field and CLI subcommand in
//! the server. Each door then needs one impl per operation of its own trait
//! (how the answer goes on its wire), in one file per operation.
//!
//! The request of every such operation is a [`ConfigSpec`] (joint values and
//! their options); the answer type is the operation's.
//!
//! Depends on the robot and joints modules, the kinematics crate and serde;
//! must not depend on any protocol.

use kinserve_kinematics::{JointKind, Transform, link_transform};
use serde::Serialize;
use serde::ser::SerializeStruct;

use crate::FkOptions;
use crate::joints::JointVector;

/// The operations answered from one validated configuration, one line each:
/// `doc comments  name: Type => [AnswerType];` where `name` is the operation's
/// name on every front door (REST path `…/{name with dashes}`, WebSocket
/// and stream flag, gRPC method, CLI subcommand), `Type` its [`ConfigOp`]
/// impl and `AnswerType` its `ConfigOp::Answer`.
///
/// Called with the name of a macro (`config_ops!(my_macro)`), it calls that
/// macro with the table; each front door's macro writes what the table means
/// there.
#[macro_export]
macro_rules! config_ops {
    ($callback:ident) => {
        $callback! {
            /// Each DH row's link matrix ⁱ⁻¹Aᵢ and its closed-form inverse at one
            /// configuration, in table order.
            link_transforms: LinkTransforms => [Vec<LinkTransform>];
        }
    };
}

/// An operation answered from one validated configuration (see the module
/// header): its answer and how it is computed. The validation (joint count,
/// units, limits) is [`crate::Robot::check_joints`], shared by all.
pub trait ConfigOp {
    /// What it answers.
    type Answer: Clone + std::fmt::Debug + PartialEq + Serialize + Send + 'static;
    /// The answer at `q`.
    fn compute(q: &JointVector<'_>) -> Self::Answer;
}

/// The request of an operation on one configuration: joint values and their
/// options, validated by [`crate::Robot::check_joints`] into a [`JointVector`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ConfigSpec {
    /// One value per movable joint in table order: revolute in
    /// `options.angle_unit`, prismatic in the model's length unit.
    pub joints: Vec<f64>,
    /// Angle unit and limit check.
    pub options: FkOptions,
}

/// Writes [`ConfigOps`] (the flags) and [`ConfigAnswers`] (the answers)
/// from the table.
macro_rules! model_sets {
    ($( $(#[$doc:meta])* $name:ident: $op:ident => [$($answer:tt)+]; )*) => {
        /// Which operations on one configuration a stream message asks for
        /// beside FK: one flag per [`config_ops!`](crate::config_ops) line.
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        pub struct ConfigOps {
            $( $(#[$doc])* pub $name: bool, )*
        }

        /// The answers of the operations a [`ConfigOps`] asked for, each
        /// `None` when not asked for (and then absent from JSON).
        #[derive(Clone, Debug, Default, PartialEq, Serialize)]
        #[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
        pub struct ConfigAnswers {
            $(
                $(#[$doc])*
                #[serde(skip_serializing_if = "Option::is_none")]
                pub $name: Option<$($answer)+>,
            )*
        }

        impl ConfigOps {
            /// The answers at `q` of those asked for.
            pub fn compute(&self, q: &JointVector<'_>) -> ConfigAnswers {
                ConfigAnswers {
                    $( $name: self.$name.then(|| <$op as ConfigOp>::compute(q)), )*
                }
            }
        }
    };
}

crate::config_ops!(model_sets);

/// One DH row's link matrix and its inverse (see [`LinkTransforms`]); in JSON
/// `{"matrix": 4×4, "inverse": 4×4}`, row-major.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct LinkTransform {
    /// `ⁱ⁻¹Aᵢ`: frame `i` in frame `i−1`, homogeneous 4×4, row-major, robot length unit.
    #[cfg_attr(feature = "openapi", schema(value_type = Vec<Vec<f64>>))]
    pub matrix: Transform,
    /// Its inverse `[Rᵀ | −Rᵀp]`, homogeneous 4×4, row-major.
    #[cfg_attr(feature = "openapi", schema(value_type = Vec<Vec<f64>>))]
    pub inverse: Transform,
}

impl Serialize for LinkTransform {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut st = s.serialize_struct("LinkTransform", 2)?;
        st.serialize_field("matrix", &self.matrix.matrix())?;
        st.serialize_field("inverse", &self.inverse.matrix())?;
        st.end()
    }
}

/// Each DH row's link matrix `ⁱ⁻¹Aᵢ` (the course notes' factors of the arm
/// matrix) and its closed-form inverse, in table order (fixed rows included;
/// base and tool are not rows): `base · A₁ ⋯ Aₙ · tool` is the tool pose.
/// Computed by the textbook definition ([`link_transform`]), not the fast
/// path.
///
/// ```
/// use kinserve_model::operations::{ConfigOp, LinkTransforms};
/// use kinserve_model::{FkOptions, ModelLimits, Robot};
/// let robot = Robot::from_json(br#"{"name": "two_r", "convention": "standard",
///   "links": [{"joint": "revolute", "a": 0.4, "alpha": 0, "d": 0, "theta": 0},
///             {"joint": "revolute", "a": 0.3, "alpha": 0, "d": 0, "theta": 0}]}"#,
///   &ModelLimits::default()).unwrap();
/// let q = robot.check_joints(&[0.5, -0.2], &FkOptions::default()).unwrap();
/// let links = LinkTransforms::compute(&q);
/// let product = links[0].matrix.compose(&links[1].matrix);
/// let tool = q.fk();
/// for i in 0..3 {
///     assert!((product.translation[i] - tool.translation[i]).abs() < 1e-12);
/// }
/// ```
#[derive(Clone, Copy, Debug)]
pub struct LinkTransforms;

impl ConfigOp for LinkTransforms {
    type Answer = Vec<LinkTransform>;

    fn compute(q: &JointVector<'_>) -> Vec<LinkTransform> {
        let chain = q.robot().chain();
        let convention = chain.convention();
        let scale = q.angle_scale();
        let mut values = q.values().iter();
        chain
            .dh_rows()
            .map(|row| {
                let v = match row.kind {
                    JointKind::Revolute => values.next().map_or(0.0, |x| x * scale),
                    JointKind::Prismatic => values.next().copied().unwrap_or(0.0),
                    JointKind::Fixed => 0.0,
                };
                let matrix = link_transform(convention, &row, v);
                LinkTransform {
                    matrix,
                    inverse: matrix.inverse(),
                }
            })
            .collect()
    }
}
