//! REST forward kinematics: built-ins against their closed forms, frames,
//! joint count and limit checks.

use serde_json::{Value, json};

use crate::helpers::pose::assert_pose_eq;
use crate::helpers::*;

/// Asserts the 3×4 upper part of a JSON pose's matrix equals `expect` (row-major).
fn assert_matrix(pose: &Value, expect: [[f64; 4]; 3], what: &str) {
    let m = matrix16(pose);
    for (r, row) in expect.iter().enumerate() {
        for (c, x) in row.iter().enumerate() {
            assert_close(
                m[r * 4 + c],
                *x,
                CLOSED_FORM_TOL,
                &format!("{what}[{r}][{c}]"),
            );
        }
    }
    assert_eq!(&m[12..], &[0.0, 0.0, 0.0, 1.0], "{what}: last row");
    let p = position(pose);
    for i in 0..3 {
        assert_close(
            p[i],
            m[i * 4 + 3],
            0.0,
            &format!("{what}: position[{i}] vs matrix"),
        );
    }
}

// ---------------------------------------------------------------- forward kinematics

#[tokio::test]
async fn planar_2dof_matches_its_closed_form() {
    let app = spawn_app().await;
    let (a1, a2) = (0.4, 0.3);
    for (t1, t2) in [(0.0, 0.0), (30.0, 45.0), (-120.0, 75.0), (179.0, -179.0)] {
        let out = fk_ok(
            &app,
            "planar_2dof",
            json!({"joints": [t1, t2], "angle_unit": "deg"}),
        )
        .await;
        assert_eq!(out["robot"], "planar_2dof");
        assert_eq!(out["length_unit"], "m");
        assert!(out.get("frames").is_none(), "no frames unless asked");
        let (r1, r12) = (f64::to_radians(t1), f64::to_radians(t1 + t2));
        let (c1, s1, c12, s12) = (r1.cos(), r1.sin(), r12.cos(), r12.sin());
        assert_matrix(
            &out["pose"],
            [
                [c12, -s12, 0.0, a1 * c1 + a2 * c12],
                [s12, c12, 0.0, a1 * s1 + a2 * s12],
                [0.0, 0.0, 1.0, 0.0],
            ],
            "planar",
        );
        assert_close(
            out["pose"]["rpy"][2].as_f64().unwrap(),
            wrap(r12),
            CLOSED_FORM_TOL,
            "yaw",
        );
        // The same configuration in rad (the default unit) gives the same pose.
        let rad = fk_ok(
            &app,
            "planar_2dof",
            json!({"joints": [r1, t2.to_radians()]}),
        )
        .await;
        assert_pose_eq(&rad["pose"], &out["pose"], SAME_LIB_TOL, "deg vs rad");
    }
}

/// An angle wrapped into (-π, π].
fn wrap(a: f64) -> f64 {
    let t = a.sin().atan2(a.cos());
    if t <= -std::f64::consts::PI {
        t + 2.0 * std::f64::consts::PI
    } else {
        t
    }
}

#[tokio::test]
async fn scara_4dof_matches_its_closed_form() {
    let app = spawn_app().await;
    let (a1, a2, d1, d4) = (0.35, 0.25, 0.4, 0.05);
    for (t1, t2, d3, t4) in [
        (0.0, 0.0, 0.0, 0.0),
        (30.0, -60.0, 0.1, 45.0),
        (-150.0, 120.0, 0.2, -90.0),
    ] {
        let out = fk_ok(
            &app,
            "scara_4dof",
            json!({"joints": [t1, t2, d3, t4], "angle_unit": "deg"}),
        )
        .await;
        let (r1, r12) = (f64::to_radians(t1), f64::to_radians(t1 + t2));
        let p = position(&out["pose"]);
        assert_close(p[0], a1 * r1.cos() + a2 * r12.cos(), CLOSED_FORM_TOL, "x");
        assert_close(p[1], a1 * r1.sin() + a2 * r12.sin(), CLOSED_FORM_TOL, "y");
        assert_close(p[2], d1 - d3 - d4, CLOSED_FORM_TOL, "z = d1 - d3 - d4");
        // Approach vector (third column) points down.
        let m = matrix16(&out["pose"]);
        for (i, want) in [0.0, 0.0, -1.0].into_iter().enumerate() {
            assert_close(m[i * 4 + 2], want, CLOSED_FORM_TOL, "approach");
        }
        // Normal vector: x4 = (cos φ, sin φ, 0) with φ = θ1 + θ2 − θ4.
        let phi = f64::to_radians(t1 + t2 - t4);
        assert_close(m[0], phi.cos(), CLOSED_FORM_TOL, "n.x");
        assert_close(m[4], phi.sin(), CLOSED_FORM_TOL, "n.y");
    }
}

#[tokio::test]
async fn cylindrical_3dof_matches_its_closed_form() {
    let app = spawn_app().await;
    let d1 = 0.5;
    for (t1, d2, d3) in [(0.0, 0.0, 0.2), (40.0, 0.3, 0.5), (-135.0, 0.6, 0.7)] {
        let out = fk_ok(
            &app,
            "cylindrical_3dof",
            json!({"joints": [t1, d2, d3], "angle_unit": "deg"}),
        )
        .await;
        let (s1, c1) = f64::to_radians(t1).sin_cos();
        assert_matrix(
            &out["pose"],
            [
                [c1, 0.0, -s1, -d3 * s1],
                [s1, 0.0, c1, d3 * c1],
                [0.0, -1.0, 0.0, d1 + d2],
            ],
            "cylindrical",
        );
    }
}

#[tokio::test]
async fn alpha_ii_in_mm_matches_its_closed_form() {
    let app = spawn_app().await;
    for q in [
        [0.0, 0.0, 0.0, 0.0, 0.0],
        [30.0, -45.0, 60.0, 20.0, 10.0],
        [-100.0, 80.0, -30.0, -70.0, 170.0],
    ] {
        let out = fk_ok(&app, "alpha_ii", json!({"joints": q, "angle_unit": "deg"})).await;
        assert_eq!(out["length_unit"], "mm");
        let r = q.map(f64::to_radians);
        let (c1, s1) = (r[0].cos(), r[0].sin());
        let (c2, s2) = (r[1].cos(), r[1].sin());
        let (c23, s23) = ((r[1] + r[2]).cos(), (r[1] + r[2]).sin());
        let (c234, s234) = ((r[1] + r[2] + r[3]).cos(), (r[1] + r[2] + r[3]).sin());
        let reach = 177.8 * c2 + 177.8 * c23 - 129.5 * s234;
        let p = position(&out["pose"]);
        assert_close(p[0], c1 * reach, CLOSED_FORM_TOL, "x");
        assert_close(p[1], s1 * reach, CLOSED_FORM_TOL, "y");
        assert_close(
            p[2],
            215.0 - 177.8 * s2 - 177.8 * s23 - 129.5 * c234,
            CLOSED_FORM_TOL,
            "z",
        );
        let m = matrix16(&out["pose"]);
        for (i, want) in [-c1 * s234, -s1 * s234, -c234].into_iter().enumerate() {
            assert_close(m[i * 4 + 2], want, CLOSED_FORM_TOL, "approach");
        }
    }
}

#[tokio::test]
async fn fk_returns_every_frame_when_asked() {
    let app = spawn_app().await;
    let out = fk_ok(
        &app,
        "planar_2dof",
        json!({"joints": [30, 45], "angle_unit": "deg", "frames": true}),
    )
    .await;
    let frames = out["frames"].as_array().expect("frames");
    assert_eq!(frames.len(), 3, "base frame plus one per DH row");
    let p0 = position(&frames[0]);
    assert_eq!(p0, [0.0, 0.0, 0.0], "base frame");
    let p1 = position(&frames[1]);
    let r1 = 30f64.to_radians();
    assert_close(p1[0], 0.4 * r1.cos(), CLOSED_FORM_TOL, "frame 1 x");
    assert_close(p1[1], 0.4 * r1.sin(), CLOSED_FORM_TOL, "frame 1 y");
    // No tool: the last frame (flange) is the pose.
    assert_pose_eq(&frames[2], &out["pose"], SAME_LIB_TOL, "flange");
    // frames: false gives the same pose and no frames.
    let plain = fk_ok(
        &app,
        "planar_2dof",
        json!({"joints": [30, 45], "angle_unit": "deg", "frames": false}),
    )
    .await;
    assert!(plain.get("frames").is_none());
    assert_pose_eq(
        &plain["pose"],
        &out["pose"],
        SAME_LIB_TOL,
        "frames vs plain",
    );
}

#[tokio::test]
async fn fk_checks_joint_count_and_limits() {
    let app = spawn_app().await;
    // Quill stroke d3 ∈ [0, 0.2] m.
    let p = problem(
        app.post(
            "/v1/robots/scara_4dof/fk",
            &json!({"joints": [0, 0, 0.3, 0]}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["joints[2]"]);
    assert!(
        p["errors"][0]["message"]
            .as_str()
            .unwrap()
            .contains("quill"),
        "{p}"
    );
    // check_limits: false computes it anyway: z = d1 - d3 - d4.
    let out = fk_ok(
        &app,
        "scara_4dof",
        json!({"joints": [0, 0, 0.3, 0], "check_limits": false}),
    )
    .await;
    assert_close(
        position(&out["pose"])[2],
        0.4 - 0.3 - 0.05,
        CLOSED_FORM_TOL,
        "z",
    );
    // Limits in degrees are checked in the request's unit: puma560 waist ±160°.
    let p = problem(
        app.post(
            "/v1/robots/puma560/fk",
            &json!({"joints": [161, 0, 0, 0, 0, 0], "angle_unit": "deg"}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&p), ["joints[0]"]);
    fk_ok(
        &app,
        "puma560",
        json!({"joints": [159, 0, 0, 0, 0, 0], "angle_unit": "deg"}),
    )
    .await;
    // Wrong joint count.
    for joints in [json!([0]), json!([0, 0, 0]), json!([])] {
        let p = problem(
            app.post("/v1/robots/planar_2dof/fk", &json!({"joints": joints}))
                .await,
            422,
        )
        .await;
        assert_eq!(fields(&p), ["joints"], "{p}");
    }
}
