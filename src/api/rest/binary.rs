//! Binary batch bodies on REST: the batch routes (`…/fk/batch`,
//! `…/jacobian/batch`, `…/ik/batch`) take and give, besides JSON (the
//! default),
//!
//! - `application/x-protobuf` ([`PROTOBUF`]): the gRPC method's own request
//!   and response messages (`kinematics.v1.ForwardKinematicsBatchRequest` /
//!   `…Response`, …). The message's `robot` may be empty (the path names the
//!   robot); a name that is not the path's is refused (422 naming `robot`).
//! - `application/octet-stream` ([`PACKED`]; FK and Jacobian): little-endian
//!   float64, no header: `n × dof` joint values in, the layout of
//!   [`kinserve_api::poses_to_le`] / [`kinserve_api::jacobians_to_le`] out.
//!   The options JSON takes in the body come as query parameters
//!   ([`PackedFkQuery`], [`PackedJacobianQuery`]); packed FK answers say
//!   their pose format and length unit in the `Kinserve-Pose-Format` and
//!   `Kinserve-Length-Unit` headers.
//!
//! The request's format is its `Content-Type` (415 for any other), the
//! answer's is chosen by `Accept` ([`negotiate`]; absent or `*/*`: JSON; none
//! of the three: 406), independently. Errors are `application/problem+json`
//! whatever `Accept` says. The limits are JSON's: the route's body limit, the
//! batch size (checked before a packed body is decoded), the batch slot and
//! the compute pool.
//!
//! Owns the batch body extractor, the content negotiation and the binary
//! answers; the byte layouts and protobuf conversions are `kinserve-api`'s,
//! the JSON answers `streamed`'s. Depends on `extract` and the service.

use axum::body::Bytes;
use axum::extract::{FromRequest, Query, Request};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use prost::Message;
use serde::Deserialize;
use serde::de::DeserializeOwned;
use utoipa::openapi::RefOr;
use utoipa::openapi::schema::{KnownFormat, ObjectBuilder, Schema, SchemaFormat, Type};

use super::AppState;
use super::dto::{FkBatchRequest, JacobianBatchRequest};
use super::extract::{content_type, is_json, parse_object, parse_object_rows, read_bytes, refusal};
use super::problem::Problem;
use crate::error::Error;
use crate::model::{
    AngleUnit, BatchPoses, Configurations, FkBatchSpec, FkOptions, IkAnswer, IkBatchSpec,
    JacobianAnswer, JacobianBatchSpec, PoseFormat, ReferenceFrame, Robot,
};
use crate::service::Service;
use kinserve_api::{ConfigurationBatch, pb};

/// The protobuf media type: the gRPC method's own messages.
pub const PROTOBUF: &str = "application/x-protobuf";
/// The packed media type: little-endian float64 (see the module documentation).
pub const PACKED: &str = "application/octet-stream";

/// The request body of a batch route, in the OpenAPI document.
pub const BATCH_BODY: &str = "The batch as JSON (`application/json`); or as the gRPC method's \
request message (`application/x-protobuf`; its `robot` empty or the path's); or, for FK and \
Jacobian batches, packed (`application/octet-stream`): n × dof little-endian float64 joint values, \
configuration after configuration (no header; a length that is not a multiple of dof × 8 is a 400 \
naming `body`), with the JSON body's options as query parameters.";

/// The request body of the IK batch, in the OpenAPI document.
pub const IK_BATCH_BODY: &str = "The targets as JSON (`application/json`), or as the \
`InverseKinematicsBatchRequest` message (`application/x-protobuf`; its `robot` empty or the path's).";

/// The 200 answer of a batch route, in the OpenAPI document.
pub const BATCH_ANSWER: &str = "The results, in the format `Accept` asks for (default \
`application/json`): JSON; the gRPC method's response message (`application/x-protobuf`); or \
packed little-endian float64 (`application/octet-stream`, FK and Jacobian batches): per FK pose \
12 numbers (`matrix`: the top three rows of the 4×4 matrix, row-major; `full` is written as \
`matrix`) or 3 (`position`), per Jacobian result the 6 × dof rows, manipulability, condition number \
(+inf for null), singular (1 or 0) and the 12 `matrix` numbers of the pose.";

/// A body or answer format of the batch routes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Media {
    /// `application/json` (the default).
    Json,
    /// [`PROTOBUF`].
    Protobuf,
    /// [`PACKED`].
    Packed,
}

/// The answer formats in the server's order of preference, with their
/// `type/subtype`.
const OFFERS: [(Media, &str, &str); 3] = [
    (Media::Json, "application", "json"),
    (Media::Protobuf, "application", "x-protobuf"),
    (Media::Packed, "application", "octet-stream"),
];

/// The answer format `Accept` asks for (RFC 9110 §12.5.1): each offer takes
/// the quality of the most specific range that matches it; the highest
/// quality wins, then the most specific match, then JSON before protobuf
/// before packed. No `Accept` (or `*/*`): JSON. None acceptable: `None`
/// (answered with [`not_acceptable`]'s 406).
/// `packed` says whether the route answers [`PACKED`].
pub fn negotiate(headers: &HeaderMap, packed: bool) -> Option<Media> {
    // The common cases, without parsing: none, `*/*` (curl), `application/json`.
    let mut values = headers.get_all(header::ACCEPT).iter();
    match (values.next().map(HeaderValue::as_bytes), values.next()) {
        (None, _) | (Some(b"*/*" | b"application/json"), None) => return Some(Media::Json),
        _ => {}
    }
    let ranges: Vec<(&str, &str, u16)> = headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .filter_map(media_range)
        .collect();
    if ranges.is_empty() {
        return Some(Media::Json);
    }
    let mut best: Option<(u16, u8, Media)> = None;
    for (media, kind, sub) in OFFERS {
        if media == Media::Packed && !packed {
            continue;
        }
        let matched = ranges
            .iter()
            .filter_map(|&(k, s, q)| specificity(k, s, kind, sub).map(|spec| (spec, q)))
            .max();
        if let Some((spec, q)) = matched
            && q > 0
            && best.is_none_or(|(bq, bs, _)| (q, spec) > (bq, bs))
        {
            best = Some((q, spec, media));
        }
    }
    best.map(|(_, _, media)| media)
}

/// One media range of `Accept`: type, subtype and quality in thousandths
/// (absent or unreadable `q`: 1).
fn media_range(text: &str) -> Option<(&str, &str, u16)> {
    let mut parts = text.split(';');
    let (kind, sub) = parts.next()?.trim().split_once('/')?;
    let q = parts
        .filter_map(|p| p.split_once('='))
        .find(|(k, _)| k.trim().eq_ignore_ascii_case("q"))
        .and_then(|(_, v)| v.trim().parse::<f64>().ok())
        .map_or(1000, |q| (q.clamp(0.0, 1.0) * 1000.0).round() as u16);
    Some((kind.trim(), sub.trim(), q))
}

/// How specifically the range `k/s` matches `kind/sub`: 2 exactly, 1 by
/// `kind/*`, 0 by `*/*`; `None` when it does not.
fn specificity(k: &str, s: &str, kind: &str, sub: &str) -> Option<u8> {
    if k == "*" && s == "*" {
        Some(0)
    } else if k.eq_ignore_ascii_case(kind) && s == "*" {
        Some(1)
    } else if k.eq_ignore_ascii_case(kind) && s.eq_ignore_ascii_case(sub) {
        Some(2)
    } else {
        None
    }
}

/// The 406 problem: what `Accept` said and what the route answers in.
fn not_acceptable(headers: &HeaderMap, packed: bool) -> Problem {
    let asked: String = headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .collect::<Vec<_>>()
        .join(", ")
        .chars()
        .take(200)
        .collect();
    let formats = if packed {
        format!("application/json (the default), {PROTOBUF} or {PACKED}")
    } else {
        format!("application/json (the default) or {PROTOBUF}")
    };
    Problem::protocol(
        StatusCode::NOT_ACCEPTABLE,
        "not-acceptable",
        "Not acceptable",
        format!("Accept '{asked}' names no format this route answers in: ask for {formats}"),
    )
}

/// A batch operation's request in its three formats.
pub trait BatchKind: Send {
    /// The JSON body.
    type Json: DeserializeOwned + Send;
    /// The protobuf request message.
    type Proto: Message + Default;
    /// The query parameters of a packed body (the JSON body's options).
    type Query: DeserializeOwned + Send + PackedQuery;
    /// The protocol-neutral request.
    type Spec;
    /// Whether packed bodies and answers are supported.
    const PACKED: bool;
    /// The JSON body as a request.
    fn from_json(json: Self::Json) -> Self::Spec;
    /// Parses the JSON body ([`parse_object`]; the configurations of FK and
    /// Jacobian batches by [`parse_object_rows`]).
    fn parse_json(bytes: &[u8]) -> Result<Self::Json, Error> {
        parse_object(bytes)
    }
    /// The message's robot name and number of items (configurations, targets).
    fn proto_head(msg: &Self::Proto) -> (&str, usize);
    /// What the message says that only the robot can check (the packed
    /// configurations' `joint_count`).
    fn check_proto(_msg: &Self::Proto, _dof: usize) -> Result<(), Error> {
        Ok(())
    }
    /// The message as a request.
    fn from_proto(msg: Self::Proto) -> Result<Self::Spec, Error>;
    /// A packed body's configurations and its query as a request.
    fn from_packed(configurations: Configurations, query: Self::Query)
    -> Result<Self::Spec, Error>;
}

/// What a batch route read: its request, in the format of its `Content-Type`,
/// and the format to answer in.
pub struct BatchBody<K: BatchKind> {
    /// The format of the answer (`Accept`).
    pub answer: Media,
    request: BatchRequest<K>,
}

enum BatchRequest<K: BatchKind> {
    Json(K::Json),
    Protobuf(Bytes),
    Packed(Bytes, K::Query),
}

impl<K: BatchKind> FromRequest<AppState> for BatchBody<K> {
    type Rejection = Response;

    async fn from_request(req: Request, state: &AppState) -> Result<Self, Self::Rejection> {
        let Some(answer) = negotiate(req.headers(), K::PACKED) else {
            return Err(not_acceptable(req.headers(), K::PACKED).into_response());
        };
        let unread = super::has_body(req.headers());
        let request = read::<K>(req, state)
            .await
            .map_err(|e| refusal(unread, e))?;
        Ok(BatchBody { answer, request })
    }
}

/// The body as its content type says (415 for any other type).
async fn read<K: BatchKind>(req: Request, state: &AppState) -> Result<BatchRequest<K>, Error> {
    let ct = content_type(&req);
    let mime = ct.split(';').next().unwrap_or("").trim();
    if is_json(ct) {
        let bytes = read_bytes(req, state).await?;
        Ok(BatchRequest::Json(K::parse_json(&bytes)?))
    } else if mime.eq_ignore_ascii_case(PROTOBUF) {
        Ok(BatchRequest::Protobuf(read_bytes(req, state).await?))
    } else if K::PACKED && mime.eq_ignore_ascii_case(PACKED) {
        let Query(query) = Query::<K::Query>::try_from_uri(req.uri())
            .map_err(|e| Error::malformed_field("query", e.body_text()))?;
        Ok(BatchRequest::Packed(read_bytes(req, state).await?, query))
    } else {
        let packed = if K::PACKED {
            format!(", {PACKED}")
        } else {
            String::new()
        };
        Err(Error::UnsupportedMediaType {
            detail: format!(
                "expected Content-Type application/json, {PROTOBUF}{packed}, got '{}'",
                ct.chars().take(100).collect::<String>()
            ),
        })
    }
}

impl<K: BatchKind> BatchBody<K> {
    /// The request for `robot` (the path's), refused as JSON's would be:
    /// a packed body that is not a whole number of configurations (400
    /// naming `body`), more items than a batch holds (413), a message for
    /// another robot (422 naming `robot`).
    pub fn spec(self, service: &Service, robot: &Robot) -> Result<K::Spec, Error> {
        match self.request {
            BatchRequest::Json(json) => Ok(K::from_json(json)),
            BatchRequest::Protobuf(bytes) => {
                let msg = K::Proto::decode(bytes).map_err(|e| {
                    Error::malformed_field(
                        "body",
                        format!("not a protobuf message of this route's request type: {e}"),
                    )
                })?;
                let (name, items) = K::proto_head(&msg);
                if !name.is_empty() && name != robot.name() {
                    return Err(Error::invalid_field(
                        "robot",
                        format!(
                            "'{}' is not the robot in the path ('{}'): leave it empty or send the path's name",
                            name.chars().take(64).collect::<String>(),
                            robot.name()
                        ),
                    ));
                }
                service.check_batch_size(items)?;
                K::check_proto(&msg, robot.dof())?;
                K::from_proto(msg)
            }
            BatchRequest::Packed(bytes, query) => {
                check_joint_count(query.joint_count(), robot.dof())?;
                service.check_batch_size(kinserve_api::packed_count(bytes.len(), robot.dof()))?;
                let configurations = kinserve_api::configurations_from_le(&bytes, robot.dof())?;
                K::from_packed(configurations, query)
            }
        }
    }
}

/// What every packed batch's query may say besides its options.
pub trait PackedQuery {
    /// The `joint_count` parameter: values per configuration, as the client
    /// packed them.
    fn joint_count(&self) -> Option<u32>;
}

impl PackedQuery for PackedFkQuery {
    fn joint_count(&self) -> Option<u32> {
        self.joint_count
    }
}

impl PackedQuery for PackedJacobianQuery {
    fn joint_count(&self) -> Option<u32> {
        self.joint_count
    }
}

/// A packed body's declared `joint_count` against the robot's
/// ([`kinserve_api::check_joint_count`], the gRPC field's check), naming
/// the query parameter.
fn check_joint_count(declared: Option<u32>, dof: usize) -> Result<(), Error> {
    match declared {
        Some(n) => Ok(kinserve_api::check_joint_count("joint_count", n, dof)?),
        None => Ok(()),
    }
}

/// The options of a packed FK batch (`application/octet-stream`), as query
/// parameters: what the JSON body says in its fields.
#[derive(Clone, Debug, Default, Deserialize, utoipa::IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct PackedFkQuery {
    /// `application/octet-stream` bodies only: unit of revolute joint values (default `rad`).
    pub angle_unit: Option<AngleUnit>,
    /// `application/octet-stream` bodies only: reject values outside the joint limits (default true).
    pub check_limits: Option<bool>,
    /// `application/octet-stream` bodies only: how each pose is written
    /// (default `full`; a packed answer writes `full` as `matrix`).
    pub pose_format: Option<PoseFormat>,
    /// `application/octet-stream` bodies only: values per configuration as
    /// packed; when given it must be the robot's number of joints (422 naming
    /// `joint_count`), so that an array of the wrong width is refused.
    pub joint_count: Option<u32>,
}

/// The options of a packed Jacobian batch, as query parameters.
#[derive(Clone, Debug, Default, Deserialize, utoipa::IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct PackedJacobianQuery {
    /// `application/octet-stream` bodies only: unit of revolute joint values (default `rad`).
    pub angle_unit: Option<AngleUnit>,
    /// `application/octet-stream` bodies only: reject values outside the joint limits (default true).
    pub check_limits: Option<bool>,
    /// `application/octet-stream` bodies only: frame of the rows (default `base`).
    pub frame: Option<ReferenceFrame>,
    /// `application/octet-stream` bodies only: values per configuration as
    /// packed; when given it must be the robot's number of joints (422 naming
    /// `joint_count`).
    pub joint_count: Option<u32>,
}

/// FK batches.
pub enum FkBatch {}

impl BatchKind for FkBatch {
    type Json = FkBatchRequest;
    type Proto = pb::ForwardKinematicsBatchRequest;
    type Query = PackedFkQuery;
    type Spec = FkBatchSpec;
    const PACKED: bool = true;
    fn from_json(json: FkBatchRequest) -> FkBatchSpec {
        FkBatchSpec::from(json)
    }
    fn parse_json(bytes: &[u8]) -> Result<FkBatchRequest, Error> {
        parse_object_rows(bytes, |r: &mut FkBatchRequest| &mut r.configurations)
    }
    fn proto_head(msg: &Self::Proto) -> (&str, usize) {
        (&msg.robot, msg.configuration_count())
    }
    fn check_proto(msg: &Self::Proto, dof: usize) -> Result<(), Error> {
        Ok(msg.check_joint_count(dof)?)
    }
    fn from_proto(msg: Self::Proto) -> Result<FkBatchSpec, Error> {
        Ok(FkBatchSpec::try_from(msg)?)
    }
    fn from_packed(c: Configurations, q: PackedFkQuery) -> Result<FkBatchSpec, Error> {
        Ok(FkBatchSpec {
            configurations: c,
            options: FkOptions::new(q.angle_unit, q.check_limits),
            pose_format: q.pose_format.unwrap_or_default(),
        })
    }
}

/// Jacobian batches.
pub enum JacobianBatch {}

impl BatchKind for JacobianBatch {
    type Json = JacobianBatchRequest;
    type Proto = pb::JacobianBatchRequest;
    type Query = PackedJacobianQuery;
    type Spec = JacobianBatchSpec;
    const PACKED: bool = true;
    fn from_json(json: JacobianBatchRequest) -> JacobianBatchSpec {
        JacobianBatchSpec::from(json)
    }
    fn parse_json(bytes: &[u8]) -> Result<JacobianBatchRequest, Error> {
        parse_object_rows(bytes, |r: &mut JacobianBatchRequest| &mut r.configurations)
    }
    fn proto_head(msg: &Self::Proto) -> (&str, usize) {
        (&msg.robot, msg.configuration_count())
    }
    fn check_proto(msg: &Self::Proto, dof: usize) -> Result<(), Error> {
        Ok(msg.check_joint_count(dof)?)
    }
    fn from_proto(msg: Self::Proto) -> Result<JacobianBatchSpec, Error> {
        Ok(JacobianBatchSpec::try_from(msg)?)
    }
    fn from_packed(c: Configurations, q: PackedJacobianQuery) -> Result<JacobianBatchSpec, Error> {
        Ok(JacobianBatchSpec {
            configurations: c,
            options: FkOptions::new(q.angle_unit, q.check_limits),
            frame: q.frame.unwrap_or_default(),
        })
    }
}

/// IK batches: JSON and protobuf (targets have no packed layout).
pub enum IkBatch {}

impl BatchKind for IkBatch {
    type Json = IkBatchSpec;
    type Proto = pb::InverseKinematicsBatchRequest;
    type Query = PackedFkQuery;
    type Spec = IkBatchSpec;
    const PACKED: bool = false;
    fn from_json(json: IkBatchSpec) -> IkBatchSpec {
        json
    }
    fn proto_head(msg: &Self::Proto) -> (&str, usize) {
        (&msg.robot, msg.targets.len())
    }
    fn from_proto(msg: Self::Proto) -> Result<IkBatchSpec, Error> {
        Ok(IkBatchSpec::try_from(msg)?)
    }
    fn from_packed(_: Configurations, _: PackedFkQuery) -> Result<IkBatchSpec, Error> {
        // `read` refuses packed bodies where `PACKED` is false.
        Err(Error::UnsupportedMediaType {
            detail: format!("{PACKED} is not taken by this route"),
        })
    }
}

/// A 200 answer of `media_type` with `body`.
fn binary_answer(media_type: &'static str, body: Vec<u8>) -> Response {
    (
        [(header::CONTENT_TYPE, HeaderValue::from_static(media_type))],
        body,
    )
        .into_response()
}

/// The binary answer (`media` protobuf or packed) of an FK batch.
pub fn fk_answer(media: Media, robot: &Robot, poses: BatchPoses) -> Response {
    let _encode = crate::trace_span!("encode").entered();
    if media == Media::Packed {
        let name = match poses.format() {
            PoseFormat::Position => "position",
            _ => "matrix",
        };
        let mut resp = binary_answer(PACKED, kinserve_api::batch_poses_to_le(&poses));
        let h = resp.headers_mut();
        h.insert(POSE_FORMAT_HEADER, HeaderValue::from_static(name));
        let unit = robot.length_unit().as_str();
        h.insert(LENGTH_UNIT_HEADER, HeaderValue::from_static(unit));
        return resp;
    }
    let msg = kinserve_api::fk_batch_to_pb(robot.name(), robot.length_unit(), poses);
    binary_answer(PROTOBUF, msg.encode_to_vec())
}

/// The binary answer (`media` protobuf or packed) of a Jacobian batch.
pub fn jacobian_answer(media: Media, robot: &Robot, answers: &[JacobianAnswer]) -> Response {
    let _encode = crate::trace_span!("encode").entered();
    if media == Media::Packed {
        let mut resp = binary_answer(PACKED, kinserve_api::jacobians_to_le(answers));
        let unit = robot.length_unit().as_str();
        resp.headers_mut()
            .insert(LENGTH_UNIT_HEADER, HeaderValue::from_static(unit));
        return resp;
    }
    let msg = kinserve_api::jacobian_batch_to_pb(robot.name(), robot.length_unit(), answers);
    binary_answer(PROTOBUF, msg.encode_to_vec())
}

/// The protobuf answer of an IK batch (`InverseKinematicsBatch`'s message).
pub fn ik_answer(robot: &Robot, angle_unit: AngleUnit, answers: &[IkAnswer]) -> Response {
    let _encode = crate::trace_span!("encode").entered();
    let msg = pb::InverseKinematicsBatchResponse {
        robot: robot.name().to_string(),
        length_unit: pb::LengthUnit::from(robot.length_unit()) as i32,
        angle_unit: pb::AngleUnit::from(angle_unit) as i32,
        results: answers
            .iter()
            .map(pb::InverseKinematicsResult::from)
            .collect(),
    };
    binary_answer(PROTOBUF, msg.encode_to_vec())
}

/// The header of a packed FK answer naming its pose format (`matrix` or `position`).
pub const POSE_FORMAT_HEADER: &str = "kinserve-pose-format";
/// The header of a packed answer naming the robot's length unit (`m` or `mm`).
pub const LENGTH_UNIT_HEADER: &str = "kinserve-length-unit";

/// The OpenAPI schema of a binary body (`type: string, format: binary`).
pub struct Binary;

impl utoipa::PartialSchema for Binary {
    fn schema() -> RefOr<Schema> {
        ObjectBuilder::new()
            .description(Some(
                "Bytes: a protobuf message or packed little-endian float64, as the operation says.",
            ))
            .schema_type(Type::String)
            .format(Some(SchemaFormat::KnownFormat(KnownFormat::Binary)))
            // Bytes have no JSON form: the packed configuration [0.5, 0.1], in hex.
            .examples(["000000000000e03f9a9999999999b93f"])
            .into()
    }
}

impl utoipa::ToSchema for Binary {}
