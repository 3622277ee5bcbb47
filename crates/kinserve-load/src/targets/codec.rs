//! What the load generator sends and reads: the REST and WebSocket request
//! bodies, the gRPC batch requests (repeated or packed), the packed REST
//! batch, and the decoding of every answer into poses ([`Poses`]) or stream
//! replies ([`Reply`]). The workers in the parent module own the timing and
//! the connections; this module owns no I/O but the packed REST call, and
//! does not depend on the parent.

use crate::{PoseFormat, Target};
use kinserve_api::pb;

#[derive(serde::Serialize)]
pub(super) struct SingleBody<'a> {
    pub(super) joints: &'a [f64],
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) pose_format: Option<&'static str>,
}

#[derive(serde::Serialize)]
pub(super) struct BatchBody<'a> {
    pub(super) configurations: Vec<&'a [f64]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) pose_format: Option<&'static str>,
}

/// A compact single reply: the pose in the field of its format (`matrix`:
/// 12 numbers, `position`: 3).
#[derive(serde::Deserialize)]
pub(super) struct CompactSingleReply {
    matrix: Option<Vec<f64>>,
    position: Option<Vec<f64>>,
}

/// A compact batch reply: the poses in the field of their format
/// (`matrices` or `positions`), each an array of numbers.
#[derive(serde::Deserialize)]
pub(super) struct CompactBatchReply {
    matrices: Option<Vec<Vec<f64>>>,
    positions: Option<Vec<Vec<f64>>>,
}

/// A single reply (REST or WebSocket) whose compact pose is one array of
/// numbers under `matrix` or `position` (both `Option<Vec<f64>>` in `T`),
/// read by the server's own fast number reader
/// ([`kinserve_model::parse_json_values`]: the same values as serde's, a
/// message of full-precision numbers in about 70 % of serde's time; the
/// client shares the machine with the server); serde alone for `full`.
fn compact_single<T: serde::de::DeserializeOwned + CompactFields>(
    bytes: &[u8],
    format: PoseFormat,
) -> Option<T> {
    let key = match format {
        PoseFormat::Full => return serde_json::from_slice(bytes).ok(),
        PoseFormat::Matrix => "matrix",
        PoseFormat::Position => "position",
    };
    kinserve_model::parse_json_values(bytes, key, |r: &mut T| {
        r.field(format).get_or_insert_with(Vec::new)
    })
    .ok()
}

/// The compact pose fields of a single reply.
trait CompactFields {
    /// The field of `format` (`matrix` for `full`, which has none).
    fn field(&mut self, format: PoseFormat) -> &mut Option<Vec<f64>>;
}

impl CompactFields for CompactSingleReply {
    fn field(&mut self, format: PoseFormat) -> &mut Option<Vec<f64>> {
        match format {
            PoseFormat::Position => &mut self.position,
            _ => &mut self.matrix,
        }
    }
}

impl CompactFields for WsReply {
    fn field(&mut self, format: PoseFormat) -> &mut Option<Vec<f64>> {
        match format {
            PoseFormat::Position => &mut self.position,
            _ => &mut self.matrix,
        }
    }
}

/// Of the fields a compact reply may carry (`matrix`-format one first), the
/// one of `format`.
pub(super) fn field_of<T>(format: PoseFormat, matrix: Option<T>, position: Option<T>) -> Option<T> {
    match format {
        PoseFormat::Full => None,
        PoseFormat::Matrix => matrix,
        PoseFormat::Position => position,
    }
}

/// `value` as JSON in a buffer of `capacity` bytes to start with: a batch
/// body written into a growing vector cost the generator fresh pages at
/// every doubling (page faults were a third of its time on 10,000-pose
/// JSON batches).
pub(super) fn json_body<T: serde::Serialize>(
    value: &T,
    capacity: usize,
) -> serde_json::Result<Vec<u8>> {
    let mut body = Vec::with_capacity(capacity);
    serde_json::to_writer(&mut body, value)?;
    Ok(body)
}

/// The arrays of numbers under the top-level `field` of a JSON body, read
/// by the scanner the server reads batch bodies with
/// ([`kinserve_model::split_rows`]), if it takes them and the rest of the
/// body is valid JSON; `None` sends the caller to serde. Rows of `stride`
/// numbers each stay one flat vector ([`Poses::Packed`], no vector per
/// pose); rows of other lengths are kept apart, so a short row is still
/// seen as one.
pub(super) fn fast_rows(bytes: &[u8], field: &str, stride: usize) -> Option<Poses> {
    let (rest, rows) = kinserve_model::split_rows(bytes, field)?;
    serde_json::from_slice::<serde::de::IgnoredAny>(&rest).ok()?;
    if rows.lens.iter().all(|&n| n as usize == stride) {
        return Some(Poses::Packed {
            values: rows.values,
            stride,
        });
    }
    let mut values = rows.values.as_slice();
    let each = rows
        .lens
        .iter()
        .map(|&n| {
            let (row, tail) = values.split_at_checked(n as usize)?;
            values = tail;
            Some(row.to_vec())
        })
        .collect::<Option<_>>()?;
    Some(Poses::Each(each))
}

/// The numbers of each pose of a REST reply body (the matrix's 16 for `full`).
pub(super) fn decode_rest(bytes: &[u8], batch: bool, format: PoseFormat) -> Result<Poses, String> {
    if batch
        && let Some(field) = field_of(format, Some("matrices"), Some("positions"))
        && let Some(poses) = fast_rows(bytes, field, format.stride())
    {
        return Ok(poses);
    }
    let decoded = match (format, batch) {
        (PoseFormat::Full, false) => {
            serde_json::from_slice::<SingleReply>(bytes).map(|v| Some(vec![flat(&v.pose.matrix)]))
        }
        (PoseFormat::Full, true) => serde_json::from_slice::<BatchReply>(bytes)
            .map(|v| Some(v.poses.iter().map(|p| flat(&p.matrix)).collect())),
        (_, false) => Ok(compact_single::<CompactSingleReply>(bytes, format)
            .and_then(|v| field_of(format, v.matrix, v.position).map(|p| vec![p]))),
        (_, true) => serde_json::from_slice::<CompactBatchReply>(bytes)
            .map(|v| field_of(format, v.matrices, v.positions)),
    };
    match decoded {
        Ok(Some(poses)) => Ok(Poses::Each(poses)),
        _ => Err("decode".to_string()),
    }
}

/// The gRPC batch request of `q` (`dof` values per configuration): one
/// `JointConfiguration` per configuration, or all of them in
/// `packed_configurations` for `grpc-batch-packed`.
pub(super) fn grpc_batch(
    args: &crate::LoadArgs,
    q: &[f64],
    dof: usize,
) -> pb::ForwardKinematicsBatchRequest {
    let mut req = pb::ForwardKinematicsBatchRequest {
        robot: args.robot.clone(),
        options: args.pose_format.pb_options(),
        ..Default::default()
    };
    if args.target == Target::GrpcBatchPacked {
        req.packed_configurations = Some(pb::PackedConfigurations {
            joint_count: u32::try_from(dof).unwrap_or(u32::MAX),
            values: q.to_vec(),
        });
    } else {
        req.configurations = q
            .chunks(dof.max(1))
            .map(|c| pb::JointConfiguration { joints: c.to_vec() })
            .collect();
    }
    req
}

/// One packed batch (`application/octet-stream` both ways): the joint values
/// as little-endian float64, the answer's poses cut into matrices (12
/// numbers, `[0, 0, 0, 1]` added for `full`, which is answered as `matrix`)
/// or positions.
pub(super) async fn rest_packed(
    http: &reqwest::Client,
    args: &crate::LoadArgs,
    q: &[f64],
) -> Result<Poses, String> {
    let format = args.pose_format.json_name().unwrap_or("full");
    let url = format!(
        "http://{}/v1/robots/{}/fk/batch?pose_format={format}",
        args.http_addr, args.robot
    );
    let mut body: Vec<u8> = Vec::with_capacity(q.len() * 8);
    for x in q {
        body.extend_from_slice(&x.to_le_bytes());
    }
    let octets = "application/octet-stream";
    let request = http
        .post(url)
        .header(reqwest::header::CONTENT_TYPE, octets)
        .header(reqwest::header::ACCEPT, octets)
        .body(body);
    let r = match request.send().await {
        Ok(r) if r.status().is_success() => r,
        Ok(r) => return Err(format!("http_{}", r.status().as_u16())),
        Err(_) => return Err("transport".into()),
    };
    let bytes = r.bytes().await.map_err(|_| "transport".to_string())?;
    let values: Vec<f64> = bytes
        .chunks_exact(8)
        .filter_map(|c| c.first_chunk::<8>())
        .map(|b| f64::from_le_bytes(*b))
        .collect();
    let stride = if args.pose_format == PoseFormat::Position {
        3
    } else {
        12
    };
    if args.pose_format != PoseFormat::Full {
        return Ok(Poses::Packed { values, stride });
    }
    Ok(Poses::Each(
        values
            .chunks(stride)
            .map(|p| [p, &[0.0, 0.0, 0.0, 1.0]].concat())
            .collect(),
    ))
}

/// The numbers of each pose of an answer: a vector per pose, or the packed
/// numbers of all poses cut into poses of `stride` numbers when looked at
/// (a compact answer is not copied pose by pose on the measured path).
pub(super) enum Poses {
    Each(Vec<Vec<f64>>),
    Packed { values: Vec<f64>, stride: usize },
}

impl Poses {
    /// Number of poses (a short last pose counts, as [`Poses::iter`] yields
    /// it, so a truncated answer is a wrong pose count, not one pose fewer).
    pub(super) fn len(&self) -> usize {
        match self {
            Poses::Each(v) => v.len(),
            Poses::Packed { values, stride } => values.len().div_ceil((*stride).max(1)),
        }
    }

    /// The numbers of each pose, in order.
    pub(super) fn iter(&self) -> Box<dyn Iterator<Item = &[f64]> + '_> {
        match self {
            Poses::Each(v) => Box::new(v.iter().map(Vec::as_slice)),
            Poses::Packed { values, stride } => Box::new(values.chunks((*stride).max(1))),
        }
    }
}

/// The numbers of each pose of a gRPC answer: the Pose messages' matrices
/// (`full`) or the packed values.
pub(super) fn grpc_poses(
    poses: Vec<pb::Pose>,
    packed: Option<pb::PackedPoses>,
    format: PoseFormat,
) -> Poses {
    match packed {
        Some(p) => Poses::Packed {
            values: p.values,
            stride: format.stride(),
        },
        None => Poses::Each(poses.into_iter().map(|p| p.matrix).collect()),
    }
}

/// Outcome of one stream reply.
pub(super) enum Reply {
    Pose(u64, Vec<f64>),
    /// The poses of a message of many configurations.
    Poses(u64, Poses),
    Error(u64, String),
    Closed(String),
}

/// A WebSocket FK message: one configuration (`joints`) or many
/// (`configurations`, with `--per-message` above 1).
#[derive(serde::Serialize)]
pub(super) struct WsMessage<'a> {
    pub(super) id: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) joints: Option<&'a [f64]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) configurations: Option<Vec<&'a [f64]>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) pose_format: Option<&'static str>,
}

/// A WebSocket reply to many configurations: its id and the poses (in the
/// batch route's field of the format: `poses`, `matrices` or `positions`)
/// or the error.
#[derive(serde::Deserialize)]
pub(super) struct WsManyReply {
    id: Option<u64>,
    poses: Option<Vec<MatrixOnly>>,
    matrices: Option<Vec<Vec<f64>>>,
    positions: Option<Vec<Vec<f64>>>,
    error: Option<WsError>,
}

/// A WebSocket reply: its id and the pose (in the field of the format asked
/// for: `pose`, `matrix` or `position`) or the error; other fields are
/// skipped.
#[derive(serde::Deserialize)]
pub(super) struct WsReply {
    id: Option<u64>,
    pose: Option<MatrixOnly>,
    matrix: Option<Vec<f64>>,
    position: Option<Vec<f64>>,
    error: Option<WsError>,
}

#[derive(serde::Deserialize)]
pub(super) struct WsError {
    status: Option<u16>,
}

/// A WebSocket reply as the worker sees it (typed decoding: cheap on the
/// client, which shares the machine with the server); `many`: a reply to
/// many configurations.
pub(super) fn decode_ws(text: &str, format: PoseFormat, many: bool) -> Reply {
    if many {
        return decode_ws_many(text, format);
    }
    let Some(r) = compact_single::<WsReply>(text.as_bytes(), format) else {
        return Reply::Closed("decode".into());
    };
    let pose = match format {
        PoseFormat::Full => r.pose.map(|p| flat(&p.matrix)),
        _ => field_of(format, r.matrix, r.position),
    };
    match pose {
        Some(pose) => Reply::Pose(r.id.unwrap_or(u64::MAX), pose),
        None => {
            let status = r.error.and_then(|e| e.status).unwrap_or(0);
            Reply::Error(r.id.unwrap_or(u64::MAX), format!("ws_error_{status}"))
        }
    }
}

/// [`decode_ws`] of a reply to many configurations.
pub(super) fn decode_ws_many(text: &str, format: PoseFormat) -> Reply {
    let Ok(r) = serde_json::from_str::<WsManyReply>(text) else {
        return Reply::Closed("decode".into());
    };
    let poses = match format {
        PoseFormat::Full => r.poses.map(|p| p.iter().map(|p| flat(&p.matrix)).collect()),
        _ => field_of(format, r.matrices, r.positions),
    };
    match poses {
        Some(poses) => Reply::Poses(r.id.unwrap_or(u64::MAX), Poses::Each(poses)),
        None => {
            let status = r.error.and_then(|e| e.status).unwrap_or(0);
            Reply::Error(r.id.unwrap_or(u64::MAX), format!("ws_error_{status}"))
        }
    }
}

/// Just the matrix of a pose.
#[derive(serde::Deserialize)]
pub(super) struct MatrixOnly {
    matrix: [[f64; 4]; 4],
}

#[derive(serde::Deserialize)]
pub(super) struct SingleReply {
    pose: MatrixOnly,
}

#[derive(serde::Deserialize)]
pub(super) struct BatchReply {
    poses: Vec<MatrixOnly>,
}

pub(super) fn flat(m: &[[f64; 4]; 4]) -> Vec<f64> {
    m.iter().flatten().copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each pose's numbers, however they are held.
    fn rows(poses: &Poses) -> Vec<Vec<f64>> {
        poses.iter().map(<[f64]>::to_vec).collect()
    }

    #[test]
    fn rest_replies_are_read_from_the_field_of_their_format() {
        let single = br#"{"robot":"r","length_unit":"m","matrix":[1,2,3,4,5,6,7,8,9,10,11,12]}"#;
        let got = decode_rest(single, false, PoseFormat::Matrix).unwrap();
        assert_eq!(
            rows(&got),
            vec![(1..=12).map(f64::from).collect::<Vec<_>>()]
        );
        let batch = br#"{"robot":"r","length_unit":"m","positions":[[1,2,3],[4,5,6]]}"#;
        let got = decode_rest(batch, true, PoseFormat::Position).unwrap();
        assert_eq!(rows(&got), vec![vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]]);
        // The shape before the compact fields (numbers in `pose`/`poses`)
        // and a field of another format are not an answer.
        assert!(decode_rest(br#"{"pose":[1,2,3]}"#, false, PoseFormat::Position).is_err());
        assert!(decode_rest(br#"{"poses":[[1,2,3]]}"#, true, PoseFormat::Position).is_err());
        assert!(decode_rest(batch, true, PoseFormat::Matrix).is_err());
        // The batch field is read by the fast scanner, and only when the rest
        // of the body is valid JSON (a trailing comma is not); rows of the
        // format's length stay one flat vector.
        let fast = fast_rows(batch, "positions", 3).unwrap();
        assert!(matches!(fast, Poses::Packed { stride: 3, .. }));
        assert_eq!(rows(&fast), vec![vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]]);
        let trailing = br#"{"positions":[[1,2,3]],}"#;
        assert!(fast_rows(trailing, "positions", 3).is_none());
        assert!(decode_rest(trailing, true, PoseFormat::Position).is_err());
        // A short or long row is kept as it came (the caller's checks see it),
        // not spread over the rows after it.
        let uneven = br#"{"positions":[[1,2],[3,4,5,6]]}"#;
        let got = decode_rest(uneven, true, PoseFormat::Position).unwrap();
        assert_eq!(rows(&got), vec![vec![1.0, 2.0], vec![3.0, 4.0, 5.0, 6.0]]);
    }

    #[test]
    fn websocket_replies_are_read_from_the_field_of_their_format() {
        let r = decode_ws(
            r#"{"id":4,"length_unit":"m","position":[1,2,3]}"#,
            PoseFormat::Position,
            false,
        );
        assert!(matches!(r, Reply::Pose(4, ref p) if p == &[1.0, 2.0, 3.0]));
        let full = r#"{"id":5,"pose":{"matrix":[[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]}}"#;
        let r = decode_ws(full, PoseFormat::Full, false);
        assert!(matches!(r, Reply::Pose(5, ref p) if p.len() == 16 && p[3] == 1.0));
        let r = decode_ws(
            r#"{"id":6,"error":{"status":422}}"#,
            PoseFormat::Matrix,
            false,
        );
        assert!(matches!(r, Reply::Error(6, ref e) if e == "ws_error_422"));
        let r = decode_ws(r#"{"id":7,"position":[1,2,3]}"#, PoseFormat::Matrix, false);
        assert!(matches!(r, Reply::Error(7, _)));
        // Full-precision numbers (read by the fast path) as serde reads them.
        let numbers = "[0.8606145157622094,-0.20669435463295582,-0.465424643763352,\
            0.32646614240204247,0.1778108775000569,0.9783710930886368,-0.10570381285084011,\
            -0.11804751546107738,0.47720639884858734,0.008212671393131995,0.8787528690858148,\
            6.123233995736766e-17]";
        let want: Vec<f64> = serde_json::from_str(numbers).unwrap_or_default();
        let r = decode_ws(
            &format!(r#"{{"id":8,"matrix":{numbers}}}"#),
            PoseFormat::Matrix,
            false,
        );
        let bits = |p: &[f64]| p.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert!(matches!(r, Reply::Pose(8, ref p) if want.len() == 12 && bits(p) == bits(&want)));
    }

    #[test]
    fn websocket_replies_to_many_configurations_are_read_from_the_batch_fields() {
        let many = |text: &str, format| match decode_ws(text, format, true) {
            Reply::Poses(id, poses) => {
                Ok((id, poses.iter().map(<[f64]>::to_vec).collect::<Vec<_>>()))
            }
            Reply::Error(id, e) => Err((id, e)),
            _ => Err((u64::MAX, "closed".into())),
        };
        let positions = r#"{"id":8,"length_unit":"m","positions":[[1,2,3],[4,5,6]]}"#;
        assert_eq!(
            many(positions, PoseFormat::Position),
            Ok((8, vec![vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]]))
        );
        let full = r#"{"id":9,"poses":[{"matrix":[[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]}]}"#;
        let (id, poses) = many(full, PoseFormat::Full).unwrap();
        assert_eq!(
            (id, poses.len(), poses[0].len(), poses[0][7]),
            (9, 1, 16, 2.0)
        );
        // The single-configuration field, or another format's, is no answer.
        assert!(many(r#"{"id":10,"position":[1,2,3]}"#, PoseFormat::Position).is_err());
        assert!(many(positions, PoseFormat::Matrix).is_err());
        assert_eq!(
            many(r#"{"id":11,"error":{"status":413}}"#, PoseFormat::Matrix),
            Err((11, "ws_error_413".to_string()))
        );
    }
}
