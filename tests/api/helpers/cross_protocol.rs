//! The cross-protocol case model: error classes and outcomes, one FK case,
//! the library's answer to it and running it over each front door (REST, gRPC
//! unary, the gRPC stream and the WebSocket).

use std::collections::BTreeMap;

use futures_util::{SinkExt, StreamExt};
use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use kinserve::model::{AngleUnit, FkOptions};
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite;
use tonic::Code;

use crate::helpers::*;

pub(crate) const TOL: f64 = 1e-12;

// ---------------------------------------------------------------- outcomes

/// What a client can tell an error apart by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Class {
    Invalid,
    NotFound,
    AlreadyExists,
    ReadOnly,
    Unauthenticated,
    TooLarge,
    Unavailable,
    Other,
}

pub(crate) fn class_of_code(code: Code) -> Class {
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

pub(crate) fn class_of_i32(code: i32) -> Class {
    class_of_code(Code::from_i32(code))
}

/// Class of an HTTP status (with the problem type to tell the two 409s apart).
pub(crate) fn class_of_http(status: u16, problem_type: &str) -> Class {
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
pub(crate) fn problem_error(status: u16, problem: &Value) -> Failure {
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
    let type_ = problem["type"].as_str().unwrap_or("");
    Failure {
        class: class_of_http(status, type_),
        kind: type_
            .strip_prefix("urn:kinserve:problem:")
            .unwrap_or_default()
            .to_string(),
        fields,
        raw: problem.to_string(),
    }
}

#[derive(Clone, Debug)]
pub(crate) struct Failure {
    pub(crate) class: Class,
    /// The problem kind (`invalid-input`): REST's problem type, gRPC's
    /// `ErrorInfo` reason; empty when the answer names none.
    pub(crate) kind: String,
    pub(crate) fields: Vec<String>,
    pub(crate) raw: String,
}

/// A pose, whatever the protocol.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct PoseOut {
    pub(crate) matrix: Vec<f64>,
    pub(crate) position: [f64; 3],
    pub(crate) quaternion: [f64; 4],
    pub(crate) rpy: [f64; 3],
}

impl PoseOut {
    pub(crate) fn from_json(p: &Value) -> PoseOut {
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

    pub(crate) fn from_pb(p: &pb::Pose) -> PoseOut {
        let pos = p.position.as_ref().expect("position");
        let q = p.quaternion.as_ref().expect("quaternion");
        let r = p.rpy.as_ref().expect("rpy");
        PoseOut {
            matrix: p.matrix.clone(),
            position: [pos.x, pos.y, pos.z],
            quaternion: [q.w, q.x, q.y, q.z],
            rpy: [r.roll, r.pitch, r.yaw],
        }
    }

    pub(crate) fn from_transform(t: &kinserve::kinematics::Transform) -> PoseOut {
        PoseOut {
            matrix: t.matrix().iter().flatten().copied().collect(),
            position: t.position(),
            quaternion: t.quaternion(),
            rpy: t.rpy(),
        }
    }

    pub(crate) fn assert_close_to(&self, want: &PoseOut, what: &str) {
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
pub(crate) struct Success {
    pub(crate) pose: PoseOut,
    pub(crate) frames: Option<Vec<PoseOut>>,
    pub(crate) length_unit: String,
}

pub(crate) type Outcome = Result<Success, Failure>;

pub(crate) fn length_unit_name(u: i32) -> String {
    match pb::LengthUnit::try_from(u) {
        Ok(pb::LengthUnit::M) => "m".into(),
        Ok(pb::LengthUnit::Mm) => "mm".into(),
        _ => format!("?{u}"),
    }
}

// ---------------------------------------------------------------- one case

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Unit {
    Rad,
    Deg,
}

#[derive(Clone, Debug)]
pub(crate) enum Expect {
    Pose,
    Error(Class, &'static [&'static str]),
}

#[derive(Clone, Debug)]
pub(crate) struct Case {
    pub(crate) label: &'static str,
    pub(crate) robot: &'static str,
    pub(crate) joints: Vec<f64>,
    pub(crate) unit: Unit,
    pub(crate) frames: bool,
    pub(crate) check_limits: bool,
    pub(crate) expect: Expect,
}

pub(crate) fn case(label: &'static str, robot: &'static str, joints: &[f64], unit: Unit) -> Case {
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
    pub(crate) fn frames(mut self) -> Self {
        self.frames = true;
        self
    }
    pub(crate) fn no_limits(mut self) -> Self {
        self.check_limits = false;
        self
    }
    pub(crate) fn fails(mut self, class: Class, fields: &'static [&'static str]) -> Self {
        self.expect = Expect::Error(class, fields);
        self
    }

    pub(crate) fn options(&self) -> Option<pb::FkOptions> {
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
            frames: Some(self.frames),
            check_limits: Some(self.check_limits),
            ..Default::default()
        })
    }

    /// The joints as JSON text (non-finite values as the stand-ins described above).
    pub(crate) fn joints_json(&self) -> String {
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
    pub(crate) fn json_fields(&self) -> String {
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

/// The library's answer for a case that should succeed.
pub(crate) fn library(case: &Case) -> Success {
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
            .fk_frames(&case.joints, &opts)
            .unwrap_or_else(|e| reject(e.into()));
        (t, Some(f.iter().map(PoseOut::from_transform).collect()))
    } else {
        let t = robot
            .fk(&case.joints, &opts)
            .unwrap_or_else(|e| reject(e.into()));
        (t, None)
    };
    Success {
        pose: PoseOut::from_transform(&t),
        frames,
        length_unit: robot.length_unit().as_str().to_string(),
    }
}

// ---------------------------------------------------------------- the four front doors

pub(crate) async fn over_rest(app: &TestApp, case: &Case) -> Outcome {
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

pub(crate) async fn over_grpc_unary(app: &TestApp, case: &Case) -> Outcome {
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
            kind: status_kind(&s),
            fields: status_fields(&s),
            raw: format!("{s:?}"),
        }),
    }
}

/// Every case on one gRPC stream (the robot changes from message to message).
pub(crate) async fn over_grpc_stream(app: &TestApp, cases: &[Case]) -> Vec<Outcome> {
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
                kind: rpc_status_kind(&e),
                fields: rpc_status_fields(&e),
                raw: format!("{e:?}"),
            }),
            StreamResult::PackedPose(p) => panic!("packed poses nobody asked for: {p:?}"),
        });
    }
    assert_eq!(out.len(), cases.len(), "one response per request");
    out
}

/// Every case over the WebSocket, one socket per robot (the robot is in the URL).
pub(crate) async fn over_websocket(app: &TestApp, cases: &[Case]) -> Vec<Outcome> {
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
