//! One worker per connection or stream, for each target.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use tokio_tungstenite::tungstenite::Message;

use super::{ConfigSource, Plan, PoseFormat, Tally, Target, verify_pose};
use kinserve_api::pb;
use kinserve_api::pb::kinematics_service_client::KinematicsServiceClient;

/// Sending schedule of one worker: closed loop (send when ready) or open loop
/// (fixed intervals; latency counts from the scheduled time).
struct Schedule {
    next: Instant,
    interval: Option<Duration>,
}

impl Schedule {
    fn new(plan: &Plan, worker: usize) -> Schedule {
        let start = plan.measure_from - plan.args.warmup;
        match plan.args.rate {
            None => Schedule {
                next: start,
                interval: None,
            },
            Some(rate) => {
                let per_worker = rate / plan.args.concurrency as f64;
                let interval = Duration::from_secs_f64(1.0 / per_worker);
                // Stagger workers across one interval.
                let offset = interval.mul_f64(worker as f64 / plan.args.concurrency as f64);
                Schedule {
                    next: start + offset,
                    interval: Some(interval),
                }
            }
        }
    }

    /// The time this request counts from (`now` in closed loop); advances
    /// the schedule.
    fn take(&mut self, now: Instant) -> Instant {
        match self.interval {
            None => now,
            Some(i) => {
                let t = self.next;
                self.next += i;
                t
            }
        }
    }

    /// Waits until the next scheduled send (open loop); returns at once in closed loop.
    async fn wait(&self) {
        if self.interval.is_some() {
            tokio::time::sleep_until(self.next.into()).await;
        }
    }

    fn due(&self, now: Instant) -> bool {
        self.interval.is_none() || self.next <= now
    }
}

fn rest_client() -> reqwest::Client {
    reqwest::Client::builder()
        .pool_max_idle_per_host(1)
        .timeout(Duration::from_secs(30))
        .build()
        .unwrap_or_default()
}

async fn grpc_client(
    plan: &Plan,
) -> Result<KinematicsServiceClient<tonic::transport::Channel>, String> {
    let ch = crate::tls::channel(&plan.args.grpc_addr, plan.tls.as_ref()).await?;
    Ok(KinematicsServiceClient::new(ch).max_decoding_message_size(usize::MAX))
}

#[derive(serde::Serialize)]
struct SingleBody<'a> {
    joints: &'a [f64],
    #[serde(skip_serializing_if = "Option::is_none")]
    pose_format: Option<&'static str>,
}

#[derive(serde::Serialize)]
struct BatchBody<'a> {
    configurations: Vec<&'a [f64]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pose_format: Option<&'static str>,
}

/// A compact single reply: the pose in the field of its format (`matrix`:
/// 12 numbers, `position`: 3).
#[derive(serde::Deserialize)]
struct CompactSingleReply {
    matrix: Option<Vec<f64>>,
    position: Option<Vec<f64>>,
}

/// A compact batch reply: the poses in the field of their format
/// (`matrices` or `positions`), each an array of numbers.
#[derive(serde::Deserialize)]
struct CompactBatchReply {
    matrices: Option<Vec<Vec<f64>>>,
    positions: Option<Vec<Vec<f64>>>,
}

/// Of the fields a compact reply may carry (`matrix`-format one first), the
/// one of `format`.
fn field_of<T>(format: PoseFormat, matrix: Option<T>, position: Option<T>) -> Option<T> {
    match format {
        PoseFormat::Full => None,
        PoseFormat::Matrix => matrix,
        PoseFormat::Position => position,
    }
}

/// The arrays of numbers under the top-level `field` of a JSON body, read
/// by the scanner the server reads batch bodies with
/// ([`kinserve_model::split_rows`]), if it takes them and the rest of the
/// body is valid JSON; `None` sends the caller to serde.
fn fast_rows(bytes: &[u8], field: &str) -> Option<Vec<Vec<f64>>> {
    let (rest, rows) = kinserve_model::split_rows(bytes, field)?;
    serde_json::from_slice::<serde::de::IgnoredAny>(&rest).ok()?;
    let mut values = rows.values.as_slice();
    rows.lens
        .iter()
        .map(|&n| {
            let (row, tail) = values.split_at_checked(n as usize)?;
            values = tail;
            Some(row.to_vec())
        })
        .collect()
}

/// The numbers of each pose of a REST reply body (the matrix's 16 for `full`).
fn decode_rest(bytes: &[u8], batch: bool, format: PoseFormat) -> Result<Vec<Vec<f64>>, String> {
    let decoded = match (format, batch) {
        (PoseFormat::Full, false) => {
            serde_json::from_slice::<SingleReply>(bytes).map(|v| Some(vec![flat(&v.pose.matrix)]))
        }
        (PoseFormat::Full, true) => serde_json::from_slice::<BatchReply>(bytes)
            .map(|v| Some(v.poses.iter().map(|p| flat(&p.matrix)).collect())),
        (_, false) => serde_json::from_slice::<CompactSingleReply>(bytes)
            .map(|v| field_of(format, v.matrix, v.position).map(|p| vec![p])),
        (_, true) => {
            let field = field_of(format, Some("matrices"), Some("positions")).unwrap_or_default();
            if let Some(poses) = fast_rows(bytes, field) {
                return Ok(poses);
            }
            serde_json::from_slice::<CompactBatchReply>(bytes)
                .map(|v| field_of(format, v.matrices, v.positions))
        }
    };
    match decoded {
        Ok(Some(poses)) => Ok(poses),
        _ => Err("decode".to_string()),
    }
}

/// The gRPC batch request of `q` (`dof` values per configuration): one
/// `JointConfiguration` per configuration, or all of them in
/// `packed_configurations` for `grpc-batch-packed`.
fn grpc_batch(args: &super::LoadArgs, q: &[f64], dof: usize) -> pb::ForwardKinematicsBatchRequest {
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
async fn rest_packed(
    http: &reqwest::Client,
    args: &super::LoadArgs,
    q: &[f64],
) -> Result<Poses, String> {
    let format = args.pose_format.json_name().unwrap_or("full");
    let url = format!(
        "http://{}/v1/robots/{}/fk/batch?pose_format={format}",
        args.http_addr, args.robot
    );
    let body: Vec<u8> = q.iter().flat_map(|x| x.to_le_bytes()).collect();
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
pub(crate) enum Poses {
    Each(Vec<Vec<f64>>),
    Packed { values: Vec<f64>, stride: usize },
}

impl Poses {
    /// Number of poses (a short last pose counts, as [`Poses::iter`] yields
    /// it, so a truncated answer is a wrong pose count, not one pose fewer).
    fn len(&self) -> usize {
        match self {
            Poses::Each(v) => v.len(),
            Poses::Packed { values, stride } => values.len().div_ceil((*stride).max(1)),
        }
    }

    /// The numbers of each pose, in order.
    fn iter(&self) -> Box<dyn Iterator<Item = &[f64]> + '_> {
        match self {
            Poses::Each(v) => Box::new(v.iter().map(Vec::as_slice)),
            Poses::Packed { values, stride } => Box::new(values.chunks((*stride).max(1))),
        }
    }
}

/// The numbers of each pose of a gRPC answer: the Pose messages' matrices
/// (`full`) or the packed values.
fn grpc_poses(poses: Vec<pb::Pose>, packed: Option<pb::PackedPoses>, format: PoseFormat) -> Poses {
    match packed {
        Some(p) => Poses::Packed {
            values: p.values,
            stride: format.stride(),
        },
        None => Poses::Each(poses.into_iter().map(|p| p.matrix).collect()),
    }
}

/// A WebSocket FK message: one configuration (`joints`) or many
/// (`configurations`, with `--per-message` above 1).
#[derive(serde::Serialize)]
struct WsMessage<'a> {
    id: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    joints: Option<&'a [f64]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    configurations: Option<Vec<&'a [f64]>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pose_format: Option<&'static str>,
}

/// A WebSocket reply to many configurations: its id and the poses (in the
/// batch route's field of the format: `poses`, `matrices` or `positions`)
/// or the error.
#[derive(serde::Deserialize)]
struct WsManyReply {
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
struct WsReply {
    id: Option<u64>,
    pose: Option<MatrixOnly>,
    matrix: Option<Vec<f64>>,
    position: Option<Vec<f64>>,
    error: Option<WsError>,
}

#[derive(serde::Deserialize)]
struct WsError {
    status: Option<u16>,
}

/// A WebSocket reply as the worker sees it (typed decoding: cheap on the
/// client, which shares the machine with the server); `many`: a reply to
/// many configurations.
fn decode_ws(text: &str, format: PoseFormat, many: bool) -> Reply {
    if many {
        return decode_ws_many(text, format);
    }
    let Ok(r) = serde_json::from_str::<WsReply>(text) else {
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
fn decode_ws_many(text: &str, format: PoseFormat) -> Reply {
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
struct MatrixOnly {
    matrix: [[f64; 4]; 4],
}

#[derive(serde::Deserialize)]
struct SingleReply {
    pose: MatrixOnly,
}

#[derive(serde::Deserialize)]
struct BatchReply {
    poses: Vec<MatrixOnly>,
}

fn flat(m: &[[f64; 4]; 4]) -> Vec<f64> {
    m.iter().flatten().copied().collect()
}

/// Runs one worker until the measurement window closes.
pub(super) async fn worker(plan: Arc<Plan>, worker: usize) -> Tally {
    let mut tally = Tally::new();
    let seed = plan.args.seed.wrapping_add(worker as u64 * 7919);
    let source = plan.robot.as_ref().map(|r| ConfigSource::new(r, seed));
    tokio::time::sleep_until((plan.measure_from - plan.args.warmup).into()).await;
    let result = match plan.args.target {
        Target::Ws | Target::GrpcStream => stream_worker(&plan, worker, source, &mut tally).await,
        _ => unary_worker(&plan, worker, source, &mut tally).await,
    };
    if let Err(e) = result {
        tally.error(format!("setup: {e}"));
    }
    tally
}

/// One request at a time (or on schedule), for every non-stream target.
async fn unary_worker(
    plan: &Plan,
    worker: usize,
    mut source: Option<ConfigSource>,
    tally: &mut Tally,
) -> Result<(), String> {
    let args = &plan.args;
    let http = rest_client();
    let mut grpc = if matches!(
        args.target,
        Target::Grpc | Target::GrpcBatch | Target::GrpcBatchPacked
    ) {
        Some(grpc_client(plan).await?)
    } else {
        None
    };
    let mut health = if args.target == Target::GrpcHealth {
        let ch = crate::tls::channel(&args.grpc_addr, plan.tls.as_ref()).await?;
        Some(tonic_health::pb::health_client::HealthClient::new(ch))
    } else {
        None
    };
    let per_request = if args.target.is_batch() {
        args.batch_size
    } else {
        1
    };
    let mut schedule = Schedule::new(plan, worker);
    let mut count = 0u64;
    let mut q: Vec<f64> = Vec::new();
    loop {
        schedule.wait().await;
        let now = Instant::now();
        let t0 = schedule.take(now);
        if now >= plan.measure_until || (args.max_requests > 0 && count >= args.max_requests) {
            return Ok(());
        }
        count += 1;
        let measuring = plan.measuring(t0);
        q.clear();
        if let Some(src) = source.as_mut() {
            for _ in 0..per_request {
                src.fill(&mut q);
            }
        }
        let dof = plan.robot.as_ref().map_or(0, |r| r.dof());
        // Returns matrices of the poses received, or an error kind.
        let outcome: Result<Poses, String> = match args.target {
            Target::RestHealth => match http
                .get(format!("http://{}/healthz", args.http_addr))
                .send()
                .await
            {
                Ok(r) if r.status().is_success() => Ok(Poses::Each(Vec::new())),
                Ok(r) => Err(format!("http_{}", r.status().as_u16())),
                Err(_) => Err("transport".into()),
            },
            Target::Rest | Target::RestBatch => {
                let pose_format = args.pose_format.json_name();
                let (url, body) = if args.target == Target::Rest {
                    (
                        format!("http://{}/v1/robots/{}/fk", args.http_addr, args.robot),
                        serde_json::to_vec(&SingleBody {
                            joints: &q,
                            pose_format,
                        }),
                    )
                } else {
                    let configurations: Vec<&[f64]> = q.chunks(dof.max(1)).collect();
                    (
                        format!(
                            "http://{}/v1/robots/{}/fk/batch",
                            args.http_addr, args.robot
                        ),
                        serde_json::to_vec(&BatchBody {
                            configurations,
                            pose_format,
                        }),
                    )
                };
                let body = body.map_err(|e| e.to_string())?;
                let request = http
                    .post(url)
                    .header(reqwest::header::CONTENT_TYPE, "application/json")
                    .body(body);
                match request.send().await {
                    Ok(r) if r.status().is_success() => {
                        // Typed decoding: only the matrices are kept (cheap on the client,
                        // which shares the machine with the server).
                        let bytes = r.bytes().await.unwrap_or_default();
                        decode_rest(&bytes, args.target == Target::RestBatch, args.pose_format)
                            .map(Poses::Each)
                    }
                    Ok(r) => Err(format!("http_{}", r.status().as_u16())),
                    Err(_) => Err("transport".into()),
                }
            }
            Target::RestBatchPacked => rest_packed(&http, args, &q).await,
            Target::GrpcHealth => {
                let Some(h) = health.as_mut() else {
                    return Err("no health client".into());
                };
                match h
                    .check(tonic_health::pb::HealthCheckRequest {
                        service: String::new(),
                    })
                    .await
                {
                    Ok(r)
                        if r.get_ref().status
                            == tonic_health::pb::health_check_response::ServingStatus::Serving
                                as i32 =>
                    {
                        Ok(Poses::Each(Vec::new()))
                    }
                    Ok(_) => Err("not_serving".into()),
                    Err(s) => Err(format!("grpc_{:?}", s.code())),
                }
            }
            Target::Grpc => {
                let Some(c) = grpc.as_mut() else {
                    return Err("no grpc client".into());
                };
                let req = pb::ForwardKinematicsRequest {
                    robot: args.robot.clone(),
                    joints: q.clone(),
                    options: args.pose_format.pb_options(),
                };
                match c.forward_kinematics(req).await {
                    Ok(r) => {
                        let r = r.into_inner();
                        let pose = r.pose.into_iter().collect();
                        Ok(grpc_poses(pose, r.packed_pose, args.pose_format))
                    }
                    Err(s) => Err(format!("grpc_{:?}", s.code())),
                }
            }
            Target::GrpcBatch | Target::GrpcBatchPacked => {
                let Some(c) = grpc.as_mut() else {
                    return Err("no grpc client".into());
                };
                let req = grpc_batch(args, &q, dof);
                match c.forward_kinematics_batch(req).await {
                    Ok(r) => {
                        let r = r.into_inner();
                        Ok(grpc_poses(r.poses, r.packed_poses, args.pose_format))
                    }
                    Err(s) => Err(format!("grpc_{:?}", s.code())),
                }
            }
            Target::Ws | Target::GrpcStream => return Err("stream target in unary worker".into()),
        };
        let latency = t0.elapsed();
        if !measuring {
            continue;
        }
        tally.sent += 1;
        tally.answered += 1;
        match outcome {
            Ok(matrices) => {
                tally.record(latency);
                let expected = if matches!(args.target, Target::RestHealth | Target::GrpcHealth) {
                    0
                } else {
                    per_request
                };
                if matrices.len() != expected {
                    tally.error("wrong_pose_count");
                    continue;
                }
                tally.poses += matrices.len() as u64;
                if args.verify
                    && let Some(robot) = plan.robot.as_ref()
                {
                    for (k, m) in matrices.iter().enumerate() {
                        if !verify_pose(robot, &q[k * dof..(k + 1) * dof], m, args.pose_format) {
                            tally.error("verify");
                        }
                    }
                }
            }
            Err(kind) => tally.error(kind),
        }
    }
}

/// A message in flight on a stream.
struct InFlight {
    id: u64,
    t0: Instant,
    measuring: bool,
    q: Vec<f64>,
}

/// Outcome of one stream reply.
enum Reply {
    Pose(u64, Vec<f64>),
    /// The poses of a message of many configurations.
    Poses(u64, Poses),
    Error(u64, String),
    Closed(String),
}

/// Where a stream worker's messages go: the WebSocket writer task, or
/// straight into the gRPC request stream.
enum Outbound {
    Ws(tokio::sync::mpsc::Sender<(u64, Vec<f64>)>),
    Grpc {
        tx: tokio::sync::mpsc::Sender<pb::StreamForwardKinematicsRequest>,
        robot: String,
        options: Option<pb::FkOptions>,
        /// Joints per configuration when a message carries many (else 0).
        many: usize,
        /// Many configurations go as `packed_configurations` (`--packed`).
        packed: bool,
    },
}

impl Outbound {
    /// Queues message `id` with joints `q` (one configuration, or many
    /// after one another); false when the stream is gone.
    async fn send(&self, id: u64, q: Vec<f64>) -> bool {
        match self {
            Outbound::Ws(tx) => tx.send((id, q)).await.is_ok(),
            Outbound::Grpc {
                tx,
                robot,
                options,
                many,
                packed,
            } => {
                let mut req = pb::StreamForwardKinematicsRequest {
                    id,
                    robot: robot.clone(),
                    options: *options,
                    ..Default::default()
                };
                match *many {
                    0 => req.joints = q,
                    dof if *packed => {
                        req.packed_configurations = Some(Box::new(pb::PackedConfigurations {
                            joint_count: u32::try_from(dof).unwrap_or(u32::MAX),
                            values: q,
                        }))
                    }
                    dof => {
                        req.configurations = q
                            .chunks(dof)
                            .map(|c| pb::JointConfiguration { joints: c.to_vec() })
                            .collect()
                    }
                }
                tx.send(req).await.is_ok()
            }
        }
    }
}

/// Joints per configuration when stream messages carry many (`--per-message`
/// above 1), else 0.
fn many_of(plan: &Plan) -> usize {
    match plan.args.per_message {
        1 => 0,
        _ => plan.robot.as_ref().map_or(1, |r| r.dof().max(1)),
    }
}

type Replies = tokio::sync::mpsc::Receiver<Reply>;

/// A WebSocket stream: a writer task that writes every message ready before
/// flushing, and a reader task decoding replies.
async fn ws_transport(plan: &Plan) -> Result<(Outbound, Replies), String> {
    let args = &plan.args;
    let many = many_of(plan);
    let url = format!("ws://{}/v1/robots/{}/fk/stream", args.http_addr, args.robot);
    let (ws, _) = tokio_tungstenite::connect_async(url)
        .await
        .map_err(|e| format!("ws connect: {e}"))?;
    let (mut sink, mut stream) = ws.split();
    let (tx, mut rx) = tokio::sync::mpsc::channel::<(u64, Vec<f64>)>(args.pipeline);
    let (rtx, rrx) = tokio::sync::mpsc::channel::<Reply>(args.pipeline + 1);
    let pose_format = args.pose_format.json_name();
    let text = move |id: u64, q: &[f64]| {
        let msg = match many {
            0 => WsMessage {
                id,
                joints: Some(q),
                configurations: None,
                pose_format,
            },
            dof => WsMessage {
                id,
                joints: None,
                configurations: Some(q.chunks(dof).collect()),
                pose_format,
            },
        };
        serde_json::to_string(&msg).map(|m| Message::Text(m.into()))
    };
    tokio::spawn(async move {
        while let Some((id, q)) = rx.recv().await {
            let Ok(first) = text(id, &q) else { return };
            if sink.feed(first).await.is_err() {
                return;
            }
            while let Ok((id, q)) = rx.try_recv() {
                let Ok(next) = text(id, &q) else { return };
                if sink.feed(next).await.is_err() {
                    return;
                }
            }
            if sink.flush().await.is_err() {
                return;
            }
        }
        let _ = sink.close().await;
    });
    let format = args.pose_format;
    tokio::spawn(async move {
        while let Some(m) = stream.next().await {
            let reply = match m {
                Ok(Message::Text(t)) => decode_ws(&t, format, many > 0),
                Ok(Message::Close(_)) => Reply::Closed("ws_closed".into()),
                Ok(_) => continue,
                Err(_) => Reply::Closed("transport".into()),
            };
            let stop = matches!(reply, Reply::Closed(_));
            if rtx.send(reply).await.is_err() || stop {
                return;
            }
        }
    });
    Ok((Outbound::Ws(tx), rrx))
}

/// A gRPC bidirectional stream: the worker writes requests into it directly;
/// a reader task turns answers into replies.
async fn grpc_transport(plan: &Plan) -> Result<(Outbound, Replies), String> {
    let args = &plan.args;
    let mut client = grpc_client(plan).await?;
    let (req_tx, req_rx) =
        tokio::sync::mpsc::channel::<pb::StreamForwardKinematicsRequest>(args.pipeline);
    let response = client
        .stream_forward_kinematics(tokio_stream::wrappers::ReceiverStream::new(req_rx))
        .await
        .map_err(|s| format!("grpc stream: {s}"))?;
    let mut inbound = response.into_inner();
    let (rtx, rrx) = tokio::sync::mpsc::channel::<Reply>(args.pipeline + 1);
    let format = args.pose_format;
    tokio::spawn(async move {
        loop {
            let reply = match inbound.message().await {
                Ok(Some(m))
                    if m.result.is_none() && (!m.poses.is_empty() || m.packed_poses.is_some()) =>
                {
                    Reply::Poses(
                        m.id,
                        grpc_poses(m.poses, m.packed_poses.map(|b| *b), format),
                    )
                }
                Ok(Some(m)) => match m.result {
                    Some(pb::stream_forward_kinematics_response::Result::Pose(p)) => {
                        Reply::Pose(m.id, p.matrix)
                    }
                    Some(pb::stream_forward_kinematics_response::Result::PackedPose(p)) => {
                        Reply::Pose(m.id, p.values)
                    }
                    Some(pb::stream_forward_kinematics_response::Result::Error(s)) => {
                        Reply::Error(m.id, format!("stream_error_{}", s.code))
                    }
                    None => Reply::Error(m.id, "empty_result".into()),
                },
                Ok(None) => Reply::Closed("stream_closed".into()),
                Err(s) => Reply::Closed(format!("grpc_{:?}", s.code())),
            };
            let stop = matches!(reply, Reply::Closed(_));
            if rtx.send(reply).await.is_err() || stop {
                return;
            }
        }
    });
    let outbound = Outbound::Grpc {
        tx: req_tx,
        robot: args.robot.clone(),
        options: args.pose_format.pb_options(),
        many: many_of(plan),
        packed: args.packed,
    };
    Ok((outbound, rrx))
}

/// Pipelined streams (WebSocket, gRPC bidi): up to `--pipeline` messages in flight.
async fn stream_worker(
    plan: &Plan,
    worker: usize,
    source: Option<ConfigSource>,
    tally: &mut Tally,
) -> Result<(), String> {
    let args = &plan.args;
    let mut source = source.ok_or("stream targets need a robot")?;
    let mut schedule = Schedule::new(plan, worker);
    let mut inflight: VecDeque<InFlight> = VecDeque::with_capacity(args.pipeline);
    let mut next_id = 0u64;
    let mut count = 0u64;

    let (outbound, mut reply_rx) = match args.target {
        Target::Ws => ws_transport(plan).await?,
        _ => grpc_transport(plan).await?,
    };

    loop {
        let now = Instant::now();
        let open =
            now < plan.measure_until && (args.max_requests == 0 || count < args.max_requests);
        if open && inflight.len() < args.pipeline && schedule.due(now) {
            let t0 = schedule.take(now);
            let mut q = Vec::with_capacity(8 * args.per_message);
            for _ in 0..args.per_message {
                source.fill(&mut q);
            }
            let id = next_id;
            next_id += 1;
            count += 1;
            let measuring = plan.measuring(t0);
            if measuring {
                tally.sent += 1;
            }
            // The joints are kept only to verify the answer.
            let (sent, kept) = match args.verify {
                true => (q.clone(), q),
                false => (q, Vec::new()),
            };
            if !outbound.send(id, sent).await {
                tally.error("send_failed");
                return Ok(());
            }
            inflight.push_back(InFlight {
                id,
                t0,
                measuring,
                q: kept,
            });
            continue;
        }
        if inflight.is_empty() {
            if !open {
                return Ok(());
            }
            schedule.wait().await;
            continue;
        }
        let reply = if open && inflight.len() < args.pipeline && schedule.interval.is_some() {
            tokio::select! {
                r = reply_rx.recv() => r,
                _ = schedule.wait() => continue,
            }
        } else {
            reply_rx.recv().await
        };
        let Some(reply) = reply else {
            tally.error("stream_ended");
            return Ok(());
        };
        let Some(head) = inflight.pop_front() else {
            tally.error("unexpected_reply");
            return Ok(());
        };
        if !settle(plan, head, reply, tally) {
            return Ok(());
        }
    }
}

/// Counts `reply` to the oldest message in flight, `head`; false when the
/// stream is over.
fn settle(plan: &Plan, head: InFlight, reply: Reply, tally: &mut Tally) -> bool {
    let latency = head.t0.elapsed();
    match reply {
        Reply::Closed(kind) => {
            if head.measuring {
                tally.error(kind);
            }
            return false;
        }
        Reply::Error(id, kind) => {
            if head.measuring {
                tally.answered += 1;
                tally.error(if id == head.id {
                    kind
                } else {
                    "out_of_order".into()
                });
            }
        }
        Reply::Pose(id, m) => {
            if !head.measuring {
                return true;
            }
            tally.answered += 1;
            tally.record(latency);
            if id != head.id {
                tally.error("out_of_order");
                return true;
            }
            tally.poses += 1;
            if plan.args.verify
                && let Some(robot) = plan.robot.as_ref()
                && !verify_pose(robot, &head.q, &m, plan.args.pose_format)
            {
                tally.error("verify");
            }
        }
        Reply::Poses(id, poses) => {
            if !head.measuring {
                return true;
            }
            tally.answered += 1;
            tally.record(latency);
            if id != head.id {
                tally.error("out_of_order");
                return true;
            }
            settle_many(plan, &head.q, &poses, tally);
        }
    }
    true
}

/// Counts and (with `--verify`) checks the poses of a reply to a message of
/// many configurations `q` (one after another).
fn settle_many(plan: &Plan, q: &[f64], poses: &Poses, tally: &mut Tally) {
    if poses.len() != plan.args.per_message {
        tally.error("wrong_pose_count");
        return;
    }
    tally.poses += poses.len() as u64;
    if let (true, Some(robot)) = (plan.args.verify, plan.robot.as_ref()) {
        let dof = robot.dof().max(1);
        for (qk, m) in q.chunks(dof).zip(poses.iter()) {
            if !verify_pose(robot, qk, m, plan.args.pose_format) {
                tally.error("verify");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rest_replies_are_read_from_the_field_of_their_format() {
        let single = br#"{"robot":"r","length_unit":"m","matrix":[1,2,3,4,5,6,7,8,9,10,11,12]}"#;
        let got = decode_rest(single, false, PoseFormat::Matrix).unwrap();
        assert_eq!(got, vec![(1..=12).map(f64::from).collect::<Vec<_>>()]);
        let batch = br#"{"robot":"r","length_unit":"m","positions":[[1,2,3],[4,5,6]]}"#;
        let got = decode_rest(batch, true, PoseFormat::Position).unwrap();
        assert_eq!(got, vec![vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]]);
        // The shape before the compact fields (numbers in `pose`/`poses`)
        // and a field of another format are not an answer.
        assert!(decode_rest(br#"{"pose":[1,2,3]}"#, false, PoseFormat::Position).is_err());
        assert!(decode_rest(br#"{"poses":[[1,2,3]]}"#, true, PoseFormat::Position).is_err());
        assert!(decode_rest(batch, true, PoseFormat::Matrix).is_err());
        // The batch field is read by the fast scanner, and only when the rest
        // of the body is valid JSON (a trailing comma is not).
        assert_eq!(
            fast_rows(batch, "positions"),
            Some(vec![vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]])
        );
        let trailing = br#"{"positions":[[1,2,3]],}"#;
        assert_eq!(fast_rows(trailing, "positions"), None);
        assert!(decode_rest(trailing, true, PoseFormat::Position).is_err());
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
