//! Numerical IK objectives beyond the pose (`IkOptions::posture`,
//! `IkOptions::axis_tolerances`): the null-space posture of redundant arms
//! (posture error falls, pose error stays within the tolerance) and per-axis
//! tolerances in the target frame (a free rotation about the tool's z axis,
//! position only along x and y, a tilt a SCARA cannot make left free), and
//! determinism with both. Every answer is checked by FK here, independently
//! of the errors it reports.

use kinserve_kinematics::Transform;
use kinserve_kinematics::ik::{IkOptions, IkSolver, Posture, rotation_error};
use kinserve_model::Robot;

use crate::jacobian::{random_config, robot};
use crate::kinematics::Rng;

fn limits(robot: &Robot) -> Vec<Option<(f64, f64)>> {
    robot.joints().iter().map(|j| j.limits).collect()
}

fn within_limits(robot: &Robot, q: &[f64]) -> bool {
    q.iter()
        .zip(robot.joints())
        .all(|(x, j)| j.limits.is_none_or(|(lo, hi)| (lo..=hi).contains(x)))
}

/// `|p_target − p|` and the rotation angle between target and pose, by FK.
fn pose_errors(robot: &Robot, target: &Transform, q: &[f64]) -> (f64, f64) {
    let pose = robot.chain().forward(q, 1.0);
    let dp = (0..3)
        .map(|i| (target.translation[i] - pose.translation[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    let w = rotation_error(target, &pose);
    (dp, (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt())
}

fn posture_cost(q: &[f64], p: &[f64]) -> f64 {
    q.iter().zip(p).map(|(a, b)| (a - b).powi(2)).sum()
}

#[test]
fn the_posture_error_falls_while_the_pose_stays_within_tolerance_on_panda_and_gen3() {
    for name in ["panda", "kinova_gen3"] {
        let robot = robot(name);
        let solver = IkSolver::new(robot.chain(), &limits(&robot));
        let mut rng = Rng(230);
        let (mut lower, n) = (0, 40);
        let (mut before_sum, mut after_sum) = (0.0, 0.0);
        for k in 0..n {
            let target = robot.chain().forward(&random_config(&robot, &mut rng), 1.0);
            let preferred = random_config(&robot, &mut rng);
            let with = |weight: f64| IkOptions {
                posture: Some(Posture {
                    joints: preferred.clone(),
                    weights: vec![weight; robot.dof()],
                }),
                ..IkOptions::default()
            };
            // Weight 0: the same start (the posture), no null-space motion.
            let plain = solver.solve(&target, None, &with(0.0));
            let pulled = solver.solve(&target, None, &with(1.0));
            let what = format!("{name} target {k}");
            assert!(plain.converged && pulled.converged, "{what}");
            assert!(within_limits(&robot, &pulled.q), "{what}: {:?}", pulled.q);
            let (dp, dr) = pose_errors(&robot, &target, &pulled.q);
            let tol = IkOptions::default().tolerance;
            assert!(dp <= tol && dr <= tol, "{what}: {dp:e} m / {dr:e} rad");
            let (before, after) = (
                posture_cost(&plain.q, &preferred),
                posture_cost(&pulled.q, &preferred),
            );
            assert!(after <= before + 1e-12, "{what}: {before} → {after}");
            lower += usize::from(after < before - 1e-6);
            before_sum += before;
            after_sum += after;
        }
        // A 7-joint arm has a one-dimensional self-motion: a solution moves
        // towards a random posture along it until the distance is locally
        // smallest or a joint limit stops it (measured: Panda lower for 36
        // of 40, the sum of squared distances 1,020 → 857 rad²; Gen3 40 of
        // 40, 618 → 533 rad²).
        assert!(lower * 2 >= n, "{name}: lower for {lower} of {n}");
        assert!(
            after_sum < 0.9 * before_sum,
            "{name}: {before_sum} → {after_sum}"
        );
    }
}

#[test]
fn a_posture_changes_nothing_on_a_six_joint_arm_but_the_start() {
    let robot = robot("ur5e");
    let solver = IkSolver::new(robot.chain(), &limits(&robot));
    let mut rng = Rng(231);
    for _ in 0..20 {
        let q = random_config(&robot, &mut rng);
        let target = robot.chain().forward(&q, 1.0);
        let opts = IkOptions {
            posture: Some(Posture {
                joints: q.clone(),
                weights: vec![1.0; 6],
            }),
            ..IkOptions::default()
        };
        let s = solver.solve(&target, None, &opts);
        // Started at the posture, which is a solution: answered at once.
        assert!(s.converged && s.attempts == 1, "{s:?}");
        assert!(posture_cost(&s.q, &q) < 1e-12, "{:?} vs {q:?}", s.q);
    }
}

#[test]
fn a_free_rotation_about_the_tool_z_axis_is_honoured() {
    let tol = 1e-9;
    let free_z = [tol, tol, tol, tol, tol, f64::INFINITY];
    for name in ["puma560", "ur5e", "panda"] {
        let robot = robot(name);
        let solver = IkSolver::new(robot.chain(), &limits(&robot));
        let mut rng = Rng(232);
        for k in 0..20 {
            let q = random_config(&robot, &mut rng);
            // Spun about its own z axis: the same tool axis, another angle about it.
            let spun = robot
                .chain()
                .forward(&q, 1.0)
                .compose(&Transform::rot_z(1.0));
            let opts = IkOptions {
                axis_tolerances: Some(free_z),
                ..IkOptions::default()
            };
            let s = solver.solve(&spun, None, &opts);
            let what = format!("{name} target {k}");
            assert!(s.converged, "{what}: {s:?}");
            assert!(within_limits(&robot, &s.q), "{what}");
            let pose = robot.chain().forward(&s.q, 1.0);
            let (dp, _) = pose_errors(&robot, &spun, &s.q);
            // The angle between the tool z axes, from |z × z_target| (exact near 0).
            let (a, b) = (
                [0, 1, 2].map(|i| pose.rotation[i][2]),
                [0, 1, 2].map(|i| spun.rotation[i][2]),
            );
            let cross = [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ];
            let z_angle = cross.iter().map(|x| x * x).sum::<f64>().sqrt().asin();
            // Each of the three components within `tol`: the norm within √3 tol.
            assert!(dp <= 3f64.sqrt() * tol, "{what}: position {dp:e}");
            assert!(z_angle <= 1e-8, "{what}: tool z axis {z_angle:e} rad off");
            // The reported errors are the full ones (here the spin is free).
            let (_, dr) = pose_errors(&robot, &spun, &s.q);
            assert!((dr - s.orientation_error).abs() <= 1e-9, "{what}");
        }
    }
}

#[test]
fn position_only_along_x_and_y_of_the_target_frame() {
    let robot = robot("ur5e");
    let solver = IkSolver::new(robot.chain(), &limits(&robot));
    let mut rng = Rng(233);
    let inf = f64::INFINITY;
    for k in 0..20 {
        let target = robot.chain().forward(&random_config(&robot, &mut rng), 1.0);
        // 5 cm along the target's z axis, which is left free.
        let moved = target.compose(&Transform::translation(0.0, 0.0, 0.05));
        let opts = IkOptions {
            axis_tolerances: Some([1e-9, 1e-9, inf, inf, inf, inf]),
            ..IkOptions::default()
        };
        let s = solver.solve(&moved, None, &opts);
        assert!(s.converged, "target {k}: {s:?}");
        let p = robot.chain().forward(&s.q, 1.0).translation;
        let d: Vec<f64> = (0..3).map(|i| p[i] - moved.translation[i]).collect();
        // The offset in the target frame: Rᵀ d.
        let local: Vec<f64> = (0..3)
            .map(|c| (0..3).map(|r| moved.rotation[r][c] * d[r]).sum())
            .collect();
        assert!(
            local[0].abs() <= 1e-9 && local[1].abs() <= 1e-9,
            "target {k}: {local:?}"
        );
    }
}

#[test]
fn a_tilt_a_scara_cannot_make_is_reached_once_left_free() {
    let robot = robot("scara_4dof");
    let solver = IkSolver::new(robot.chain(), &limits(&robot));
    let mut rng = Rng(234);
    let tol = 1e-9;
    for k in 0..20 {
        let target = robot
            .chain()
            .forward(&random_config(&robot, &mut rng), 1.0)
            .compose(&Transform::rot_x(0.3));
        let full = solver.solve(
            &target,
            None,
            &IkOptions {
                restarts: 5,
                ..IkOptions::default()
            },
        );
        assert!(!full.converged, "target {k}: a SCARA cannot tilt its tool");
        let free_tilt = IkOptions {
            axis_tolerances: Some([tol, tol, tol, f64::INFINITY, f64::INFINITY, tol]),
            ..IkOptions::default()
        };
        let s = solver.solve(&target, None, &free_tilt);
        assert!(s.converged, "target {k}: {s:?}");
        let (dp, dr) = pose_errors(&robot, &target, &s.q);
        assert!(dp <= 3f64.sqrt() * tol, "target {k}: {dp:e}");
        // What is left of the rotation is the tilt about x (0.3 rad).
        assert!((dr - 0.3).abs() <= 1e-8, "target {k}: {dr}");
    }
}

#[test]
fn answers_with_a_posture_and_free_axes_are_deterministic() {
    let robot = robot("panda");
    let solver = IkSolver::new(robot.chain(), &limits(&robot));
    let mut rng = Rng(235);
    let target = robot.chain().forward(&random_config(&robot, &mut rng), 1.0);
    let opts = IkOptions {
        posture: Some(Posture {
            joints: random_config(&robot, &mut rng),
            weights: vec![0.5; 7],
        }),
        axis_tolerances: Some([1e-9, 1e-9, 1e-9, 1e-9, 1e-9, f64::INFINITY]),
        ..IkOptions::default()
    };
    let first = solver.solve(&target, None, &opts);
    assert!(first.converged, "{first:?}");
    for _ in 0..3 {
        assert_eq!(solver.solve(&target, None, &opts), first);
    }
}
