//! kinserve-model: robot models as clients write them and as the math accepts
//! them.
//!
//! It owns the schema ([`RobotSpec`], read from robot files, REST bodies and,
//! field by field, gRPC messages), its validation into a [`Robot`] with every
//! broken rule reported under its field path (`links[3].alpha`), units, base
//! and tool, and the validated joint vector ([`JointVector`], [`JointBatch`]):
//! the only input a robot's forward kinematics accepts, so "checked" is a
//! type, not a naming convention. On top of it: the Jacobian of a joint
//! vector ([`JointVector::jacobian`]) and validated inverse-kinematics
//! requests ([`IkSpec`] → [`Robot::check_ik`] → [`IkRequest`]).
//!
//! Units: a model keeps its own length unit (m or mm) and declares the angle
//! unit of its table (rad or deg); internally angles are rad.
//!
//! Depends on `kinserve-kinematics` (the math) and serde. Must not depend on:
//! tokio, axum, tonic, prost, hyper, tower, reqwest — nor on the server crate.
//! With the `openapi` feature the schema types also derive `utoipa::ToSchema`.
#![doc = include_str!("crate_example.md")]

mod base_tool;
mod closed_form;
mod error;
mod ik;
mod ik_objectives;
mod ik_path;
mod ik_solutions;
mod joints;
mod json;
mod json_rows;
pub mod operations;
mod pose_format;
mod requests;
mod robot;
mod spec;
mod text;
mod urdf;
mod urdf_import;
mod velocity;

pub use closed_form::{ClosedForm, JointVariable, SymbolicMatrix};
pub use error::{FieldViolation, ModelError, Result, summary};
pub use ik::{
    IK_MAX_ITERATIONS, IK_MAX_RESTARTS, IK_TOLERANCE_RANGE, IkAnswer, IkBatch, IkBatchSpec,
    IkRequest, IkSpec, IkTarget, IkTargetSpec,
};
pub use ik_objectives::{AxisTolerancesSpec, PoseAxis, PostureSpec};
pub use ik_path::{
    IkPathAnswer, IkPathRequest, IkPathSpec, PATH_DEFAULT_JOINT_STEP, PATH_DEFAULT_STEP_ANGLE,
    PathStop, PathStopReason,
};
pub use ik_solutions::{
    IK_DEFAULT_MAX_SOLUTIONS, IK_MAX_BATCH_SOLUTIONS, IK_MAX_SOLUTIONS, IkBranch, IkSolutionItem,
    IkSolutionsMode, IkSolverChoice, IkSolverUsed, Singularity,
};
pub use joints::{JointBatch, JointVector};
pub use json::{
    MAX_ROBOT_FILE_BYTES, load_robot_file, load_robot_file_with, parse_json, read_robot_file,
};
pub use json_rows::{parse_json_rows, parse_json_values, split_rows, split_values};
pub use pose_format::{BatchPoses, PoseFormat, matrix12};
pub use requests::{
    Configurations, FkBatchSpec, FkSpec, JacobianBatchSpec, JacobianSpec, StreamOp,
};
pub use robot::{FkOptions, Joint, ModelLimits, Robot};
pub use spec::{
    AngleUnit, ConventionSpec, JointType, LengthUnit, LinkSpec, QuaternionSpec, RobotSpec,
    TransformSpec,
};
pub use text::{SAFE_SET, check_label, check_text, forbidden};
pub use urdf::to_urdf;
pub use urdf_import::{UrdfImport, import_urdf, import_urdf_with};
pub use velocity::{JacobianAnswer, ReferenceFrame};

/// Tolerance on `RᵀR − I` and `det R − 1` for a matrix to count as rigid.
pub const RIGID_TOLERANCE: f64 = 1e-6;
/// Longest `description` / `source` accepted (characters; see [`check_text`]).
pub const MAX_TEXT_CHARS: usize = 4096;
/// Longest link name accepted (characters; see [`check_label`]).
pub const MAX_LINK_NAME_CHARS: usize = 64;
/// Largest magnitude accepted for a model's DH parameters (`a`, `d`, `alpha`,
/// `theta`), base/tool translations and prismatic limits, and for prismatic
/// joint values in FK requests: 1e9 in the model's own units (m or mm, rad or
/// deg). With at most a few hundred rows every pose then stays many orders of
/// magnitude below `f64::MAX`, so FK never overflows to infinity or NaN.
pub const MAX_MAGNITUDE: f64 = 1e9;

/// Largest magnitude of a revolute joint value accepted in an FK request, in
/// rad (±1e5 rad, about ±15,900 turns; ±5,729,578° in degrees). Beyond it the
/// angle's own rounding (an ulp of 1e5 is 1.5e-11 rad) would start to differ
/// between evaluation paths; no joint turns that far.
pub const MAX_REVOLUTE_RAD: f64 = 1e5;

/// Checks a robot name: 1–64 characters of `[a-z0-9_-]`, first a letter or digit.
pub fn validate_name(name: &str) -> std::result::Result<(), String> {
    if name.is_empty() {
        return Err("must not be empty".into());
    }
    if name.len() > 64 {
        return Err(format!(
            "must be at most 64 characters, got {}",
            name.chars().count()
        ));
    }
    let ok_char = |c: char| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_' || c == '-';
    if !name.chars().all(ok_char) {
        return Err("may contain only lowercase letters a-z, digits, '_' and '-'".into());
    }
    let first = name.as_bytes()[0];
    if !(first.is_ascii_lowercase() || first.is_ascii_digit()) {
        return Err("must start with a lowercase letter or a digit".into());
    }
    Ok(())
}
