//! One worker per connection or stream, for each target.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use tokio_tungstenite::tungstenite::Message;

mod codec;

use super::{ConfigPool, ConfigSource, Plan, Tally, Target, verify_pose};
use codec::{
    BatchBody, Poses, Reply, SingleBody, WsMessage, decode_rest, decode_ws, grpc_batch, grpc_poses,
    json_body, rest_packed,
};
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

/// Runs one worker until the measurement window closes.
pub(super) async fn worker(plan: Arc<Plan>, worker: usize) -> Tally {
    let mut tally = Tally::new();
    let seed = plan.args.seed.wrapping_add(worker as u64 * 7919);
    let per_request = match plan.args.target {
        Target::Ws | Target::GrpcStream => plan.args.per_message,
        t if t.is_batch() => plan.args.batch_size,
        _ => 1,
    };
    let source = plan
        .robot
        .as_ref()
        .map(|r| ConfigPool::new(ConfigSource::new(r, seed), per_request));
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
    mut source: Option<ConfigPool>,
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
    loop {
        schedule.wait().await;
        let now = Instant::now();
        let t0 = schedule.take(now);
        if now >= plan.measure_until || (args.max_requests > 0 && count >= args.max_requests) {
            return Ok(());
        }
        count += 1;
        let measuring = plan.measuring(t0);
        let q: &[f64] = source.as_mut().map_or(&[], ConfigPool::take);
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
                        json_body(
                            &SingleBody {
                                joints: q,
                                pose_format,
                            },
                            256,
                        ),
                    )
                } else {
                    let configurations: Vec<&[f64]> = q.chunks(dof.max(1)).collect();
                    (
                        format!(
                            "http://{}/v1/robots/{}/fk/batch",
                            args.http_addr, args.robot
                        ),
                        // 17 significant digits, sign, point, exponent and comma.
                        json_body(
                            &BatchBody {
                                configurations,
                                pose_format,
                            },
                            q.len() * 26 + 256,
                        ),
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
                    }
                    Ok(r) => Err(format!("http_{}", r.status().as_u16())),
                    Err(_) => Err("transport".into()),
                }
            }
            Target::RestBatchPacked => rest_packed(&http, args, q).await,
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
                    joints: q.to_vec(),
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
                let req = grpc_batch(args, q, dof);
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
    // An 8 KiB read buffer, as the server's: tungstenite zero-fills the free
    // part of its buffer before every read, and its default of 128 KiB made
    // that `memset` 4 % of the generator's time on this target.
    let config = tokio_tungstenite::tungstenite::protocol::WebSocketConfig::default()
        .read_buffer_size(8 << 10);
    let (ws, _) = tokio_tungstenite::connect_async_with_config(url, Some(config), false)
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
    source: Option<ConfigPool>,
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
            let q = source.take().to_vec();
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
