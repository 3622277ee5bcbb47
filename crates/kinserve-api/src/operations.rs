//! The operations on one configuration ([`kinserve_model::operations`]) on
//! the wire: [`PbConfigOp`] says, per operation, which messages its gRPC
//! method takes and answers and which fields carry it on the FK stream; the
//! table ([`kinserve_model::config_ops!`]) turns those into the stream
//! message's flags ([`stream_ops`], [`stream_op_flag`]) and the stream reply's fields
//! ([`put_stream_answers`]) with no line per operation here. The server's
//! gRPC methods come from the same table.
//!
//! Depends on the model, [`crate::fk`] and [`crate::pb`] only.

use kinserve_model::operations::{
    ConfigAnswers, ConfigOp, ConfigOps, ConfigSpec, LinkTransform, LinkTransforms,
};
use kinserve_model::{LengthUnit, Result};

use crate::fk::FkOptionsExt;
use crate::pb;

/// An operation on one configuration on gRPC: its unary method's messages
/// and its fields on the FK stream.
pub trait PbConfigOp: ConfigOp {
    /// The unary method's request.
    type Request: Send + 'static;
    /// The unary method's response.
    type Response: Send + 'static;
    /// The robot the request names (field `robot`).
    fn robot(r: &Self::Request) -> &str;
    /// The request as the protocol-neutral spec (errors with REST's field paths).
    fn spec(r: Self::Request) -> Result<ConfigSpec>;
    /// The unary response for `robot`'s `answer`.
    fn response(robot: String, length_unit: LengthUnit, answer: &Self::Answer) -> Self::Response;
    /// The stream message's flag asking for the operation (the field
    /// [`PbConfigOp::asked`] reads), as refusals name it.
    const STREAM_FLAG: &'static str;
    /// Whether a stream message asks for the operation.
    fn asked(msg: &pb::StreamForwardKinematicsRequest) -> bool;
    /// Writes the answer into a stream reply.
    fn put(answer: &Self::Answer, reply: &mut pb::StreamForwardKinematicsResponse);
}

/// Writes [`stream_ops`] and [`put_stream_answers`] from the table.
macro_rules! pb_stream {
    ($( $(#[$doc:meta])* $name:ident: $op:ident => [$($answer:tt)+]; )*) => {
        /// The operations on one configuration a stream message asks for.
        pub fn stream_ops(msg: &pb::StreamForwardKinematicsRequest) -> ConfigOps {
            ConfigOps {
                $( $name: <$op as PbConfigOp>::asked(msg), )*
            }
        }

        /// The stream flag of the first operation a message asks for
        /// ([`PbConfigOp::STREAM_FLAG`]), to name it where it is refused.
        pub fn stream_op_flag(msg: &pb::StreamForwardKinematicsRequest) -> Option<&'static str> {
            $(
                if <$op as PbConfigOp>::asked(msg) {
                    return Some(<$op as PbConfigOp>::STREAM_FLAG);
                }
            )*
            None
        }

        /// Writes the answers into a stream reply.
        pub fn put_stream_answers(
            answers: &ConfigAnswers,
            reply: &mut pb::StreamForwardKinematicsResponse,
        ) {
            $(
                if let Some(a) = &answers.$name {
                    <$op as PbConfigOp>::put(a, reply);
                }
            )*
        }
    };
}

kinserve_model::config_ops!(pb_stream);

impl From<&LinkTransform> for pb::LinkTransform {
    fn from(l: &LinkTransform) -> Self {
        let matrix = |t: &kinserve_kinematics::Transform| pb::Matrix4 {
            values: t.matrix().iter().flatten().copied().collect(),
        };
        pb::LinkTransform {
            matrix: Some(matrix(&l.matrix)),
            inverse: Some(matrix(&l.inverse)),
        }
    }
}

impl PbConfigOp for LinkTransforms {
    type Request = pb::LinkTransformsRequest;
    type Response = pb::LinkTransformsResponse;
    const STREAM_FLAG: &'static str = "include_link_transforms";
    fn robot(r: &Self::Request) -> &str {
        &r.robot
    }
    fn spec(r: Self::Request) -> Result<ConfigSpec> {
        // Angle unit and limit check; frames and pose format do not apply.
        let (options, _, _) = r.options.read()?;
        Ok(ConfigSpec {
            joints: r.joints,
            options,
        })
    }
    fn response(robot: String, unit: LengthUnit, links: &Vec<LinkTransform>) -> Self::Response {
        pb::LinkTransformsResponse {
            robot,
            length_unit: pb::LengthUnit::from(unit) as i32,
            link_transforms: links.iter().map(pb::LinkTransform::from).collect(),
        }
    }
    fn asked(msg: &pb::StreamForwardKinematicsRequest) -> bool {
        msg.include_link_transforms
    }
    fn put(links: &Vec<LinkTransform>, reply: &mut pb::StreamForwardKinematicsResponse) {
        reply.link_transforms = links.iter().map(pb::LinkTransform::from).collect();
    }
}
