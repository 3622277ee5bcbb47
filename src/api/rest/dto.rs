//! REST request and response bodies.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::pose::{Pose, PoseMatrices, PoseMatrix, PosePosition, PosePositions};
use crate::api::pose_format::{self, AsMatrix, AsPose, AsPosition, Many, One, PoseFormat};
use crate::api::pose_json;
use crate::kinematics::Transform;
use crate::model::operations::{ConfigAnswers, ConfigOps, ConfigSpec};
use crate::model::{
    AngleUnit, ConventionSpec, FkOptions, IkAnswer, IkBranch, IkPathSpec, IkSolutionItem,
    IkSolverUsed, IkSpec, LengthUnit, PathStop, ReferenceFrame, Singularity,
};
use crate::model::{
    Configurations, FkBatchSpec, FkSpec, JacobianBatchSpec, JacobianSpec, StreamOp,
};

fn default_true() -> bool {
    true
}

/// A line of `GET /v1/robots`.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct RobotSummaryDto {
    /// Robot name.
    pub name: String,
    /// Number of movable joints.
    pub dof: usize,
    /// DH convention.
    pub convention: ConventionSpec,
    /// Length unit of its positions.
    pub length_unit: LengthUnit,
    /// `builtin` (read-only, from robots/) or `registered` (through the API).
    #[schema(example = "builtin")]
    pub source: String,
    /// Closed-form IK class (`spherical_wrist_parallel_23`,
    /// `spherical_wrist_intersecting_12`, `spherical_wrist_intersecting_23`,
    /// `three_parallel_234`): `solver: "analytic"` and `solutions: "all"`
    /// work; absent when only the numeric solver applies.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(example = "spherical_wrist_parallel_23")]
    pub ik_class: Option<String>,
}

/// `GET /v1/robots`.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({"robots": [{"name": "planar_2dof", "dof": 2, "convention": "standard", "length_unit": "m", "source": "builtin"}, {"name": "puma560", "dof": 6, "convention": "standard", "length_unit": "m", "source": "builtin", "ik_class": "spherical_wrist_parallel_23"}]}))]
pub struct RobotList {
    /// One page of robots, sorted by name.
    pub robots: Vec<RobotSummaryDto>,
    /// Pass as `page_token` for the next page; absent on the last page.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub next_page_token: Option<String>,
}

/// `GET /readyz`: ready, and how the registry store is doing.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({"status": "ready", "store": {"kind": "postgres", "state": "down", "snapshot_age_seconds": 12.5}}))]
pub struct Readiness {
    /// Always `ready` (a 200 answer).
    pub status: String,
    /// The registry store.
    pub store: StoreState,
}

/// The registry store's state in `/readyz`. A store that is down does not
/// make the server unready: FK, list and get go on from the snapshot; only
/// writes are refused (503).
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct StoreState {
    /// `file` (the data directory), `postgres` or `memory`.
    pub kind: String,
    /// `up` (writes accepted) or `down` (writes answered 503; reconnecting).
    pub state: String,
    /// Seconds since the snapshot was last known to equal the store.
    pub snapshot_age_seconds: f64,
}

/// Query of `GET /v1/robots` (AIP-158 pagination).
#[derive(Clone, Debug, Deserialize, utoipa::IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ListParams {
    /// Most robots to return: absent or 0 means 100; above 1000 means 1000
    /// (AIP-158); negative is a 400. Any int64 is accepted, as documented.
    #[param(minimum = 0)]
    pub page_size: Option<i64>,
    /// `next_page_token` of the previous page; absent for the first page.
    pub page_token: Option<String>,
}

/// `POST /v1/robots/{name}/fk`.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"joints": [0.5, 0.1], "angle_unit": "rad", "frames": false, "check_limits": true}))]
pub struct FkRequest {
    /// One value per movable joint in table order: revolute in `angle_unit`, prismatic in the model length unit.
    pub joints: Vec<f64>,
    /// Unit of revolute joint values (default `rad`).
    #[serde(default)]
    pub angle_unit: AngleUnit,
    /// Also return every intermediate frame (default false).
    #[serde(default)]
    pub frames: bool,
    /// Reject values outside the joint limits (default true).
    #[serde(default = "default_true")]
    pub check_limits: bool,
    /// How the pose and frames are written (default `full`): see [`PoseFormat`].
    #[serde(default)]
    pub pose_format: PoseFormat,
}

fn options(angle_unit: AngleUnit, check_limits: bool) -> FkOptions {
    FkOptions::new(Some(angle_unit), Some(check_limits))
}

impl From<FkRequest> for FkSpec {
    fn from(r: FkRequest) -> FkSpec {
        FkSpec {
            options: options(r.angle_unit, r.check_limits),
            joints: r.joints,
            frames: r.frames,
            pose_format: r.pose_format,
        }
    }
}

/// `POST /v1/robots/{name}/fk/batch`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"configurations": [[0.5, 0.1], [0.0, 0.0]], "angle_unit": "rad", "check_limits": true}))]
pub struct FkBatchRequest {
    /// Joint configurations, each like `joints` of a single request.
    #[schema(value_type = Vec<Vec<f64>>)]
    pub configurations: Configurations,
    /// Unit of revolute joint values (default `rad`).
    #[serde(default)]
    pub angle_unit: AngleUnit,
    /// Reject values outside the joint limits (default true).
    #[serde(default = "default_true")]
    pub check_limits: bool,
    /// How each pose is written (default `full`): see [`PoseFormat`].
    #[serde(default)]
    pub pose_format: PoseFormat,
}

impl From<FkBatchRequest> for FkBatchSpec {
    fn from(r: FkBatchRequest) -> FkBatchSpec {
        FkBatchSpec {
            options: options(r.angle_unit, r.check_limits),
            configurations: r.configurations,
            pose_format: r.pose_format,
        }
    }
}

/// `POST /v1/robots/{name}/jacobian`.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"joints": [0, -30, 45, 0, 60, 0], "angle_unit": "deg", "frame": "base"}))]
pub struct JacobianRequest {
    /// One value per movable joint in table order: revolute in `angle_unit`, prismatic in the model length unit.
    pub joints: Vec<f64>,
    /// Unit of revolute joint values (default `rad`). The Jacobian's columns are per rad whatever this is.
    #[serde(default)]
    pub angle_unit: AngleUnit,
    /// Reject values outside the joint limits (default true).
    #[serde(default = "default_true")]
    pub check_limits: bool,
    /// Frame of the Jacobian's rows (default `base`).
    #[serde(default)]
    pub frame: ReferenceFrame,
}

impl From<JacobianRequest> for JacobianSpec {
    fn from(r: JacobianRequest) -> JacobianSpec {
        JacobianSpec {
            options: options(r.angle_unit, r.check_limits),
            joints: r.joints,
            frame: r.frame,
        }
    }
}

/// The body of every operation on one configuration (`POST
/// /v1/robots/{name}/{operation}`; see [`crate::model::operations`]).
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"joints": [0.5, 0.1], "angle_unit": "rad"}))]
pub struct JointsRequest {
    /// One value per movable joint in table order: revolute in `angle_unit`, prismatic in the model length unit.
    pub joints: Vec<f64>,
    /// Unit of revolute joint values (default `rad`).
    #[serde(default)]
    pub angle_unit: AngleUnit,
    /// Reject values outside the joint limits (default true).
    #[serde(default = "default_true")]
    pub check_limits: bool,
}

impl From<JointsRequest> for ConfigSpec {
    fn from(r: JointsRequest) -> ConfigSpec {
        ConfigSpec {
            options: options(r.angle_unit, r.check_limits),
            joints: r.joints,
        }
    }
}

/// `POST /v1/robots/{name}/jacobian/batch`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"configurations": [[0, 0], [0.5, -0.3]], "frame": "tool"}))]
pub struct JacobianBatchRequest {
    /// Joint configurations, each like `joints` of a single request.
    #[schema(value_type = Vec<Vec<f64>>)]
    pub configurations: Configurations,
    /// Unit of revolute joint values (default `rad`).
    #[serde(default)]
    pub angle_unit: AngleUnit,
    /// Reject values outside the joint limits (default true).
    #[serde(default = "default_true")]
    pub check_limits: bool,
    /// Frame of the Jacobians' rows (default `base`).
    #[serde(default)]
    pub frame: ReferenceFrame,
}

impl From<JacobianBatchRequest> for JacobianBatchSpec {
    fn from(r: JacobianBatchRequest) -> JacobianBatchSpec {
        JacobianBatchSpec {
            options: options(r.angle_unit, r.check_limits),
            configurations: r.configurations,
            frame: r.frame,
        }
    }
}

/// `POST /v1/robots/{name}/fk` response as it is written: [`FkOutput`] with
/// the pose and frames in the fields of the request's `pose_format`,
/// serialised straight from the transforms.
///
/// [`FkOutput`]: crate::api::pose::FkOutput
#[derive(Debug, Serialize)]
pub struct FkReply<'a> {
    /// Robot name.
    pub robot: &'a str,
    /// Length unit of every position.
    pub length_unit: LengthUnit,
    /// Tool pose (`full`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pose: Option<One<AsPose>>,
    /// Tool pose (`matrix`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub matrix: Option<One<AsMatrix>>,
    /// Tool position (`position`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub position: Option<One<AsPosition>>,
    /// Every frame, when asked for (`full`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frames: Option<Many<'a, AsPose>>,
    /// Every frame, when asked for (`matrix`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_matrices: Option<Many<'a, AsMatrix>>,
    /// Every frame's position, when asked for (`position`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_positions: Option<Many<'a, AsPosition>>,
}

impl<'a> FkReply<'a> {
    /// The answer with `pose` and `frames` (when asked for) in `format`.
    pub fn new(
        robot: &'a str,
        length_unit: LengthUnit,
        format: PoseFormat,
        pose: Transform,
        frames: Option<&'a [Transform]>,
    ) -> FkReply<'a> {
        let p = pose_format::one(format, pose);
        let f = pose_format::many(format, frames);
        FkReply {
            robot,
            length_unit,
            pose: p.full,
            matrix: p.matrix,
            position: p.position,
            frames: f.full,
            frame_matrices: f.matrix,
            frame_positions: f.position,
        }
    }
}

impl FkReply<'_> {
    /// Appends this answer's JSON: exactly the bytes serde_json writes for it
    /// (tested), with the poses written by [`pose_json`] rather than through
    /// serde (the `fk` handler's answer; other paths keep serde).
    pub fn write_json(&self, out: &mut Vec<u8>) -> serde_json::Result<()> {
        out.extend_from_slice(b"{\"robot\":");
        serde_json::to_writer(&mut *out, self.robot)?;
        out.extend_from_slice(b",\"length_unit\":");
        serde_json::to_writer(&mut *out, &self.length_unit)?;
        let one = [
            ("pose", PoseFormat::Full, self.pose.map(|p| p.0)),
            ("matrix", PoseFormat::Matrix, self.matrix.map(|p| p.0)),
            ("position", PoseFormat::Position, self.position.map(|p| p.0)),
        ];
        for (name, format, t) in one {
            if let Some(t) = t {
                field_name(out, name);
                pose_json::pose(out, format, &t);
            }
        }
        let many = [
            ("frames", PoseFormat::Full, self.frames.map(|m| m.0)),
            (
                "frame_matrices",
                PoseFormat::Matrix,
                self.frame_matrices.map(|m| m.0),
            ),
            (
                "frame_positions",
                PoseFormat::Position,
                self.frame_positions.map(|m| m.0),
            ),
        ];
        for (name, format, ts) in many {
            if let Some(ts) = ts {
                field_name(out, name);
                pose_json::poses(out, format, ts);
            }
        }
        out.push(b'}');
        Ok(())
    }
}

/// `,"name":` (names here are plain ASCII: nothing to escape).
fn field_name(out: &mut Vec<u8>, name: &str) {
    out.extend_from_slice(b",\"");
    out.extend_from_slice(name.as_bytes());
    out.extend_from_slice(b"\":");
}

/// `POST /v1/robots/{name}/fk/batch` response. The poses come in exactly one
/// field, chosen by the request's `pose_format`: `poses` (`full`, the
/// default), `matrices` (`matrix`) or `positions` (`position`).
// Whichever it is, it is the last field written (`streamed` relies on it).
#[derive(Debug, Serialize, ToSchema)]
#[schema(example = json!({"robot": "planar_2dof", "length_unit": "m", "poses": [{"matrix": [[0.8253356149096783, -0.5646424733950354, 0.0, 0.5986337092290526], [0.5646424733950354, 0.8253356149096783, 0.0, 0.36116295746019184], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], "position": [0.5986337092290526, 0.36116295746019184, 0.0], "quaternion": {"w": 0.955336489125606, "x": 0.0, "y": 0.0, "z": 0.2955202066613396}, "rpy": [0.0, -0.0, 0.6]}, {"matrix": [[1.0, 0.0, 0.0, 0.7], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], "position": [0.7, 0.0, 0.0], "quaternion": {"w": 1.0, "x": 0.0, "y": 0.0, "z": 0.0}, "rpy": [0.0, -0.0, 0.0]}]}))]
pub struct FkBatchResponse<'a> {
    /// Robot name.
    pub robot: &'a str,
    /// Length unit of every position.
    pub length_unit: LengthUnit,
    /// One full pose object per configuration, in request order. Present
    /// when `pose_format` is `full` (the default); absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Vec<Pose>)]
    pub poses: Option<Many<'a, AsPose>>,
    /// One pose per configuration, in request order, as 12 numbers. Present
    /// only when `pose_format` is `matrix`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PoseMatrices)]
    pub matrices: Option<Many<'a, AsMatrix>>,
    /// One position `[x, y, z]` per configuration, in request order. Present
    /// only when `pose_format` is `position`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PosePositions)]
    pub positions: Option<Many<'a, AsPosition>>,
}

impl<'a> FkBatchResponse<'a> {
    /// The answer with `poses` in the field of `format`.
    pub fn new(
        robot: &'a str,
        length_unit: LengthUnit,
        format: PoseFormat,
        poses: &'a [Transform],
    ) -> FkBatchResponse<'a> {
        let p = pose_format::many(format, Some(poses));
        FkBatchResponse {
            robot,
            length_unit,
            poses: p.full,
            matrices: p.matrix,
            positions: p.position,
        }
    }
}

/// Writes [`WsRequest`] and its conversion with one flag per operation on one
/// configuration (the table [`crate::model::config_ops!`]).
macro_rules! ws_request {
    ($( $(#[$doc:meta])* $name:ident: $op:ident => [$($answer:tt)+]; )*) => {
/// A WebSocket request: like [`FkRequest`] plus a client `id` echoed in the
/// reply; with `"jacobian": true` the reply carries the Jacobian too; with
/// `"ik": {...}` (an IK request body, and no `joints`) it is an IK request.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"id": 1, "joints": [0.5, 0.1], "angle_unit": "rad"}))]
pub struct WsRequest {
    /// Any JSON value; echoed in the reply.
    #[serde(default)]
    pub id: serde_json::Value,
    /// Joint values (see [`FkRequest::joints`]); required unless `ik` is given.
    #[serde(default)]
    pub joints: Option<Vec<f64>>,
    /// Also return the Jacobian and its measures (default false).
    #[serde(default)]
    pub jacobian: bool,
    /// Frame of the Jacobian's rows (default `base`).
    #[serde(default)]
    pub frame: ReferenceFrame,
    /// An IK request instead of FK (like the body of `POST /v1/robots/{name}/ik`).
    // Boxed, as `ik_path`: inline they made every FK message's request 864
    // bytes, copied at each move.
    #[serde(default)]
    pub ik: Option<Box<IkSpec>>,
    /// A Cartesian path instead of FK (like the body of `POST /v1/robots/{name}/ik/path`).
    #[serde(default)]
    pub ik_path: Option<Box<IkPathSpec>>,
    /// Many configurations instead of `joints`: FK of each, as
    /// `POST /v1/robots/{name}/fk/batch` computes it (at most the batch limit;
    /// no frames, Jacobian or operations on one configuration). The reply
    /// carries `poses`, `matrices` or `positions` as that route answers.
    #[serde(default)]
    #[schema(value_type = Option<Vec<Vec<f64>>>)]
    pub configurations: Option<Configurations>,
    $(
        $(#[$doc])*
        ///
        /// Also answered with FK when `true` (default false), under its own
        /// name, as its REST route answers it.
        #[serde(default)]
        pub $name: bool,
    )*
    /// Unit of revolute joint values (default `rad`).
    #[serde(default)]
    pub angle_unit: AngleUnit,
    /// Also return every intermediate frame (default false).
    #[serde(default)]
    pub frames: bool,
    /// Reject values outside the joint limits (default true).
    #[serde(default = "default_true")]
    pub check_limits: bool,
    /// How the pose and frames of an FK reply are written (default `full`):
    /// see [`PoseFormat`]. IK replies always carry the full pose.
    #[serde(default)]
    pub pose_format: PoseFormat,
}

impl TryFrom<WsRequest> for StreamOp {
    type Error = crate::model::ModelError;
    /// FK (with the Jacobian and the operations on one configuration when
    /// asked for) or IK; both `joints` and `ik`, or neither, is refused
    /// naming `joints`.
    fn try_from(r: WsRequest) -> Result<StreamOp, Self::Error> {
        use crate::model::ModelError;
        if let Some(configurations) = r.configurations {
            // Refused as the gRPC stream refuses them, naming the field.
            if r.joints.is_some() || r.ik.is_some() || r.ik_path.is_some() {
                return Err(ModelError::invalid_field(
                    "configurations",
                    "give joints (FK), configurations (FK of many), ik or ik_path, one of them",
                ));
            }
            if r.jacobian {
                return Err(ModelError::invalid_field(
                    "jacobian",
                    "the Jacobian is for one configuration: send joints, or use POST …/jacobian/batch",
                ));
            }
            $(
            if r.$name {
                return Err(ModelError::invalid_field(
                    stringify!($name),
                    "operations on one configuration need joints, not configurations",
                ));
            }
            )*
            if r.frames {
                return Err(ModelError::malformed_field(
                    "frames",
                    "FK of many configurations returns tool poses only: send joints for frames",
                ));
            }
            return Ok(StreamOp::FkBatch(FkBatchSpec {
                configurations,
                options: options(r.angle_unit, r.check_limits),
                pose_format: r.pose_format,
            }));
        }
        if let Some(path) = r.ik_path {
            if r.ik.is_some() || r.joints.is_some() {
                return Err(ModelError::invalid_field(
                    "joints",
                    "give joints (FK), ik or ik_path, one of them",
                ));
            }
            return Ok(StreamOp::IkPath(path));
        }
        match (r.ik, r.joints) {
            (Some(_), Some(_)) => Err(ModelError::invalid_field(
                "joints",
                "give joints (FK) or ik, not both",
            )),
            (Some(ik), None) => Ok(StreamOp::Ik(ik)),
            // As serde reports a missing field (400), naming the alternative.
            (None, None) => Err(ModelError::malformed_field(
                "joints",
                "missing field `joints` (or give `ik`)",
            )),
            (None, Some(joints)) => Ok(StreamOp::Fk {
                fk: FkSpec {
                    joints,
                    options: options(r.angle_unit, r.check_limits),
                    frames: r.frames,
                    pose_format: r.pose_format,
                },
                jacobian: r.jacobian.then_some(r.frame),
                ops: ConfigOps {
                    $( $name: r.$name, )*
                },
            }),
        }
    }
}
    };
}

crate::model::config_ops!(ws_request);

/// Just the `id` of a WebSocket message that failed to parse.
#[derive(Deserialize)]
pub struct WsIdOnly {
    /// The client's id, if it could be read.
    #[serde(default)]
    pub id: serde_json::Value,
}

/// A WebSocket reply. On success the pose comes in exactly one field, chosen
/// by the message's `pose_format` (FK and Jacobian replies; IK replies always
/// carry `pose`): `pose` and `frames` (`full`, the default), `matrix` and
/// `frame_matrices` (`matrix`) or `position` and `frame_positions`
/// (`position`); the frame fields only with `"frames": true`.
#[derive(Debug, Serialize, ToSchema)]
#[schema(example = json!({"id": 1, "length_unit": "m", "pose": {"matrix": [[0.8253356149096783, -0.5646424733950354, 0.0, 0.5986337092290526], [0.5646424733950354, 0.8253356149096783, 0.0, 0.36116295746019184], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], "position": [0.5986337092290526, 0.36116295746019184, 0.0], "quaternion": {"w": 0.955336489125606, "x": 0.0, "y": 0.0, "z": 0.2955202066613396}, "rpy": [0.0, -0.0, 0.6]}}))]
pub struct WsReply<'a> {
    /// The request's `id`.
    #[schema(value_type = Object)]
    pub id: &'a serde_json::Value,
    /// Length unit of every position in this reply, on success.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub length_unit: Option<LengthUnit>,
    /// The tool pose as the full pose object, on success: for FK when
    /// `pose_format` is `full` (the default), for IK always (the pose at the
    /// joints found).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Pose)]
    pub pose: Option<One<AsPose>>,
    /// The tool pose as 12 numbers, on success, only when `pose_format` is
    /// `matrix`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PoseMatrix)]
    pub matrix: Option<One<AsMatrix>>,
    /// The tool position `[x, y, z]`, on success, only when `pose_format` is
    /// `position`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PosePosition)]
    pub position: Option<One<AsPosition>>,
    /// Every frame as a full pose object, when `"frames": true` and
    /// `pose_format` is `full`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Vec<Pose>)]
    pub frames: Option<Many<'a, AsPose>>,
    /// Every frame as 12 numbers, when `"frames": true` and `pose_format` is
    /// `matrix`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PoseMatrices)]
    pub frame_matrices: Option<Many<'a, AsMatrix>>,
    /// Every frame's position `[x, y, z]`, when `"frames": true` and
    /// `pose_format` is `position`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PosePositions)]
    pub frame_positions: Option<Many<'a, AsPosition>>,
    /// With `configurations`: one full pose object per configuration, in
    /// order, when `pose_format` is `full` (as `POST …/fk/batch` answers).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Vec<Pose>)]
    pub poses: Option<Many<'a, AsPose>>,
    /// With `configurations`: one pose per configuration as 12 numbers, when
    /// `pose_format` is `matrix`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PoseMatrices)]
    pub matrices: Option<Many<'a, AsMatrix>>,
    /// With `configurations`: one position `[x, y, z]` per configuration,
    /// when `pose_format` is `position`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = PosePositions)]
    pub positions: Option<Many<'a, AsPosition>>,
    /// With `"jacobian": true`: the Jacobian and its measures (as `POST …/jacobian` answers them).
    #[serde(flatten)]
    pub jacobian: Option<WsJacobian>,
    /// For an IK request: the answer (as `POST …/ik` answers it, `pose` above).
    #[serde(flatten)]
    pub ik: Option<WsIk>,
    /// For a Cartesian path: the answer (as `POST …/ik/path` answers it).
    #[serde(flatten)]
    pub ik_path: Option<WsIkPath>,
    /// The operations on one configuration asked for (`"<name>": true`),
    /// each under its name as its REST route answers it.
    #[serde(flatten)]
    pub ops: ConfigAnswers,
    /// The problem, on failure.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<super::problem::Problem>,
}

impl<'a> WsReply<'a> {
    /// A reply to `id` with nothing in it yet.
    pub fn empty(id: &'a serde_json::Value) -> WsReply<'a> {
        WsReply {
            id,
            length_unit: None,
            pose: None,
            matrix: None,
            position: None,
            frames: None,
            frame_matrices: None,
            frame_positions: None,
            poses: None,
            matrices: None,
            positions: None,
            jacobian: None,
            ik: None,
            ik_path: None,
            ops: ConfigAnswers::default(),
            error: None,
        }
    }

    /// A success reply with `pose` and `frames` (when asked for) in `format`.
    pub fn posed(
        id: &'a serde_json::Value,
        length_unit: LengthUnit,
        format: PoseFormat,
        pose: Transform,
        frames: Option<&'a [Transform]>,
    ) -> WsReply<'a> {
        let p = pose_format::one(format, pose);
        let f = pose_format::many(format, frames);
        WsReply {
            length_unit: Some(length_unit),
            pose: p.full,
            matrix: p.matrix,
            position: p.position,
            frames: f.full,
            frame_matrices: f.matrix,
            frame_positions: f.position,
            ..WsReply::empty(id)
        }
    }
}

/// The Jacobian part of a WebSocket reply (see [`crate::api::jacobian::JacobianItem`]).
#[derive(Debug, Serialize, ToSchema)]
pub struct WsJacobian {
    /// Frame of the rows.
    pub frame: ReferenceFrame,
    /// 6 rows × one column per joint.
    pub jacobian: Vec<Vec<f64>>,
    /// `√det(J Jᵀ)` (see the REST endpoint).
    pub manipulability: f64,
    /// Largest over smallest singular value; `null` when the smallest is 0.
    pub condition_number: Option<f64>,
    /// Smallest singular value below 1e-6.
    pub singular: bool,
}

impl From<&crate::model::JacobianAnswer> for WsJacobian {
    fn from(a: &crate::model::JacobianAnswer) -> Self {
        let item = crate::api::jacobian::JacobianItem::from(a);
        WsJacobian {
            frame: item.frame,
            jacobian: item.jacobian,
            manipulability: item.manipulability,
            condition_number: item.condition_number,
            singular: item.singular,
        }
    }
}

/// The path part of a WebSocket reply (see [`crate::api::ik::IkPathOutput`]).
#[derive(Debug, Serialize, ToSchema)]
pub struct WsIkPath {
    /// Joint values per step: the start, then each step taken.
    pub points: Vec<Vec<f64>>,
    /// Steps taken ÷ steps planned.
    pub fraction: f64,
    /// Waypoints fully reached.
    pub waypoints_reached: usize,
    /// `null` when complete; else where and why it stopped.
    pub stop: Option<PathStop>,
}

/// The IK part of a WebSocket reply (see [`crate::api::ik::IkItem`]).
#[derive(Debug, Serialize, ToSchema)]
pub struct WsIk {
    /// Joint values in the request's angle unit.
    pub joints: Vec<f64>,
    /// Always true here (not converged is an `error` with the best attempt).
    pub converged: bool,
    /// Distance from the target position, robot length unit.
    pub position_error: f64,
    /// Angle from the target orientation, rad (`null` without one).
    pub orientation_error: Option<f64>,
    /// Solver iterations.
    pub iterations: u32,
    /// The solver that ran (`analytic` or `numeric`).
    pub solver: IkSolverUsed,
    /// The closed-form branch of `joints` (`null` from the numeric solver).
    pub branch: Option<IkBranch>,
    /// Singularities `joints` stands at.
    pub singular: Vec<Singularity>,
    /// With `solutions: "all"` only: every solution, nearest the seed first.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solutions: Option<Vec<IkSolutionItem>>,
    /// With `solutions: "all"` only: whether more fit than `max_solutions`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truncated: Option<bool>,
}

impl From<&IkAnswer> for WsIk {
    fn from(a: &IkAnswer) -> Self {
        WsIk {
            joints: a.joints.clone(),
            converged: a.converged,
            position_error: a.position_error,
            orientation_error: a.orientation_error,
            iterations: a.iterations,
            solver: a.solver,
            branch: a.branch,
            singular: a.singular.clone(),
            solutions: a.solutions.clone(),
            truncated: a.solutions.is_some().then_some(a.truncated),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fk_answer_written_directly_is_serde_jsons_byte_for_byte() {
        let pose = Transform::rot_z(0.6).compose(&Transform::translation(0.3, -0.0, 1.0 / 3.0));
        let frames = [Transform::IDENTITY, Transform::rot_x(-2.9), pose];
        for format in [PoseFormat::Full, PoseFormat::Matrix, PoseFormat::Position] {
            for with_frames in [None, Some(&frames[..])] {
                for unit in [LengthUnit::M, LengthUnit::Mm] {
                    let reply = FkReply::new("ur5e \"copy\"", unit, format, pose, with_frames);
                    let mut fast = Vec::new();
                    reply.write_json(&mut fast).unwrap();
                    let reference = serde_json::to_vec(&reply).unwrap();
                    assert_eq!(
                        String::from_utf8(fast).unwrap(),
                        String::from_utf8(reference).unwrap(),
                        "{format:?}, frames: {}",
                        with_frames.is_some()
                    );
                }
            }
        }
    }
}
