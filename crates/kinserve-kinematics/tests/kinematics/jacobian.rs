//! The analytic geometric Jacobian against central differences of FK, for
//! every robot in `robots/` and for random chains (both conventions,
//! prismatic and fixed rows, base and tool), in both frames; manipulability,
//! condition number and the singular flag against their definitions, and
//! against an independent SVD (of the central-difference Jacobian) at and
//! near singular configurations.

use kinserve_kinematics::{
    Chain, Convention, DhRow, Jacobian, JacobianFrame, JointKind, SINGULAR_THRESHOLD, Transform,
};
use kinserve_model::{Robot, load_robot_file};
use nalgebra::{DMatrix, Matrix3};

use crate::kinematics::Rng;

/// Every robot file in `robots/`, sorted by name.
pub fn all_robots() -> Vec<Robot> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let mut robots: Vec<Robot> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .map(|p| load_robot_file(&p).unwrap())
        .collect();
    robots.sort_by(|a, b| a.name().cmp(b.name()));
    robots
}

/// The shipped robot named `name`.
pub fn robot(name: &str) -> Robot {
    all_robots()
        .into_iter()
        .find(|r| r.name() == name)
        .unwrap_or_else(|| panic!("no shipped robot named {name}"))
}

/// A configuration within the robot's limits (rad / length unit); unlimited
/// revolute joints in [-π, π], unlimited prismatic ones in [-0.5, 0.5]·reach.
pub fn random_config(robot: &Robot, rng: &mut Rng) -> Vec<f64> {
    let reach: f64 = robot.chain().dh_rows().map(|r| r.a.abs() + r.d.abs()).sum();
    robot
        .joints()
        .iter()
        .map(|j| match (j.limits, j.kind) {
            (Some((lo, hi)), _) => rng.range(lo, hi),
            (None, JointKind::Prismatic) => rng.range(-0.5, 0.5) * reach.max(1.0),
            (None, _) => rng.range(-std::f64::consts::PI, std::f64::consts::PI),
        })
        .collect()
}

/// `vee((M − Mᵀ)/2)` of `M = A·Bᵀ`: `sin θ · axis` of the rotation taking B to A,
/// i.e. `θ · axis` to within θ³/6 (for the small θ of a finite difference).
fn small_rotation(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [f64; 3] {
    let m = Matrix3::from_fn(|i, j| a[i][0] * b[j][0] + a[i][1] * b[j][1] + a[i][2] * b[j][2]);
    [
        0.5 * (m[(2, 1)] - m[(1, 2)]),
        0.5 * (m[(0, 2)] - m[(2, 0)]),
        0.5 * (m[(1, 0)] - m[(0, 1)]),
    ]
}

fn rotate_back(r: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| r[0][i] * v[0] + r[1][i] * v[1] + r[2][i] * v[2])
}

/// Column `j` by central differences of FK with step `h`, in `frame`:
/// world twist from `p(q±h)` and `R(q+h)·R(q−h)ᵀ`; tool twist from `R(q)ᵀ Δp`
/// and `R(q−h)ᵀ·R(q+h)` (the body rotation), computed independently.
fn fd_column(chain: &Chain, q: &[f64], j: usize, h: f64, frame: JacobianFrame) -> [f64; 6] {
    let mut qp = q.to_vec();
    let mut qm = q.to_vec();
    qp[j] += h;
    qm[j] -= h;
    let (tp, tm, t0) = (
        chain.forward(&qp, 1.0),
        chain.forward(&qm, 1.0),
        chain.forward(q, 1.0),
    );
    let dp: [f64; 3] = std::array::from_fn(|i| (tp.translation[i] - tm.translation[i]) / (2.0 * h));
    let (v, w) = match frame {
        JacobianFrame::Base => (dp, small_rotation(&tp.rotation, &tm.rotation)),
        JacobianFrame::Tool => {
            let tpt = transpose(&tp.rotation);
            let tmt = transpose(&tm.rotation);
            // The body rotation R(q−h)ᵀ·R(q+h) = A·Bᵀ with A = R(q−h)ᵀ, B = R(q+h)ᵀ.
            (rotate_back(&t0.rotation, dp), small_rotation(&tmt, &tpt))
        }
    };
    let w = w.map(|x| x / (2.0 * h));
    [v[0], v[1], v[2], w[0], w[1], w[2]]
}

fn transpose(r: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| r[j][i]))
}

/// Largest difference between the analytic Jacobian and central differences,
/// relative to `scale` (the chain's reach, at least 1).
fn worst_fd_error(chain: &Chain, q: &[f64], frame: JacobianFrame, scale: f64) -> f64 {
    let (tool, jac) = chain.jacobian(q, 1.0, frame);
    assert!(tool.max_abs_diff(&chain.forward(q, 1.0)) <= 1e-12 * scale);
    assert_eq!(jac.dof(), q.len());
    let h = 1e-6;
    let mut worst: f64 = 0.0;
    for (j, col) in jac.columns().iter().enumerate() {
        let fd = fd_column(chain, q, j, h, frame);
        for (a, b) in col.iter().zip(&fd) {
            worst = worst.max((a - b).abs() / scale);
        }
    }
    worst
}

/// Central differences with h = 1e-6 are exact to ~h²·|p'''| ≈ 1e-12·reach,
/// plus rounding of ~1e-16·|p|/h ≈ 1e-10·reach. Measured worst (relative to
/// the reach): 2.3e-10 over the robot files, 1.9e-10 over the random chains.
/// 1e-8 leaves a margin while a wrong axis or sign gives errors of order 1
/// (reading the modified-DH axes from the wrong frame fails every test here).
const FD_TOLERANCE: f64 = 1e-8;

fn reach(chain: &Chain) -> f64 {
    let rows: f64 = chain.dh_rows().map(|r| r.a.abs() + r.d.abs()).sum();
    let ends = chain
        .base()
        .translation
        .iter()
        .map(|x| x.abs())
        .sum::<f64>()
        + chain
            .tool()
            .map_or(0.0, |t| t.translation.iter().map(|x| x.abs()).sum());
    (rows + ends).max(1.0)
}

#[test]
fn every_robot_matches_central_differences_in_both_frames() {
    let mut rng = Rng(16);
    let robots = all_robots();
    assert!(robots.len() >= 19);
    let mut seen_modified = false;
    let mut seen_prismatic = false;
    for robot in &robots {
        let chain = robot.chain();
        seen_modified |= chain.convention() == Convention::Modified;
        seen_prismatic |= chain.joint_kinds().any(|k| k == JointKind::Prismatic);
        let scale = reach(chain);
        for _ in 0..50 {
            let q = random_config(robot, &mut rng);
            for frame in [JacobianFrame::Base, JacobianFrame::Tool] {
                let err = worst_fd_error(chain, &q, frame, scale);
                assert!(
                    err <= FD_TOLERANCE,
                    "{} {frame:?} at {q:?}: relative error {err:e}",
                    robot.name()
                );
            }
        }
    }
    assert!(
        seen_modified && seen_prismatic,
        "both conventions and prismatic joints are covered"
    );
}

/// A random chain: 1–8 rows of random kinds (fixed rows included), random
/// DH parameters, base and tool.
fn random_chain(rng: &mut Rng, convention: Convention) -> Chain {
    let n = 1 + (rng.unit() * 8.0) as usize;
    let mut rows: Vec<DhRow> = (0..n)
        .map(|_| {
            let u = rng.unit();
            DhRow {
                kind: if u < 0.6 {
                    JointKind::Revolute
                } else if u < 0.85 {
                    JointKind::Prismatic
                } else {
                    JointKind::Fixed
                },
                a: rng.range(-0.8, 0.8),
                alpha: rng.range(-3.2, 3.2),
                d: rng.range(-0.8, 0.8),
                theta: rng.range(-3.2, 3.2),
            }
        })
        .collect();
    rows[0].kind = JointKind::Revolute;
    let pose = |rng: &mut Rng| {
        Transform::from_translation_rpy(
            [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ],
            [
                rng.range(-3.0, 3.0),
                rng.range(-1.5, 1.5),
                rng.range(-3.0, 3.0),
            ],
        )
    };
    let base = pose(rng);
    let tool = pose(rng);
    Chain::new(convention, &rows, base, Some(tool))
}

#[test]
fn random_chains_match_central_differences_in_both_conventions() {
    let mut rng = Rng(1616);
    for convention in [Convention::Standard, Convention::Modified] {
        for _ in 0..200 {
            let chain = random_chain(&mut rng, convention);
            let q: Vec<f64> = (0..chain.dof()).map(|_| rng.range(-3.0, 3.0)).collect();
            for frame in [JacobianFrame::Base, JacobianFrame::Tool] {
                let err = worst_fd_error(&chain, &q, frame, reach(&chain));
                assert!(
                    err <= FD_TOLERANCE,
                    "{convention:?} {frame:?}: {err:e}\n{chain:?}"
                );
            }
        }
    }
}

#[test]
fn degree_scaled_joint_values_give_columns_per_radian() {
    let robot = robot("puma560");
    let chain = robot.chain();
    let q_rad = [0.3, -0.4, 0.5, 0.2, -0.7, 1.1];
    let q_deg = q_rad.map(f64::to_degrees);
    let (_, a) = chain.jacobian(&q_rad, 1.0, JacobianFrame::Base);
    let (_, b) = chain.jacobian(&q_deg, std::f64::consts::PI / 180.0, JacobianFrame::Base);
    for (ca, cb) in a.columns().iter().zip(b.columns()) {
        for (x, y) in ca.iter().zip(cb) {
            assert!((x - y).abs() <= 1e-12, "{x} vs {y}");
        }
    }
}

fn as_matrix(j: &Jacobian) -> DMatrix<f64> {
    DMatrix::from_fn(6, j.dof(), |r, c| j.get(r, c).unwrap())
}

#[test]
fn manipulability_is_sqrt_det_j_jt_and_condition_number_matches_eigenvalues() {
    let mut rng = Rng(7);
    for robot in &all_robots() {
        for _ in 0..10 {
            let q = random_config(robot, &mut rng);
            let (_, jac) = robot.chain().jacobian(&q, 1.0, JacobianFrame::Base);
            let m = jac.measures();
            // The definition: the linear rows for up to 3 joints, all six otherwise;
            // det(J Jᵀ) when J has at least as many columns as rows, det(Jᵀ J) below.
            let a = as_matrix(&jac);
            let a = if jac.dof() <= 3 {
                a.rows(0, 3).into_owned()
            } else {
                a
            };
            assert_eq!(m.rows, a.nrows());
            let gram = if jac.dof() >= a.nrows() {
                &a * a.transpose()
            } else {
                a.transpose() * &a
            };
            // Compared squared: det(G) is rounded to ~n·ε·Π G_ii (Hadamard's
            // bound), which near a singularity is far above det(G) itself.
            let det = gram.determinant();
            let hadamard: f64 = gram.diagonal().iter().product();
            assert!(
                (m.manipulability.powi(2) - det).abs() <= 1e-12 * hadamard,
                "{}: {}² vs det = {det}",
                robot.name(),
                m.manipulability
            );
            // σ_max² / σ_min² are the extreme eigenvalues of the Gram matrix.
            let eig = gram.symmetric_eigenvalues();
            let (lo, hi) = (eig.min(), eig.max());
            assert!(m.condition_number >= 1.0);
            if lo > 1e-10 * hi {
                let expected = (hi / lo).sqrt();
                assert!(
                    (m.condition_number - expected).abs() <= 1e-6 * expected,
                    "{}: κ = {} vs {expected}",
                    robot.name(),
                    m.condition_number
                );
            }
            let smallest = *m.singular_values.last().unwrap();
            assert_eq!(
                m.singular,
                smallest < SINGULAR_THRESHOLD,
                "{}",
                robot.name()
            );
        }
    }
}

#[test]
fn known_singular_configurations_are_flagged_and_generic_ones_are_not() {
    let robots = all_robots();
    let get = |n: &str| robots.iter().find(|r| r.name() == n).unwrap();
    // PUMA 560 with θ5 = 0: joints 4 and 6 share an axis (wrist singularity).
    let puma = get("puma560");
    let (_, j) = puma
        .chain()
        .jacobian(&[0.1, -0.5, 0.4, 0.3, 0.0, 0.2], 1.0, JacobianFrame::Base);
    let m = j.measures();
    assert!(m.singular, "{m:?}");
    assert!(
        m.manipulability < 1e-12 && m.condition_number > 1e12,
        "{m:?}"
    );
    // UR5e with the elbow straight (q3 = 0): the arm is stretched out.
    let ur = get("ur5e");
    let (_, j) = ur
        .chain()
        .jacobian(&[0.2, -1.0, 0.0, -1.2, 1.3, 0.4], 1.0, JacobianFrame::Tool);
    assert!(j.measures().singular);
    // The planar 2R arm stretched out (θ2 = 0) cannot move its tip radially;
    // its manipulability is the textbook a1·a2·|sin θ2| (a1 = 0.4, a2 = 0.3 m).
    let planar = get("planar_2dof");
    for t2 in [0.0, 0.3, 1.2, -2.0] {
        let (_, j) = planar
            .chain()
            .jacobian(&[0.7, t2], 1.0, JacobianFrame::Base);
        let m = j.measures();
        assert!(
            (m.manipulability - 0.4 * 0.3 * f64::sin(t2).abs()).abs() <= 1e-15,
            "{m:?}"
        );
        assert_eq!(m.singular, t2 == 0.0, "θ2 = {t2}");
    }
    // A generic configuration of each is not singular.
    for (r, q) in [
        (puma, [0.1, -0.5, 0.4, 0.3, 0.6, 0.2]),
        (ur, [0.2, -1.0, 1.1, -1.2, 1.3, 0.4]),
    ] {
        let (_, j) = r.chain().jacobian(&q, 1.0, JacobianFrame::Base);
        let m = j.measures();
        assert!(
            !m.singular && m.manipulability > 1e-4,
            "{}: {m:?}",
            r.name()
        );
    }
}

#[test]
fn the_measures_do_not_depend_on_the_frame() {
    // Rotating the rows by an orthogonal matrix keeps the singular values.
    let mut rng = Rng(99);
    for robot in &all_robots() {
        let q = random_config(robot, &mut rng);
        let (_, a) = robot.chain().jacobian(&q, 1.0, JacobianFrame::Base);
        let (_, b) = robot.chain().jacobian(&q, 1.0, JacobianFrame::Tool);
        let (ma, mb) = (a.measures(), b.measures());
        for (x, y) in ma.singular_values.iter().zip(&mb.singular_values) {
            assert!(
                (x - y).abs() <= 1e-9 * ma.singular_values[0],
                "{}",
                robot.name()
            );
        }
    }
}

/// The central-difference Jacobian (step 1e-6) in the base frame, as the
/// rows the measures use (linear rows only for up to 3 joints).
fn fd_matrix(chain: &Chain, q: &[f64]) -> DMatrix<f64> {
    let rows = if q.len() <= 3 { 3 } else { 6 };
    let cols: Vec<[f64; 6]> = (0..q.len())
        .map(|j| fd_column(chain, q, j, 1e-6, JacobianFrame::Base))
        .collect();
    DMatrix::from_fn(rows, q.len(), |r, c| cols[c][r])
}

/// Configurations at and near singularities, `(robot, q, what)`: PUMA 560's
/// wrist (θ5 → 0), UR5e's elbow (q3 → 0) and wrist (q5 → 0), the planar
/// arm stretched out (θ2 → 0); each at distances 0, 1e-9, 1e-7, 1e-5, 1e-3
/// and 0.1 rad from the singularity.
fn near_singular() -> Vec<(&'static str, Vec<f64>, String)> {
    let mut out = Vec::new();
    for eps in [0.0, 1e-9, 1e-7, 1e-5, 1e-3, 0.1] {
        let cases: [(&str, Vec<f64>, &str); 4] = [
            ("puma560", vec![0.1, -0.5, 0.4, 0.3, eps, 0.2], "wrist θ5"),
            ("ur5e", vec![0.2, -1.0, eps, -1.2, 1.3, 0.4], "elbow q3"),
            ("ur5e", vec![0.2, -1.0, 1.1, -1.2, eps, 0.4], "wrist q5"),
            ("planar_2dof", vec![0.7, eps], "stretched θ2"),
        ];
        for (robot, q, what) in cases {
            out.push((robot, q, format!("{what} = {eps:e}")));
        }
    }
    out
}

/// The `singular` flag, the smallest singular value and the condition
/// number against an independent SVD: nalgebra's, of the central-difference
/// Jacobian, at and near singular configurations. By Weyl's inequality each
/// singular value moves by at most ‖J − J_fd‖₂ ≤ ‖J − J_fd‖_F ≤ √(6n)·δ
/// (δ: [`FD_TOLERANCE`] times the reach, the entrywise bound checked
/// above), so σ_min must be within that of the independent one, the flag
/// must agree wherever σ_min is farther than that from the threshold, and κ
/// must lie in the interval the bounds give.
#[test]
fn singular_flag_and_condition_number_agree_with_an_independent_svd_near_singularities() {
    let robots = all_robots();
    let (mut flagged, mut clear) = (0, 0);
    for (name, q, what) in near_singular() {
        let robot = robots.iter().find(|r| r.name() == name).unwrap();
        let chain = robot.chain();
        let (_, jac) = chain.jacobian(&q, 1.0, JacobianFrame::Base);
        let m = jac.measures();
        let sv = fd_matrix(chain, &q).singular_values();
        let (hi, lo) = (sv.max(), sv.min());
        let delta = (6.0 * q.len() as f64).sqrt() * FD_TOLERANCE * reach(chain);
        let smallest = *m.singular_values.last().unwrap();
        let at = format!("{name} {what}: {m:?}, independent σ {hi:e} … {lo:e}");
        assert_eq!(m.singular_values.len(), sv.len(), "{at}");
        assert!(
            (smallest - lo).abs() <= delta,
            "{at}: σ_min off by more than {delta:e}"
        );
        if (lo - SINGULAR_THRESHOLD).abs() > delta {
            assert_eq!(m.singular, lo < SINGULAR_THRESHOLD, "{at}: singular flag");
            if m.singular { flagged += 1 } else { clear += 1 }
        }
        let low = (hi - delta) / (lo + delta);
        assert!(m.condition_number >= low, "{at}: κ below {low:e}");
        if lo > delta {
            let high = (hi + delta) / (lo - delta);
            assert!(m.condition_number <= high, "{at}: κ above {high:e}");
        }
    }
    // Both sides of the threshold are reached near every singularity.
    assert!(
        flagged >= 8 && clear >= 8,
        "{flagged} flagged, {clear} clear"
    );
}
