//! The Jacobian on the wire: `JacobianRequest` / `JacobianBatchRequest` →
//! [`JacobianSpec`] / [`JacobianBatchSpec`], [`JacobianAnswer`] →
//! `JacobianResult`. Depends on the model, [`crate::fk`], [`crate::pose`] and
//! [`crate::pb`].

use kinserve_model::{
    JacobianAnswer, JacobianBatchSpec, JacobianSpec, ModelError, ReferenceFrame, Result,
};

use crate::fk::{FkOptionsExt, batch_configurations};
use crate::pb;
use crate::pose::pose_to_pb;

impl TryFrom<pb::JacobianRequest> for JacobianSpec {
    type Error = ModelError;
    fn try_from(r: pb::JacobianRequest) -> Result<JacobianSpec> {
        let frame = frame_from_pb(r.frame, "frame")?;
        let (options, _, _) = r.options.read()?;
        Ok(JacobianSpec {
            joints: r.joints,
            options,
            frame,
        })
    }
}

impl TryFrom<pb::JacobianBatchRequest> for JacobianBatchSpec {
    type Error = ModelError;
    fn try_from(r: pb::JacobianBatchRequest) -> Result<JacobianBatchSpec> {
        let frame = frame_from_pb(r.frame, "frame")?;
        let (options, _, _) = r.options.read()?;
        Ok(JacobianBatchSpec {
            configurations: batch_configurations(&r.configurations, r.packed_configurations)?,
            options,
            frame,
        })
    }
}

impl From<&JacobianAnswer> for pb::JacobianResult {
    fn from(a: &JacobianAnswer) -> Self {
        jacobian_to_pb(a)
    }
}

/// Proto frame → model frame (unspecified: base).
pub fn frame_from_pb(frame: i32, field: &str) -> Result<ReferenceFrame> {
    match pb::JacobianFrame::try_from(frame) {
        Ok(pb::JacobianFrame::Unspecified | pb::JacobianFrame::Base) => Ok(ReferenceFrame::Base),
        Ok(pb::JacobianFrame::Tool) => Ok(ReferenceFrame::Tool),
        Err(_) => Err(ModelError::malformed_field(
            field,
            "unknown frame: use JACOBIAN_FRAME_BASE or JACOBIAN_FRAME_TOOL",
        )),
    }
}

/// Model frame → proto frame.
pub fn frame_to_pb(frame: ReferenceFrame) -> pb::JacobianFrame {
    match frame {
        ReferenceFrame::Base => pb::JacobianFrame::Base,
        ReferenceFrame::Tool => pb::JacobianFrame::Tool,
    }
}

/// A Jacobian answer as its message (6 × n values, row-major).
fn jacobian_to_pb(a: &JacobianAnswer) -> pb::JacobianResult {
    let c = a.measures.condition_number;
    pb::JacobianResult {
        frame: frame_to_pb(a.frame) as i32,
        columns: a.jacobian.dof() as u32,
        values: a.jacobian.rows().into_iter().flatten().collect(),
        manipulability: a.measures.manipulability,
        condition_number: c.is_finite().then_some(c),
        singular: a.measures.singular,
        pose: Some(pose_to_pb(&a.pose)),
    }
}
