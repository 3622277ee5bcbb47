//! Property checks over arbitrary input bytes, shared by the `cargo fuzz`
//! targets in `fuzz/` and by the corpus replay test (`tests/core/fuzz_corpus.rs`),
//! so a corpus file means the same thing to both.
//!
//! Each check takes any bytes, must never panic on its own account, and panics
//! (with a message saying which property broke) when kinserve violates one:
//!
//! * [`check_model`]: robot model parsing and validation never panic; a model
//!   that validates gives finite, rigid poses for every in-limit configuration
//!   (single pose, every frame, batch), the fast and reference paths agree, and
//!   the model round-trips through its JSON form (as the registry stores it).
//! * [`check_fk_request`]: the REST FK body, the batch body and the WebSocket
//!   message, parsed as the server parses them and evaluated against a few
//!   built-in robots (the batch and WebSocket bodies by the fast number
//!   scanner and by serde, which must agree bit for bit or fail alike),
//!   either fail with a client error (4xx) or give finite,
//!   rigid poses that serialise to JSON numbers (never `null`); a batch
//!   computed in each pose format the way binary and gRPC answers are (the
//!   kernel writing the compact numbers) holds the transforms' numbers bit
//!   for bit.
//! * [`check_ik_request`] (in `fuzz_ik`): the REST IK body, the IK batch body
//!   and the WebSocket IK message, validated and solved (under a short time
//!   cap) for a few built-in robots, either fail with a client error or give
//!   joints within the limits whose FK is the reported pose, honest errors,
//!   and `converged` exactly when those errors are within the tolerance.
//!

use std::sync::OnceLock;

use crate::rng::SplitMix64;
use kinserve::api::pose::Pose;
use kinserve::api::rest::{FkBatchRequest, FkRequest, WsRequest};
use kinserve::error::Error;
use kinserve::registry::{MemoryStore, Registry};
use kinserve::service::{Service, ServiceLimits, WriteAccess};
use kinserve_kinematics::{JointKind, Transform};
use kinserve_model::{
    AngleUnit, BatchPoses, FkBatchSpec, FkOptions, FkSpec, MAX_MAGNITUDE, MAX_REVOLUTE_RAD,
    ModelError, ModelLimits, PoseFormat, Robot, StreamOp, parse_json,
};

pub use crate::fuzz_ik::check_ik_request;
use crate::fuzz_shared::{assert_client_error, check_pose, robots};
use crate::reference::forward_reference;

/// Relative tolerance between the fast (polynomial, SIMD) FK and the `std`
/// per-frame FK: both are accurate to ~1e-15 per row, so this only trips on a
/// real disagreement.
const AGREE: f64 = 1e-9;

/// Parses `bytes` as a robot model with default limits; if it validates,
/// evaluates it at a set of in-limit configurations derived from the bytes and
/// checks every pose. Panics if a property is violated.
pub fn check_model(bytes: &[u8]) {
    let limits = ModelLimits::default();
    let robot = match Robot::from_json(bytes, &limits) {
        Ok(r) => r,
        Err(e) => {
            assert_client_error(&Error::from(e), "model");
            return;
        }
    };
    let dof = robot.dof();
    assert!(
        (1..=limits.max_joints).contains(&dof),
        "validated robot has {dof} movable joints"
    );
    assert_eq!(robot.chain().dof(), dof, "chain and model disagree on dof");
    assert!(robot.chain().rows() <= limits.max_links);

    // The registry stores a model as its JSON and loads it again at start-up:
    // what validated once must validate again, unchanged.
    let json = serde_json::to_vec(robot.spec()).expect("a validated spec serialises");
    match Robot::from_json(&json, &limits) {
        Ok(again) => check_same_spec(&again, &robot),
        Err(e) => panic!("validated spec fails validation after a JSON round trip: {e}"),
    }

    let scale = reach(&robot);
    let mut rng = Rng::new(bytes);
    let configs = in_limit_configurations(&robot, &mut rng);
    let opts = FkOptions::default();
    for q in &configs {
        let t = match robot.fk(q, &opts) {
            Ok(t) => t,
            Err(e) => panic!("in-limit configuration {q:?} rejected: {e}"),
        };
        check_pose(&t, "fk_checked", q);
        let (tool, frames) = robot.chain().forward_frames(q, 1.0);
        check_pose(&tool, "forward_frames tool", q);
        assert_eq!(frames.len(), robot.chain().rows() + 1, "frame count");
        for f in &frames {
            check_pose(f, "forward_frames frame", q);
        }
        check_agree(&t, &tool, scale, "fk_checked vs forward_frames", q);
        let plain = forward_reference(robot.chain(), q, 1.0);
        check_agree(&t, &plain, scale, "fast path vs reference product", q);
    }

    // The batch path (8-wide blocks plus a remainder) must match one by one.
    let flat: Vec<f64> = configs.iter().flatten().copied().collect();
    let mut out = vec![Transform::IDENTITY; configs.len()];
    robot.chain().forward_batch(&flat, 1.0, &mut out);
    for (q, t) in configs.iter().zip(&out) {
        check_pose(t, "forward_batch", q);
        check_agree(
            t,
            &robot.chain().forward(q, 1.0),
            scale,
            "batch vs single",
            q,
        );
    }

    // Limits off: revolute values within ±MAX_REVOLUTE_RAD (in rad, so also
    // accepted as degrees), prismatic values within their bound.
    let free = FkOptions {
        angle_unit: AngleUnit::Rad,
        check_limits: false,
    };
    for _ in 0..3 {
        let q: Vec<f64> = robot
            .joints()
            .iter()
            .map(|j| match j.kind {
                JointKind::Prismatic => rng.bounded(MAX_MAGNITUDE),
                _ => rng.bounded(MAX_REVOLUTE_RAD),
            })
            .collect();
        match robot.fk(&q, &free) {
            Ok(t) => check_pose(&t, "fk_checked without limits", &q),
            Err(e) => panic!("finite configuration {q:?} rejected without limit checks: {e}"),
        }
        let deg = FkOptions {
            angle_unit: AngleUnit::Deg,
            check_limits: false,
        };
        match robot.fk_frames(&q, &deg) {
            Ok((t, frames)) => {
                check_pose(&t, "fk_frames_checked deg", &q);
                frames
                    .iter()
                    .for_each(|f| check_pose(f, "fk_frames_checked deg frame", &q));
            }
            Err(e) => panic!("finite configuration {q:?} rejected in deg: {e}"),
        }
    }

    // Bad vectors are client errors, never panics.
    let mut bad = configs[0].clone();
    bad.push(0.0);
    expect_invalid(robot.fk(&bad, &opts), "one value too many");
    let mut bad = configs[0].clone();
    bad[rng.below(dof)] = f64::NAN;
    expect_invalid(robot.fk(&bad, &free), "NaN joint value");
    if let Some(i) = robot
        .joints()
        .iter()
        .position(|j| j.kind == JointKind::Revolute)
    {
        let mut far = vec![0.0; robot.dof()];
        far[i] = 2.0 * MAX_REVOLUTE_RAD;
        expect_invalid(robot.fk(&far, &free), "revolute value beyond the bound");
    }
    if let Some(i) = robot
        .joints()
        .iter()
        .position(|j| j.kind == JointKind::Prismatic)
    {
        let mut bad = configs[0].clone();
        bad[i] = MAX_MAGNITUDE * 2.0;
        expect_invalid(robot.fk(&bad, &free), "prismatic value over the bound");
    }
}

/// `bytes` as a REST FK batch body, read as the handler reads it (the fast
/// path of `parse_json_rows`), checked against the plain parse ([`same_parse`]).
fn parse_batch(bytes: &[u8]) -> Result<FkBatchRequest, ModelError> {
    let fast =
        kinserve_model::parse_json_rows(bytes, "configurations", |r: &mut FkBatchRequest| {
            &mut r.configurations
        });
    same_parse(fast, parse_json::<FkBatchRequest>(bytes), "batch body")
}

/// `bytes` as a WebSocket message, read as the handler reads it (the fast
/// path of `parse_json_values` for `joints`; a top-level array is refused
/// before it), checked against the plain parse ([`same_parse`]).
fn parse_ws(bytes: &[u8]) -> Result<WsRequest, ModelError> {
    let plain = parse_json::<WsRequest>(bytes);
    let first = bytes.iter().find(|b| !b.is_ascii_whitespace());
    if first == Some(&b'[') {
        return plain;
    }
    let fast = kinserve_model::parse_json_values(bytes, "joints", |r: &mut WsRequest| {
        r.joints.get_or_insert_with(Vec::new)
    });
    same_parse(fast, plain, "WebSocket message")
}

/// The fast parse `fast` of a `what`, after checking that the plain parse
/// `plain` gives the same value (every number bit for bit: `Debug` writes
/// the shortest round-trip form and the sign of zero) or the same error.
fn same_parse<T: std::fmt::Debug>(
    fast: Result<T, ModelError>,
    plain: Result<T, ModelError>,
    what: &str,
) -> Result<T, ModelError> {
    match (&fast, &plain) {
        (Ok(f), Ok(p)) => assert_eq!(
            format!("{f:?}"),
            format!("{p:?}"),
            "fast and plain parse of a {what} differ"
        ),
        (Err(f), Err(p)) => assert_eq!(f, p, "fast and plain parse of a {what} fail differently"),
        _ => panic!("fast parse {fast:?}, plain parse {plain:?} of a {what}"),
    }
    fast
}

/// Parses `bytes` as a REST FK body, a REST batch body and a WebSocket FK
/// message, and evaluates whatever parses against a few built-in robots the
/// way the handlers do. Panics if a property is violated.
pub fn check_fk_request(bytes: &[u8]) {
    let service = service();
    match parse_json::<FkRequest>(bytes) {
        Ok(req) => {
            for robot in robots() {
                evaluate_one(service, robot, &FkSpec::from(req.clone()));
            }
        }
        Err(e) => assert_client_error(&Error::from(e), "FkRequest"),
    }
    match parse_batch(bytes) {
        Ok(req) => {
            let spec = FkBatchSpec::from(req);
            for robot in robots() {
                evaluate_batch(service, robot, &spec);
            }
        }
        Err(e) => assert_client_error(&Error::from(e), "FkBatchRequest"),
    }
    match parse_ws(bytes) {
        Ok(req) => {
            // An IK message is the IK check's business (check_ik_request).
            if let Ok(StreamOp::Fk { fk, .. }) = StreamOp::try_from(req) {
                for robot in robots() {
                    evaluate_one(service, robot, &fk);
                }
            }
        }
        Err(e) => assert_client_error(&Error::from(e), "WsRequest"),
    }
}

fn evaluate_one(service: &Service, robot: &Robot, spec: &FkSpec) {
    let (q, opts) = (&spec.joints[..], &spec.options);
    let with_frames = FkSpec {
        frames: true,
        ..spec.clone()
    };
    let without = FkSpec {
        frames: false,
        ..spec.clone()
    };
    let single = match service.fk(robot, &without) {
        Ok(t) => t.pose,
        Err(e) => {
            assert_client_error(&e, "fk");
            // The frames path must refuse the same input.
            assert!(
                service.fk(robot, &with_frames).is_err(),
                "fk and fk_frames disagree"
            );
            return;
        }
    };
    check_pose(&single, "fk", q);
    check_serialises(&single, q);
    if spec.frames || opts.angle_unit == AngleUnit::Rad {
        let (tool, all) = match service.fk(robot, &with_frames) {
            Ok(r) => (r.pose, r.frames.unwrap_or_default()),
            Err(e) => panic!("fk accepted {q:?} but fk_frames refused it: {e}"),
        };
        check_pose(&tool, "fk_frames", q);
        for f in &all {
            check_pose(f, "fk_frames frame", q);
            check_serialises(f, q);
        }
        if opts.angle_unit == AngleUnit::Rad {
            check_agree(&single, &tool, reach_with(robot, q), "fk vs fk_frames", q);
        }
    }
}

fn evaluate_batch(service: &Service, robot: &Robot, spec: &FkBatchSpec) {
    let (configs, opts) = (&spec.configurations, &spec.options);
    let poses = match service.fk_batch(robot, spec) {
        Ok(p) => p,
        Err(e) => {
            assert_client_error(&e, "fk_batch");
            return;
        }
    };
    assert_eq!(poses.len(), configs.len(), "one pose per configuration");
    check_in_formats(service, robot, spec, &poses);
    let dof = robot.dof();
    for (q, t) in configs.values.chunks_exact(dof.max(1)).zip(&poses) {
        check_pose(t, "fk_batch", q);
        check_serialises(t, q);
        if opts.angle_unit == AngleUnit::Rad {
            let one = robot
                .fk(q, opts)
                .unwrap_or_else(|e| panic!("batch accepted {q:?} but fk refused it: {e}"));
            check_agree(t, &one, reach_with(robot, q), "batch vs single", q);
        }
    }
}

/// The batch in every pose format as the binary and gRPC answers compute it
/// (the kernel writing the compact numbers itself) holds, bit for bit, the
/// numbers of the transforms `poses` packed afterwards.
fn check_in_formats(service: &Service, robot: &Robot, spec: &FkBatchSpec, poses: &[Transform]) {
    for format in [PoseFormat::Full, PoseFormat::Matrix, PoseFormat::Position] {
        let spec = FkBatchSpec {
            pose_format: format,
            ..spec.clone()
        };
        let got = service
            .fk_batch_as_format(robot, &spec)
            .unwrap_or_else(|e| panic!("fk_batch accepted the batch, {format:?} refused it: {e}"));
        let want = BatchPoses::from_transforms(format, poses.to_vec());
        let bits = |p: &BatchPoses| -> Vec<u64> {
            match p {
                BatchPoses::Full(t) => t
                    .iter()
                    .flat_map(|t| t.matrix().concat())
                    .map(f64::to_bits)
                    .collect(),
                BatchPoses::Matrix(v) | BatchPoses::Position(v) => {
                    v.iter().map(|x| x.to_bits()).collect()
                }
            }
        };
        assert_eq!(
            got.format(),
            format,
            "fk_batch_as_format answered another format"
        );
        assert!(
            bits(&got) == bits(&want),
            "{format:?} batch differs from the packed transforms"
        );
    }
}

/// The service the handlers call (in-memory store, default limits).
fn service() -> &'static Service {
    static SERVICE: OnceLock<Service> = OnceLock::new();
    SERVICE.get_or_init(|| {
        Service::new(
            Registry::new(Box::new(MemoryStore)),
            ServiceLimits::default(),
            WriteAccess::Open,
        )
    })
}

/// The spec after a JSON round trip equals the original: exactly if serde_json
/// parses floats exactly (its `float_roundtrip` feature), else within a few ulp
/// (its default parser can be off by one or two ulp on 17-digit input, so an
/// exact comparison would only rediscover that).
fn check_same_spec(again: &Robot, robot: &Robot) {
    if again.spec() == robot.spec() {
        return;
    }
    // A 17-digit literal the default serde_json parser rounds wrongly.
    const PROBE: &str = "1.5707269963748967";
    let exact = serde_json::from_str::<f64>(PROBE).ok() == PROBE.parse::<f64>().ok();
    assert!(
        !exact,
        "spec changed in a JSON round trip:\n{:?}\n{:?}",
        robot.spec(),
        again.spec()
    );
    let a = serde_json::to_value(robot.spec()).expect("a spec serialises");
    let b = serde_json::to_value(again.spec()).expect("a spec serialises");
    assert!(
        same_within_ulps(&a, &b),
        "spec changed in a JSON round trip by more than rounding:\n{a}\n{b}"
    );
}

fn same_within_ulps(a: &serde_json::Value, b: &serde_json::Value) -> bool {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => {
                let scale = x.abs().max(y.abs()).max(f64::MIN_POSITIVE);
                (x - y).abs() <= 4.0 * f64::EPSILON * scale
            }
            _ => x == y,
        },
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same_within_ulps(x, y))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| same_within_ulps(v, w)))
        }
        _ => a == b,
    }
}

fn expect_invalid(r: Result<Transform, ModelError>, what: &str) {
    match r {
        Ok(t) => panic!("{what}: accepted, giving {t:?}"),
        Err(e) => assert!(
            matches!(e, ModelError::Invalid { .. }),
            "{what}: expected an invalid-input error, got {e}"
        ),
    }
}

/// serde_json writes a non-finite number as `null`, which the schema forbids.
fn check_serialises(t: &Transform, q: &[f64]) {
    let json = serde_json::to_string(&Pose::from(t)).expect("a pose serialises");
    assert!(
        !json.contains("null"),
        "pose serialises with null for q = {q:?}: {json}"
    );
}

/// `a` and `b` agree: rotations to `AGREE`, translations to `AGREE · scale`.
fn check_agree(a: &Transform, b: &Transform, scale: f64, what: &str, q: &[f64]) {
    for i in 0..3 {
        for j in 0..3 {
            let d = (a.rotation[i][j] - b.rotation[i][j]).abs();
            assert!(
                d <= AGREE,
                "{what}: rotation differs by {d:e} for q = {q:?}"
            );
        }
        let d = (a.translation[i] - b.translation[i]).abs();
        assert!(
            d <= AGREE * scale,
            "{what}: translation differs by {d:e} (scale {scale:e}) for q = {q:?}"
        );
    }
}

/// An upper bound on every translation the robot can produce with prismatic
/// values within the model bound (the scale for translation tolerances).
pub(crate) fn reach(robot: &Robot) -> f64 {
    let n = robot
        .joints()
        .iter()
        .filter(|j| j.kind == JointKind::Prismatic)
        .count();
    fixed_reach(robot) + n as f64 * MAX_MAGNITUDE
}

/// Like [`reach`], with the actual prismatic values of `q`.
fn reach_with(robot: &Robot, q: &[f64]) -> f64 {
    fixed_reach(robot) + q.iter().map(|x| x.abs().min(MAX_MAGNITUDE)).sum::<f64>()
}

/// 1 + every constant length of the model (`a`, `d`, base and tool translations).
fn fixed_reach(robot: &Robot) -> f64 {
    let spec = robot.spec();
    let t = |s: &Option<kinserve_model::TransformSpec>| {
        s.as_ref().map_or(0.0, |s| {
            let m: f64 = s
                .matrix
                .map_or(0.0, |m| m.iter().take(3).map(|r| r[3].abs()).sum());
            let tr: f64 = s
                .translation
                .map_or(0.0, |t| t.iter().map(|x| x.abs()).sum());
            m + tr
        })
    };
    let links: f64 = spec.links.iter().map(|l| l.a.abs() + l.d.abs()).sum();
    1.0 + t(&spec.base) + t(&spec.tool) + links
}

/// Joint vectors inside every limit, in internal units (rad, model length
/// unit): zeros clamped into the limits, all lower limits, all upper limits,
/// midpoints, then values drawn from the input bytes. At least 10, so the
/// batch path runs a full 8-wide block and a remainder.
fn in_limit_configurations(robot: &Robot, rng: &mut Rng) -> Vec<Vec<f64>> {
    let joints = robot.joints();
    let pick = |f: &mut dyn FnMut(Option<(f64, f64)>, JointKind) -> f64| -> Vec<f64> {
        joints.iter().map(|j| f(j.limits, j.kind)).collect()
    };
    let mut out = vec![
        pick(&mut |l, _| l.map_or(0.0, |(lo, hi)| 0.0f64.clamp(lo, hi))),
        pick(&mut |l, _| l.map_or(0.0, |(lo, _)| lo)),
        pick(&mut |l, _| l.map_or(0.0, |(_, hi)| hi)),
        pick(&mut |l, _| l.map_or(0.0, |(lo, hi)| (lo / 2.0 + hi / 2.0).clamp(lo, hi))),
    ];
    for _ in 0..7 {
        out.push(pick(&mut |l, kind| match (l, kind) {
            (Some((lo, hi)), _) => {
                let f = rng.unit();
                (lo * (1.0 - f) + hi * f).clamp(lo, hi)
            }
            (None, JointKind::Prismatic) => rng.bounded(MAX_MAGNITUDE),
            (None, _) => rng.bounded(MAX_REVOLUTE_RAD),
        }));
    }
    out
}

/// A small deterministic generator seeded from the input ([`SplitMix64`]).
struct Rng(SplitMix64);

impl Rng {
    fn new(bytes: &[u8]) -> Rng {
        // FNV-1a of the input.
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in bytes {
            h = (h ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3);
        }
        Rng(SplitMix64(h))
    }

    fn below(&mut self, n: usize) -> usize {
        self.0.below(n)
    }

    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f64 {
        self.0.unit()
    }

    /// A value in `[-bound, bound]`, often one of the ends or zero.
    fn bounded(&mut self, bound: f64) -> f64 {
        match self.below(6) {
            0 => bound,
            1 => -bound,
            2 => 0.0,
            3 => self.unit() * 2.0 - 1.0,
            _ => (self.unit() * 2.0 - 1.0) * bound,
        }
    }
}
