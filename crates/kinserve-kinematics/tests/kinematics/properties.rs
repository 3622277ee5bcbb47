//! Property tests (proptest) over random DH tables and configurations.

use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, Transform};
use kinserve_testkit::{forward_reference, supported_kernels};
use proptest::prelude::*;

fn kind() -> impl Strategy<Value = JointKind> {
    prop_oneof![4 => Just(JointKind::Revolute), 1 => Just(JointKind::Prismatic), 1 => Just(JointKind::Fixed)]
}

/// Any value in the range, or exactly one of `special` (0 and, for angles, the
/// multiples of 90° in rad that real tables use): those compile to the
/// aligned steps, the rest to general ones.
fn value(lo: f64, hi: f64, special: &'static [f64]) -> impl Strategy<Value = f64> {
    prop_oneof![lo..hi, prop::sample::select(special)]
}

const HALF_PI: f64 = std::f64::consts::FRAC_PI_2;
const ANGLES: &[f64] = &[0.0, HALF_PI, -HALF_PI, std::f64::consts::PI];

fn row() -> impl Strategy<Value = DhRow> {
    (
        kind(),
        value(-2.0, 2.0, &[0.0]),
        value(-3.2, 3.2, ANGLES),
        value(-2.0, 2.0, &[0.0]),
        value(-3.2, 3.2, ANGLES),
    )
        .prop_map(|(kind, a, alpha, d, theta)| DhRow {
            kind,
            a,
            alpha,
            d,
            theta,
        })
}

fn rigid() -> impl Strategy<Value = Transform> {
    (
        prop::array::uniform3(-2.0..2.0f64),
        prop::array::uniform3(-3.2..3.2f64),
    )
        .prop_map(|(t, rpy)| Transform::from_translation_rpy(t, rpy))
}

/// A table with at least one movable joint, and joint values for it.
fn table() -> impl Strategy<Value = (Vec<DhRow>, Vec<f64>)> {
    prop::collection::vec(row(), 1..10)
        .prop_map(|mut rows| {
            if rows.iter().all(|r| r.kind == JointKind::Fixed) {
                rows[0].kind = JointKind::Revolute;
            }
            rows
        })
        .prop_flat_map(|rows| {
            let dof = rows.iter().filter(|r| r.kind != JointKind::Fixed).count();
            (Just(rows), prop::collection::vec(-7.0..7.0f64, dof))
        })
}

/// The same arm in the modified convention: row i holds α_{i-1}, a_{i-1}, θ_i, d_i,
/// and a final fixed row carries a_n, α_n.
fn to_modified(rows: &[DhRow]) -> Vec<DhRow> {
    let mut out = Vec::with_capacity(rows.len() + 1);
    let (mut prev_a, mut prev_alpha) = (0.0, 0.0);
    for r in rows {
        out.push(DhRow {
            kind: r.kind,
            a: prev_a,
            alpha: prev_alpha,
            d: r.d,
            theta: r.theta,
        });
        prev_a = r.a;
        prev_alpha = r.alpha;
    }
    out.push(DhRow {
        kind: JointKind::Fixed,
        a: prev_a,
        alpha: prev_alpha,
        d: 0.0,
        theta: 0.0,
    });
    out
}

const TOL: f64 = 1e-12;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn every_pose_is_rigid_and_its_representations_agree((rows, q) in table(), base in rigid(), tool in rigid()) {
        for convention in [Convention::Standard, Convention::Modified] {
            let chain = Chain::new(convention, &rows, base, Some(tool));
            let t = chain.forward(&q, 1.0);
            prop_assert!(t.rigidity_error() < 1e-12, "rigidity {}", t.rigidity_error());
            let m = t.matrix();
            prop_assert_eq!(m[3], [0.0, 0.0, 0.0, 1.0]);
            let quat = t.quaternion();
            prop_assert!(quat[0] >= 0.0);
            let norm = quat.iter().map(|x| x * x).sum::<f64>().sqrt();
            prop_assert!((norm - 1.0).abs() < 1e-12);
            let from_q = Transform::from_translation_quaternion(t.translation, quat).unwrap();
            prop_assert!(from_q.max_abs_diff(&t) < 1e-9, "quaternion disagrees: {}", from_q.max_abs_diff(&t));
            let from_rpy = Transform::from_translation_rpy(t.translation, t.rpy());
            prop_assert!(from_rpy.max_abs_diff(&t) < 1e-9, "rpy disagrees: {}", from_rpy.max_abs_diff(&t));
        }
    }

    #[test]
    fn standard_and_modified_tables_of_the_same_arm_agree((rows, q) in table()) {
        let std_chain = Chain::new(Convention::Standard, &rows, Transform::IDENTITY, None);
        let mdh_chain = Chain::new(Convention::Modified, &to_modified(&rows), Transform::IDENTITY, None);
        let a = std_chain.forward(&q, 1.0);
        let b = mdh_chain.forward(&q, 1.0);
        prop_assert!(a.max_abs_diff(&b) < 1e-11, "diff {}", a.max_abs_diff(&b));
    }

    #[test]
    fn base_and_tool_compose_as_stated((rows, q) in table(), base in rigid(), tool in rigid()) {
        let bare = Chain::new(Convention::Standard, &rows, Transform::IDENTITY, None).forward(&q, 1.0);
        let full = Chain::new(Convention::Standard, &rows, base, Some(tool)).forward(&q, 1.0);
        let expect = base * bare * tool;
        prop_assert!(full.max_abs_diff(&expect) < 1e-11, "diff {}", full.max_abs_diff(&expect));
    }

    #[test]
    fn fast_paths_match_the_plain_product((rows, q) in table(), base in rigid(), tool in rigid()) {
        for convention in [Convention::Standard, Convention::Modified] {
            for tool in [None, Some(tool)] {
                let chain = Chain::new(convention, &rows, base, tool);
                let reference = forward_reference(&chain, &q, 1.0);
                prop_assert!(chain.forward(&q, 1.0).max_abs_diff(&reference) <= TOL);
                let batch_q: Vec<f64> = q.iter().cycle().take(q.len() * 9).copied().collect();
                for kernel in supported_kernels() {
                    prop_assert!(chain.forward_with(kernel, &q, 1.0).max_abs_diff(&reference) <= TOL, "{kernel:?}");
                    let (t, frames) = chain.forward_frames_with(kernel, &q, 1.0);
                    prop_assert!(t.max_abs_diff(&reference) <= TOL, "{kernel:?} frames");
                    prop_assert_eq!(frames.len(), rows.len() + 1);
                    let mut out = vec![Transform::IDENTITY; 9];
                    chain.forward_batch_with(kernel, &batch_q, 1.0, &mut out);
                    for t in &out {
                        prop_assert!(t.max_abs_diff(&reference) <= TOL, "{kernel:?} batch");
                    }
                }
            }
        }
    }
}
