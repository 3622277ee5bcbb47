//! `kinserve-load`: a load generator for every kinserve front door, with
//! closed- and open-loop modes, HDR latency histograms and optional
//! verification of every pose against the core library.

mod targets;
mod tls;

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::{Parser, ValueEnum};
use hdrhistogram::Histogram;
use serde::Serialize;

use kinserve_api::parse_duration;
use kinserve_kinematics::{JointKind, Transform};
use kinserve_model::{ModelLimits, Robot, RobotSpec};

/// What to load.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Target {
    /// `POST /v1/robots/{name}/fk`, one pose per request.
    Rest,
    /// `POST /v1/robots/{name}/fk/batch` with `--batch-size` configurations.
    RestBatch,
    /// The same batch as packed little-endian float64 both ways
    /// (`application/octet-stream`).
    RestBatchPacked,
    /// The WebSocket stream, `--pipeline` messages in flight per connection.
    Ws,
    /// gRPC `ForwardKinematics`.
    Grpc,
    /// gRPC `ForwardKinematicsBatch`.
    GrpcBatch,
    /// The same batch with its configurations in `packed_configurations`.
    GrpcBatchPacked,
    /// gRPC `StreamForwardKinematics`, `--pipeline` messages in flight per stream.
    GrpcStream,
    /// `GET /healthz` (baseline).
    RestHealth,
    /// `grpc.health.v1.Health/Check` (baseline).
    GrpcHealth,
}

impl Target {
    /// Every target, in table order.
    pub const ALL: [Target; 10] = [
        Target::RestHealth,
        Target::Rest,
        Target::RestBatch,
        Target::RestBatchPacked,
        Target::Ws,
        Target::GrpcHealth,
        Target::Grpc,
        Target::GrpcBatch,
        Target::GrpcBatchPacked,
        Target::GrpcStream,
    ];

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Target::Rest => "rest",
            Target::RestBatch => "rest-batch",
            Target::RestBatchPacked => "rest-batch-packed",
            Target::Ws => "ws",
            Target::Grpc => "grpc",
            Target::GrpcBatch => "grpc-batch",
            Target::GrpcBatchPacked => "grpc-batch-packed",
            Target::GrpcStream => "grpc-stream",
            Target::RestHealth => "rest-health",
            Target::GrpcHealth => "grpc-health",
        }
    }

    fn is_batch(self) -> bool {
        matches!(
            self,
            Target::RestBatch
                | Target::RestBatchPacked
                | Target::GrpcBatch
                | Target::GrpcBatchPacked
        )
    }

    /// Loads the gRPC listener (and so may go over TLS with `--tls-ca`).
    pub fn is_grpc(self) -> bool {
        matches!(
            self,
            Target::Grpc
                | Target::GrpcBatch
                | Target::GrpcBatchPacked
                | Target::GrpcStream
                | Target::GrpcHealth
        )
    }
}

/// How the server is asked to write poses (`pose_format` over REST and the
/// WebSocket, `FkOptions.pose_format` over gRPC).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PoseFormat {
    /// The full pose object (the option is not sent: the server's default).
    #[default]
    Full,
    /// 12 numbers per pose: the top three rows of the matrix, row-major.
    Matrix,
    /// 3 numbers per pose: the position.
    Position,
}

impl PoseFormat {
    /// The REST / WebSocket value; `None` for `full` (left out of requests).
    pub fn json_name(self) -> Option<&'static str> {
        match self {
            PoseFormat::Full => None,
            PoseFormat::Matrix => Some("matrix"),
            PoseFormat::Position => Some("position"),
        }
    }

    /// gRPC `FkOptions` asking for this format (`None` for `full`).
    fn pb_options(self) -> Option<kinserve_api::pb::FkOptions> {
        use kinserve_api::pb::PoseFormat as Pb;
        let format = match self {
            PoseFormat::Full => return None,
            PoseFormat::Matrix => Pb::Matrix,
            PoseFormat::Position => Pb::Position,
        };
        Some(kinserve_api::pb::FkOptions {
            pose_format: format as i32,
            ..Default::default()
        })
    }

    /// Numbers per pose as received: the 16 of the full matrix, 12 or 3.
    fn stride(self) -> usize {
        match self {
            PoseFormat::Full => 16,
            PoseFormat::Matrix => 12,
            PoseFormat::Position => 3,
        }
    }
}

/// Command line of `kinserve-load`.
#[derive(Clone, Debug, Parser)]
#[command(
    name = "kinserve-load",
    version,
    about = "Load generator for kinserve (REST, WebSocket, gRPC)"
)]
pub struct LoadArgs {
    /// What to load.
    #[arg(long, value_enum)]
    pub target: Target,
    /// Robot to compute FK for.
    #[arg(long, default_value = "puma560")]
    pub robot: String,
    /// Connections (REST, WebSocket, gRPC channels) or streams, one worker each.
    #[arg(long, default_value_t = 16)]
    pub concurrency: usize,
    /// How long to measure.
    #[arg(long, default_value = "10s", value_parser = parse_duration)]
    pub duration: Duration,
    /// Load before measuring (not recorded).
    #[arg(long, default_value = "2s", value_parser = parse_duration)]
    pub warmup: Duration,
    /// Open loop: total requests per second, spread over the workers; latency
    /// counts from each request's scheduled send time. Absent: closed loop.
    #[arg(long)]
    pub rate: Option<f64>,
    /// Configurations per batch request.
    #[arg(long, default_value_t = 100)]
    pub batch_size: usize,
    /// Messages in flight per stream (ws, grpc-stream).
    #[arg(long, default_value_t = 32)]
    pub pipeline: usize,
    /// Configurations per stream message (ws, grpc-stream). 1: `joints`, one
    /// pose per message; more: `configurations`, answered with that many
    /// poses in one reply (the batch route's `poses`/`matrices`/`positions`,
    /// gRPC's `poses`/`packed_poses`).
    #[arg(long, default_value_t = 1)]
    pub per_message: usize,
    /// grpc-stream with `--per-message` above 1: send each message's
    /// configurations as `packed_configurations` (one packed field).
    #[arg(long)]
    pub packed: bool,
    /// Seed of the random joint configurations (drawn within the joint limits).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Check every returned pose against the core library (a wrong pose counts as an error).
    #[arg(long)]
    pub verify: bool,
    /// Pose format asked of the server on every FK target (`full` is the
    /// server's default and is not sent); `--verify` checks the numbers received.
    #[arg(long, value_enum, default_value_t = PoseFormat::Full)]
    pub pose_format: PoseFormat,
    /// Print the result as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// REST address.
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub http_addr: String,
    /// gRPC address.
    #[arg(long, default_value = "127.0.0.1:50051")]
    pub grpc_addr: String,
    /// Stop after this many requests (0: no limit); for smoke tests.
    #[arg(long, default_value_t = 0)]
    pub max_requests: u64,
    /// PEM file of the CA that signed the server's certificate: the gRPC
    /// targets connect over TLS (a server started with --tls-cert and
    /// --tls-key). The REST and WebSocket targets have no TLS here
    /// (`scripts/bench.sh` measures REST over TLS with wrk).
    #[arg(long)]
    pub tls_ca: Option<PathBuf>,
    /// The name the server's certificate must carry (with --tls-ca).
    #[arg(long, default_value = "localhost")]
    pub tls_server_name: String,
}

/// Latency summary in microseconds.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Latency {
    /// Median.
    pub p50: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 99th percentile.
    pub p99: f64,
    /// 99.9th percentile.
    pub p999: f64,
    /// Maximum.
    pub max: f64,
}

/// Result of one run.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Target loaded.
    pub target: Target,
    /// Robot.
    pub robot: String,
    /// Workers.
    pub concurrency: usize,
    /// Measured seconds.
    pub duration_s: f64,
    /// `closed` or `open@<rate>`.
    pub mode: String,
    /// Requests (messages) sent during measurement.
    pub sent: u64,
    /// Requests answered (successfully or not) during measurement.
    pub answered: u64,
    /// Poses received.
    pub poses: u64,
    /// Requests per second.
    pub requests_per_s: f64,
    /// Poses per second.
    pub poses_per_s: f64,
    /// Latency of answered requests (µs).
    pub latency_us: Latency,
    /// Error counts by kind.
    pub errors: BTreeMap<String, u64>,
    /// Whether poses were verified.
    pub verified: bool,
    /// Pose format asked for.
    pub pose_format: PoseFormat,
    /// Configurations per stream message (`--per-message`; 1 elsewhere).
    pub per_message: usize,
}

impl Report {
    /// Total errors.
    pub fn error_count(&self) -> u64 {
        self.errors.values().sum()
    }

    /// One table row (see [`Report::table_header`]).
    pub fn table_row(&self) -> String {
        format!(
            "{:<12} {:>5} {:>11.0} {:>12.0} {:>9.0} {:>9.0} {:>9.0} {:>9.0} {:>9.0} {:>7}",
            self.target.name(),
            self.concurrency,
            self.requests_per_s,
            self.poses_per_s,
            self.latency_us.p50,
            self.latency_us.p90,
            self.latency_us.p99,
            self.latency_us.p999,
            self.latency_us.max,
            self.error_count()
        )
    }

    /// Header of [`Report::table_row`].
    pub fn table_header() -> String {
        format!(
            "{:<12} {:>5} {:>11} {:>12} {:>9} {:>9} {:>9} {:>9} {:>9} {:>7}",
            "target",
            "conc",
            "req/s",
            "poses/s",
            "p50 µs",
            "p90 µs",
            "p99 µs",
            "p99.9 µs",
            "max µs",
            "errors"
        )
    }
}

/// Per-worker tallies.
#[derive(Debug)]
struct Tally {
    hist: Histogram<u64>,
    sent: u64,
    answered: u64,
    poses: u64,
    errors: BTreeMap<String, u64>,
}

impl Tally {
    fn new() -> Tally {
        Tally {
            hist: Histogram::new_with_bounds(1, 60_000_000, 3).expect("valid histogram bounds"),
            sent: 0,
            answered: 0,
            poses: 0,
            errors: BTreeMap::new(),
        }
    }

    fn error(&mut self, kind: impl Into<String>) {
        *self.errors.entry(kind.into()).or_insert(0) += 1;
    }

    fn record(&mut self, latency: Duration) {
        let us = (latency.as_secs_f64() * 1e6).round().max(1.0) as u64;
        let _ = self.hist.record(us.min(60_000_000));
    }

    fn merge(&mut self, other: Tally) {
        let _ = self.hist.add(&other.hist);
        self.sent += other.sent;
        self.answered += other.answered;
        self.poses += other.poses;
        for (k, v) in other.errors {
            *self.errors.entry(k).or_insert(0) += v;
        }
    }
}

/// What every worker shares.
struct Plan {
    args: LoadArgs,
    robot: Option<Robot>,
    /// TLS of the gRPC channels (`--tls-ca`).
    tls: Option<tls::GrpcTls>,
    /// Measurement window.
    measure_from: Instant,
    measure_until: Instant,
}

impl Plan {
    fn measuring(&self, at: Instant) -> bool {
        at >= self.measure_from && at < self.measure_until
    }
}

/// Random joint configurations within the limits (revolute without limits: ±π;
/// prismatic without limits: [0, 1] model units), in rad.
pub struct ConfigSource {
    state: u64,
    ranges: Vec<(f64, f64)>,
}

impl ConfigSource {
    /// A source for `robot`, seeded.
    pub fn new(robot: &Robot, seed: u64) -> ConfigSource {
        let ranges = robot
            .joints()
            .iter()
            .map(|j| match (j.limits, j.kind) {
                (Some(l), _) => l,
                (None, JointKind::Revolute) => (-std::f64::consts::PI, std::f64::consts::PI),
                (None, _) => (0.0, 1.0),
            })
            .collect();
        ConfigSource {
            state: seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1,
            ranges,
        }
    }

    fn next_unit(&mut self) -> f64 {
        self.state ^= self.state << 13;
        self.state ^= self.state >> 7;
        self.state ^= self.state << 17;
        (self.state >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Appends one configuration to `out`.
    pub fn fill(&mut self, out: &mut Vec<f64>) {
        for i in 0..self.ranges.len() {
            let (lo, hi) = self.ranges[i];
            let u = self.next_unit();
            out.push(lo + (hi - lo) * u);
        }
    }
}

/// Distinct configurations a [`ConfigPool`] holds beyond one request's worth.
const POOL_CONFIGS: usize = 1024;

/// Configurations drawn before the run, handed out as windows: drawing
/// 60,000 random values for a 10,000-configuration batch took most of the
/// load generator's time per batch and sat inside the timed request (it
/// made the gRPC batch ÷ core ratio measure the generator's random numbers).
/// Each request takes the next window of `per_request` configurations,
/// starting one past where the previous one started, so consecutive
/// requests differ; nothing is drawn or allocated per request.
pub struct ConfigPool {
    values: Vec<f64>,
    dof: usize,
    per_request: usize,
    next: usize,
}

impl ConfigPool {
    /// `POOL_CONFIGS + per_request` configurations from `source`.
    pub fn new(mut source: ConfigSource, per_request: usize) -> ConfigPool {
        let dof = source.ranges.len();
        let count = POOL_CONFIGS + per_request;
        let mut values = Vec::with_capacity(count * dof);
        for _ in 0..count {
            source.fill(&mut values);
        }
        ConfigPool {
            values,
            dof,
            per_request,
            next: 0,
        }
    }

    /// The next request's `per_request` configurations, back to back.
    pub fn take(&mut self) -> &[f64] {
        let start = self.next;
        self.next = (self.next + 1) % POOL_CONFIGS;
        &self.values[start * self.dof..(start + self.per_request) * self.dof]
    }
}

/// Checks a returned pose against the library's FK: the 16 values of the
/// row-major matrix (`full`), its top 12 (`matrix`) or the position (`position`).
fn verify_pose(robot: &Robot, q: &[f64], values: &[f64], format: PoseFormat) -> bool {
    if values.len() != format.stride() {
        return false;
    }
    let expect: Transform = robot.chain().forward(q, 1.0);
    let m = expect.matrix();
    let scale = 1.0
        + expect
            .translation
            .iter()
            .fold(0.0f64, |a, x| a.max(x.abs()));
    let close = |(a, b): (&f64, &f64)| (a - b).abs() <= 1e-9 * scale;
    match format {
        PoseFormat::Position => expect.translation.iter().zip(values).all(close),
        _ => m.iter().flatten().zip(values).all(close),
    }
}

/// Fetches the robot model: over gRPC (`GetRobot`, through the TLS of the
/// gRPC targets when set) for a gRPC target, over REST otherwise.
async fn fetch_robot(args: &LoadArgs, tls: Option<&tls::GrpcTls>) -> Result<Robot, String> {
    let spec = if args.target.is_grpc() {
        fetch_spec_grpc(&args.grpc_addr, &args.robot, tls).await?
    } else {
        fetch_spec_rest(&args.http_addr, &args.robot).await?
    };
    Robot::from_spec(
        spec,
        &ModelLimits {
            max_joints: 4096,
            max_links: 8192,
        },
    )
    .map_err(|e| e.to_string())
}

async fn fetch_spec_rest(http_addr: &str, name: &str) -> Result<RobotSpec, String> {
    let url = format!("http://{http_addr}/v1/robots/{name}");
    let resp = reqwest::get(&url)
        .await
        .map_err(|e| format!("GET {url}: {e}"))?;
    if !resp.status().is_success() {
        return Err(format!("GET {url}: HTTP {}", resp.status()));
    }
    resp.json().await.map_err(|e| format!("GET {url}: {e}"))
}

async fn fetch_spec_grpc(
    grpc_addr: &str,
    name: &str,
    tls: Option<&tls::GrpcTls>,
) -> Result<RobotSpec, String> {
    use kinserve_api::pb;
    let what = format!("GetRobot {name:?} at {grpc_addr}");
    let channel = tls::channel(grpc_addr, tls).await?;
    let answer = pb::kinematics_service_client::KinematicsServiceClient::new(channel)
        .get_robot(pb::GetRobotRequest { name: name.into() })
        .await
        .map_err(|s| format!("{what}: {} {}", s.code(), s.message()))?
        .into_inner();
    let robot = answer
        .robot
        .ok_or(format!("{what}: no robot in the answer"))?;
    RobotSpec::try_from(robot).map_err(|e| format!("{what}: {e}"))
}

/// Most workers (`--concurrency`) and messages in flight per stream (`--pipeline`).
pub const MAX_WORKERS: usize = 100_000;
/// Most configurations per batch request (`--batch-size`).
pub const MAX_BATCH: usize = 1_000_000;
/// Slowest and fastest open-loop rates (`--rate`), requests per second: the
/// interval between a worker's sends stays a representable duration.
pub const MIN_RATE: f64 = 1e-3;
/// See [`MIN_RATE`].
pub const MAX_RATE: f64 = 1e9;

/// Runs one load test and returns its report.
pub async fn run(args: LoadArgs) -> Result<Report, String> {
    if !(1..=MAX_WORKERS).contains(&args.concurrency) {
        return Err(format!("--concurrency must be from 1 to {MAX_WORKERS}"));
    }
    if !(1..=MAX_WORKERS).contains(&args.pipeline) || !(1..=MAX_BATCH).contains(&args.batch_size) {
        return Err(format!(
            "--pipeline must be from 1 to {MAX_WORKERS} and --batch-size from 1 to {MAX_BATCH}"
        ));
    }
    if !(1..=MAX_BATCH).contains(&args.per_message) {
        return Err(format!("--per-message must be from 1 to {MAX_BATCH}"));
    }
    if args.packed && (args.target != Target::GrpcStream || args.per_message < 2) {
        return Err(
            "--packed is for grpc-stream with --per-message above 1 (the batch's packed \
             form is --target grpc-batch-packed)"
                .into(),
        );
    }
    if args.per_message > 1 && !matches!(args.target, Target::Ws | Target::GrpcStream) {
        return Err(format!(
            "--per-message: only the stream targets (ws, grpc-stream) send several \
             configurations per message, not {}; use --batch-size for the batch targets",
            args.target.name()
        ));
    }
    if let Some(r) = args.rate
        && !(r.is_finite() && (MIN_RATE..=MAX_RATE).contains(&r))
    {
        return Err(format!(
            "--rate must be a number of requests per second from {MIN_RATE} to {MAX_RATE:e}"
        ));
    }
    let tls = match &args.tls_ca {
        None => None,
        Some(_) if !args.target.is_grpc() => {
            return Err(format!(
                "--tls-ca: only the gRPC targets connect over TLS, not {}; \
                 measure REST over TLS with wrk https://… (scripts/bench.sh does)",
                args.target.name()
            ));
        }
        Some(ca) => Some(tls::GrpcTls::new(ca, &args.tls_server_name)?),
    };
    let robot = match args.target {
        Target::RestHealth | Target::GrpcHealth => None,
        _ => Some(fetch_robot(&args, tls.as_ref()).await?),
    };
    let start = Instant::now() + Duration::from_millis(50);
    let plan = Arc::new(Plan {
        measure_from: start + args.warmup,
        measure_until: start + args.warmup + args.duration,
        robot,
        tls,
        args: args.clone(),
    });
    let mut handles = Vec::with_capacity(args.concurrency);
    for worker in 0..args.concurrency {
        let plan = plan.clone();
        handles.push(tokio::spawn(
            async move { targets::worker(plan, worker).await },
        ));
    }
    let mut total = Tally::new();
    for h in handles {
        match h.await {
            Ok(t) => total.merge(t),
            Err(e) => total.error(format!("worker_panic: {e}")),
        }
    }
    let secs = args.duration.as_secs_f64().max(1e-9);
    let h = &total.hist;
    let latency = if h.is_empty() {
        Latency::default()
    } else {
        Latency {
            p50: h.value_at_quantile(0.5) as f64,
            p90: h.value_at_quantile(0.9) as f64,
            p99: h.value_at_quantile(0.99) as f64,
            p999: h.value_at_quantile(0.999) as f64,
            max: h.max() as f64,
        }
    };
    Ok(Report {
        target: args.target,
        robot: args.robot.clone(),
        concurrency: args.concurrency,
        duration_s: secs,
        mode: match args.rate {
            Some(r) => format!("open@{r}"),
            None => "closed".into(),
        },
        sent: total.sent,
        answered: total.answered,
        poses: total.poses,
        requests_per_s: total.answered as f64 / secs,
        poses_per_s: total.poses as f64 / secs,
        latency_us: latency,
        errors: total.errors,
        verified: args.verify,
        pose_format: args.pose_format,
        per_message: args.per_message,
    })
}

#[cfg(test)]
mod argument_tests {
    use clap::Parser;

    use super::{LoadArgs, run};

    #[tokio::test]
    async fn out_of_range_arguments_are_errors_not_panics() {
        for (flag, value) in [
            ("--rate", "1e-300"),
            ("--rate", "1e300"),
            ("--concurrency", "100000000000"),
            ("--concurrency", "0"),
            ("--pipeline", "0"),
            ("--batch-size", "100000000"),
            ("--per-message", "0"),
            ("--per-message", "2"),
        ] {
            let args = LoadArgs::try_parse_from(["kinserve-load", "--target", "rest", flag, value])
                .unwrap();
            let e = run(args).await.expect_err(flag);
            assert!(e.contains(flag), "{flag} {value}: {e}");
        }
    }
}

#[cfg(test)]
mod pool_tests {
    use super::{ConfigPool, ConfigSource, ModelLimits, POOL_CONFIGS, Robot};

    /// Windows of the asked size, inside the joint ranges, each starting one
    /// configuration after the previous, wrapping after `POOL_CONFIGS`.
    #[test]
    fn the_pool_hands_out_shifted_windows_within_the_limits() {
        let robot = Robot::from_json(
            br#"{"name": "two", "convention": "standard", "links": [
                {"a": 0.4, "alpha": 0, "d": 0, "theta": 0, "joint": "revolute", "limits": [-1, 2]},
                {"a": 0, "alpha": 0, "d": 0.1, "theta": 0, "joint": "prismatic"}]}"#,
            &ModelLimits::default(),
        )
        .unwrap();
        let mut pool = ConfigPool::new(ConfigSource::new(&robot, 7), 5);
        let first = pool.take().to_vec();
        let second = pool.take().to_vec();
        assert_eq!(first.len(), 10);
        assert_eq!(first[2..], second[..8]);
        assert_ne!(first, second);
        for q in first.chunks(2) {
            assert!(
                (-1.0..=2.0).contains(&q[0]) && (0.0..=1.0).contains(&q[1]),
                "{q:?}"
            );
        }
        for _ in 2..POOL_CONFIGS {
            pool.take();
        }
        assert_eq!(pool.take(), first.as_slice());
    }
}
