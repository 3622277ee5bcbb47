//! Analytic IK (`kinserve_kinematics::analytic_ik`): the classification of
//! every shipped arm and of random arms of each class (both DH conventions,
//! base and tool transforms, fixed rows, m and mm); every solution checked by
//! FK (`Chain::forward`) to 1e-10 (position, length unit; rotation-matrix
//! entries); the configuration a target came from is among its solutions;
//! no solution missed against a dense numeric multi-start (`IkSolver` from
//! many random seeds, deduplicated); the 2π copies inside wide limits and
//! their order; singular targets; unreachable targets.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use kinserve_kinematics::analytic_ik::{
    AnalyticIk, AnalyticOptions, ArmClass, NotAnalytic, Principal, RawSolution,
};
use kinserve_kinematics::ik::{IkOptions, IkSolver};
use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, Transform};
use kinserve_model::Robot;

use crate::jacobian::{all_robots, random_config, robot};
use crate::kinematics::Rng;

/// FK agreement every answer must meet (length unit; rotation entries).
const FK_TOL: f64 = 1e-10;

fn wrapped(a: f64) -> f64 {
    let w = a.rem_euclid(TAU);
    if w > PI { w - TAU } else { w }
}

/// Whether two configurations are the same pose-wise solution (mod 2π).
fn same(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| wrapped(x - y).abs() <= tol)
}

/// Position error and the largest rotation-entry error of FK at `q`.
fn fk_errors(chain: &Chain, q: &[f64], target: &Transform) -> (f64, f64) {
    let pose = chain.forward(q, 1.0);
    let dp = (0..3)
        .map(|i| (pose.translation[i] - target.translation[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    let dr = (0..9)
        .map(|k| (pose.rotation[k / 3][k % 3] - target.rotation[k / 3][k % 3]).abs())
        .fold(0.0, f64::max);
    (dp, dr)
}

fn assert_fk(chain: &Chain, q: &[f64], target: &Transform, what: &str) {
    let (dp, dr) = fk_errors(chain, q, target);
    assert!(
        dp <= FK_TOL * length_scale(chain) && dr <= FK_TOL,
        "{what}: FK off by {dp:e} (position) / {dr:e} (rotation) at {q:?}"
    );
}

/// 1 for chains in m, 1000 for chains in mm (the tolerance is relative to a
/// metre-sized arm).
fn length_scale(chain: &Chain) -> f64 {
    let reach: f64 = chain.dh_rows().map(|r| r.a.abs() + r.d.abs()).sum();
    if reach > 50.0 { 1000.0 } else { 1.0 }
}

fn limits(robot: &Robot) -> Vec<Option<(f64, f64)>> {
    robot.joints().iter().map(|j| j.limits).collect()
}

fn principal(ik: &AnalyticIk, target: &Transform, reference: &[f64]) -> Vec<RawSolution> {
    let mut out = Principal::new();
    ik.solve_principal(target, reference, 1e-9, &mut out);
    out.as_slice().to_vec()
}

/// FK of `n` random configurations of `chain` → every solution checked by
/// FK, distinct, and the configuration among them. Returns the total count.
fn round_trips(ik: &AnalyticIk, n: usize, rng: &mut Rng, what: &str) -> usize {
    let chain = ik.chain();
    let mut total = 0;
    for _ in 0..n {
        let q: Vec<f64> = (0..6).map(|_| rng.range(-PI, PI)).collect();
        let target = chain.forward(&q, 1.0);
        let sols = principal(ik, &target, &[0.0; 6]);
        assert!(
            (1..=8).contains(&sols.len()),
            "{what}: {} solutions",
            sols.len()
        );
        for s in &sols {
            assert_fk(chain, &s.q, &target, what);
            assert!(
                s.q.iter().all(|x| (-PI..=PI).contains(x)),
                "{what}: {:?}",
                s.q
            );
        }
        for (i, a) in sols.iter().enumerate() {
            for b in &sols[..i] {
                assert!(!same(&a.q, &b.q, 1e-9), "{what}: duplicate {:?}", a.q);
            }
        }
        assert!(
            sols.iter().any(|s| same(&s.q, &q, 1e-6)),
            "{what}: {q:?} not among {:?}",
            sols.iter().map(|s| s.q).collect::<Vec<_>>()
        );
        total += sols.len();
    }
    total
}

/// The solutions a dense numeric multi-start finds (unlimited joints, `seeds`
/// random seeds, deduplicated mod 2π).
fn multistart(chain: &Chain, target: &Transform, seeds: usize, rng: &mut Rng) -> Vec<Vec<f64>> {
    let solver = IkSolver::new(chain, &[]);
    let opts = IkOptions {
        tolerance: 1e-10,
        restarts: 0,
        max_iterations: 200,
        ..IkOptions::default()
    };
    let mut found: Vec<Vec<f64>> = Vec::new();
    for _ in 0..seeds {
        let seed: Vec<f64> = (0..6).map(|_| rng.range(-PI, PI)).collect();
        let s = solver.solve(target, Some(&seed), &opts);
        if s.converged && !found.iter().any(|f| same(f, &s.q, 1e-6)) {
            found.push(s.q);
        }
    }
    found
}

// ---------------------------------------------------------------- shipped arms

fn expected_class(name: &str) -> Result<ArmClass, NotAnalytic> {
    match name {
        "puma560" | "abb_irb140" | "kuka_kr5" | "inline_6dof" => {
            Ok(ArmClass::SphericalWristParallel23)
        }
        "ur3e" | "ur5" | "ur5e" | "ur10e" | "ur20" => Ok(ArmClass::ThreeParallel234),
        "stanford" => Err(NotAnalytic::Prismatic(2)),
        "cylindrical_wrist_6dof" => Err(NotAnalytic::Prismatic(1)),
        "panda" | "kinova_gen3" => Err(NotAnalytic::JointCount(7)),
        _ => Err(NotAnalytic::JointCount(0)),
    }
}

#[test]
fn shipped_arms_are_classified() {
    let mut classified = 0;
    for robot in all_robots() {
        let got = AnalyticIk::new(robot.chain()).map(|ik| ik.class());
        match (expected_class(robot.name()), got) {
            (Err(NotAnalytic::JointCount(0)), Err(NotAnalytic::JointCount(n))) => {
                assert_eq!(n, robot.dof(), "{}", robot.name());
            }
            (want, got) => assert_eq!(got, want, "{}", robot.name()),
        }
        classified += usize::from(AnalyticIk::new(robot.chain()).is_ok());
    }
    assert_eq!(classified, 9);
    let msg = NotAnalytic::Prismatic(2).to_string();
    assert!(
        msg.contains("numeric") && msg.contains("prismatic"),
        "{msg}"
    );
}

fn classified_arms() -> Vec<(Robot, AnalyticIk)> {
    all_robots()
        .into_iter()
        .filter_map(|r| AnalyticIk::new(r.chain()).ok().map(|ik| (r, ik)))
        .collect()
}

#[test]
fn shipped_arms_every_solution_checked_by_fk_and_the_source_among_them() {
    let mut rng = Rng(2301);
    for (robot, ik) in classified_arms() {
        let total = round_trips(&ik, 300, &mut rng, robot.name());
        // Generic targets of these arms have 8 solutions (a few fewer near the
        // workspace boundary).
        assert!(
            total >= 300 * 6,
            "{}: {total} solutions over 300 targets",
            robot.name()
        );
    }
}

#[test]
fn shipped_arms_no_solution_missed_against_a_numeric_multistart() {
    let mut rng = Rng(2302);
    let mut compared = 0;
    for (robot, ik) in classified_arms() {
        for _ in 0..3 {
            let q = random_config(&robot, &mut rng);
            let target = robot.chain().forward(&q, 1.0);
            let analytic = principal(&ik, &target, &[0.0; 6]);
            let numeric = multistart(robot.chain(), &target, 150, &mut rng);
            for n in &numeric {
                assert!(
                    analytic.iter().any(|a| same(&a.q, n, 1e-6)),
                    "{}: the multi-start found {n:?}, the analytic solver did not",
                    robot.name()
                );
            }
            assert_eq!(numeric.len(), analytic.len(), "{}: {q:?}", robot.name());
            compared += 1;
        }
    }
    assert_eq!(compared, 27);
}

// ----------------------------------------------------------------- random arms

/// The arm families drawn at random: (class, convention).
const FAMILIES: [(ArmClass, Convention); 6] = [
    (ArmClass::SphericalWristParallel23, Convention::Standard),
    (ArmClass::SphericalWristParallel23, Convention::Modified),
    (ArmClass::SphericalWristIntersecting12, Convention::Standard),
    (ArmClass::SphericalWristIntersecting23, Convention::Standard),
    (ArmClass::ThreeParallel234, Convention::Standard),
    (ArmClass::ThreeParallel234, Convention::Modified),
];

fn rev(a: f64, alpha: f64, d: f64, theta: f64) -> DhRow {
    DhRow {
        kind: JointKind::Revolute,
        a,
        alpha,
        d,
        theta,
    }
}

/// A twist well away from 0 and π (rad).
fn twist(rng: &mut Rng) -> f64 {
    let t = rng.range(0.4, PI - 0.4);
    if rng.unit() < 0.5 { -t } else { t }
}

fn random_fixed(rng: &mut Rng) -> DhRow {
    DhRow {
        kind: JointKind::Fixed,
        a: rng.range(-0.1, 0.1),
        alpha: rng.range(-PI, PI),
        d: rng.range(-0.1, 0.1),
        theta: rng.range(-PI, PI),
    }
}

fn random_transform(rng: &mut Rng) -> Transform {
    let t = [
        rng.range(-0.5, 0.5),
        rng.range(-0.5, 0.5),
        rng.range(-0.5, 0.5),
    ];
    let rpy = [rng.range(-PI, PI), rng.range(-1.5, 1.5), rng.range(-PI, PI)];
    Transform::from_translation_rpy(t, rpy)
}

/// Six revolute rows of the family, lengths in m, random θ offsets;
/// `fixed_after[i]`: a fixed row goes after joint `i + 1` (only where it keeps the class).
fn family_rows(class: ArmClass, conv: Convention, rng: &mut Rng) -> (Vec<DhRow>, [bool; 6]) {
    let mut r = |lo: f64, hi: f64| rng.range(lo, hi);
    let th = [
        r(-PI, PI),
        r(-PI, PI),
        r(-PI, PI),
        r(-PI, PI),
        r(-PI, PI),
        r(-PI, PI),
    ];
    let (rows, fixed_after) = match (class, conv) {
        (ArmClass::SphericalWristParallel23, Convention::Standard) => (
            vec![
                rev(r(0.0, 0.3), 0.0, r(0.2, 0.6), th[0]),
                rev(r(0.2, 0.6), 0.0, r(-0.2, 0.2), th[1]),
                rev(r(-0.1, 0.1), 0.0, r(-0.2, 0.2), th[2]),
                rev(0.0, 0.0, r(0.2, 0.5), th[3]),
                rev(0.0, 0.0, 0.0, th[4]),
                rev(r(-0.1, 0.1), r(-PI, PI), r(0.0, 0.2), th[5]),
            ],
            [true, false, true, false, false, true],
        ),
        (ArmClass::SphericalWristParallel23, Convention::Modified) => (
            vec![
                rev(r(-0.2, 0.2), r(-PI, PI), r(0.2, 0.5), th[0]),
                rev(r(0.0, 0.3), 0.0, r(-0.2, 0.2), th[1]),
                rev(r(0.2, 0.6), 0.0, r(-0.2, 0.2), th[2]),
                rev(r(-0.1, 0.1), 0.0, r(0.2, 0.5), th[3]),
                rev(0.0, 0.0, 0.0, th[4]),
                rev(0.0, 0.0, r(0.0, 0.2), th[5]),
            ],
            [true, false, true, false, false, true],
        ),
        (ArmClass::SphericalWristIntersecting12, _) => (
            vec![
                rev(0.0, 0.0, r(0.2, 0.6), th[0]),
                rev(r(0.2, 0.6), 0.0, r(-0.2, 0.2), th[1]),
                rev(r(-0.1, 0.1), 0.0, r(-0.2, 0.2), th[2]),
                rev(0.0, 0.0, r(0.2, 0.5), th[3]),
                rev(0.0, 0.0, 0.0, th[4]),
                rev(r(-0.1, 0.1), r(-PI, PI), r(0.0, 0.2), th[5]),
            ],
            [false, false, true, false, false, true],
        ),
        (ArmClass::SphericalWristIntersecting23, _) => (
            vec![
                rev(r(0.1, 0.3), 0.0, r(0.2, 0.6), th[0]),
                rev(0.0, 0.0, r(-0.2, 0.2), th[1]),
                rev(r(-0.1, 0.1), 0.0, r(0.2, 0.5), th[2]),
                rev(0.0, 0.0, r(0.2, 0.5), th[3]),
                rev(0.0, 0.0, 0.0, th[4]),
                rev(r(-0.1, 0.1), r(-PI, PI), r(0.0, 0.2), th[5]),
            ],
            [false, false, true, false, false, true],
        ),
        (ArmClass::ThreeParallel234, Convention::Standard) => (
            vec![
                rev(r(-0.1, 0.1), 0.0, r(0.1, 0.3), th[0]),
                rev(r(-0.6, -0.2), 0.0, r(-0.1, 0.1), th[1]),
                rev(r(-0.5, -0.2), 0.0, r(-0.1, 0.1), th[2]),
                rev(r(-0.05, 0.05), 0.0, r(0.1, 0.2), th[3]),
                rev(0.0, 0.0, r(0.08, 0.15), th[4]),
                rev(r(-0.1, 0.1), r(-PI, PI), r(0.0, 0.2), th[5]),
            ],
            [true, false, false, false, false, true],
        ),
        (ArmClass::ThreeParallel234, Convention::Modified) => (
            vec![
                rev(r(-0.2, 0.2), r(-PI, PI), r(0.1, 0.3), th[0]),
                rev(r(-0.1, 0.1), 0.0, r(-0.1, 0.1), th[1]),
                rev(r(0.2, 0.6), 0.0, r(-0.1, 0.1), th[2]),
                rev(r(0.2, 0.5), 0.0, r(0.1, 0.2), th[3]),
                rev(r(-0.05, 0.05), 0.0, r(0.08, 0.15), th[4]),
                rev(0.0, 0.0, r(0.0, 0.2), th[5]),
            ],
            [true, false, false, false, false, true],
        ),
    };
    (rows, fixed_after)
}

/// Which rows get a twist (α ≠ 0, π) so the class holds and nothing more.
fn twisted(class: ArmClass, conv: Convention) -> [bool; 6] {
    match (class, conv) {
        (ArmClass::SphericalWristParallel23, Convention::Standard) => {
            [true, false, true, true, true, false]
        }
        (ArmClass::SphericalWristParallel23, Convention::Modified) => {
            [false, true, false, true, true, true]
        }
        (ArmClass::SphericalWristIntersecting12, _) => [true, true, true, true, true, false],
        (ArmClass::SphericalWristIntersecting23, _) => [true, true, true, true, true, false],
        (ArmClass::ThreeParallel234, Convention::Standard) => {
            [true, false, false, true, true, false]
        }
        (ArmClass::ThreeParallel234, Convention::Modified) => {
            [false, true, false, false, true, true]
        }
    }
}

/// A random arm of the family, with base, tool and fixed rows.
fn random_arm(class: ArmClass, conv: Convention, rng: &mut Rng) -> Chain {
    let (mut rows, fixed_after) = family_rows(class, conv, rng);
    for (row, t) in rows.iter_mut().zip(twisted(class, conv)) {
        if t {
            row.alpha = twist(rng);
        }
    }
    let mut table = Vec::new();
    for (i, row) in rows.into_iter().enumerate() {
        table.push(row);
        if fixed_after[i] && rng.unit() < 0.7 {
            table.push(random_fixed(rng));
        }
    }
    let base = random_transform(rng);
    let tool = random_transform(rng);
    Chain::new(conv, &table, base, Some(tool))
}

#[test]
fn random_arms_of_every_class_and_convention() {
    let mut rng = Rng(2303);
    for (class, conv) in FAMILIES {
        let mut total = 0;
        for arm in 0..12 {
            let chain = random_arm(class, conv, &mut rng);
            let ik = AnalyticIk::new(&chain).unwrap_or_else(|e| panic!("{class:?} {conv:?}: {e}"));
            assert_eq!(ik.class(), class, "{conv:?} arm {arm}");
            total += round_trips(&ik, 40, &mut rng, &format!("{class:?} {conv:?} arm {arm}"));
        }
        // Measured: 4.8–5.7 solutions per target on these random arms.
        assert!(total >= 12 * 40 * 4, "{class:?} {conv:?}: {total}");
    }
}

#[test]
fn random_arms_no_solution_missed_against_a_numeric_multistart() {
    let mut rng = Rng(2304);
    let mut full = 0;
    for (class, conv) in FAMILIES {
        for _ in 0..2 {
            let chain = random_arm(class, conv, &mut rng);
            let ik = AnalyticIk::new(&chain).unwrap();
            let q: Vec<f64> = (0..6).map(|_| rng.range(-PI, PI)).collect();
            let target = chain.forward(&q, 1.0);
            let analytic = principal(&ik, &target, &[0.0; 6]);
            let numeric = multistart(&chain, &target, 150, &mut rng);
            for n in &numeric {
                assert!(
                    analytic.iter().any(|a| same(&a.q, n, 1e-6)),
                    "{class:?} {conv:?}: the multi-start found {n:?}, the analytic solver did not"
                );
            }
            assert!(numeric.len() <= analytic.len());
            full += usize::from(numeric.len() == analytic.len());
        }
    }
    // The multi-start is a lower bound; it finds every solution on most targets.
    assert!(full >= 10, "{full} of 12 targets fully matched");
}

#[test]
fn arms_not_classified_say_why() {
    let r = |kind, a, alpha, d| DhRow {
        kind,
        a,
        alpha,
        d,
        theta: 0.0,
    };
    let rv = JointKind::Revolute;
    // A general 6R (no wrist centre, no parallel triple).
    let general: Vec<DhRow> = (0..6)
        .map(|i| r(rv, 0.1 + 0.05 * i as f64, 0.7 + 0.3 * i as f64, 0.2))
        .collect();
    let chain = Chain::new(Convention::Standard, &general, Transform::IDENTITY, None);
    assert_eq!(
        AnalyticIk::new(&chain).err(),
        Some(NotAnalytic::Unsupported)
    );
    let seven: Vec<DhRow> = (0..7).map(|_| r(rv, 0.1, FRAC_PI_2, 0.1)).collect();
    let chain = Chain::new(Convention::Modified, &seven, Transform::IDENTITY, None);
    assert_eq!(
        AnalyticIk::new(&chain).err(),
        Some(NotAnalytic::JointCount(7))
    );
    let mut prismatic = general.clone();
    prismatic[4].kind = JointKind::Prismatic;
    let chain = Chain::new(Convention::Standard, &prismatic, Transform::IDENTITY, None);
    assert_eq!(
        AnalyticIk::new(&chain).err(),
        Some(NotAnalytic::Prismatic(4))
    );
}

// ------------------------------------------------------------ units and reach

#[test]
fn millimetre_chains_give_the_same_angles() {
    let puma = robot("puma560");
    let m = puma.chain();
    let rows: Vec<DhRow> = m
        .dh_rows()
        .map(|r| DhRow {
            a: r.a * 1000.0,
            d: r.d * 1000.0,
            ..r
        })
        .collect();
    let mm = Chain::new(Convention::Standard, &rows, Transform::IDENTITY, None);
    let (ik_m, ik_mm) = (AnalyticIk::new(m).unwrap(), AnalyticIk::new(&mm).unwrap());
    let q = [0.4, -0.3, 0.9, -1.2, 0.6, 2.0];
    let (tm, tmm) = (m.forward(&q, 1.0), mm.forward(&q, 1.0));
    let (a, b) = (principal(&ik_m, &tm, &[]), principal(&ik_mm, &tmm, &[]));
    assert_eq!(a.len(), 8);
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert!(same(&x.q, &y.q, 1e-9), "{:?} vs {:?}", x.q, y.q);
        assert_fk(&mm, &y.q, &tmm, "puma560 in mm");
        assert_eq!(x.branch, y.branch);
    }
}

#[test]
fn unreachable_and_non_finite_targets_have_no_solutions() {
    for name in ["puma560", "ur5e"] {
        let r = robot(name);
        let ik = AnalyticIk::new(r.chain()).unwrap();
        let far = Transform::translation(5.0, 0.0, 0.0);
        let answer = ik.solve(&far, &limits(&r), None, &AnalyticOptions::default());
        assert!(
            answer.solutions.is_empty() && answer.principal == 0,
            "{name}"
        );
        let mut nan = r.chain().forward(&[0.1; 6], 1.0);
        nan.translation[1] = f64::NAN;
        let answer = ik.solve(
            &nan,
            &limits(&r),
            Some(&[f64::NAN; 6]),
            &AnalyticOptions::default(),
        );
        assert!(answer.solutions.is_empty(), "{name}");
    }
}

// ------------------------------------------------------------- 2π copies, order

/// How many copies of `x + 2πk` lie in `[lo, hi]`.
fn turns_inside(x: f64, lo: f64, hi: f64) -> usize {
    let k0 = ((lo - 1e-12 - x) / TAU).ceil() as i64;
    let k1 = ((hi + 1e-12 - x) / TAU).floor() as i64;
    (k1 - k0 + 1).max(0) as usize
}

/// The answer holds every copy inside the limits once, FK-checked, within
/// the limits, nearest the reference first, with honest distances.
fn assert_copies(
    chain: &Chain,
    limits: &[Option<(f64, f64)>],
    target: &Transform,
    seed: &[f64],
) -> usize {
    let ik = AnalyticIk::new(chain).unwrap();
    let answer = ik.solve(target, limits, Some(seed), &AnalyticOptions::default());
    let base = principal(&ik, target, seed);
    let expected: usize = base
        .iter()
        .map(|s| {
            (0..6)
                .map(|j| match limits[j] {
                    Some((lo, hi)) => turns_inside(s.q[j], lo, hi),
                    None => 1,
                })
                .product::<usize>()
        })
        .sum();
    assert_eq!(answer.principal, base.len());
    assert_eq!(answer.solutions.len(), expected);
    assert!(!answer.truncated);
    let mut last = 0.0;
    for (i, s) in answer.solutions.iter().enumerate() {
        assert_fk(chain, &s.q, target, "copy");
        for (j, x) in s.q.iter().enumerate() {
            match limits[j] {
                Some((lo, hi)) => assert!(
                    (lo..=hi).contains(x),
                    "joint {j} = {x} outside [{lo}, {hi}]"
                ),
                None => assert!((x - seed[j]).abs() <= PI + 1e-12),
            }
        }
        let d =
            s.q.iter()
                .zip(seed)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
        assert!((d - s.distance).abs() < 1e-9, "{d} vs {}", s.distance);
        assert!(s.distance >= last - 1e-12, "not sorted at {i}");
        last = s.distance;
        assert!(
            base.iter()
                .any(|b| same(&b.q, &s.q, 1e-9) && b.branch == s.branch)
        );
        for o in &answer.solutions[..i] {
            assert!(
                o.q.iter().zip(&s.q).any(|(a, b)| (a - b).abs() > 1e-6),
                "copy twice"
            );
        }
    }
    expected
}

#[test]
fn copies_inside_wide_limits_nearest_the_seed_first() {
    let ur = robot("ur5e"); // ±360° on every joint: up to 2⁶ copies of each solution
    let q = [0.4, -1.1, 1.3, -0.7, 0.9, 2.2];
    let target = ur.chain().forward(&q, 1.0);
    let n = assert_copies(ur.chain(), &limits(&ur), &target, &q);
    assert!(n >= 8 * 32, "{n} copies");
    let ik = AnalyticIk::new(ur.chain()).unwrap();
    let all = ik.solve(&target, &limits(&ur), Some(&q), &AnalyticOptions::default());
    assert!(
        all.solutions[0].distance < 1e-9,
        "the seed's own solution comes first"
    );
    // A cap keeps the nearest ones and says it cut.
    let opts = AnalyticOptions {
        max_solutions: 10,
        ..AnalyticOptions::default()
    };
    let ten = ik.solve(&target, &limits(&ur), Some(&q), &opts);
    assert!(ten.truncated && ten.solutions.len() == 10);
    for (a, b) in ten.solutions.iter().zip(&all.solutions) {
        assert!((a.distance - b.distance).abs() < 1e-12);
    }
    // Huge limits stay bounded by the cap.
    let huge = vec![Some((-1e9, 1e9)); 6];
    let capped = ik.solve(&target, &huge, Some(&q), &opts);
    assert!(capped.truncated && capped.solutions.len() == 10);
    // Narrow real limits (PUMA 560) and no limits at all.
    let puma = robot("puma560");
    let qp = [0.2, -0.4, 0.6, 3.5, 0.7, -3.9];
    let tp = puma.chain().forward(&qp, 1.0);
    assert!(assert_copies(puma.chain(), &limits(&puma), &tp, &qp) >= 1);
    assert_eq!(assert_copies(puma.chain(), &[None; 6], &tp, &qp), 8);
}

#[test]
fn without_a_seed_the_middle_of_the_limits_is_the_reference() {
    let ur = robot("ur5e");
    let ik = AnalyticIk::new(ur.chain()).unwrap();
    let target = ur.chain().forward(&[0.4, -1.1, 1.3, -0.7, 0.9, 2.2], 1.0);
    let answer = ik.solve(&target, &limits(&ur), None, &AnalyticOptions::default());
    let mid: Vec<f64> = limits(&ur)
        .iter()
        .map(|l| l.map_or(0.0, |(lo, hi)| 0.5 * (lo + hi)))
        .collect();
    let first = &answer.solutions[0];
    let d = first
        .q
        .iter()
        .zip(&mid)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!((d - first.distance).abs() < 1e-9);
    assert!(
        first.q.iter().all(|x| x.abs() <= PI),
        "nearest the middle (0): principal values"
    );
}

// ---------------------------------------------------------- singular targets

#[test]
fn wrist_singular_targets_give_the_family_representative() {
    for (name, q, free) in [
        ("puma560", [0.3, -0.5, 0.8, 0.2, 0.0, -1.1], 3),
        ("ur5e", [0.3, -1.0, 1.2, -0.4, 0.0, 0.8], 5),
    ] {
        let r = robot(name);
        let ik = AnalyticIk::new(r.chain()).unwrap();
        let target = r.chain().forward(&q, 1.0);
        let mut seed = q;
        seed[free] += 0.5;
        let answer = ik.solve(
            &target,
            &[None; 6],
            Some(&seed),
            &AnalyticOptions::default(),
        );
        assert!(answer.singular().wrist, "{name}: singular not reported");
        let family: Vec<_> = answer
            .solutions
            .iter()
            .filter(|s| s.singular.wrist)
            .collect();
        assert!(!family.is_empty());
        for s in &answer.solutions {
            assert_fk(r.chain(), &s.q, &target, name);
        }
        for s in family {
            assert!(
                (s.q[free] - seed[free]).abs() < 1e-12,
                "{name}: free joint {} not the seed's",
                free + 1
            );
        }
    }
}

/// A configuration of `inline_6dof` whose wrist centre is on axis 1.
fn shoulder_singular_inline() -> [f64; 6] {
    let r = robot("inline_6dof");
    let x_of = |q3: f64| {
        let q = [0.0, 1.2, q3, 0.0, 0.0, 0.0];
        r.chain().forward_frames(&q, 1.0).1[4].translation[0]
    };
    let (mut lo, mut hi) = (-PI, -PI);
    for k in 1..=64 {
        let b = -PI + TAU * k as f64 / 64.0;
        if x_of(lo).signum() != x_of(b).signum() {
            hi = b;
            break;
        }
        lo = b;
    }
    assert!(hi > lo, "no sign change");
    for _ in 0..80 {
        let m = 0.5 * (lo + hi);
        if x_of(m).signum() == x_of(lo).signum() {
            lo = m
        } else {
            hi = m
        }
    }
    [0.9, 1.2, 0.5 * (lo + hi), 0.3, 0.8, -0.6]
}

#[test]
fn shoulder_singular_targets_give_the_family_representative() {
    let r = robot("inline_6dof");
    let q = shoulder_singular_inline();
    let wc = r.chain().forward_frames(&q, 1.0).1[4].translation;
    assert!(
        wc[0].hypot(wc[1]) < 1e-12,
        "wrist centre {wc:?} not on axis 1"
    );
    let ik = AnalyticIk::new(r.chain()).unwrap();
    let target = r.chain().forward(&q, 1.0);
    let seed = [0.2, 0.0, 0.0, 0.0, 0.0, 0.0];
    let answer = ik.solve(
        &target,
        &[None; 6],
        Some(&seed),
        &AnalyticOptions::default(),
    );
    assert!(answer.singular().shoulder);
    assert!(!answer.solutions.is_empty());
    for s in &answer.solutions {
        assert_fk(r.chain(), &s.q, &target, "inline_6dof");
        assert!(s.singular.shoulder);
        assert!(
            (s.q[0] - 0.2).abs() < 1e-12,
            "q1 = {} is not the seed's",
            s.q[0]
        );
    }
}
