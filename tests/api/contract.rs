//! The cross-protocol contract suite: one table of cases (robots, joint
//! configurations, bad inputs) run over REST, gRPC unary, the gRPC stream and
//! the WebSocket against one server, asserting identical poses (to 1e-12, and
//! equal to the library) and the same error class and field paths.
//!
//! Error classes: REST 400/422 ↔ INVALID_ARGUMENT (invalid), 404 ↔ NOT_FOUND,
//! 409 read-only ↔ FAILED_PRECONDITION, 409 already-exists ↔ ALREADY_EXISTS,
//! 401 ↔ UNAUTHENTICATED, 413 ↔ RESOURCE_EXHAUSTED (too large).
//!
//! Non-finite joint values: gRPC sends NaN / ±inf as doubles. JSON cannot carry
//! them, so REST and the WebSocket send the nearest JSON stand-ins instead: the
//! string `"x"` for NaN and the overflowing literal `1e999` / `-1e999` for ±inf.
//! Those are rejected by the JSON layer (400 malformed) rather than by the
//! finiteness check (422), which is the same class (invalid) and must name the
//! same field.

use std::collections::BTreeMap;

use futures_util::{SinkExt, StreamExt};
use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use kinserve::model::{AngleUnit, FkOptions};
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite;
use tonic::Code;

use crate::grpc::{channel, fk_request, rpc_status_fields, status_fields, stream_request};
use crate::helpers::*;

const TOL: f64 = 1e-12;

// ---------------------------------------------------------------- outcomes

/// What a client can tell an error apart by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Class {
    Invalid,
    NotFound,
    AlreadyExists,
    ReadOnly,
    Unauthenticated,
    TooLarge,
    Unavailable,
    Other,
}

fn class_of_code(code: Code) -> Class {
    match code {
        Code::InvalidArgument => Class::Invalid,
        Code::NotFound => Class::NotFound,
        Code::AlreadyExists => Class::AlreadyExists,
        Code::FailedPrecondition => Class::ReadOnly,
        Code::Unauthenticated => Class::Unauthenticated,
        Code::ResourceExhausted => Class::TooLarge,
        Code::Unavailable => Class::Unavailable,
        _ => Class::Other,
    }
}

fn class_of_i32(code: i32) -> Class {
    class_of_code(Code::from_i32(code))
}

/// Class of an HTTP status (with the problem type to tell the two 409s apart).
fn class_of_http(status: u16, problem_type: &str) -> Class {
    match status {
        400 | 422 => Class::Invalid,
        404 if problem_type.ends_with(":not-found") => Class::NotFound,
        409 if problem_type.ends_with(":read-only") => Class::ReadOnly,
        409 if problem_type.ends_with(":already-exists") => Class::AlreadyExists,
        401 => Class::Unauthenticated,
        413 => Class::TooLarge,
        503 => Class::Unavailable,
        _ => Class::Other,
    }
}

/// An error as a problem+json document gives it.
fn problem_error(status: u16, problem: &Value) -> Failure {
    assert_eq!(
        problem["status"].as_u64(),
        Some(status as u64),
        "problem status matches: {problem}"
    );
    let fields = problem["errors"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|e| e["field"].as_str().expect("field").to_string())
                .collect()
        })
        .unwrap_or_default();
    Failure {
        class: class_of_http(status, problem["type"].as_str().unwrap_or("")),
        fields,
        raw: problem.to_string(),
    }
}

#[derive(Clone, Debug)]
struct Failure {
    class: Class,
    fields: Vec<String>,
    raw: String,
}

/// A pose, whatever the protocol.
#[derive(Clone, Debug, PartialEq)]
struct PoseOut {
    matrix: Vec<f64>,
    position: [f64; 3],
    quaternion: [f64; 4],
    rpy: [f64; 3],
}

impl PoseOut {
    fn from_json(p: &Value) -> PoseOut {
        let q = &p["quaternion"];
        let arr3 = |v: &Value| -> [f64; 3] {
            let a = v.as_array().expect("array of 3");
            [
                a[0].as_f64().unwrap(),
                a[1].as_f64().unwrap(),
                a[2].as_f64().unwrap(),
            ]
        };
        PoseOut {
            matrix: matrix16(p),
            position: arr3(&p["position"]),
            quaternion: [
                q["w"].as_f64().unwrap(),
                q["x"].as_f64().unwrap(),
                q["y"].as_f64().unwrap(),
                q["z"].as_f64().unwrap(),
            ],
            rpy: arr3(&p["rpy"]),
        }
    }

    fn from_pb(p: &pb::Pose) -> PoseOut {
        let pos = p.position.as_ref().expect("position");
        let q = p.orientation.as_ref().expect("orientation");
        let r = p.rpy.as_ref().expect("rpy");
        PoseOut {
            matrix: p.matrix.clone(),
            position: [pos.x, pos.y, pos.z],
            quaternion: [q.w, q.x, q.y, q.z],
            rpy: [r.roll, r.pitch, r.yaw],
        }
    }

    fn from_transform(t: &kinserve::kinematics::Transform) -> PoseOut {
        PoseOut {
            matrix: t.matrix().iter().flatten().copied().collect(),
            position: t.position(),
            quaternion: t.quaternion(),
            rpy: t.rpy(),
        }
    }

    fn assert_close_to(&self, want: &PoseOut, what: &str) {
        assert_eq!(self.matrix.len(), 16, "{what}: matrix has 16 values");
        let pairs = self
            .matrix
            .iter()
            .zip(&want.matrix)
            .chain(self.position.iter().zip(&want.position))
            .chain(self.quaternion.iter().zip(&want.quaternion))
            .chain(self.rpy.iter().zip(&want.rpy));
        for (a, b) in pairs {
            assert_close(*a, *b, TOL, what);
        }
    }
}

#[derive(Clone, Debug)]
struct Success {
    pose: PoseOut,
    frames: Option<Vec<PoseOut>>,
    length_unit: String,
}

type Outcome = Result<Success, Failure>;

fn length_unit_name(u: i32) -> String {
    match pb::LengthUnit::try_from(u) {
        Ok(pb::LengthUnit::M) => "m".into(),
        Ok(pb::LengthUnit::Mm) => "mm".into(),
        _ => format!("?{u}"),
    }
}

// ---------------------------------------------------------------- the table

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Unit {
    Rad,
    Deg,
}

#[derive(Clone, Debug)]
enum Expect {
    Pose,
    Error(Class, &'static [&'static str]),
}

#[derive(Clone, Debug)]
struct Case {
    label: &'static str,
    robot: &'static str,
    joints: Vec<f64>,
    unit: Unit,
    frames: bool,
    check_limits: bool,
    expect: Expect,
}

fn case(label: &'static str, robot: &'static str, joints: &[f64], unit: Unit) -> Case {
    Case {
        label,
        robot,
        joints: joints.to_vec(),
        unit,
        frames: false,
        check_limits: true,
        expect: Expect::Pose,
    }
}

impl Case {
    fn frames(mut self) -> Self {
        self.frames = true;
        self
    }
    fn no_limits(mut self) -> Self {
        self.check_limits = false;
        self
    }
    fn fails(mut self, class: Class, fields: &'static [&'static str]) -> Self {
        self.expect = Expect::Error(class, fields);
        self
    }

    fn options(&self) -> Option<pb::FkOptions> {
        // Leave options absent when they are all defaults: that path must mean
        // "radians, no frames, limits checked" too.
        if self.unit == Unit::Rad && !self.frames && self.check_limits {
            return None;
        }
        Some(pb::FkOptions {
            angle_unit: match self.unit {
                Unit::Rad => pb::AngleUnit::Rad,
                Unit::Deg => pb::AngleUnit::Deg,
            } as i32,
            include_frames: self.frames,
            skip_limit_check: !self.check_limits,
        })
    }

    /// The joints as JSON text (non-finite values as the stand-ins described above).
    fn joints_json(&self) -> String {
        let parts: Vec<String> = self
            .joints
            .iter()
            .map(|x| {
                if x.is_nan() {
                    "\"x\"".to_string()
                } else if x.is_infinite() {
                    if *x > 0.0 { "1e999" } else { "-1e999" }.to_string()
                } else {
                    serde_json::to_string(x).unwrap()
                }
            })
            .collect();
        format!("[{}]", parts.join(","))
    }

    /// The JSON fields shared by the REST body and the WebSocket message
    /// (defaults left out, as a client would).
    fn json_fields(&self) -> String {
        let mut s = format!("\"joints\":{}", self.joints_json());
        if self.unit == Unit::Deg {
            s.push_str(",\"angle_unit\":\"deg\"");
        }
        if self.frames {
            s.push_str(",\"frames\":true");
        }
        if !self.check_limits {
            s.push_str(",\"check_limits\":false");
        }
        s
    }
}

const NAN: f64 = f64::NAN;
const INF: f64 = f64::INFINITY;

fn table() -> Vec<Case> {
    use Class::*;
    use Unit::*;
    vec![
        // puma560: standard DH, 6R, limits in degrees.
        case("puma home", "puma560", &[0.0; 6], Rad),
        case(
            "puma rad",
            "puma560",
            &[0.3, -0.5, 0.8, 1.2, -0.7, 2.5],
            Rad,
        ),
        case(
            "puma deg",
            "puma560",
            &[30.0, -45.0, 60.0, 90.0, -30.0, 120.0],
            Deg,
        ),
        case(
            "puma qr frames",
            "puma560",
            &[0.0, 90.0, -90.0, 0.0, 0.0, 0.0],
            Deg,
        )
        .frames(),
        case(
            "puma qn at joint 3's limit",
            "puma560",
            &[0.0, 45.0, 135.0, 0.0, 45.0, 0.0],
            Deg,
        ),
        case(
            "puma joint 5 over limit",
            "puma560",
            &[0.0, 0.0, 0.0, 0.0, 120.0, 0.0],
            Deg,
        )
        .fails(Invalid, &["joints[4]"]),
        case(
            "puma joint 5 over limit, unchecked",
            "puma560",
            &[0.0, 0.0, 0.0, 0.0, 120.0, 0.0],
            Deg,
        )
        .no_limits(),
        case(
            "puma joint 1 over limit in rad",
            "puma560",
            &[3.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            Rad,
        )
        .fails(Invalid, &["joints[0]"]),
        case("puma 5 values", "puma560", &[0.0; 5], Rad).fails(Invalid, &["joints"]),
        case("puma 7 values", "puma560", &[0.0; 7], Deg).fails(Invalid, &["joints"]),
        case("puma no values", "puma560", &[], Rad).fails(Invalid, &["joints"]),
        case("puma NaN", "puma560", &[0.0, 0.0, NAN, 0.0, 0.0, 0.0], Rad)
            .fails(Invalid, &["joints[2]"]),
        case(
            "puma +inf, unchecked",
            "puma560",
            &[INF, 0.0, 0.0, 0.0, 0.0, 0.0],
            Rad,
        )
        .no_limits()
        .fails(Invalid, &["joints[0]"]),
        case(
            "puma -inf",
            "puma560",
            &[0.0, 0.0, 0.0, 0.0, 0.0, -INF],
            Deg,
        )
        .fails(Invalid, &["joints[5]"]),
        // panda: modified DH, 7R plus a fixed flange row, limits in radians.
        case(
            "panda ready",
            "panda",
            &[0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
            Rad,
        ),
        case(
            "panda frames",
            "panda",
            &[0.5, 0.3, -0.4, -1.5, 0.6, 2.0, -1.0],
            Rad,
        )
        .frames(),
        case(
            "panda deg",
            "panda",
            &[10.0, 20.0, -30.0, -90.0, 45.0, 100.0, 0.0],
            Deg,
        ),
        case(
            "panda joint 4 over limit",
            "panda",
            &[0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            Rad,
        )
        .fails(Invalid, &["joints[3]"]),
        case(
            "panda joint 4 over limit, unchecked, frames",
            "panda",
            &[0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            Rad,
        )
        .no_limits()
        .frames(),
        case(
            "panda joint 6 under limit in deg",
            "panda",
            &[0.0, 0.0, 0.0, -90.0, 0.0, -5.0, 0.0],
            Deg,
        )
        .fails(Invalid, &["joints[5]"]),
        case(
            "panda 8 values (the fixed row is no joint)",
            "panda",
            &[0.0; 8],
            Rad,
        )
        .fails(Invalid, &["joints"]),
        // stanford: prismatic joint 3 in metres whatever the angle unit.
        case(
            "stanford rad",
            "stanford",
            &[0.0, 0.0, 0.5, 0.0, 0.0, 0.0],
            Rad,
        ),
        case(
            "stanford deg (prismatic still in m)",
            "stanford",
            &[0.0, 0.0, 0.5, 0.0, 0.0, 0.0],
            Deg,
        ),
        case(
            "stanford deg",
            "stanford",
            &[30.0, -20.0, 1.0, 45.0, 60.0, -90.0],
            Deg,
        ),
        case(
            "stanford frames",
            "stanford",
            &[0.2, -0.3, 0.9, 0.4, -0.5, 0.6],
            Rad,
        )
        .frames(),
        case(
            "stanford prismatic under limit",
            "stanford",
            &[0.0, 0.0, 0.1, 0.0, 0.0, 0.0],
            Rad,
        )
        .fails(Invalid, &["joints[2]"]),
        case(
            "stanford prismatic over limit, unchecked",
            "stanford",
            &[0.0, 0.0, 2.0, 0.0, 0.0, 0.0],
            Deg,
        )
        .no_limits(),
        case(
            "stanford prismatic NaN",
            "stanford",
            &[0.0, 0.0, NAN, 0.0, 0.0, 0.0],
            Deg,
        )
        .fails(Invalid, &["joints[2]"]),
        // alpha_ii: millimetres and degrees, no joint limits.
        case("alpha home", "alpha_ii", &[0.0; 5], Deg),
        case(
            "alpha deg",
            "alpha_ii",
            &[10.0, 20.0, -30.0, 40.0, 50.0],
            Deg,
        ),
        case(
            "alpha beyond a turn (no limits)",
            "alpha_ii",
            &[720.0, -400.0, 1000.0, 0.0, 0.0],
            Deg,
        ),
        case(
            "alpha rad frames",
            "alpha_ii",
            &[0.1, 0.2, 0.3, 0.4, 0.5],
            Rad,
        )
        .frames(),
        case("alpha 6 values", "alpha_ii", &[0.0; 6], Deg).fails(Invalid, &["joints"]),
        case("alpha NaN", "alpha_ii", &[0.0, 0.0, 0.0, 0.0, NAN], Deg)
            .fails(Invalid, &["joints[4]"]),
        // Another standard robot, for good measure.
        case(
            "ur5 deg",
            "ur5",
            &[0.0, -90.0, 90.0, -90.0, -90.0, 0.0],
            Deg,
        ),
        case(
            "ur5 over limit",
            "ur5",
            &[0.0, 0.0, 0.0, 0.0, 0.0, 400.0],
            Deg,
        )
        .fails(Invalid, &["joints[5]"]),
        // Unknown robot.
        case("unknown robot", "no_such_robot", &[0.0; 6], Rad).fails(NotFound, &[]),
    ]
}

/// The library's answer for a case that should succeed.
fn library(case: &Case) -> Success {
    let robot = kinserve::model::load_robot_file(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("robots/{}.json", case.robot)),
    )
    .expect("robot file loads");
    let opts = FkOptions {
        angle_unit: match case.unit {
            Unit::Rad => AngleUnit::Rad,
            Unit::Deg => AngleUnit::Deg,
        },
        check_limits: case.check_limits,
    };
    let reject =
        |e: kinserve::Error| -> ! { panic!("{}: the library rejects it: {e}", case.label) };
    let (t, frames) = if case.frames {
        let (t, f) = robot
            .fk_frames_checked(&case.joints, &opts)
            .unwrap_or_else(|e| reject(e));
        (t, Some(f.iter().map(PoseOut::from_transform).collect()))
    } else {
        let t = robot
            .fk_checked(&case.joints, &opts)
            .unwrap_or_else(|e| reject(e));
        (t, None)
    };
    Success {
        pose: PoseOut::from_transform(&t),
        frames,
        length_unit: robot.length_unit().as_str().to_string(),
    }
}

// ---------------------------------------------------------------- the four front doors

async fn over_rest(app: &TestApp, case: &Case) -> Outcome {
    let body = format!("{{{}}}", case.json_fields());
    let r = app
        .client
        .post(format!("{}/v1/robots/{}/fk", app.http, case.robot))
        .header("content-type", "application/json")
        .body(body)
        .send()
        .await
        .expect("request sent");
    let status = r.status().as_u16();
    let v: Value = r.json().await.expect("JSON body");
    if status != 200 {
        return Err(problem_error(status, &v));
    }
    assert_eq!(v["robot"], case.robot);
    Ok(Success {
        pose: PoseOut::from_json(&v["pose"]),
        frames: v.get("frames").map(|f| {
            f.as_array()
                .unwrap()
                .iter()
                .map(PoseOut::from_json)
                .collect()
        }),
        length_unit: v["length_unit"].as_str().unwrap().to_string(),
    })
}

async fn over_grpc_unary(app: &TestApp, case: &Case) -> Outcome {
    let mut c = app.grpc_client().await;
    match c
        .forward_kinematics(fk_request(case.robot, &case.joints, case.options()))
        .await
    {
        Ok(r) => {
            let r = r.into_inner();
            assert_eq!(r.robot, case.robot);
            Ok(Success {
                pose: PoseOut::from_pb(r.pose.as_ref().expect("pose")),
                frames: case
                    .frames
                    .then(|| r.frames.iter().map(PoseOut::from_pb).collect()),
                length_unit: length_unit_name(r.length_unit),
            })
        }
        Err(s) => Err(Failure {
            class: class_of_code(s.code()),
            fields: status_fields(&s),
            raw: format!("{s:?}"),
        }),
    }
}

/// Every case on one gRPC stream (the robot changes from message to message).
async fn over_grpc_stream(app: &TestApp, cases: &[Case]) -> Vec<Outcome> {
    let mut c = app.grpc_client().await;
    let requests: Vec<_> = cases
        .iter()
        .enumerate()
        .map(|(i, k)| stream_request(1000 + i as u64, k.robot, &k.joints, k.options()))
        .collect();
    let mut rx = c
        .stream_forward_kinematics(tokio_stream::iter(requests))
        .await
        .expect("stream opens")
        .into_inner();
    let mut out = Vec::new();
    while let Some(m) = rx.message().await.expect("no stream error") {
        let i = out.len();
        assert_eq!(m.id, 1000 + i as u64, "stream responses in order");
        out.push(match m.result.expect("a result") {
            StreamResult::Pose(p) => Ok(Success {
                pose: PoseOut::from_pb(&p),
                frames: cases[i]
                    .frames
                    .then(|| m.frames.iter().map(PoseOut::from_pb).collect()),
                length_unit: length_unit_name(m.length_unit),
            }),
            StreamResult::Error(e) => Err(Failure {
                class: class_of_i32(e.code),
                fields: rpc_status_fields(&e),
                raw: format!("{e:?}"),
            }),
        });
    }
    assert_eq!(out.len(), cases.len(), "one response per request");
    out
}

/// Every case over the WebSocket, one socket per robot (the robot is in the URL).
async fn over_websocket(app: &TestApp, cases: &[Case]) -> Vec<Outcome> {
    let mut out: Vec<Option<Outcome>> = vec![None; cases.len()];
    let mut by_robot: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, c) in cases.iter().enumerate() {
        by_robot.entry(c.robot).or_default().push(i);
    }
    for (robot, idx) in by_robot {
        let url = format!("{}/v1/robots/{robot}/fk/stream", app.ws);
        let mut ws = match tokio_tungstenite::connect_async(url).await {
            Ok((ws, _)) => ws,
            Err(tungstenite::Error::Http(resp)) => {
                // Refused at the upgrade: every case of this robot gets that error.
                let status = resp.status().as_u16();
                let body: Value = serde_json::from_slice(resp.body().as_deref().unwrap_or(b""))
                    .expect("problem body");
                for i in idx {
                    out[i] = Some(Err(problem_error(status, &body)));
                }
                continue;
            }
            Err(e) => panic!("websocket to {robot}: {e}"),
        };
        for &i in &idx {
            let text = format!("{{\"id\":{i},{}}}", cases[i].json_fields());
            ws.send(tungstenite::Message::Text(text.into()))
                .await
                .unwrap();
        }
        for &i in &idx {
            let reply: Value = loop {
                match ws.next().await.expect("socket open").expect("no error") {
                    tungstenite::Message::Text(t) => {
                        break serde_json::from_str(t.as_str()).unwrap();
                    }
                    tungstenite::Message::Ping(_) | tungstenite::Message::Pong(_) => continue,
                    other => panic!("unexpected {other:?}"),
                }
            };
            assert_eq!(reply["id"], json!(i), "in order, id echoed");
            out[i] = Some(if let Some(p) = reply.get("error") {
                assert!(reply.get("pose").is_none());
                Err(problem_error(p["status"].as_u64().unwrap() as u16, p))
            } else {
                Ok(Success {
                    pose: PoseOut::from_json(&reply["pose"]),
                    frames: reply.get("frames").map(|f| {
                        f.as_array()
                            .unwrap()
                            .iter()
                            .map(PoseOut::from_json)
                            .collect()
                    }),
                    // The WebSocket reply carries no unit: it is the robot's.
                    length_unit: String::new(),
                })
            });
        }
        let _ = ws.close(None).await;
    }
    out.into_iter().map(|o| o.expect("answered")).collect()
}

fn check(case: &Case, protocol: &str, got: &Outcome, want: &Option<Success>) {
    let what = format!("{} over {protocol}", case.label);
    match (&case.expect, got) {
        (Expect::Pose, Ok(s)) => {
            let want = want.as_ref().unwrap();
            s.pose.assert_close_to(&want.pose, &what);
            if !s.length_unit.is_empty() {
                assert_eq!(s.length_unit, want.length_unit, "{what}: length unit");
            }
            match (&s.frames, &want.frames) {
                (None, None) => {}
                (Some(g), Some(w)) => {
                    assert_eq!(g.len(), w.len(), "{what}: frame count");
                    for (k, (a, b)) in g.iter().zip(w).enumerate() {
                        a.assert_close_to(b, &format!("{what}: frame {k}"));
                    }
                }
                (g, w) => panic!("{what}: frames {g:?} vs expected {w:?}"),
            }
        }
        (Expect::Error(class, fields), Err(f)) => {
            assert_eq!(f.class, *class, "{what}: error class ({})", f.raw);
            assert_eq!(f.fields, *fields, "{what}: field paths ({})", f.raw);
        }
        (e, g) => panic!("{what}: expected {e:?}, got {g:?}"),
    }
}

#[tokio::test]
async fn every_case_gives_the_same_answer_over_rest_grpc_stream_and_websocket() {
    let app = spawn_app().await;
    let cases = table();
    let want: Vec<Option<Success>> = cases
        .iter()
        .map(|c| matches!(c.expect, Expect::Pose).then(|| library(c)))
        .collect();

    let mut rest = Vec::new();
    let mut unary = Vec::new();
    for c in &cases {
        rest.push(over_rest(&app, c).await);
        unary.push(over_grpc_unary(&app, c).await);
    }
    let stream = over_grpc_stream(&app, &cases).await;
    let ws = over_websocket(&app, &cases).await;

    for (i, c) in cases.iter().enumerate() {
        // Each door against the table (and the library)...
        check(c, "REST", &rest[i], &want[i]);
        check(c, "gRPC unary", &unary[i], &want[i]);
        check(c, "gRPC stream", &stream[i], &want[i]);
        check(c, "WebSocket", &ws[i], &want[i]);
        // ...and the doors against each other.
        if let Ok(r) = &rest[i] {
            for (name, other) in [
                ("gRPC unary", &unary[i]),
                ("gRPC stream", &stream[i]),
                ("WebSocket", &ws[i]),
            ] {
                let o = other.as_ref().unwrap();
                o.pose
                    .assert_close_to(&r.pose, &format!("{}: {name} vs REST", c.label));
                for (a, b) in o.frames.iter().flatten().zip(r.frames.iter().flatten()) {
                    a.assert_close_to(b, &format!("{}: {name} frames vs REST", c.label));
                }
            }
        }
    }
}

#[tokio::test]
async fn batches_agree_with_single_requests_over_rest_and_grpc() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    // Group the table's good cases by robot and options: one batch each.
    let mut groups: BTreeMap<(&str, Unit, bool), Vec<Case>> = BTreeMap::new();
    for k in table() {
        if matches!(k.expect, Expect::Pose) {
            groups
                .entry((k.robot, k.unit, k.check_limits))
                .or_default()
                .push(k);
        }
    }
    assert!(groups.len() >= 6);
    for ((robot, unit, check_limits), cases) in groups {
        let wants: Vec<Success> = cases.iter().map(library).collect();
        let configs = format!(
            "[{}]",
            cases
                .iter()
                .map(|k| k.joints_json())
                .collect::<Vec<_>>()
                .join(",")
        );
        let body = format!(
            "{{\"configurations\":{configs},\"angle_unit\":\"{}\",\"check_limits\":{check_limits}}}",
            if unit == Unit::Deg { "deg" } else { "rad" }
        );
        let r = app
            .client
            .post(format!("{}/v1/robots/{robot}/fk/batch", app.http))
            .header("content-type", "application/json")
            .body(body)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200, "{robot}");
        let v: Value = r.json().await.unwrap();
        let rest_poses: Vec<PoseOut> = v["poses"]
            .as_array()
            .unwrap()
            .iter()
            .map(PoseOut::from_json)
            .collect();

        let g = c
            .forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
                robot: robot.into(),
                configurations: cases
                    .iter()
                    .map(|k| pb::JointConfiguration {
                        joints: k.joints.clone(),
                    })
                    .collect(),
                options: cases[0].options().map(|mut o| {
                    o.include_frames = false;
                    o
                }),
            })
            .await
            .unwrap()
            .into_inner();
        assert_eq!(rest_poses.len(), cases.len());
        assert_eq!(g.poses.len(), cases.len());
        assert_eq!(v["length_unit"], wants[0].length_unit);
        assert_eq!(length_unit_name(g.length_unit), wants[0].length_unit);
        for (k, case) in cases.iter().enumerate() {
            rest_poses[k].assert_close_to(&wants[k].pose, &format!("{}: REST batch", case.label));
            PoseOut::from_pb(&g.poses[k])
                .assert_close_to(&wants[k].pose, &format!("{}: gRPC batch", case.label));
        }
    }
}

// ---------------------------------------------------------------- registry and limits

/// A JSON robot model (REST schema) as the protobuf message, field by field.
/// Enum strings the proto does not know become an out-of-range enum value.
fn model_to_pb(m: &Value) -> pb::Robot {
    let s = |v: &Value| v.as_str().map(str::to_string);
    let f = |v: &Value| v.as_f64().unwrap_or(0.0);
    let transform = |t: &Value| -> Option<pb::FixedTransform> {
        if t.is_null() {
            return None;
        }
        let v3 = |v: &Value| pb::Vector3 {
            x: f(&v[0]),
            y: f(&v[1]),
            z: f(&v[2]),
        };
        let rotation = if !t["rpy"].is_null() {
            Some(pb::fixed_transform::Rotation::Rpy(pb::Rpy {
                roll: f(&t["rpy"][0]),
                pitch: f(&t["rpy"][1]),
                yaw: f(&t["rpy"][2]),
            }))
        } else if !t["quaternion"].is_null() {
            let q = &t["quaternion"];
            Some(pb::fixed_transform::Rotation::Quaternion(pb::Quaternion {
                w: f(&q["w"]),
                x: f(&q["x"]),
                y: f(&q["y"]),
                z: f(&q["z"]),
            }))
        } else if !t["matrix"].is_null() {
            Some(pb::fixed_transform::Rotation::Matrix(pb::Matrix4 {
                values: t["matrix"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .flat_map(|r| r.as_array().unwrap().iter().map(f).collect::<Vec<_>>())
                    .collect(),
            }))
        } else {
            None
        };
        Some(pb::FixedTransform {
            translation: (!t["translation"].is_null()).then(|| v3(&t["translation"])),
            rotation,
        })
    };
    pb::Robot {
        name: s(&m["name"]).unwrap_or_default(),
        description: s(&m["description"]),
        source: s(&m["source"]),
        convention: match m["convention"].as_str() {
            Some("standard") => pb::Convention::Standard as i32,
            Some("modified") => pb::Convention::Modified as i32,
            _ => 99,
        },
        angle_unit: match m["angle_unit"].as_str() {
            Some("rad") | None => pb::AngleUnit::Rad as i32,
            Some("deg") => pb::AngleUnit::Deg as i32,
            _ => 99,
        },
        length_unit: match m["length_unit"].as_str() {
            Some("m") | None => pb::LengthUnit::M as i32,
            Some("mm") => pb::LengthUnit::Mm as i32,
            _ => 99,
        },
        base: transform(&m["base"]),
        tool: transform(&m["tool"]),
        links: m["links"]
            .as_array()
            .map(|links| {
                links
                    .iter()
                    .map(|l| pb::Link {
                        name: s(&l["name"]),
                        joint: match l["joint"].as_str() {
                            Some("revolute") => pb::JointType::Revolute as i32,
                            Some("prismatic") => pb::JointType::Prismatic as i32,
                            Some("fixed") => pb::JointType::Fixed as i32,
                            _ => 99,
                        },
                        a: f(&l["a"]),
                        alpha: f(&l["alpha"]),
                        d: f(&l["d"]),
                        theta: f(&l["theta"]),
                        limits: l["limits"].as_array().map(|x| pb::Limits {
                            lo: f(&x[0]),
                            hi: f(&x[1]),
                        }),
                    })
                    .collect()
            })
            .unwrap_or_default(),
    }
}

fn modified(name: &str, edit: impl FnOnce(&mut Value)) -> Value {
    let mut m = planar_model(name);
    edit(&mut m);
    m
}

async fn register_over_rest(app: &TestApp, model: &Value, token: Option<&str>) -> Outcome {
    let mut req = app
        .client
        .post(format!("{}/v1/robots", app.http))
        .json(model);
    if let Some(t) = token {
        req = req.header("authorization", t);
    }
    rest_outcome(req.send().await.unwrap(), &[200, 201]).await
}

async fn rest_outcome(r: reqwest::Response, ok: &[u16]) -> Outcome {
    let status = r.status().as_u16();
    if ok.contains(&status) {
        return Ok(Success {
            pose: PoseOut {
                matrix: vec![],
                position: [0.0; 3],
                quaternion: [0.0; 4],
                rpy: [0.0; 3],
            },
            frames: None,
            length_unit: String::new(),
        });
    }
    let v: Value = r.json().await.expect("problem body");
    Err(problem_error(status, &v))
}

fn grpc_outcome<T>(r: Result<tonic::Response<T>, tonic::Status>) -> Outcome {
    match r {
        Ok(_) => Ok(Success {
            pose: PoseOut {
                matrix: vec![],
                position: [0.0; 3],
                quaternion: [0.0; 4],
                rpy: [0.0; 3],
            },
            frames: None,
            length_unit: String::new(),
        }),
        Err(s) => Err(Failure {
            class: class_of_code(s.code()),
            fields: status_fields(&s),
            raw: format!("{s:?}"),
        }),
    }
}

fn assert_error(o: &Outcome, class: Class, fields: &[&str], what: &str) {
    match o {
        Err(f) => {
            assert_eq!(f.class, class, "{what}: class ({})", f.raw);
            assert_eq!(f.fields, fields, "{what}: fields ({})", f.raw);
        }
        Ok(_) => panic!("{what}: expected {class:?}, it succeeded"),
    }
}

#[tokio::test]
async fn bad_models_are_rejected_alike_over_rest_and_grpc() {
    let app = spawn_app_with(|c| c.max_joints = 3).await;
    let mut c = app.grpc_client().await;
    let cases: Vec<(&str, Value, &[&str])> = vec![
        ("bad name", planar_model("Not OK"), &["name"]),
        ("empty name", planar_model(""), &["name"]),
        (
            "no links",
            modified("m1", |m| m["links"] = json!([])),
            &["links"],
        ),
        (
            "unknown convention",
            modified("m2", |m| m["convention"] = json!("sideways")),
            &["convention"],
        ),
        (
            "unknown joint type",
            modified("m3", |m| m["links"][1]["joint"] = json!("ball")),
            &["links[1].joint"],
        ),
        (
            "limits upside down",
            modified("m4", |m| m["links"][0]["limits"] = json!([10, -10])),
            &["links[0].limits"],
        ),
        (
            "zero tool quaternion",
            modified("m5", |m| {
                m["tool"] = json!({"quaternion": {"w": 0, "x": 0, "y": 0, "z": 0}})
            }),
            &["tool.quaternion"],
        ),
        (
            "non-rigid base matrix",
            modified("m6", |m| {
                m["base"] = json!({"matrix": [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})
            }),
            &["base.matrix"],
        ),
        (
            "too many joints",
            modified("m7", |m| {
                let l = m["links"][1].clone();
                m["links"] = json!([l, l, l, l]);
            }),
            &["links"],
        ),
    ];
    for (label, model, fields) in cases {
        let rest = register_over_rest(&app, &model, None).await;
        let grpc = grpc_outcome(
            c.register_robot(pb::RegisterRobotRequest {
                robot: Some(model_to_pb(&model)),
                replace: false,
            })
            .await,
        );
        let (Err(r), Err(g)) = (&rest, &grpc) else {
            panic!("{label}: REST {rest:?}, gRPC {grpc:?}");
        };
        assert_eq!(r.class, Class::Invalid, "{label} over REST: {}", r.raw);
        assert_eq!(g.class, Class::Invalid, "{label} over gRPC: {}", g.raw);
        // Same field paths on both doors; the first one is the expected field.
        let rs: Vec<&str> = r.fields.iter().map(String::as_str).collect();
        let gs: Vec<&str> = g.fields.iter().map(String::as_str).collect();
        assert_eq!(rs, gs, "{label}: REST {} vs gRPC {}", r.raw, g.raw);
        assert!(
            rs.first().is_some_and(|f| f.starts_with(fields[0])),
            "{label}: {rs:?} should name {fields:?}"
        );
    }
    // The good model converts and registers on both doors.
    register_over_rest(&app, &planar_model("fine_rest"), None)
        .await
        .unwrap();
    c.register_robot(pb::RegisterRobotRequest {
        robot: Some(model_to_pb(&planar_model("fine_grpc"))),
        replace: false,
    })
    .await
    .unwrap();
}

#[tokio::test]
async fn registry_errors_have_the_same_class_over_rest_and_grpc() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let http =
        |m: reqwest::Method, path: &str| app.client.request(m, format!("{}{path}", app.http));
    use reqwest::Method;

    register_over_rest(&app, &planar_model("taken"), None)
        .await
        .unwrap();

    // Name taken: ALREADY_EXISTS / 409 already-exists.
    let rest = register_over_rest(&app, &planar_model("taken"), None).await;
    let grpc = grpc_outcome(
        c.register_robot(pb::RegisterRobotRequest {
            robot: Some(model_to_pb(&planar_model("taken"))),
            replace: false,
        })
        .await,
    );
    assert_error(&rest, Class::AlreadyExists, &[], "taken over REST");
    assert_error(&grpc, Class::AlreadyExists, &[], "taken over gRPC");

    // Built-ins: read-only, whether created, replaced or deleted.
    let rest = register_over_rest(&app, &planar_model("puma560"), None).await;
    let grpc = grpc_outcome(
        c.register_robot(pb::RegisterRobotRequest {
            robot: Some(model_to_pb(&planar_model("puma560"))),
            replace: false,
        })
        .await,
    );
    assert_error(&rest, Class::ReadOnly, &[], "create built-in over REST");
    assert_error(&grpc, Class::ReadOnly, &[], "create built-in over gRPC");
    let rest = rest_outcome(
        http(Method::PUT, "/v1/robots/puma560")
            .json(&planar_model("puma560"))
            .send()
            .await
            .unwrap(),
        &[200, 201],
    )
    .await;
    let grpc = grpc_outcome(
        c.register_robot(pb::RegisterRobotRequest {
            robot: Some(model_to_pb(&planar_model("puma560"))),
            replace: true,
        })
        .await,
    );
    assert_error(&rest, Class::ReadOnly, &[], "replace built-in over REST");
    assert_error(&grpc, Class::ReadOnly, &[], "replace built-in over gRPC");
    let rest = rest_outcome(
        http(Method::DELETE, "/v1/robots/panda")
            .send()
            .await
            .unwrap(),
        &[204],
    )
    .await;
    let grpc = grpc_outcome(
        c.delete_robot(pb::DeleteRobotRequest {
            name: "panda".into(),
        })
        .await,
    );
    assert_error(&rest, Class::ReadOnly, &[], "delete built-in over REST");
    assert_error(&grpc, Class::ReadOnly, &[], "delete built-in over gRPC");

    // Unknown robots.
    let rest = rest_outcome(
        http(Method::DELETE, "/v1/robots/ghost")
            .send()
            .await
            .unwrap(),
        &[204],
    )
    .await;
    let grpc = grpc_outcome(
        c.delete_robot(pb::DeleteRobotRequest {
            name: "ghost".into(),
        })
        .await,
    );
    assert_error(&rest, Class::NotFound, &[], "delete unknown over REST");
    assert_error(&grpc, Class::NotFound, &[], "delete unknown over gRPC");
    let rest = rest_outcome(
        http(Method::GET, "/v1/robots/ghost").send().await.unwrap(),
        &[200],
    )
    .await;
    let grpc = grpc_outcome(
        c.get_robot(pb::GetRobotRequest {
            name: "ghost".into(),
        })
        .await,
    );
    assert_error(&rest, Class::NotFound, &[], "get unknown over REST");
    assert_error(&grpc, Class::NotFound, &[], "get unknown over gRPC");
    let rest = rest_outcome(
        http(Method::POST, "/v1/robots/ghost/fk/batch")
            .json(&json!({"configurations": [[0, 0]]}))
            .send()
            .await
            .unwrap(),
        &[200],
    )
    .await;
    let grpc = grpc_outcome(
        c.forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "ghost".into(),
            configurations: vec![pb::JointConfiguration {
                joints: vec![0.0, 0.0],
            }],
            options: None,
        })
        .await,
    );
    assert_error(&rest, Class::NotFound, &[], "batch unknown over REST");
    assert_error(&grpc, Class::NotFound, &[], "batch unknown over gRPC");

    // A bad configuration in a batch is named the same way.
    let rest = rest_outcome(
        http(Method::POST, "/v1/robots/taken/fk/batch")
            .json(&json!({"configurations": [[0, 0], [0, 0], [400, 0]], "angle_unit": "deg"}))
            .send()
            .await
            .unwrap(),
        &[200],
    )
    .await;
    let grpc = grpc_outcome(
        c.forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "taken".into(),
            configurations: vec![
                pb::JointConfiguration {
                    joints: vec![0.0, 0.0],
                },
                pb::JointConfiguration {
                    joints: vec![0.0, 0.0],
                },
                pb::JointConfiguration {
                    joints: vec![400.0, 0.0],
                },
            ],
            options: Some(pb::FkOptions {
                angle_unit: pb::AngleUnit::Deg as i32,
                ..Default::default()
            }),
        })
        .await,
    );
    assert_error(
        &rest,
        Class::Invalid,
        &["configurations[2][0]"],
        "batch limit over REST",
    );
    assert_error(
        &grpc,
        Class::Invalid,
        &["configurations[2][0]"],
        "batch limit over gRPC",
    );
}

#[tokio::test]
async fn auth_and_size_limits_have_the_same_class_over_rest_and_grpc() {
    let app = spawn_app_with(|c| {
        c.api_token = Some("tok".into());
        c.max_batch = 3;
        c.max_batch_body_bytes = 32 << 10;
    })
    .await;
    let mut c = app.grpc_client().await;

    for token in [None, Some("Bearer nope")] {
        let rest = register_over_rest(&app, &planar_model("guarded"), token).await;
        let mut req = tonic::Request::new(pb::RegisterRobotRequest {
            robot: Some(model_to_pb(&planar_model("guarded"))),
            replace: false,
        });
        if let Some(t) = token {
            req.metadata_mut()
                .insert("authorization", t.parse().unwrap());
        }
        let grpc = grpc_outcome(c.register_robot(req).await);
        assert_error(&rest, Class::Unauthenticated, &[], "register over REST");
        assert_error(&grpc, Class::Unauthenticated, &[], "register over gRPC");
    }
    let rest = rest_outcome(
        app.client
            .delete(format!("{}/v1/robots/puma560", app.http))
            .send()
            .await
            .unwrap(),
        &[204],
    )
    .await;
    let grpc = grpc_outcome(
        c.delete_robot(pb::DeleteRobotRequest {
            name: "puma560".into(),
        })
        .await,
    );
    assert_error(&rest, Class::Unauthenticated, &[], "delete over REST");
    assert_error(&grpc, Class::Unauthenticated, &[], "delete over gRPC");

    // Over the batch count: too large, naming `configurations`.
    let rest = rest_outcome(
        app.post(
            "/v1/robots/puma560/fk/batch",
            &json!({"configurations": vec![vec![0; 6]; 4]}),
        )
        .await,
        &[200],
    )
    .await;
    let grpc = grpc_outcome(
        c.forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "puma560".into(),
            configurations: vec![
                pb::JointConfiguration {
                    joints: vec![0.0; 6]
                };
                4
            ],
            options: None,
        })
        .await,
    );
    assert_error(
        &rest,
        Class::TooLarge,
        &["configurations"],
        "batch count over REST",
    );
    assert_error(
        &grpc,
        Class::TooLarge,
        &["configurations"],
        "batch count over gRPC",
    );

    // Over the byte limit of a batch body / message (the count limit is not reached).
    let joints = vec![0.123456789; 5000]; // 40 KB as doubles, ~60 KB as JSON
    let rest = rest_outcome(
        app.post(
            "/v1/robots/puma560/fk/batch",
            &json!({"configurations": [joints.clone()]}),
        )
        .await,
        &[200],
    )
    .await;
    let grpc = grpc_outcome(
        c.forward_kinematics_batch(pb::ForwardKinematicsBatchRequest {
            robot: "puma560".into(),
            configurations: vec![pb::JointConfiguration { joints }],
            options: None,
        })
        .await,
    );
    assert_error(&rest, Class::TooLarge, &[], "batch bytes over REST");
    assert_error(&grpc, Class::TooLarge, &[], "batch bytes over gRPC");

    // Health of the gRPC door, for completeness of the suite's server.
    let mut h = tonic_health::pb::health_client::HealthClient::new(channel(&app).await);
    let s = h
        .check(tonic_health::pb::HealthCheckRequest {
            service: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(
        s.status,
        tonic_health::pb::health_check_response::ServingStatus::Serving as i32
    );
    assert_eq!(app.get("/readyz").await.status(), 200);
}

/// The table's good cases with `include_frames` flipped, over gRPC and REST.
async fn with_and_without_frames(app: &TestApp) -> Vec<(String, Success, Success)> {
    let mut out = Vec::new();
    for k in table() {
        if !matches!(k.expect, Expect::Pose) {
            continue;
        }
        let mut flipped = k.clone();
        flipped.frames = !k.frames;
        for (door, a, b) in [
            (
                "gRPC",
                over_grpc_unary(app, &k).await,
                over_grpc_unary(app, &flipped).await,
            ),
            (
                "REST",
                over_rest(app, &k).await,
                over_rest(app, &flipped).await,
            ),
        ] {
            out.push((format!("{} over {door}", k.label), a.unwrap(), b.unwrap()));
        }
    }
    out
}

fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::TAU);
    d.min(std::f64::consts::TAU - d)
}

#[tokio::test]
async fn the_tool_pose_does_not_depend_on_include_frames() {
    let app = spawn_app().await;
    for (what, a, b) in with_and_without_frames(&app).await {
        let (a, b) = (&a.pose, &b.pose);
        for (x, y) in a
            .matrix
            .iter()
            .zip(&b.matrix)
            .chain(a.position.iter().zip(&b.position))
        {
            assert_close(*x, *y, TOL, &what);
        }
        for (x, y) in a.quaternion.iter().zip(&b.quaternion) {
            assert_close(*x, *y, TOL, &format!("{what}: quaternion"));
        }
        // The same angles, up to a turn (see the ignored test below for ±π).
        for (x, y) in a.rpy.iter().zip(&b.rpy) {
            assert!(
                angle_diff(*x, *y) <= TOL,
                "{what}: rpy {:?} vs {:?}",
                a.rpy,
                b.rpy
            );
        }
    }
}

#[tokio::test]
// Was a bug: rpy took atan2 of a ±1e-17 residue at roll = ±π; Transform::rpy now reports (-π, π].
async fn rpy_does_not_depend_on_include_frames() {
    let app = spawn_app().await;
    for (what, a, b) in with_and_without_frames(&app).await {
        for (x, y) in a.pose.rpy.iter().zip(&b.pose.rpy) {
            assert_close(*x, *y, TOL, &format!("{what}: rpy"));
        }
    }
}
