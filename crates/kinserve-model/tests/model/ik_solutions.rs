//! Closed-form IK through the validated layer: `solutions: "all"` answers
//! every solution inside the limits (each checked here by the robot's own FK
//! in the request's unit, to 1e-10), nearest the seed first, with the
//! source configuration among them; `solver` says which ran; `auto` falls
//! back to numeric where there is no closed form; requests the arm cannot
//! honour are refused naming `solver`, `solutions` or `max_solutions`.

use std::f64::consts::TAU;
use std::time::{Duration, Instant};

use kinserve_model::{
    AngleUnit, FkOptions, IkBatchSpec, IkSolutionsMode, IkSolverChoice, IkSolverUsed, IkSpec,
    IkTargetSpec, ModelError, QuaternionSpec, Robot, load_robot_file,
};
use serde_json::json;

/// FK agreement asked of every solution: position (length unit) and matrix entries.
const FK_TOL: f64 = 1e-10;

fn load(name: &str) -> Robot {
    let path = format!("{}/../../robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
    load_robot_file(std::path::Path::new(&path)).unwrap()
}

/// The pose at `q` (rad) as a position + quaternion target.
fn target_of(robot: &Robot, q: &[f64]) -> IkTargetSpec {
    let t = robot.fk(q, &FkOptions::default()).unwrap();
    let [w, x, y, z] = t.quaternion();
    IkTargetSpec {
        position: Some(t.translation),
        quaternion: Some(QuaternionSpec { w, x, y, z }),
        matrix: None,
    }
}

/// A deterministic configuration inside the limits (rad), from `k`.
fn sample(robot: &Robot, k: u64) -> Vec<f64> {
    let mut x = k.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    robot
        .joints()
        .iter()
        .map(|j| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let u = (x >> 11) as f64 / (1u64 << 53) as f64;
            let (lo, hi) = j.limits.unwrap_or((-3.0, 3.0));
            // Keep a margin from the limits and from ±π (where copies tie).
            let (lo, hi) = (lo.max(-3.0) + 0.05, hi.min(3.0) - 0.05);
            lo + (hi - lo) * u
        })
        .collect()
}

fn all_spec(target: IkTargetSpec) -> IkSpec {
    IkSpec {
        target,
        solutions: IkSolutionsMode::All,
        ..IkSpec::default()
    }
}

/// The violated field paths of a request that must be refused.
fn refused(robot: &Robot, spec: serde_json::Value) -> Vec<(String, String)> {
    let spec: IkSpec = serde_json::from_value(spec).unwrap();
    match robot.check_ik(&spec) {
        Ok(_) => panic!("should be refused: {spec:?}"),
        Err(e) => e
            .violations()
            .iter()
            .map(|v| (v.field.clone(), v.message.clone()))
            .collect(),
    }
}

#[test]
fn every_solution_reaches_the_target_and_the_source_is_among_them() {
    for name in [
        "puma560",
        "abb_irb140",
        "kuka_kr5",
        "ur5e",
        "ur10e",
        "inline_6dof",
    ] {
        let r = load(name);
        assert!(r.ik_class().is_some(), "{name} has a closed form");
        for k in 0..40 {
            let q = sample(&r, k + 1);
            let target = target_of(&r, &q);
            let a = r.check_ik(&all_spec(target)).unwrap().solve(None);
            assert_eq!(a.solver, IkSolverUsed::Analytic, "{name}");
            assert!(a.converged && a.iterations == 0, "{name}: {a:?}");
            let sols = a.solutions.as_ref().expect("solutions with \"all\"");
            assert!(
                !sols.is_empty() && sols.len() <= 64,
                "{name}: {}",
                sols.len()
            );
            assert_eq!(a.joints, sols[0].joints, "joints is the nearest solution");
            let goal = r.fk(&q, &FkOptions::default()).unwrap();
            for s in sols {
                let pose = r.fk(&s.joints, &FkOptions::default()).unwrap();
                assert!(pose.max_abs_diff(&goal) < FK_TOL, "{name} {k}: {s:?}");
                assert!(s.position_error <= 1e-9 && s.orientation_error <= 1e-9);
                assert!(s.branch.is_some() && s.singular.is_empty(), "{s:?}");
            }
            assert!(
                sols.windows(2).all(|w| w[0].distance <= w[1].distance),
                "{name}: sorted by distance"
            );
            let found = sols
                .iter()
                .any(|s| s.joints.iter().zip(&q).all(|(a, b)| (a - b).abs() < 1e-7));
            assert!(
                found,
                "{name} {k}: source {q:?} not among {} solutions",
                sols.len()
            );
        }
    }
}

#[test]
fn two_pi_copies_inside_wide_limits_are_answered_and_capped() {
    // UR5e joints turn ±360°: each principal solution has copies a turn away.
    let r = load("ur5e");
    let q = [0.4, -1.1, 1.3, -0.7, 1.2, 0.3];
    let mut spec = all_spec(target_of(&r, &q));
    spec.max_solutions = Some(1024);
    let a = r.check_ik(&spec).unwrap().solve(None);
    let sols = a.solutions.unwrap();
    assert!(sols.len() > 8, "copies expected, got {}", sols.len());
    for (i, s) in sols.iter().enumerate() {
        assert!(r.check_joints(&s.joints, &FkOptions::default()).is_ok());
        for t in &sols[..i] {
            assert!(s.joints != t.joints, "duplicate solution {s:?}");
        }
    }
    // Each copy of the source differs from it by whole turns.
    let copies = sols
        .iter()
        .filter(|s| {
            s.joints.iter().zip(&q).all(|(a, b)| {
                let turns = (a - b) / TAU;
                (turns - turns.round()).abs() < 1e-9
            })
        })
        .count();
    assert!(copies >= 2, "the source and at least one copy: {copies}");
    spec.max_solutions = Some(3);
    let capped = r.check_ik(&spec).unwrap().solve(None);
    assert_eq!(capped.solutions.as_ref().unwrap().len(), 3);
    assert!(capped.truncated);
    assert_eq!(capped.solutions.unwrap()[..], sols[..3]);
}

#[test]
fn the_best_answer_is_the_solution_nearest_the_seed_in_the_request_unit() {
    let r = load("puma560");
    let q: [f64; 6] = [0.3, -0.5, 0.8, 0.2, 0.7, -1.1];
    let deg: Vec<f64> = q.iter().map(|x| x.to_degrees()).collect();
    let near: Vec<f64> = deg.iter().map(|x| x + 3.0).collect();
    let spec = IkSpec {
        target: target_of(&r, &q),
        seed: Some(near),
        angle_unit: AngleUnit::Deg,
        ..IkSpec::default()
    };
    let a = r.check_ik(&spec).unwrap().solve(None);
    assert_eq!(a.solver, IkSolverUsed::Analytic);
    assert!(a.solutions.is_none() && !a.truncated);
    for (x, y) in a.joints.iter().zip(&deg) {
        assert!((x - y).abs() < 1e-7, "{:?} vs {deg:?}", a.joints);
    }
    let opts = FkOptions::new(Some(AngleUnit::Deg), Some(true));
    assert!(r.check_joints(&a.joints, &opts).is_ok());
    // The numeric solver, asked for, reaches the same pose.
    let numeric = IkSpec {
        solver: IkSolverChoice::Numeric,
        ..spec
    };
    let n = r.check_ik(&numeric).unwrap().solve(None);
    assert_eq!(n.solver, IkSolverUsed::Numeric);
    assert!(n.converged && n.branch.is_none());
    assert!(n.pose.max_abs_diff(&a.pose) < 1e-8);
}

#[test]
fn arms_without_a_closed_form_use_the_numeric_solver_or_are_refused() {
    let panda = load("panda");
    assert_eq!(panda.ik_class(), None);
    let q = sample(&panda, 7);
    let a = panda
        .check_ik(&IkSpec {
            target: target_of(&panda, &q),
            ..IkSpec::default()
        })
        .unwrap()
        .solve(None);
    assert_eq!(a.solver, IkSolverUsed::Numeric);
    assert!(a.converged, "{a:?}");
    let t = serde_json::to_value(target_of(&panda, &q)).unwrap();
    let f = refused(&panda, json!({"target": t, "solver": "analytic"}));
    assert_eq!(f[0].0, "solver");
    assert!(
        f[0].1.contains("6 movable joints") && f[0].1.contains("numeric"),
        "{f:?}"
    );
    let f = refused(&panda, json!({"target": t, "solutions": "all"}));
    assert_eq!(f[0].0, "solutions");
    assert!(f[0].1.contains("\"best\""), "{f:?}");
}

#[test]
fn requests_the_closed_form_cannot_honour_name_their_field() {
    let r = load("puma560");
    let t = serde_json::to_value(target_of(&r, &[0.1, 0.2, 0.3, 0.4, 0.5, 0.6])).unwrap();
    let cases = [
        (
            json!({"target": {"position": [0.3, 0.1, 0.2]}, "position_only": true, "solver": "analytic"}),
            "solver",
        ),
        (
            json!({"target": {"position": [0.3, 0.1, 0.2]}, "position_only": true, "solutions": "all"}),
            "solutions",
        ),
        (
            json!({"target": t, "solver": "numeric", "solutions": "all"}),
            "solutions",
        ),
        (json!({"target": t, "max_solutions": 4}), "max_solutions"),
        (
            json!({"target": t, "solutions": "all", "max_solutions": 0}),
            "max_solutions",
        ),
        (
            json!({"target": t, "solutions": "all", "max_solutions": 1025}),
            "max_solutions",
        ),
    ];
    for (spec, field) in cases {
        let f = refused(&r, spec.clone());
        assert_eq!(f.len(), 1, "{spec}: {f:?}");
        assert_eq!(f[0].0, field, "{spec}: {f:?}");
    }
    // Unknown values are refused by the schema.
    let bad: Result<IkSpec, _> = serde_json::from_value(json!({"target": t, "solver": "ikfast"}));
    assert!(bad.is_err());
}

#[test]
fn an_unreachable_target_is_answered_unconverged_inside_the_limits() {
    let r = load("puma560");
    let far = IkTargetSpec {
        position: Some([5.0, 0.0, 0.0]),
        quaternion: Some(QuaternionSpec {
            w: 1.0,
            x: 0.0,
            y: 0.0,
            z: 0.0,
        }),
        matrix: None,
    };
    let forced = IkSpec {
        target: far.clone(),
        solver: IkSolverChoice::Analytic,
        solutions: IkSolutionsMode::All,
        ..IkSpec::default()
    };
    let a = r.check_ik(&forced).unwrap().solve(None);
    assert_eq!(a.solver, IkSolverUsed::Analytic);
    assert!(!a.converged && a.iterations == 0 && a.position_error > 3.0);
    assert_eq!(a.solutions, Some(vec![]));
    assert!(r.check_joints(&a.joints, &FkOptions::default()).is_ok());
    // auto tries the numeric solver too (its best attempt is answered).
    let auto = IkSpec {
        target: far,
        restarts: Some(2),
        ..IkSpec::default()
    };
    let a = r.check_ik(&auto).unwrap().solve(None);
    assert_eq!(a.solver, IkSolverUsed::Numeric);
    assert!(!a.converged && a.iterations > 0);
}

#[test]
fn a_batch_with_every_solution_keeps_its_branch_along_a_path() {
    let r = load("ur5e");
    let path: Vec<IkTargetSpec> = (0..30)
        .map(|k| target_of(&r, &[0.3 + 0.02 * k as f64, -1.2, 1.1, -0.5, 1.3, 0.2]))
        .collect();
    let batch = IkBatchSpec {
        targets: path,
        seed: Some(vec![0.3, -1.2, 1.1, -0.5, 1.3, 0.2]),
        solutions: IkSolutionsMode::All,
        max_solutions: Some(16),
        ..IkBatchSpec::default()
    };
    let far = Instant::now() + Duration::from_secs(60);
    let answers = r
        .check_ik_batch(&batch)
        .unwrap()
        .solve(Duration::from_secs(10), far);
    let first = answers[0].branch.expect("closed-form branch");
    for (k, a) in answers.iter().enumerate() {
        assert_eq!(a.solver, IkSolverUsed::Analytic);
        assert_eq!(a.branch, Some(first), "{k}: no flip along the path");
        assert!((a.joints[0] - (0.3 + 0.02 * k as f64)).abs() < 1e-7, "{k}");
        let n = a.solutions.as_ref().unwrap().len();
        assert!((1..=16).contains(&n), "{k}: {n}");
    }
    // targets × max_solutions over the cap: refused before solving.
    let big = IkBatchSpec {
        targets: vec![answers_target(&r); 2_000],
        solutions: IkSolutionsMode::All,
        ..IkBatchSpec::default()
    };
    match r.check_ik_batch(&big) {
        Err(ModelError::TooLarge { field, .. }) => {
            assert_eq!(field.as_deref(), Some("max_solutions"))
        }
        other => panic!("expected too large: {other:?}"),
    }
}

fn answers_target(r: &Robot) -> IkTargetSpec {
    target_of(r, &[0.1; 6])
}
