//! The IK request's property check ([`check_ik_request`]), shared by the
//! `ik_request` cargo-fuzz target and the corpus replay test like the checks
//! in `fuzzing.rs` (whose robots and pose checks, in `fuzz_shared.rs`, it
//! shares).
//!
//! Depends on the server crate's request types (as the front doors parse
//! them) and on the model's validation; solves under a short time cap, so a
//! fuzz input asking for 10,000 iterations × 1,000 restarts stays cheap.

use std::time::{Duration, Instant};

use kinserve::api::ik::IkItem;
use kinserve::api::rest::{Problem, WsRequest};
use kinserve::error::Error;
use kinserve_kinematics::JointKind;
use kinserve_kinematics::ik::rotation_error;
use kinserve_model::{
    AngleUnit, FkOptions, IkAnswer, IkBatchSpec, IkSpec, IkTarget, Robot, parse_json,
};

use crate::fuzz_shared::{assert_client_error, check_pose, robots};

/// Time cap of one solve in the check (the server's default is 50 ms).
const SOLVE_CAP: Duration = Duration::from_millis(5);

/// Parses `bytes` as the REST IK body, the IK batch body and a WebSocket
/// message; whatever parses is validated for a few built-in robots and, if
/// valid, solved. Panics if a property is violated:
///
/// * a refusal is a client error (4xx), never a 5xx;
/// * every answer has one finite value per joint, within the joint limits
///   when read in the request's angle unit (it passes the FK check as sent);
/// * its pose is rigid and is the FK of its joints;
/// * its position and orientation errors are those of that pose against the
///   target, and `converged` is true exactly when they are within the tolerance;
/// * it serialises to JSON with numbers, never `null` (but for an absent
///   orientation error when the target has no orientation).
pub fn check_ik_request(bytes: &[u8]) {
    match parse_json::<IkSpec>(bytes) {
        Ok(spec) => robots().iter().for_each(|r| single(r, &spec)),
        Err(e) => assert_client_error(&Error::from(e), "IkSpec"),
    }
    match parse_json::<IkBatchSpec>(bytes) {
        Ok(spec) => robots().iter().for_each(|r| batch(r, &spec)),
        Err(e) => assert_client_error(&Error::from(e), "IkBatchSpec"),
    }
    match parse_json::<WsRequest>(bytes) {
        Ok(WsRequest { ik: Some(spec), .. }) => robots().iter().for_each(|r| single(r, &spec)),
        Ok(_) => {}
        Err(e) => assert_client_error(&Error::from(e), "WsRequest"),
    }
}

fn single(robot: &Robot, spec: &IkSpec) {
    let request = match robot.check_ik(spec) {
        Ok(r) => r,
        Err(e) => return assert_client_error(&Error::from(e), "check_ik"),
    };
    let answer = request.solve(Some(Instant::now() + SOLVE_CAP));
    let tolerance = request.options().tolerance;
    check_answer(
        robot,
        &answer,
        request.target(),
        spec.angle_unit,
        tolerance,
        spec.position_only,
    );
    if !answer.converged {
        let e = Error::ik_not_converged(answer, robot.length_unit().as_str());
        let p = Problem::from_error(&e);
        assert_eq!(p.status, 422, "not converged is a 422");
        assert!(
            p.best_attempt.is_some(),
            "not converged carries the best attempt"
        );
    }
}

fn batch(robot: &Robot, spec: &IkBatchSpec) {
    if spec.targets.len() > 16 {
        return; // the server's batch limit is the service's business; keep the check quick
    }
    let checked = match robot.check_ik_batch(spec) {
        Ok(b) => b,
        Err(e) => return assert_client_error(&Error::from(e), "check_ik_batch"),
    };
    let deadline = Instant::now() + SOLVE_CAP * 4;
    let answers = checked.solve(SOLVE_CAP, deadline);
    assert_eq!(answers.len(), spec.targets.len(), "one answer per target");
    // Targets validated the same way alone give the targets the batch solved for.
    for (a, t) in answers.iter().zip(&spec.targets) {
        let alone = IkSpec {
            target: t.clone(),
            position_only: spec.position_only,
            ..IkSpec::default()
        };
        let target = robot.check_ik(&alone).map(|r| *r.target());
        let target = target.unwrap_or_else(|e| panic!("a batch target is refused alone: {e}"));
        let tolerance = spec
            .tolerance
            .unwrap_or(kinserve_kinematics::ik::DEFAULT_TOLERANCE);
        check_answer(
            robot,
            a,
            &target,
            spec.angle_unit,
            tolerance,
            spec.position_only,
        );
    }
}

fn check_answer(
    robot: &Robot,
    a: &IkAnswer,
    target: &IkTarget,
    unit: AngleUnit,
    tolerance: f64,
    position_only: bool,
) {
    let what = robot.name();
    assert_eq!(a.joints.len(), robot.dof(), "{what}: one value per joint");
    let opts = FkOptions::new(Some(unit), Some(true));
    let q = match robot.check_joints(&a.joints, &opts) {
        Ok(q) => q,
        Err(e) => panic!("{what}: the answer {:?} fails the FK check: {e}", a.joints),
    };
    let pose = q.fk();
    check_pose(&a.pose, "ik answer", &a.joints);
    let scale =
        1.0 + pose.translation.iter().map(|x| x.abs()).sum::<f64>() + joint_scale(robot, &a.joints);
    assert!(
        pose.max_abs_diff(&a.pose) <= 1e-9 * scale,
        "{what}: the answer's pose is not the FK of its joints"
    );
    let dp = (0..3)
        .map(|i| (target.pose.translation[i] - a.pose.translation[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        (dp - a.position_error).abs() <= 1e-9 * (1.0 + dp),
        "{what}: position error {} is not the distance {dp}",
        a.position_error
    );
    let w = rotation_error(&target.pose, &a.pose);
    let dr = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    match a.orientation_error {
        Some(e) => assert!(
            target.oriented && (e - dr).abs() <= 1e-9,
            "{what}: orientation error"
        ),
        None => assert!(!target.oriented, "{what}: orientation error missing"),
    }
    let within = a.position_error <= tolerance
        && (position_only || a.orientation_error.is_none_or(|e| e <= tolerance));
    assert_eq!(
        a.converged, within,
        "{what}: converged says {}",
        a.converged
    );
    let json = serde_json::to_value(IkItem::from(a)).expect("serialises");
    let nulls = json.to_string().matches("null").count();
    // `orientation_error` without an orientation, `branch` from the numeric solver.
    let allowed = usize::from(a.orientation_error.is_none()) + usize::from(a.branch.is_none());
    assert!(nulls <= allowed, "{what}: null in {json}");
    assert_eq!(
        a.branch.is_some(),
        a.solver == kinserve::model::IkSolverUsed::Analytic,
        "{what}: a branch exactly from the closed form"
    );
}

/// Magnitude of the prismatic joint values (they move the tool by as much).
fn joint_scale(robot: &Robot, q: &[f64]) -> f64 {
    q.iter()
        .zip(robot.joints())
        .filter(|(_, j)| j.kind == JointKind::Prismatic)
        .map(|(x, _)| x.abs())
        .sum()
}
