//! Command line and configuration: every `serve` flag has a `KINSERVE_*` env twin.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::api::budget::{ByteBudget, StreamBudget};
use crate::api::grpc::GrpcSettings;
use crate::api::rest::RestSettings;
use crate::compute::{ComputePool, share_of};
use crate::model::ModelLimits;
use crate::service::ServiceLimits;

/// kinserve: forward kinematics of serial robots (DH tables) over REST and gRPC.
#[derive(Debug, Parser)]
#[command(name = "kinserve", version, about)]
pub struct Cli {
    /// What to do (default: serve).
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the server (REST + gRPC).
    #[command(
        after_help = "Durations: 250ms, 10s, 2m, 1h or plain seconds, at most 24h \
        (--ik-time-limit at most 60s). Counts at most 1000000; --max-joints and \
        --max-links at most 4096; body sizes at most 1 GiB; buffered byte budgets \
        at most 64 GiB. Out-of-range values stop start-up."
    )]
    Serve(Box<ServeConfig>),
    /// Check robot files; prints every error with its field; exits 1 on any.
    Validate {
        /// Robot files (JSON).
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
    /// Compute FK once and print it as JSON (the REST API's `fk` response).
    Fk(FkArgs),
    /// Compute the geometric Jacobian once and print it as JSON (the REST
    /// API's `jacobian` response).
    Jacobian(JacobianArgs),
    /// The operations on one configuration, one subcommand each (the table
    /// `kinserve_model::config_ops!`), printing the REST answer as JSON.
    #[command(flatten)]
    Op(OpCommand),
    /// Solve inverse kinematics once and print the answer as JSON (the REST
    /// API's `ik` response); exits 1 (printing the best attempt) if the
    /// target is not reached within the tolerance.
    Ik(IkArgs),
    /// Solve a Cartesian path once and print it as JSON (the REST API's
    /// `ik/path` response); exits 1 (printing the steps taken and why it
    /// stopped) if the path stops before its end.
    IkPath(IkPathArgs),
    /// Print the closed-form FK of a robot's DH table as JSON (the REST API's
    /// `closed-form` response), or one rendering of ⁰Tₙ with --format.
    ClosedForm(ClosedFormArgs),
    /// Print a robot as URDF (metres, radians; the REST API's `urdf` response).
    Urdf(ModelArgs),
    /// Convert the chain of a URDF file into a robot file (an exact DH table,
    /// checked against the URDF's FK) and print it as JSON; exits 1, naming
    /// the element, on what a DH table cannot hold.
    ImportUrdf(ImportUrdfArgs),
    /// Time FK of a model on this machine: single pose, with every frame, batched.
    Bench(BenchArgs),
    /// Probe a running server's readiness (`GET /readyz`); exit 0 if ready, 1 otherwise.
    /// Used as the container HEALTHCHECK (the image has no curl).
    Healthcheck {
        /// Address of the HTTP listener to probe.
        #[arg(
            long,
            env = "KINSERVE_HEALTHCHECK_ADDR",
            default_value = "127.0.0.1:8080"
        )]
        addr: String,
        /// Give up after this long.
        #[arg(long, default_value = "3s", value_parser = parse_duration)]
        timeout: Duration,
        /// Probe over TLS (a server with --tls-cert); the server's
        /// certificate is not checked: the probe asks about readiness, not identity.
        #[arg(long, env = "KINSERVE_HEALTHCHECK_TLS", action = clap::ArgAction::SetTrue)]
        tls: bool,
        /// With --tls: present this client certificate (PEM), for a server
        /// that requires one (--tls-client-ca). Needs --client-key.
        #[arg(
            long,
            env = "KINSERVE_HEALTHCHECK_CLIENT_CERT",
            requires = "client_key"
        )]
        client_cert: Option<PathBuf>,
        /// The private key of --client-cert (PEM).
        #[arg(
            long,
            env = "KINSERVE_HEALTHCHECK_CLIENT_KEY",
            requires = "client_cert"
        )]
        client_key: Option<PathBuf>,
    },
}

/// Arguments of `kinserve fk`.
#[derive(Debug, Args)]
pub struct FkArgs {
    /// The robot.
    #[command(flatten)]
    pub which: ModelArgs,
    /// Joint values, comma separated: rad (or deg with --deg) for revolute, model length unit for prismatic.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    pub joints: Vec<f64>,
    /// Revolute joint values are in degrees.
    #[arg(long)]
    pub deg: bool,
    /// Also print every intermediate frame.
    #[arg(long)]
    pub frames: bool,
    /// Do not check joint limits.
    #[arg(long)]
    pub no_limits: bool,
}

/// Writes [`OpCommand`]: one subcommand per operation on one configuration
/// (the table [`crate::model::config_ops!`]), named after it (dashes).
macro_rules! op_commands {
    ($( $(#[$doc:meta])* $name:ident: $op:ident => [$($answer:tt)+]; )*) => {
        /// The subcommands of the operations on one configuration.
        #[derive(Debug, Subcommand)]
        pub enum OpCommand {
            $(
                $(#[$doc])*
                ///
                /// Prints the REST answer as JSON.
                $op(ConfigArgs),
            )*
        }
    };
}

crate::model::config_ops!(op_commands);

/// Arguments of the subcommand of an operation on one configuration.
#[derive(Debug, Args)]
pub struct ConfigArgs {
    /// The robot.
    #[command(flatten)]
    pub which: ModelArgs,
    /// Joint values, comma separated: rad (or deg with --deg) for revolute, model length unit for prismatic.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    pub joints: Vec<f64>,
    /// Revolute joint values are in degrees.
    #[arg(long)]
    pub deg: bool,
    /// Do not check joint limits.
    #[arg(long)]
    pub no_limits: bool,
}

/// Arguments of `kinserve jacobian`.
#[derive(Debug, Args)]
pub struct JacobianArgs {
    /// The robot.
    #[command(flatten)]
    pub which: ModelArgs,
    /// Joint values, comma separated: rad (or deg with --deg) for revolute, model length unit for prismatic.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    pub joints: Vec<f64>,
    /// Revolute joint values are in degrees (the Jacobian's columns stay per rad).
    #[arg(long)]
    pub deg: bool,
    /// Do not check joint limits.
    #[arg(long)]
    pub no_limits: bool,
    /// Frame of the Jacobian's rows.
    #[arg(long, value_enum, default_value_t = FrameArg::Base)]
    pub frame: FrameArg,
}

/// Frame of a Jacobian's rows on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FrameArg {
    /// The world frame FK poses are given in.
    Base,
    /// The tool frame.
    Tool,
}

/// Arguments of `kinserve ik-path`: a start configuration and one or more
/// `--waypoint`s.
#[derive(Debug, Args)]
pub struct IkPathArgs {
    /// The robot.
    #[command(flatten)]
    pub which: ModelArgs,
    /// Start configuration, comma separated, in the answer's angle unit.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    pub start: Vec<f64>,
    /// A pose to pass through: x,y,z,w,qx,qy,qz (position and quaternion), or
    /// x,y,z with --position-only. Repeat for more, in order.
    #[arg(long = "waypoint", required = true, allow_hyphen_values = true)]
    pub waypoints: Vec<String>,
    /// Start, --max-joint-step and answer in degrees.
    #[arg(long)]
    pub deg: bool,
    /// Match positions only.
    #[arg(long)]
    pub position_only: bool,
    /// Longest Cartesian step, robot length unit (default 0.01 m or 10 mm).
    #[arg(long)]
    pub max_step_length: Option<f64>,
    /// Largest orientation change per step, rad (default 0.05).
    #[arg(long)]
    pub max_step_angle: Option<f64>,
    /// Largest move of a joint between steps (default 20°; prismatic: ten steps).
    #[arg(long)]
    pub max_joint_step: Option<f64>,
    /// IK tolerance per step (default 1e-9).
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Which solver runs per step.
    #[arg(long, value_enum, default_value_t = SolverArg::Auto)]
    pub solver: SolverArg,
    /// Posture and partial-pose objectives of each step.
    #[command(flatten)]
    pub objectives: crate::cli_objectives::IkObjectiveArgs,
    /// Give up after this long (the steps so far are printed; at most 60 s).
    #[arg(long, default_value = "10s", value_parser = parse_ik_time_limit)]
    pub time_limit: Duration,
}

/// `kinserve ik --solver`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SolverArg {
    /// The closed form where the arm has one and the target an orientation, else numeric.
    Auto,
    /// The closed form only.
    Analytic,
    /// Damped least squares with restarts.
    Numeric,
}

/// Arguments of `kinserve ik`: a target as `--matrix` or `--position`
/// (with `--quaternion` unless `--position-only`).
#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("target").required(true).args(["matrix", "position"])))]
pub struct IkArgs {
    /// The robot.
    #[command(flatten)]
    pub which: ModelArgs,
    /// Target as a homogeneous 4×4 matrix: 16 values, row-major, comma separated.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub matrix: Option<Vec<f64>>,
    /// Target position x,y,z in the robot's length unit.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub position: Option<Vec<f64>>,
    /// Target orientation as a quaternion w,x,y,z.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub quaternion: Option<Vec<f64>>,
    /// Start configuration, comma separated, in the answer's angle unit.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub seed: Option<Vec<f64>>,
    /// Seed and answer in degrees.
    #[arg(long)]
    pub deg: bool,
    /// Match the position only.
    #[arg(long)]
    pub position_only: bool,
    /// Tolerance: length unit (position) and rad (orientation); default 1e-9.
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Iterations per attempt (default 100).
    #[arg(long)]
    pub max_iterations: Option<u32>,
    /// Restarts after a stalled attempt (all run when given; default: up to
    /// 1000, past 100 only while the best attempt is within 1e-3 of the target).
    #[arg(long)]
    pub restarts: Option<u32>,
    /// Which solver runs: auto (the closed form where the arm has one), analytic, numeric.
    #[arg(long, value_enum, default_value_t = SolverArg::Auto)]
    pub solver: SolverArg,
    /// Every solution inside the limits (closed form), nearest the seed first.
    #[arg(long)]
    pub all: bool,
    /// With --all, at most this many solutions (default 64; 1 to 1024).
    #[arg(long)]
    pub max_solutions: Option<u32>,
    /// Posture and partial-pose objectives.
    #[command(flatten)]
    pub objectives: crate::cli_objectives::IkObjectiveArgs,
    /// Give up after this long, answering the best attempt (at most 60 s).
    #[arg(long, default_value = "1s", value_parser = parse_ik_time_limit)]
    pub time_limit: Duration,
}

pub use crate::telemetry::LogFormat;

/// Which robot a command works on: a built-in by name or a model file.
#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("which").required(true).args(["robot", "model"])))]
pub struct ModelArgs {
    /// A built-in robot by name (or one from --robots-dir).
    #[arg(long)]
    pub robot: Option<String>,
    /// A robot model file (JSON).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// A directory of robot files (JSON) that add to or override the built-in robots.
    #[arg(long, env = "KINSERVE_ROBOTS_DIR")]
    pub robots_dir: Option<PathBuf>,
}

/// Arguments of `kinserve import-urdf`.
#[derive(Debug, Args)]
pub struct ImportUrdfArgs {
    /// The URDF file.
    pub file: PathBuf,
    /// The chain's first link (default: the URDF's root, when it has only one).
    #[arg(long, value_name = "LINK")]
    pub base: Option<String>,
    /// The chain's last link (default: the only leaf below the base; otherwise
    /// the error lists the candidates).
    #[arg(long, value_name = "LINK")]
    pub tip: Option<String>,
    /// The DH convention of the table.
    #[arg(long, value_enum, default_value_t = ConventionArg::Standard)]
    pub convention: ConventionArg,
    /// The robot's name (default: the file's stem, lowercased, every
    /// character outside `[a-z0-9_-]` made `-`).
    #[arg(long)]
    pub name: Option<String>,
}

/// `--convention` of `kinserve import-urdf`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ConventionArg {
    /// Standard (distal) DH.
    Standard,
    /// Modified (proximal, Craig) DH.
    Modified,
}

/// Arguments of `kinserve closed-form`.
#[derive(Debug, Args)]
pub struct ClosedFormArgs {
    /// The robot.
    #[command(flatten)]
    pub which: ModelArgs,
    /// What to print: the whole answer as JSON, or ⁰Tₙ as text rows, LaTeX or MathML.
    #[arg(long, value_enum, default_value_t = ClosedFormFormat::Json)]
    pub format: ClosedFormFormat,
}

/// Output of `kinserve closed-form`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ClosedFormFormat {
    /// The REST API's JSON answer.
    Json,
    /// ⁰Tₙ, one row per line, entries separated by ` | `.
    Text,
    /// ⁰Tₙ as a LaTeX bmatrix.
    Latex,
    /// ⁰Tₙ as presentation MathML.
    Mathml,
}

/// Arguments of `kinserve bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// The robot.
    #[command(flatten)]
    pub which: ModelArgs,
    /// Configurations in the batch figure.
    #[arg(long, default_value_t = 10_000, value_parser = parse_batch)]
    pub batch: usize,
    /// Print `{"robot", "simd", "single_ns", "frames_ns", "batch_ns_per_pose"}` (ns) instead of a table
    /// (with `--kernel all`, one such line per kernel).
    #[arg(long)]
    pub json: bool,
    /// Which compiled kernel to time: `best` (the one the server uses on this
    /// CPU), `portable`, `avx2` (AVX2 + FMA), `avx512`, or `all` this CPU supports.
    #[arg(long, default_value = "best", value_parser = parse_bench_kernel)]
    pub kernel: BenchKernel,
}

/// `--kernel` of `kinserve bench`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BenchKernel {
    /// The kernel the server picks on this CPU.
    Best,
    /// One kernel (refused at run time if the CPU lacks it).
    One(crate::kinematics::Kernel),
    /// Every kernel this CPU supports, narrowest first.
    All,
}

/// `--kernel` of `kinserve bench`: `best`, `all`, or a kernel's name.
fn parse_bench_kernel(s: &str) -> Result<BenchKernel, String> {
    use crate::kinematics::Kernel;
    match s.trim() {
        "best" => Ok(BenchKernel::Best),
        "all" => Ok(BenchKernel::All),
        "portable" => Ok(BenchKernel::One(Kernel::Portable)),
        "avx2" | "avx2+fma" => Ok(BenchKernel::One(Kernel::Avx2Fma)),
        "avx512" => Ok(BenchKernel::One(Kernel::Avx512)),
        _ => Err(format!(
            "not a kernel: '{s}'; use best, all, portable, avx2 or avx512"
        )),
    }
}

/// `--grpc-stream-window`: 65535 (HTTP/2's default) to 16 MiB.
fn parse_grpc_window(s: &str) -> Result<u32, String> {
    match s.trim().parse::<u32>() {
        Ok(n @ 65_535..=0x100_0000) => Ok(n),
        _ => Err(format!("not a window from 65535 to 16777216 bytes: '{s}'")),
    }
}

/// `--batch` of `kinserve bench`: 1 to 1,000,000 configurations.
fn parse_batch(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n @ 1..=1_000_000) => Ok(n),
        _ => Err(format!("not a batch size from 1 to 1000000: '{s}'")),
    }
}

pub use kinserve_api::{MAX_DURATION, MAX_IK_TIME_LIMIT, parse_duration, parse_ik_time_limit};

/// Most of anything counted by a `serve` option (configurations, robots,
/// requests, connections, streams, batches): one million.
pub const MAX_COUNT: u64 = 1_000_000;

/// Most joints (`--max-joints`) and DH rows (`--max-links`) a model may be allowed.
pub const MAX_MODEL_SIZE: u64 = 4096;

/// Largest request body or message (`--max-body-bytes`, `--max-batch-body-bytes`): 1 GiB.
pub const MAX_BODY_BYTES: u64 = 1 << 30;

/// Largest buffered byte budget (`--max-buffered-request-bytes`,
/// `--max-buffered-response-bytes`): 64 GiB.
pub const MAX_BUFFERED_BYTES: u64 = 64 << 30;

/// A whole number from 0 to `MAX` (a count or a byte size).
fn parse_at_most<const MAX: u64>(s: &str) -> Result<usize, String> {
    let too_large = || format!("too large: at most {MAX}");
    let n: u64 = s
        .parse()
        .map_err(|e: std::num::ParseIntError| match e.kind() {
            std::num::IntErrorKind::PosOverflow => too_large(),
            _ => e.to_string(),
        })?;
    if n > MAX {
        return Err(too_large());
    }
    usize::try_from(n).map_err(|_| too_large())
}

/// Configuration of `kinserve serve`. Its `Debug` output never shows the API
/// token (only whether one is set), so the configuration can be logged.
#[derive(Clone, Args)]
pub struct ServeConfig {
    /// REST listener (port 0 picks a free port).
    #[arg(long, env = "KINSERVE_HTTP_ADDR", default_value = "0.0.0.0:8080")]
    pub http_addr: SocketAddr,
    /// gRPC listener (port 0 picks a free port).
    #[arg(long, env = "KINSERVE_GRPC_ADDR", default_value = "0.0.0.0:50051")]
    pub grpc_addr: SocketAddr,
    /// A directory of read-only robot files (JSON) that add to or override the
    /// built-in robots, which are embedded in the binary.
    #[arg(long, env = "KINSERVE_ROBOTS_DIR")]
    pub robots_dir: Option<PathBuf>,
    /// Where registered robots are persisted (unused with --database-url).
    #[arg(long, env = "KINSERVE_DATA_DIR", default_value = "./data")]
    pub data_dir: PathBuf,
    /// PostgreSQL (13+) holding the registered robots, shared by every replica:
    /// `postgres://user:password@host:5432/db` (or `key=value` form). Unset:
    /// the file store in --data-dir. Never logged.
    #[arg(long, env = "KINSERVE_DATABASE_URL", hide_env_values = true)]
    pub database_url: Option<String>,
    /// A file holding the database password (its first line), which replaces
    /// any password in --database-url (e.g. a mounted secret).
    #[arg(long, env = "KINSERVE_DATABASE_PASSWORD_FILE")]
    pub database_password_file: Option<PathBuf>,
    /// With a database: full resync of the snapshot at this interval, besides
    /// LISTEN/NOTIFY and the resync after every reconnect.
    #[arg(long, env = "KINSERVE_DATABASE_RESYNC_INTERVAL", default_value = "30s", value_parser = parse_duration)]
    pub database_resync_interval: Duration,
    /// Bearer token required for register/replace/delete (REST and gRPC).
    /// Unset: the registry is read-only (writes are 403 / PERMISSION_DENIED)
    /// unless --allow-unauthenticated-writes is given.
    #[arg(long, env = "KINSERVE_API_TOKEN", hide_env_values = true)]
    pub api_token: Option<String>,
    /// Without --api-token: let anyone who can reach the server register,
    /// replace and delete robots (a warning is logged at start-up). Only on
    /// a network you trust; ignored when a token is set.
    #[arg(long, env = "KINSERVE_ALLOW_UNAUTHENTICATED_WRITES", default_value_t = false, action = clap::ArgAction::Set, num_args = 0..=1, default_missing_value = "true")]
    pub allow_unauthenticated_writes: bool,
    /// Allowed CORS origin (repeatable; env: comma separated). Default: any origin.
    #[arg(
        long = "cors-origin",
        env = "KINSERVE_CORS_ORIGINS",
        value_delimiter = ','
    )]
    pub cors_origins: Vec<String>,
    /// One access-log line per HTTP request and gRPC call at info (method,
    /// route, status, duration, request id); `false` turns it off.
    #[arg(long, env = "KINSERVE_ACCESS_LOG", default_value_t = true, action = clap::ArgAction::Set)]
    pub access_log: bool,
    /// Log format.
    #[arg(long, env = "KINSERVE_LOG_FORMAT", value_enum, default_value_t = LogFormat::Human)]
    pub log_format: LogFormat,
    /// OpenTelemetry trace export (off unless --otlp-endpoint).
    #[command(flatten)]
    pub traces: crate::telemetry::traces::TraceConfig,
    /// Most configurations in one batch request.
    #[arg(long, env = "KINSERVE_MAX_BATCH", default_value_t = 10_000, value_parser = parse_at_most::<MAX_COUNT>)]
    pub max_batch: usize,
    /// Most registered robots (built-ins not counted); registering one more is 507.
    #[arg(long, env = "KINSERVE_MAX_ROBOTS", default_value_t = 1000, value_parser = parse_at_most::<MAX_COUNT>)]
    pub max_robots: usize,
    /// Most movable joints in a model.
    #[arg(long, env = "KINSERVE_MAX_JOINTS", default_value_t = ModelLimits::DEFAULT_MAX_JOINTS, value_parser = parse_at_most::<MAX_MODEL_SIZE>)]
    pub max_joints: usize,
    /// Most DH rows (movable and fixed) in a model.
    #[arg(long, env = "KINSERVE_MAX_LINKS", default_value_t = ModelLimits::DEFAULT_MAX_LINKS, value_parser = parse_at_most::<MAX_MODEL_SIZE>)]
    pub max_links: usize,
    /// Largest request body in bytes (all routes but batch).
    #[arg(long, env = "KINSERVE_MAX_BODY_BYTES", default_value_t = 1 << 20, value_parser = parse_at_most::<MAX_BODY_BYTES>)]
    pub max_body_bytes: usize,
    /// Largest batch request body (REST) or message (gRPC) in bytes.
    #[arg(long, env = "KINSERVE_MAX_BATCH_BODY_BYTES", default_value_t = 16 << 20, value_parser = parse_at_most::<MAX_BODY_BYTES>)]
    pub max_batch_body_bytes: usize,
    /// Most requests in flight at once; more are answered 503 / RESOURCE_EXHAUSTED at once.
    #[arg(long, env = "KINSERVE_MAX_CONCURRENT_REQUESTS", default_value_t = 1024, value_parser = parse_at_most::<MAX_COUNT>)]
    pub max_concurrent_requests: usize,
    /// Longest time a request may take.
    #[arg(long, env = "KINSERVE_REQUEST_TIMEOUT", default_value = "30s", value_parser = parse_duration)]
    pub request_timeout: Duration,
    /// Longest time a client may take to send a request head: every request of
    /// an HTTP/1 connection (the first one and each kept-alive one); on HTTP/2,
    /// a connection with no request under way for this long is closed (GOAWAY).
    #[arg(long, env = "KINSERVE_HEADER_TIMEOUT", default_value = "10s", value_parser = parse_duration)]
    pub header_timeout: Duration,
    /// A WebSocket or gRPC stream that makes no progress in either direction
    /// for this long is closed: no data message from the client and no reply
    /// taken by it (pings do not count; a reply the client does not read is
    /// no progress).
    #[arg(long, env = "KINSERVE_STREAM_IDLE_TIMEOUT", default_value = "300s", value_parser = parse_duration)]
    pub stream_idle_timeout: Duration,
    /// Most connections open at once, both listeners together; with every
    /// slot taken nothing more is accepted (new clients wait in the kernel's
    /// backlog) until one closes. Each idle connection costs about 10–20 KiB.
    #[arg(long, env = "KINSERVE_MAX_CONNECTIONS", default_value_t = 4096, value_parser = parse_at_most::<MAX_COUNT>)]
    pub max_connections: usize,
    /// Most streams open at once (WebSockets and gRPC StreamForwardKinematics
    /// calls together); streams never take request permits. More are refused
    /// at once: 503 before the WebSocket upgrade, RESOURCE_EXHAUSTED on gRPC.
    /// A WebSocket may hold up to about 2.5 × --max-body-bytes while a client
    /// sends a fragmented message: 64 × 2.5 MiB keeps the worst case near 160 MiB.
    #[arg(long, env = "KINSERVE_MAX_STREAMS", default_value_t = 64, value_parser = parse_at_most::<MAX_COUNT>)]
    pub max_streams: usize,
    /// Most streams open at once on one connection (an HTTP/1 connection
    /// carries one WebSocket; HTTP/2 ones many).
    #[arg(
        long,
        env = "KINSERVE_MAX_STREAMS_PER_CONNECTION",
        default_value_t = 16,
        value_parser = parse_at_most::<MAX_COUNT>
    )]
    pub max_streams_per_connection: usize,
    /// HTTP/2 receive window of each gRPC call, in bytes (65535 to 16777216):
    /// how much a client may send on a call before the server's next window
    /// update. A packed 10,000-configuration batch (480 KB) fits the default
    /// 1 MiB, so a planner across a network sends it in one round trip; with
    /// HTTP/2's own 65535 it takes about eight. The cost: a stream whose
    /// server side has stopped reading (its client reads no replies) holds up
    /// to this much, so stalled streams may hold --max-streams × this (64 MiB
    /// by default). The connection window follows (docs/configuration.md).
    #[arg(long, env = "KINSERVE_GRPC_STREAM_WINDOW", default_value_t = crate::api::grpc::DEFAULT_STREAM_WINDOW, value_parser = parse_grpc_window)]
    pub grpc_stream_window: u32,
    /// Most bytes of request bodies buffered at once, REST bodies and gRPC
    /// messages together (one budget): a REST body that does not fit is
    /// answered 503 (Retry-After); a gRPC call that needs more fails at once
    /// with RESOURCE_EXHAUSTED (each gRPC call's first 64 KiB are not counted).
    #[arg(long, env = "KINSERVE_MAX_BUFFERED_REQUEST_BYTES", default_value_t = 64 << 20, value_parser = parse_at_most::<MAX_BUFFERED_BYTES>)]
    pub max_buffered_request_bytes: usize,
    /// Longest wait for the next piece of a request body; past it the request
    /// is answered 408 and the connection closed. (The whole body must also
    /// arrive within the request timeout.) Bodies are read before a request
    /// permit is taken.
    #[arg(long, env = "KINSERVE_BODY_TIMEOUT", default_value = "10s", value_parser = parse_duration)]
    pub body_timeout: Duration,
    /// A connection whose client takes none of the answer for this long is closed.
    #[arg(long, env = "KINSERVE_WRITE_TIMEOUT", default_value = "30s", value_parser = parse_duration)]
    pub write_timeout: Duration,
    /// Longest lingering close: after answering, a closing connection reads and
    /// discards what the client still sends for at most this long (at most 5 s
    /// between two reads), so that the client sees the answer (413, 401…).
    #[arg(long, env = "KINSERVE_LINGER_TIMEOUT", default_value = "30s", value_parser = parse_duration)]
    pub linger_timeout: Duration,
    /// Most bytes of REST answers (of 64 KiB or more each) waiting to be sent
    /// at once; an answer that does not fit is replaced by 503 (Retry-After).
    #[arg(long, env = "KINSERVE_MAX_BUFFERED_RESPONSE_BYTES", default_value_t = 64 << 20, value_parser = parse_at_most::<MAX_BUFFERED_BYTES>)]
    pub max_buffered_response_bytes: usize,
    /// Most batch requests (REST `…/batch`) under way at once; more wait
    /// their turn within the request timeout, except that a client already
    /// holding its share (--client-share-percent) is refused at once (503).
    /// 0: one less than the number of CPUs, at least 2.
    #[arg(long, env = "KINSERVE_MAX_CONCURRENT_BATCHES", default_value_t = 0, value_parser = parse_at_most::<MAX_COUNT>)]
    pub max_concurrent_batches: usize,
    /// On shutdown, how long `/readyz` (and gRPC health) answer not-ready while
    /// requests are still served as usual, so that load balancers stop sending
    /// new ones before the listeners close.
    #[arg(long, env = "KINSERVE_SHUTDOWN_GRACE", default_value = "5s", value_parser = parse_duration)]
    pub shutdown_grace: Duration,
    /// How long shutdown waits for in-flight requests (after the grace period
    /// and the listeners closed) before exiting anyway.
    #[arg(long, env = "KINSERVE_SHUTDOWN_TIMEOUT", default_value = "10s", value_parser = parse_duration)]
    pub shutdown_timeout: Duration,
    /// Longest time one IK solve may take; past it the best attempt is
    /// answered (not converged). An IK batch may take half the request timeout.
    #[arg(long, env = "KINSERVE_IK_TIME_LIMIT", default_value = "50ms", value_parser = parse_ik_time_limit)]
    pub ik_time_limit: Duration,
    /// Computations at once on the compute pool: IK (single, batch, stream
    /// messages), Jacobian batches, FK batches of more than 256
    /// configurations, closed forms and URDF exports.
    /// More are refused at once (503 + Retry-After, RESOURCE_EXHAUSTED).
    /// 0: one less than the number of CPUs, at least 2 (so that two clients
    /// each have one).
    #[arg(long, env = "KINSERVE_COMPUTE_THREADS", default_value_t = 0, value_parser = parse_at_most::<4096>)]
    pub compute_threads: usize,
    /// Percent of each budget one client may hold: requests in flight,
    /// streams, batch slots, compute permits (at least one of each); 100: no
    /// per-client cap (batches then queue for a slot as before). A client
    /// is a peer IP address (IPv6: its /64), or the last X-Forwarded-For
    /// address with --trust-forwarded-for.
    #[arg(long, env = "KINSERVE_CLIENT_SHARE_PERCENT", default_value_t = 50, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub client_share_percent: u8,
    /// The peers are the operator's proxies: the last X-Forwarded-For address
    /// (REST header, gRPC metadata) names the client. Off by default: a
    /// client could otherwise claim any address.
    #[arg(long, env = "KINSERVE_TRUST_FORWARDED_FOR", default_value_t = false, action = clap::ArgAction::Set)]
    pub trust_forwarded_for: bool,
    /// A stream (WebSocket, gRPC stream) whose client sends no message this
    /// long after it opened is closed (at most --stream-idle-timeout).
    #[arg(long, env = "KINSERVE_STREAM_FIRST_MESSAGE_TIMEOUT", default_value = "10s", value_parser = parse_duration)]
    pub stream_first_message_timeout: Duration,
    /// TLS on the listeners and to the database (docs/tls.md).
    #[command(flatten)]
    pub tls: crate::tls::TlsOptions,
}

impl std::fmt::Debug for ServeConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ServeConfig {
            http_addr,
            grpc_addr,
            robots_dir,
            data_dir,
            database_url,
            database_password_file,
            database_resync_interval,
            api_token,
            allow_unauthenticated_writes,
            cors_origins,
            log_format,
            traces,
            access_log,
            max_batch,
            max_robots,
            max_joints,
            max_links,
            max_body_bytes,
            max_batch_body_bytes,
            max_concurrent_requests,
            request_timeout,
            header_timeout,
            body_timeout,
            write_timeout,
            linger_timeout,
            max_buffered_request_bytes,
            max_buffered_response_bytes,
            max_concurrent_batches,
            stream_idle_timeout,
            max_connections,
            max_streams,
            max_streams_per_connection,
            grpc_stream_window,
            shutdown_grace,
            shutdown_timeout,
            ik_time_limit,
            compute_threads,
            client_share_percent,
            trust_forwarded_for,
            stream_first_message_timeout,
            tls,
        } = self;
        f.debug_struct("ServeConfig")
            .field("http_addr", http_addr)
            .field("grpc_addr", grpc_addr)
            .field("robots_dir", robots_dir)
            .field("data_dir", data_dir)
            .field("database_url", &database_url.as_ref().map(|_| "<redacted>"))
            .field("database_password_file", database_password_file)
            .field("database_resync_interval", database_resync_interval)
            .field("api_token", &api_token.as_ref().map(|_| "<redacted>"))
            .field("allow_unauthenticated_writes", allow_unauthenticated_writes)
            .field("cors_origins", cors_origins)
            .field("log_format", log_format)
            .field("traces", traces)
            .field("access_log", access_log)
            .field("max_batch", max_batch)
            .field("max_robots", max_robots)
            .field("max_joints", max_joints)
            .field("max_links", max_links)
            .field("max_body_bytes", max_body_bytes)
            .field("max_batch_body_bytes", max_batch_body_bytes)
            .field("max_concurrent_requests", max_concurrent_requests)
            .field("request_timeout", request_timeout)
            .field("header_timeout", header_timeout)
            .field("body_timeout", body_timeout)
            .field("write_timeout", write_timeout)
            .field("linger_timeout", linger_timeout)
            .field("max_buffered_request_bytes", max_buffered_request_bytes)
            .field("max_buffered_response_bytes", max_buffered_response_bytes)
            .field("max_concurrent_batches", max_concurrent_batches)
            .field("stream_idle_timeout", stream_idle_timeout)
            .field("max_connections", max_connections)
            .field("max_streams", max_streams)
            .field("max_streams_per_connection", max_streams_per_connection)
            .field("grpc_stream_window", grpc_stream_window)
            .field("shutdown_grace", shutdown_grace)
            .field("shutdown_timeout", shutdown_timeout)
            .field("ik_time_limit", ik_time_limit)
            .field("compute_threads", compute_threads)
            .field("client_share_percent", client_share_percent)
            .field("trust_forwarded_for", trust_forwarded_for)
            .field("stream_first_message_timeout", stream_first_message_timeout)
            .field("tls", tls)
            .finish()
    }
}

/// `ServeConfig` as a whole command line, to parse it on its own.
#[derive(Parser)]
struct ServeOnly {
    #[command(flatten)]
    c: ServeConfig,
}

impl Default for ServeConfig {
    fn default() -> Self {
        // As if `kinserve serve` ran with no flags: the flag defaults, overridden by any
        // KINSERVE_* environment variables that are set.
        ServeOnly::parse_from(["kinserve"]).c
    }
}

impl ServeConfig {
    /// The flag defaults alone, whatever KINSERVE_* variables are set.
    pub fn flag_defaults() -> ServeConfig {
        use clap::{CommandFactory, FromArgMatches};
        let matches = ServeOnly::command()
            .mut_args(|a| a.env(None))
            .get_matches_from(["kinserve"]);
        match ServeOnly::from_arg_matches(&matches) {
            Ok(only) => only.c,
            Err(e) => e.exit(),
        }
    }

    /// A configuration for tests: [`ServeConfig::flag_defaults`] with both
    /// listeners on 127.0.0.1 port 0, data in `data_dir`, no shutdown grace
    /// (stopping a test server is instant), no env influence, and registry
    /// writes open without a token (`--allow-unauthenticated-writes`: most
    /// tests register robots; the read-only default has tests of its own).
    pub fn for_tests(data_dir: PathBuf) -> ServeConfig {
        let local = SocketAddr::from(([127, 0, 0, 1], 0));
        ServeConfig {
            http_addr: local,
            grpc_addr: local,
            data_dir,
            allow_unauthenticated_writes: true,
            shutdown_grace: Duration::ZERO,
            ..ServeConfig::flag_defaults()
        }
    }

    /// What the REST adapter is given.
    pub fn rest_settings(&self) -> RestSettings {
        RestSettings {
            max_body_bytes: self.max_body_bytes,
            max_batch_body_bytes: self.max_batch_body_bytes,
            request_timeout: self.request_timeout,
            body_timeout: self.body_timeout,
            max_buffered_response_bytes: self.max_buffered_response_bytes,
            max_concurrent_batches: match self.max_concurrent_batches {
                0 => ComputePool::default_permits(),
                n => n,
            },
            client_share_percent: self.client_share_percent,
            trust_forwarded_for: self.trust_forwarded_for,
            stream_idle_timeout: self.stream_idle_timeout,
            stream_first_message_timeout: self.stream_first_message_timeout,
            cors_origins: self.cors_origins.clone(),
            access_log: self.access_log,
        }
    }

    /// What the gRPC adapter is given.
    pub fn grpc_settings(&self) -> GrpcSettings {
        GrpcSettings {
            max_message_bytes: self.max_batch_body_bytes,
            max_document_bytes: self.max_body_bytes,
            request_timeout: self.request_timeout,
            stream_idle_timeout: self.stream_idle_timeout,
            stream_first_message_timeout: self.stream_first_message_timeout,
            access_log: self.access_log,
            trust_forwarded_for: self.trust_forwarded_for,
            stream_window: self.grpc_stream_window,
        }
    }

    /// The buffered request bytes budget (one per server, shared by REST
    /// bodies and gRPC messages).
    pub fn request_byte_budget(&self) -> ByteBudget {
        ByteBudget::new(self.max_buffered_request_bytes)
    }

    /// The stream budget these settings describe (one per server, shared by
    /// the WebSocket and gRPC adapters).
    pub fn stream_budget(&self) -> StreamBudget {
        StreamBudget::new(
            self.max_streams,
            self.max_streams_per_connection,
            share_of(self.max_streams, self.client_share_percent),
        )
    }

    /// The service limits this configuration sets.
    pub fn service_limits(&self) -> ServiceLimits {
        ServiceLimits {
            model: ModelLimits {
                max_joints: self.max_joints,
                max_links: self.max_links,
            },
            max_batch: self.max_batch,
            ik_time_limit: self.ik_time_limit,
            ik_batch_time_limit: self.request_timeout / 2,
            compute_permits: match self.compute_threads {
                0 => ComputePool::default_permits(),
                n => n,
            },
            client_share_percent: self.client_share_percent,
        }
    }
}

#[cfg(test)]
mod tests;
