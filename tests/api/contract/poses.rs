//! Cross-protocol poses: the case table run over REST, gRPC unary, the gRPC
//! stream and the WebSocket, batches against single requests, and poses with
//! and without frames.

use std::collections::BTreeMap;

use kinserve::api::grpc::pb;
use serde_json::Value;

use crate::helpers::*;

// ---------------------------------------------------------------- the table

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
            assert!(
                !f.kind.is_empty(),
                "{what}: names its problem kind ({})",
                f.raw
            );
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
        // ...and the doors against each other: the same problem kind (the
        // gRPC ErrorInfo reason is REST's problem type), except that JSON's
        // stand-ins for non-finite values are malformed where gRPC's doubles
        // are invalid (see the module header)...
        if let Err(r) = &rest[i] {
            let json_stand_in = c.joints.iter().any(|x| !x.is_finite());
            for (name, other, json) in [
                ("gRPC unary", &unary[i], false),
                ("gRPC stream", &stream[i], false),
                ("WebSocket", &ws[i], true),
            ] {
                let o = other.as_ref().unwrap_err();
                if json || !json_stand_in {
                    assert_eq!(o.kind, r.kind, "{}: {name} vs REST ({})", c.label, o.raw);
                }
            }
            let (u, s) = (
                unary[i].as_ref().unwrap_err(),
                stream[i].as_ref().unwrap_err(),
            );
            assert_eq!(
                s.kind, u.kind,
                "{}: gRPC stream vs unary ({})",
                c.label, s.raw
            );
        }
        // ...and the same poses.
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
                    o.frames = Some(false);
                    o
                }),
                ..Default::default()
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
