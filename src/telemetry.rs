//! Logging (tracing) and metrics (Prometheus): set-up, and the one list of
//! metric families with their help texts. Label sets are bounded: robots are
//! labelled by name only for the built-ins and the first
//! [`MAX_REGISTERED_ROBOT_LABELS`] registered names, later ones as `other`.
//! Traces: [`traces`] (subscriber, OTLP export), [`spans`] (server spans
//! and W3C trace context at the front doors), [`w3c`] (`traceparent`).
//! Depends on no other module of the crate.

pub mod spans;
pub mod traces;
pub mod w3c;

use std::collections::HashSet;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};

use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};

/// Log output format.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum LogFormat {
    /// Human-readable lines (colours only on a terminal).
    #[default]
    Human,
    /// One JSON object per line.
    Json,
}

/// Installs the global tracing subscriber (level from `RUST_LOG`, default `info`).
/// Later calls do nothing.
/// Trace export stays off; [`traces::init`] also exports.
pub fn init_tracing(format: LogFormat) {
    let _ = traces::init(
        format,
        traces::LogLines::Direct,
        &traces::TraceConfig::default(),
        None,
    )
    .map(traces::Tracing::shutdown);
}

/// Latency histogram buckets in seconds (50 µs … 10 s).
const LATENCY_BUCKETS: &[f64] = &[
    0.00005, 0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0,
    2.5, 10.0,
];

/// The process-wide Prometheus recorder (installed on first use).
pub fn metrics_handle() -> PrometheusHandle {
    static HANDLE: OnceLock<PrometheusHandle> = OnceLock::new();
    HANDLE
        .get_or_init(|| {
            let builder = PrometheusBuilder::new()
                .set_buckets_for_metric(
                    Matcher::Suffix("_duration_seconds".into()),
                    LATENCY_BUCKETS,
                )
                .unwrap_or_else(|_| PrometheusBuilder::new());
            let handle = match builder.install_recorder() {
                Ok(handle) => handle,
                // Another recorder is installed already (e.g. by an embedding program):
                // keep a private one so /metrics still answers.
                Err(_) => PrometheusBuilder::new().build_recorder().handle(),
            };
            describe_families();
            metrics::gauge!("kinserve_build_info", "version" => env!("CARGO_PKG_VERSION")).set(1.0);
            spawn_upkeep(handle.clone());
            handle
        })
        .clone()
}

/// How often the recorder's pending histogram samples are folded into their
/// buckets by the thread [`metrics_handle`] starts.
pub const METRICS_UPKEEP_PERIOD: std::time::Duration = std::time::Duration::from_secs(1);

/// Upkeep passes run since start (read by the tests).
static UPKEEPS: AtomicU64 = AtomicU64::new(0);

/// Upkeep passes run so far by the thread [`metrics_handle`] starts.
pub fn metrics_upkeeps() -> u64 {
    UPKEEPS.load(Ordering::Relaxed)
}

/// Starts the thread that runs the recorder's upkeep every
/// [`METRICS_UPKEEP_PERIOD`]. The recorder keeps every histogram sample
/// (8 bytes and more) until a `/metrics` scrape or an upkeep folds it into
/// the buckets; `install_recorder` starts no upkeep of its own, so a server
/// nobody scraped grew by ~23 bytes per request without bound (1.6 MB/s
/// under a /healthz load on 2 cores). One plain thread, not a task: the
/// recorder is installed before, and outlives, any runtime.
fn spawn_upkeep(handle: PrometheusHandle) {
    let spawned = std::thread::Builder::new()
        .name("kinserve-metrics".into())
        .spawn(move || {
            loop {
                std::thread::sleep(METRICS_UPKEEP_PERIOD);
                handle.run_upkeep();
                UPKEEPS.fetch_add(1, Ordering::Relaxed);
            }
        });
    if let Err(e) = spawned {
        tracing::error!(error = %e, "metrics upkeep thread not started: histogram samples are folded only when /metrics is scraped");
    }
}

/// Every metric family with its help text (the `# HELP` lines of `/metrics`).
pub const FAMILIES: &[(&str, &str)] = &[
    (
        "kinserve_http_requests_total",
        "HTTP requests answered, by method, route and status.",
    ),
    (
        "kinserve_http_request_duration_seconds",
        "HTTP request latency in seconds, by method and route.",
    ),
    (
        "kinserve_http_rejected_total",
        "HTTP requests refused before a handler ran, by reason (overloaded: no request permit; streams: the open-streams budget refused a WebSocket).",
    ),
    (
        "kinserve_grpc_requests_total",
        "gRPC calls answered, by method and status code.",
    ),
    (
        "kinserve_grpc_request_duration_seconds",
        "gRPC call latency in seconds (streams: until the response headers), by method.",
    ),
    (
        "kinserve_grpc_rejected_total",
        "gRPC calls refused before a handler ran, by reason (overloaded: no request permit; streams: the open-streams budget; buffered_bytes: the buffered request bytes budget).",
    ),
    (
        "kinserve_compute_rejected_total",
        "Computations (IK, batches, closed forms, URDF) refused at once because the compute pool or the client's share of it was taken.",
    ),
    (
        "kinserve_ws_messages_total",
        "WebSocket FK messages answered, by result (ok or error).",
    ),
    (
        "kinserve_streams_open",
        "Open FK streams, by protocol (websocket, grpc).",
    ),
    (
        "kinserve_stream_duration_seconds",
        "Lifetime of closed FK streams in seconds, by protocol.",
    ),
    (
        "kinserve_ik_solves_total",
        "Inverse-kinematics targets solved (REST, WebSocket, gRPC, single and batch), by converged (true or false).",
    ),
    (
        "kinserve_ik_paths_total",
        "Cartesian paths solved (REST, WebSocket, gRPC), by outcome (complete or the stop reason).",
    ),
    (
        "kinserve_poses_computed_total",
        "Poses computed, by robot (built-ins and the first registered names; others as `other`) and protocol.",
    ),
    ("kinserve_robots", "Robots in the registry, by source."),
    (
        "kinserve_store_write_duration_seconds",
        "Latency of durable registry writes in seconds, by operation (put, delete).",
    ),
    (
        "kinserve_store_up",
        "1 while the registry store accepts writes (for postgres: the database is reachable), else 0; by store (file, memory, postgres).",
    ),
    (
        "kinserve_store_snapshot_age_seconds",
        "Seconds since this replica's snapshot of registered robots was last known to equal the store, by store (0 for the file store).",
    ),
    (
        "kinserve_store_changes_applied_total",
        "Changes of other replicas (or missed ones) applied to the snapshot from the database, by source (notify, resync).",
    ),
    (
        "kinserve_store_reconnects_total",
        "Times the database link was lost or could not be made, and a reconnection started.",
    ),
    (
        "kinserve_build_info",
        "Always 1; the version label says which build answers.",
    ),
    (
        "process_resident_memory_bytes",
        "Resident set size of the process in bytes.",
    ),
    (
        "process_virtual_memory_bytes",
        "Virtual memory size of the process in bytes.",
    ),
    (
        "process_cpu_seconds_total",
        "User and system CPU time of the process in seconds.",
    ),
    (
        "kinserve_log_lines_dropped_total",
        "Log lines dropped because the log writer thread fell behind (its queue holds 65,536).",
    ),
    ("process_open_fds", "Open file descriptors of the process."),
    (
        "process_start_time_seconds",
        "Start time of the process since the Unix epoch in seconds.",
    ),
    ("process_threads", "Threads of the process."),
];

fn describe_families() {
    for (name, help) in FAMILIES {
        let kind = if name.starts_with("process_")
            || *name == "kinserve_build_info"
            || name.ends_with("_age_seconds")
        {
            "gauge"
        } else if name.ends_with("_total") {
            "counter"
        } else if name.ends_with("_seconds") {
            "histogram"
        } else {
            "gauge"
        };
        match kind {
            "counter" => metrics::describe_counter!(*name, *help),
            "histogram" => metrics::describe_histogram!(*name, metrics::Unit::Seconds, *help),
            _ => metrics::describe_gauge!(*name, *help),
        }
    }
}

/// The front door a pose was computed for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Protocol {
    /// REST (single and batch FK).
    Rest,
    /// The WebSocket stream.
    WebSocket,
    /// gRPC (unary, batch and stream).
    Grpc,
}

impl Protocol {
    /// The label value.
    pub fn as_str(self) -> &'static str {
        match self {
            Protocol::Rest => "rest",
            Protocol::WebSocket => "websocket",
            Protocol::Grpc => "grpc",
        }
    }
}

/// Registered robots that get their own `robot` label; later ones count as `other`.
pub const MAX_REGISTERED_ROBOT_LABELS: usize = 64;

/// The `robot` label for a robot: its name for built-ins, and for registered
/// robots while fewer than [`MAX_REGISTERED_ROBOT_LABELS`] names have one.
pub fn robot_label(name: &str, builtin: bool) -> String {
    static LABELLED: OnceLock<Mutex<HashSet<String>>> = OnceLock::new();
    if builtin {
        return name.to_string();
    }
    let set = LABELLED.get_or_init(|| Mutex::new(HashSet::new()));
    let mut set = set.lock().unwrap_or_else(|p| p.into_inner());
    if set.contains(name) || set.len() < MAX_REGISTERED_ROBOT_LABELS {
        set.insert(name.to_string());
        name.to_string()
    } else {
        "other".to_string()
    }
}

/// A robot's `kinserve_poses_computed_total` counters, one per protocol,
/// resolved once (no label work per request).
#[derive(Debug)]
pub struct PoseCounters([metrics::Counter; 3]);

impl PoseCounters {
    /// The counters of the robot labelled `robot` (see [`robot_label`]).
    pub fn new(robot: &str) -> PoseCounters {
        let c = |p: Protocol| metrics::counter!("kinserve_poses_computed_total", "robot" => robot.to_string(), "protocol" => p.as_str());
        PoseCounters([c(Protocol::Rest), c(Protocol::WebSocket), c(Protocol::Grpc)])
    }

    /// Counts `n` poses computed for `protocol`.
    pub fn add(&self, protocol: Protocol, n: u64) {
        let i = match protocol {
            Protocol::Rest => 0,
            Protocol::WebSocket => 1,
            Protocol::Grpc => 2,
        };
        if let Some(c) = self.0.get(i) {
            c.increment(n);
        }
    }
}

/// An open FK stream: counted in `kinserve_streams_open` while it lives, its
/// lifetime recorded in `kinserve_stream_duration_seconds` when dropped.
pub struct StreamGuard {
    protocol: Protocol,
    start: std::time::Instant,
}

impl StreamGuard {
    /// Opens a stream of `protocol`.
    pub fn open(protocol: Protocol) -> StreamGuard {
        metrics::gauge!("kinserve_streams_open", "protocol" => protocol.as_str()).increment(1.0);
        StreamGuard {
            protocol,
            start: std::time::Instant::now(),
        }
    }
}

impl Drop for StreamGuard {
    fn drop(&mut self) {
        let p = self.protocol.as_str();
        metrics::gauge!("kinserve_streams_open", "protocol" => p).decrement(1.0);
        metrics::histogram!("kinserve_stream_duration_seconds", "protocol" => p)
            .record(self.start.elapsed().as_secs_f64());
    }
}

/// Refreshes the `process_*` gauges from `/proc/self` (Linux; elsewhere
/// nothing) and the count of dropped log lines.
pub fn update_process_metrics() {
    metrics::counter!("kinserve_log_lines_dropped_total").absolute(traces::log_lines_dropped());
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return;
    };
    // Fields after the parenthesised command name; see proc(5).
    let Some(rest) = stat.rsplit_once(')').map(|(_, r)| r) else {
        return;
    };
    let f: Vec<&str> = rest.split_whitespace().collect();
    let num = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok());
    // Linux reports times in clock ticks (USER_HZ, 100 on every platform the
    // kernel ABI supports) and the resident set in pages (4096 bytes here).
    const TICKS: f64 = 100.0;
    const PAGE: f64 = 4096.0;
    if let (Some(utime), Some(stime)) = (num(11), num(12)) {
        metrics::gauge!("process_cpu_seconds_total").set((utime + stime) / TICKS);
    }
    if let Some(threads) = num(17) {
        metrics::gauge!("process_threads").set(threads);
    }
    if let Some(vsize) = num(20) {
        metrics::gauge!("process_virtual_memory_bytes").set(vsize);
    }
    if let Some(rss) = num(21) {
        metrics::gauge!("process_resident_memory_bytes").set(rss * PAGE);
    }
    if let Some(start) = num(19).zip(boot_time()) {
        metrics::gauge!("process_start_time_seconds").set(start.1 + start.0 / TICKS);
    }
    if let Ok(fds) = std::fs::read_dir("/proc/self/fd") {
        metrics::gauge!("process_open_fds").set(fds.count() as f64);
    }
}

/// System boot time (seconds since the epoch), from `/proc/stat`.
fn boot_time() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    stat.lines()
        .find_map(|l| l.strip_prefix("btime "))
        .and_then(|v| v.trim().parse().ok())
}

/// Publishes the registry store's state: `kinserve_store_up` and
/// `kinserve_store_snapshot_age_seconds`, labelled by store kind.
pub fn record_store_health(kind: &'static str, up: bool, snapshot_age: std::time::Duration) {
    metrics::gauge!("kinserve_store_up", "store" => kind).set(if up { 1.0 } else { 0.0 });
    metrics::gauge!("kinserve_store_snapshot_age_seconds", "store" => kind)
        .set(snapshot_age.as_secs_f64());
}

/// Counts one WebSocket FK message answered (`ok`: a pose, else an error reply).
pub fn ws_message(ok: bool) {
    static OK: OnceLock<metrics::Counter> = OnceLock::new();
    static ERR: OnceLock<metrics::Counter> = OnceLock::new();
    let (cell, result) = if ok { (&OK, "ok") } else { (&ERR, "error") };
    cell.get_or_init(|| metrics::counter!("kinserve_ws_messages_total", "result" => result))
        .increment(1);
}

/// A kind of overload answer, logged by [`log_overload`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Overload {
    /// HTTP 503 (overloaded, store unavailable, starting or stopping).
    Http503,
    /// HTTP 507 (registry full, storage failure).
    Http507,
    /// gRPC RESOURCE_EXHAUSTED (a budget or limit spent).
    GrpcResourceExhausted,
}

impl Overload {
    const ALL: [Overload; 3] = [
        Overload::Http503,
        Overload::Http507,
        Overload::GrpcResourceExhausted,
    ];

    fn label(self) -> &'static str {
        match self {
            Overload::Http503 => "http 503",
            Overload::Http507 => "http 507",
            Overload::GrpcResourceExhausted => "grpc RESOURCE_EXHAUSTED",
        }
    }
}

/// Shortest time between two overload lines of one kind.
pub const OVERLOAD_LOG_INTERVAL: std::time::Duration = std::time::Duration::from_secs(1);

/// At most one event per interval; counts the ones it holds back.
#[derive(Debug, Default)]
pub struct RateLimit {
    state: Mutex<(Option<std::time::Instant>, u64)>,
}

impl RateLimit {
    /// Whether an event at `now` may be logged: `Some(n)` with the number of
    /// events suppressed since the last one logged, `None` to suppress it.
    pub fn admit(&self, now: std::time::Instant, interval: std::time::Duration) -> Option<u64> {
        let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        let (last, suppressed) = &mut *state;
        if last.is_some_and(|t| now.saturating_duration_since(t) < interval) {
            *suppressed += 1;
            return None;
        }
        *last = Some(now);
        Some(std::mem::take(suppressed))
    }
}

/// Logs an overload answer at WARN (target `kinserve::overload`), whether or
/// not the access log is on, at most once per [`OVERLOAD_LOG_INTERVAL`] per
/// kind; the line counts the answers of that kind suppressed before it.
/// Every answer is counted in the request metrics regardless.
pub fn log_overload(kind: Overload) {
    static LIMITS: OnceLock<[RateLimit; 3]> = OnceLock::new();
    let limits = LIMITS.get_or_init(Default::default);
    let Some(limit) = Overload::ALL
        .iter()
        .position(|k| *k == kind)
        .and_then(|i| limits.get(i))
    else {
        return;
    };
    if let Some(suppressed) = limit.admit(std::time::Instant::now(), OVERLOAD_LOG_INTERVAL) {
        tracing::warn!(
            target: "kinserve::overload",
            kind = kind.label(),
            suppressed,
            "overload answer sent ({suppressed} more of this kind since the previous line were not logged; the request metrics count every one)"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_recorder_is_kept_up_without_scrapes() {
        // Samples recorded and never scraped are folded by the upkeep thread
        // (else they pile up for ever): it runs once per period (two passes
        // asked for in 3.5 periods, slack for a loaded machine).
        let _ = metrics_handle();
        metrics::histogram!("kinserve_http_request_duration_seconds", "method" => "GET", "route" => "/t")
            .record(0.001);
        let before = metrics_upkeeps();
        std::thread::sleep(METRICS_UPKEEP_PERIOD * 7 / 2);
        let after = metrics_upkeeps();
        assert!(
            after >= before + 2,
            "upkeeps {before} -> {after} in 3.5 periods"
        );
    }

    #[test]
    fn registered_robot_labels_are_bounded_and_built_ins_always_named() {
        let labels: HashSet<String> = (0..3 * MAX_REGISTERED_ROBOT_LABELS)
            .map(|i| robot_label(&format!("arm-{i}"), false))
            .collect();
        assert!(labels.contains("other"));
        assert!(
            labels.len() <= MAX_REGISTERED_ROBOT_LABELS + 1,
            "{}",
            labels.len()
        );
        // A name that got a label keeps it; built-ins are always named.
        assert_eq!(robot_label("arm-0", false), "arm-0");
        assert_eq!(robot_label("puma560", true), "puma560");
    }

    #[test]
    fn overload_lines_are_limited_to_one_per_interval_with_the_count_held_back() {
        use std::time::{Duration, Instant};
        let limit = super::RateLimit::default();
        let t0 = Instant::now();
        let second = Duration::from_secs(1);
        assert_eq!(limit.admit(t0, second), Some(0));
        for ms in [1, 500, 999] {
            assert_eq!(limit.admit(t0 + Duration::from_millis(ms), second), None);
        }
        assert_eq!(
            limit.admit(t0 + Duration::from_millis(1000), second),
            Some(3)
        );
        assert_eq!(limit.admit(t0 + Duration::from_millis(1001), second), None);
        assert_eq!(
            limit.admit(t0 + Duration::from_millis(2500), second),
            Some(1)
        );
    }
}
