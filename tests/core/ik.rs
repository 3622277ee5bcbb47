//! Numerical IK (`kinserve_kinematics::ik`): FK → IK → FK round trips on
//! every shipped 6- and 7-joint arm, with and without a seed, limits
//! respected in every answer; unreachable targets; position-only mode;
//! determinism.

use kinserve::kinematics::ik::{IkOptions, IkSolution, IkSolver, rotation_error};
use kinserve::kinematics::{JointKind, Transform};
use kinserve::model::Robot;

use crate::jacobian::{all_robots, random_config};
use crate::kinematics::Rng;

/// The shipped arms with 6 or 7 joints.
fn arms() -> Vec<Robot> {
    all_robots()
        .into_iter()
        .filter(|r| (6..=7).contains(&r.dof()))
        .collect()
}

fn limits(robot: &Robot) -> Vec<Option<(f64, f64)>> {
    robot.joints().iter().map(|j| j.limits).collect()
}

/// Every joint of `q` within its limits (exactly: the solver clamps).
fn assert_within_limits(robot: &Robot, q: &[f64], what: &str) {
    assert_eq!(q.len(), robot.dof());
    for (x, j) in q.iter().zip(robot.joints()) {
        assert!(x.is_finite(), "{what}: {q:?}");
        if let Some((lo, hi)) = j.limits {
            assert!(
                (lo..=hi).contains(x),
                "{what}: joint '{}' = {x} outside [{lo}, {hi}]",
                j.name
            );
        }
    }
}

/// The errors an answer reports are those of FK at its joints, against the target.
fn assert_honest(robot: &Robot, target: &Transform, s: &IkSolution, tol: f64) {
    let pose = robot.chain().forward(&s.q, 1.0);
    assert!(pose.max_abs_diff(&s.pose) <= 1e-12);
    let dp: f64 = (0..3)
        .map(|i| (target.translation[i] - pose.translation[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    let dr = rotation_error(target, &pose);
    let dr = (dr[0] * dr[0] + dr[1] * dr[1] + dr[2] * dr[2]).sqrt();
    assert!((dp - s.position_error).abs() <= 1e-15 + 1e-9 * dp);
    assert!((dr - s.orientation_error).abs() <= 1e-15 + 1e-9 * dr);
    if s.converged {
        assert!(dp <= tol && dr <= tol, "converged but {dp:e} m / {dr:e} rad");
    }
}

#[test]
fn unseeded_round_trips_converge_on_every_arm() {
    let opts = IkOptions::default();
    let mut rng = Rng(160);
    let arms = arms();
    assert!(arms.len() >= 10, "{} arms", arms.len());
    for robot in &arms {
        let solver = IkSolver::new(robot.chain(), &limits(robot));
        let mut failed = 0;
        let mut iterations = Vec::new();
        for _ in 0..500 {
            let q = random_config(robot, &mut rng);
            let target = robot.chain().forward(&q, 1.0);
            let s = solver.solve(&target, None, &opts);
            assert_within_limits(robot, &s.q, robot.name());
            assert_honest(robot, &target, &s, opts.tolerance);
            iterations.push(s.iterations);
            if !s.converged {
                failed += 1;
            }
        }
        iterations.sort();
        eprintln!(
            "{}: {failed}/500 failed, iterations median {} p90 {} max {}",
            robot.name(),
            iterations[250],
            iterations[450],
            iterations[499]
        );
        assert!(failed <= 5, "{}: {failed} of 500 did not converge", robot.name());
    }
}
