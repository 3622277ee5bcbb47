//! Numerical IK (`kinserve_kinematics::ik`): FK → IK → FK round trips on
//! every shipped 6- and 7-joint arm, with and without a seed, limits
//! respected in every answer; unreachable targets; position-only mode;
//! determinism.

use kinserve_kinematics::ik::{
    DEFAULT_RESTARTS, FAR_RESTARTS, IkOptions, IkSolution, IkSolver, rotation_error,
};
use kinserve_kinematics::{JointKind, Transform};
use kinserve_model::Robot;

use crate::jacobian::{all_robots, random_config, robot};
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
fn assert_honest(robot: &Robot, target: &Transform, s: &IkSolution, opts: &IkOptions) {
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
    let tol = opts.tolerance;
    let within = dp <= tol && (opts.position_only || dr <= tol);
    assert_eq!(s.converged, within, "{dp:e} m / {dr:e} rad");
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
        for _ in 0..500 {
            let q = random_config(robot, &mut rng);
            let target = robot.chain().forward(&q, 1.0);
            let s = solver.solve(&target, None, &opts);
            assert_within_limits(robot, &s.q, robot.name());
            assert_honest(robot, &target, &s, &opts);
            if !s.converged {
                failed += 1;
            }
        }
        // The target of the issue: ≥ 99 % of 500 converge (measured: at most 1 miss per arm).
        assert!(
            failed <= 5,
            "{}: {failed} of 500 did not converge",
            robot.name()
        );
    }
}

/// A smooth path through joint space, kept within the limits.
fn path_point(robot: &Robot, q0: &[f64], k: usize) -> Vec<f64> {
    q0.iter()
        .zip(robot.joints())
        .enumerate()
        .map(|(i, (x, j))| {
            let v = x + 0.2 * (0.005 * k as f64 + i as f64).sin();
            j.limits.map_or(v, |(lo, hi)| v.clamp(lo, hi))
        })
        .collect()
}

#[test]
fn seeded_tracking_converges_in_few_iterations_and_stays_continuous() {
    let opts = IkOptions::default();
    let mut rng = Rng(161);
    for robot in &arms() {
        let solver = IkSolver::new(robot.chain(), &limits(robot));
        let q0 = random_config(robot, &mut rng);
        let mut seed = path_point(robot, &q0, 0);
        for k in 1..200 {
            let q = path_point(robot, &q0, k);
            let target = robot.chain().forward(&q, 1.0);
            let s = solver.solve(&target, Some(&seed), &opts);
            let what = format!("{} step {k}", robot.name());
            assert!(s.converged, "{what}: {s:?}");
            assert_eq!(s.attempts, 1, "{what}: a restart was needed");
            assert_within_limits(robot, &s.q, &what);
            assert_honest(robot, &target, &s, &opts);
            // Tracking: the answer stays next to the previous one (steps are ≤ 1 mrad).
            let jump =
                s.q.iter()
                    .zip(&seed)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
            assert!(jump < 0.01, "{what}: jumped by {jump} rad");
            seed = s.q;
        }
    }
}

#[test]
fn an_unreachable_target_is_not_converged_and_reports_its_best_attempt() {
    let opts = IkOptions {
        restarts: 5,
        ..IkOptions::default()
    };
    // Arms whose prismatic joints are unlimited reach everything; the others
    // are bounded by their reach.
    let bounded = arms().into_iter().filter(|r| {
        r.joints()
            .iter()
            .all(|j| j.kind != JointKind::Prismatic || j.limits.is_some())
    });
    for robot in &bounded.collect::<Vec<_>>() {
        let solver = IkSolver::new(robot.chain(), &limits(robot));
        // Rows, tool and the longest stroke of each prismatic joint.
        let strokes: f64 = robot
            .joints()
            .iter()
            .filter(|j| j.kind == JointKind::Prismatic)
            .filter_map(|j| j.limits.map(|(lo, hi)| lo.abs().max(hi.abs())))
            .sum();
        let reach: f64 = robot
            .chain()
            .dh_rows()
            .map(|r| r.a.abs() + r.d.abs())
            .sum::<f64>()
            + robot
                .chain()
                .tool()
                .map_or(0.0, |t| t.translation.iter().map(|x| x.abs()).sum())
            + strokes;
        let far = 3.0 * reach + 1.0;
        let target = Transform::translation(far, 0.0, 0.0);
        let s = solver.solve(&target, None, &opts);
        assert!(!s.converged, "{}", robot.name());
        assert_eq!(s.attempts, 6, "{}: every restart was tried", robot.name());
        assert_within_limits(robot, &s.q, robot.name());
        assert_honest(robot, &target, &s, &opts);
        // No closer than the reach allows, and no worse (in the squared error
        // minimised) than the start.
        let base = robot.chain().base().translation;
        let lower = far - base[0].abs() - base[1].abs() - base[2].abs() - reach;
        assert!(
            s.position_error >= lower,
            "{}: {}",
            robot.name(),
            s.position_error
        );
        let start = solver.solve(
            &target,
            None,
            &IkOptions {
                max_iterations: 0,
                restarts: 0,
                ..opts.clone()
            },
        );
        assert_eq!(start.q, mid(robot));
        let cost = |s: &IkSolution| s.position_error.powi(2) + s.orientation_error.powi(2);
        assert!(cost(&s) <= cost(&start), "{}", robot.name());
    }
}

/// Two reachable Panda targets (FK of these configurations: joint 5 within
/// 0.02 rad of the wrist singularity, joint 7 near its limit) that the first
/// 100 restarts miss at 1e-6 — one in 20,000 random targets each in the
/// `ik_peers` runs of seeds 2 and 3 — are solved by the further restarts the
/// default allows while the best attempt is close; a target out of reach
/// still stops after [`FAR_RESTARTS`], unless the restarts were asked for.
#[test]
fn near_singular_targets_use_the_further_restarts_and_far_ones_stop_after_100() {
    let panda = robot("panda");
    let solver = IkSolver::new(panda.chain(), &limits(&panda));
    let opts = IkOptions {
        tolerance: 1e-6,
        ..IkOptions::default()
    };
    const { assert!(DEFAULT_RESTARTS > FAR_RESTARTS) };
    let sources: [[f64; 7]; 2] = [
        [
            -0.05542081384039088,
            -1.3890473346627372,
            2.778706758984993,
            -0.4712276306487557,
            0.020258345469975847,
            2.026602271814058,
            -2.5891036595997177,
        ],
        [
            -0.45833373804711597,
            -1.5664928566274603,
            2.2062655461749805,
            -0.47322416484743623,
            0.014090831926740321,
            2.6624837055598434,
            -2.456635576195651,
        ],
    ];
    for q in &sources {
        let target = panda.chain().forward(q, 1.0);
        let s = solver.solve(&target, None, &opts);
        assert!(s.converged, "{q:?}: {s:?}");
        assert!(
            s.attempts > FAR_RESTARTS + 1,
            "{q:?}: solved in {} attempts, within the first 100 restarts",
            s.attempts
        );
        assert_within_limits(&panda, &s.q, "panda");
        assert_honest(&panda, &target, &s, &opts);
        let capped = solver.solve(
            &target,
            None,
            &IkOptions {
                restarts: FAR_RESTARTS,
                ..opts.clone()
            },
        );
        assert!(!capped.converged, "{q:?}: 100 restarts now suffice");
    }
    let far = Transform::translation(10.0, 0.0, 0.0);
    let s = solver.solve(&far, None, &opts);
    assert!(!s.converged);
    assert_eq!(
        s.attempts,
        FAR_RESTARTS + 1,
        "a far target gives up after 100 restarts"
    );
    // Restarts a caller asks for all run (the API's explicit `restarts`).
    let asked = IkOptions {
        restarts: 150,
        far_restarts: None,
        ..opts.clone()
    };
    assert_eq!(solver.solve(&far, None, &asked).attempts, 151);
}

/// The unseeded start: the middle of each joint's limits (0 where unlimited).
fn mid(robot: &Robot) -> Vec<f64> {
    robot
        .joints()
        .iter()
        .map(|j| j.limits.map_or(0.0, |(lo, hi)| 0.5 * (lo + hi)))
        .collect()
}

#[test]
fn an_orientation_out_of_reach_with_a_reachable_position_fails_the_full_solve_only() {
    // A 3-joint arm cannot also set the orientation: the full solve fails, the
    // position-only solve of the same target succeeds.
    let robot = robot("spatial_3r");
    let solver = IkSolver::new(robot.chain(), &limits(&robot));
    let q = [0.4, -0.3, 0.9];
    let reached = robot.chain().forward(&q, 1.0);
    let target = Transform {
        rotation: Transform::rot_x(2.0).rotation,
        ..reached
    };
    let full = solver.solve(
        &target,
        None,
        &IkOptions {
            restarts: 10,
            ..IkOptions::default()
        },
    );
    assert!(!full.converged && full.orientation_error > 0.1, "{full:?}");
    let pos = solver.solve(
        &target,
        None,
        &IkOptions {
            position_only: true,
            ..IkOptions::default()
        },
    );
    assert!(pos.converged && pos.position_error <= 1e-9, "{pos:?}");
    assert!(
        pos.orientation_error > 0.1,
        "the orientation is out of reach: {pos:?}"
    );
}

#[test]
fn position_only_round_trips_on_the_small_arms() {
    let opts = IkOptions {
        position_only: true,
        ..IkOptions::default()
    };
    let mut rng = Rng(162);
    let small: Vec<Robot> = all_robots().into_iter().filter(|r| r.dof() < 6).collect();
    assert!(small.len() >= 5);
    for robot in &small {
        let solver = IkSolver::new(robot.chain(), &limits(robot));
        let mut failed = 0;
        for _ in 0..200 {
            let q = random_config(robot, &mut rng);
            let target = robot.chain().forward(&q, 1.0);
            let s = solver.solve(&target, None, &opts);
            assert_within_limits(robot, &s.q, robot.name());
            assert_honest(robot, &target, &s, &opts);
            failed += usize::from(!s.converged);
        }
        assert!(failed <= 2, "{}: {failed} of 200 failed", robot.name());
    }
}

#[test]
fn answers_are_deterministic_restarts_included() {
    let robot = robot("panda");
    let solver = IkSolver::new(robot.chain(), &limits(&robot));
    // Out of reach: every restart is used, and the best of them answered.
    let target = Transform::translation(3.0, 1.0, 0.5);
    let opts = IkOptions {
        restarts: 10,
        ..IkOptions::default()
    };
    let a = solver.solve(&target, None, &opts);
    assert_eq!(a.attempts, 11);
    for _ in 0..3 {
        assert_eq!(solver.solve(&target, None, &opts), a);
    }
}

#[test]
fn a_deadline_in_the_past_answers_at_once_with_the_start() {
    let robot = robot("ur5e");
    let solver = IkSolver::new(robot.chain(), &limits(&robot));
    let target = robot
        .chain()
        .forward(&[0.3, -1.5, 1.2, -0.4, 1.4, 0.2], 1.0);
    let opts = IkOptions {
        deadline: Some(std::time::Instant::now()),
        ..IkOptions::default()
    };
    let s = solver.solve(&target, None, &opts);
    assert_eq!((s.iterations, s.attempts, s.converged), (0, 1, false));
    assert_eq!(s.q, mid(&robot));
    assert_honest(&robot, &target, &s, &opts);
}

#[test]
fn a_seed_outside_the_limits_is_clamped_and_unlimited_joints_answer_near_the_seed() {
    let puma = robot("puma560");
    let solver = IkSolver::new(puma.chain(), &limits(&puma));
    let q = [0.3, -0.5, 0.2, 0.4, 0.6, -0.2];
    let target = puma.chain().forward(&q, 1.0);
    let s = solver.solve(&target, Some(&[50.0; 6]), &IkOptions::default());
    assert!(s.converged);
    assert_within_limits(&puma, &s.q, "clamped seed");
    // inline_6dof has no limits: answers are within π of the seed.
    let robot = robot("inline_6dof");
    let solver = IkSolver::new(robot.chain(), &limits(&robot));
    let seed = [10.0, 10.0, 10.0, 10.0, 10.0, 10.0];
    let target = robot.chain().forward(&q, 1.0);
    let s = solver.solve(&target, Some(&seed), &IkOptions::default());
    assert!(s.converged);
    for x in &s.q {
        assert!(
            (x - 10.0).abs() <= std::f64::consts::PI + 1e-12,
            "{:?}",
            s.q
        );
    }
}
