//! The fast FK paths against the plain product of link matrices, and the
//! vectorised sine/cosine against `std`.

use kinserve_kinematics::sincos::{POLY_LIMIT, sincos_poly_impl, sincos_slice, sincos_slice_with};
use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, PackedLayout, Transform};
use kinserve_testkit::{forward_reference, supported_kernels};

/// Deterministic pseudo-random numbers: `unit()` in [0, 1), `range(lo, hi)`.
pub use kinserve_testkit::SplitMix64 as Rng;

/// Absolute error bound of the polynomial sine/cosine against `std`, for |x| ≤ 1e5 rad.
/// Cody–Waite reduction leaves ~|x|·2^-53·(π/2 split error) and the polynomial ~1 ulp.
const SINCOS_ABS_BOUND: f64 = 4e-16;

/// The kernel tests say which kernels ran; under CI a kernel whose CPU
/// flags the machine has (the CI machine has AVX-512) is among them, so a
/// detection that drops it fails instead of silently testing less.
#[test]
fn the_kernels_tested_are_every_one_this_cpu_runs() {
    let kernels = supported_kernels();
    assert_eq!(
        kernels.first(),
        Some(&kinserve_kinematics::Kernel::Portable)
    );
    let flags = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    if kinserve_testkit::under_ci() && flags.contains(" avx512f") {
        assert!(
            kernels.contains(&kinserve_kinematics::Kernel::Avx512),
            "AVX-512 CPU under CI, kernels tested: {kernels:?}"
        );
    }
}

/// The angles the sine/cosine tests check (rad, all within ±`POLY_LIMIT`):
/// random ones over the whole range and within ±10, the quadrant edges and
/// special points, and the hardest reductions: the doubles nearest large
/// multiples of π/2, where `x − j·π/2` cancels to a tiny remainder.
fn sincos_samples() -> Vec<f64> {
    let mut rng = Rng(1);
    let mut xs: Vec<f64> = (0..200_000)
        .map(|_| rng.range(-POLY_LIMIT, POLY_LIMIT))
        .collect();
    xs.extend((0..200_000).map(|_| rng.range(-10.0, 10.0)));
    // Quadrant edges and special points.
    for k in -64..=64 {
        let b = k as f64 * std::f64::consts::FRAC_PI_4;
        xs.extend([b, b + 1e-12, b - 1e-12, f64::from_bits(b.to_bits() + 1)]);
    }
    xs.extend([0.0, -0.0, 1e-300, -1e-300, POLY_LIMIT, -POLY_LIMIT]);
    for k in (1..63_000).step_by(7).chain(62_000..63_600) {
        let b = k as f64 * std::f64::consts::FRAC_PI_2;
        xs.extend([
            b,
            -b,
            f64::from_bits(b.to_bits() + 1),
            f64::from_bits(b.to_bits() - 1),
        ]);
    }
    xs.retain(|x| x.abs() <= POLY_LIMIT);
    xs
}

#[test]
fn sincos_matches_std_over_range() {
    let xs = sincos_samples();
    let mut s = vec![0.0; xs.len()];
    let mut c = vec![0.0; xs.len()];
    for kernel in supported_kernels().into_iter().map(Some).chain([None]) {
        match kernel {
            Some(k) => sincos_slice_with(k, &xs, &mut s, &mut c),
            None => sincos_slice(&xs, &mut s, &mut c),
        }
        let mut worst: f64 = 0.0;
        for i in 0..xs.len() {
            let (es, ec) = xs[i].sin_cos();
            worst = worst.max((s[i] - es).abs()).max((c[i] - ec).abs());
        }
        assert!(
            worst <= SINCOS_ABS_BOUND,
            "{kernel:?}: max abs error {worst:e} > {SINCOS_ABS_BOUND:e}"
        );
    }
}

/// Both variants of the polynomial (unfused, fused) within
/// [`SINCOS_ABS_BOUND`] of `f64::sin_cos` (and 3 ulp where the value is not
/// near 0), on the angles of [`sincos_samples`].
#[test]
fn every_sincos_variant_matches_std() {
    let xs = sincos_samples();
    type Variant = (&'static str, fn(f64) -> (f64, f64));
    let variants: [Variant; 2] = [
        ("unfused", sincos_poly_impl::<false>),
        ("fused", sincos_poly_impl::<true>),
    ];
    // Units in the last place between two doubles of the same sign.
    let ulps = |a: f64, b: f64| (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs();
    for (name, f) in variants {
        for &x in &xs {
            let ((s, c), (es, ec)) = (f(x), x.sin_cos());
            for (v, e) in [(s, es), (c, ec)] {
                assert!(
                    (v - e).abs() <= SINCOS_ABS_BOUND,
                    "{name}: {x:e} gives {v:e}, std {e:e}"
                );
                // Away from the zeros, in relative terms too (a wrong
                // reduction constant shows here first).
                assert!(
                    e.abs() <= 1e-3 || ulps(v, e) <= 3,
                    "{name}: {x:e} gives {v:e}, std {e:e}"
                );
            }
        }
    }
}

#[test]
fn sincos_falls_back_to_std_outside_the_polynomial_range() {
    let xs = [1e6, -3e7, 1e300, f64::NAN, f64::INFINITY, -f64::INFINITY];
    let mut s = [0.0; 6];
    let mut c = [0.0; 6];
    sincos_slice(&xs, &mut s, &mut c);
    for i in 0..xs.len() {
        let (es, ec) = xs[i].sin_cos();
        assert!(
            s[i].to_bits() == es.to_bits() || (s[i].is_nan() && es.is_nan()),
            "sin({})",
            xs[i]
        );
        assert!(
            c[i].to_bits() == ec.to_bits() || (c[i].is_nan() && ec.is_nan()),
            "cos({})",
            xs[i]
        );
    }
}

/// A random chain of `n` rows mixing joint kinds, with random base and tool.
pub fn random_chain(rng: &mut Rng, convention: Convention, n: usize) -> Chain {
    let rows: Vec<DhRow> = (0..n)
        .map(|i| DhRow {
            kind: match i % 5 {
                3 => JointKind::Prismatic,
                4 => JointKind::Fixed,
                _ => JointKind::Revolute,
            },
            a: rng.range(-1.0, 1.0),
            alpha: rng.range(-3.2, 3.2),
            d: rng.range(-1.0, 1.0),
            theta: rng.range(-3.2, 3.2),
        })
        .collect();
    let base = Transform::from_translation_rpy(
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
    );
    let tool = Transform::from_translation_rpy([0.0, 0.01, 0.2], [0.1, -0.2, 0.3]);
    Chain::new(convention, &rows, base, Some(tool))
}

/// Stated accuracy of every fast path against the plain product.
const FAST_PATH_TOL: f64 = 1e-12;

#[test]
fn fast_single_batch_and_frames_match_the_plain_product() {
    let mut rng = Rng(7);
    for convention in [Convention::Standard, Convention::Modified] {
        for n in [1, 2, 5, 6, 7, 12, 30, 85] {
            let chain = random_chain(&mut rng, convention, n);
            let dof = chain.dof();
            let count = 37; // not a multiple of the batch block size
            let qs: Vec<f64> = (0..count * dof).map(|_| rng.range(-6.0, 6.0)).collect();
            for kernel in supported_kernels() {
                let mut batch = vec![Transform::IDENTITY; count];
                chain.forward_batch_with(kernel, &qs, 1.0, &mut batch);
                for k in 0..count {
                    let q = &qs[k * dof..(k + 1) * dof];
                    let reference = forward_reference(&chain, q, 1.0);
                    let single = chain.forward_with(kernel, q, 1.0);
                    let (framed, frames) = chain.forward_frames_with(kernel, q, 1.0);
                    for (what, t) in [("single", single), ("batch", batch[k]), ("frames", framed)] {
                        let e = t.max_abs_diff(&reference);
                        assert!(
                            e <= FAST_PATH_TOL,
                            "{convention:?} n={n} {kernel:?} {what}: diff {e:e}"
                        );
                    }
                    assert_eq!(frames.len(), chain.rows() + 1);
                }
            }
        }
    }
}

/// A random chain shaped like real arms: twists of 0, ±90° and 180° (in rad, so
/// not exactly representable, as in the robot files), zero `a`/`d`/`θ` half the
/// time, prismatic and fixed rows anywhere (also first and last), with or
/// without a base and a tool. These compile to the aligned steps.
fn random_aligned_chain(rng: &mut Rng, convention: Convention, n: usize) -> Chain {
    fn pick(rng: &mut Rng) -> f64 {
        let v = rng.range(-1.0, 1.0);
        if rng.unit() < 0.5 { 0.0 } else { v }
    }
    let rows: Vec<DhRow> = (0..n)
        .map(|_| {
            let u = rng.unit();
            DhRow {
                kind: if u < 0.6 {
                    JointKind::Revolute
                } else if u < 0.8 {
                    JointKind::Prismatic
                } else {
                    JointKind::Fixed
                },
                a: pick(rng),
                alpha: [0.0f64, 90.0, -90.0, 180.0, 270.0][(rng.unit() * 5.0) as usize]
                    .to_radians(),
                d: pick(rng),
                theta: [0.0, 0.0, 90f64.to_radians(), rng.range(-3.2, 3.2)]
                    [(rng.unit() * 4.0) as usize],
            }
        })
        .collect();
    let base = if rng.unit() < 0.5 {
        Transform::IDENTITY
    } else {
        Transform::from_translation_rpy([0.1, -0.2, 0.3], [0.3, -0.2, 1.0])
    };
    let tool = (rng.unit() < 0.5).then(|| Transform::translation(0.0, 0.0, 0.1));
    Chain::new(convention, &rows, base, tool)
}

/// A pose is the same to the last bit whichever path computes it: the batch
/// (blocks of eight, tiles, and the tail by the single path) and the single
/// pose, on every kernel, for general and aligned tables of 1 to 12 rows.
/// The service relies on it: a batch answer equals its parts' answers joined.
#[test]
fn batch_and_single_poses_agree_bit_for_bit() {
    let mut rng = Rng(23);
    for case in 0..120 {
        let convention = [Convention::Standard, Convention::Modified][case % 2];
        let n = 1 + case % 12;
        let chain = if case % 3 == 0 {
            random_chain(&mut rng, convention, n)
        } else {
            random_aligned_chain(&mut rng, convention, n)
        };
        let dof = chain.dof();
        let count = 27;
        let qs: Vec<f64> = (0..count * dof).map(|_| rng.range(-6.0, 6.0)).collect();
        for kernel in supported_kernels() {
            let mut batch = vec![Transform::IDENTITY; count];
            chain.forward_batch_with(kernel, &qs, 1.0, &mut batch);
            for (k, pose) in batch.iter().enumerate() {
                let single = chain.forward_with(kernel, &qs[k * dof..(k + 1) * dof], 1.0);
                assert!(
                    single.matrix12().map(f64::to_bits) == pose.matrix12().map(f64::to_bits),
                    "case {case} {kernel:?} pose {k}: {single:?} != {pose:?}"
                );
            }
        }
    }
}

#[test]
fn aligned_tables_match_the_plain_product_on_every_kernel() {
    let mut rng = Rng(17);
    let mut aligned = 0;
    for convention in [Convention::Standard, Convention::Modified] {
        for case in 0..300 {
            let chain = random_aligned_chain(&mut rng, convention, 1 + case % 12);
            aligned += chain.aligned_steps();
            let dof = chain.dof();
            let count = 19;
            let qs: Vec<f64> = (0..count * dof).map(|_| rng.range(-6.0, 6.0)).collect();
            for kernel in supported_kernels() {
                let mut batch = vec![Transform::IDENTITY; count];
                chain.forward_batch_with(kernel, &qs, 1.0, &mut batch);
                for k in 0..count {
                    let q = &qs[k * dof..(k + 1) * dof];
                    let reference = forward_reference(&chain, q, 1.0);
                    let (framed, frames) = chain.forward_frames_with(kernel, q, 1.0);
                    for (what, t) in [
                        ("single", chain.forward_with(kernel, q, 1.0)),
                        ("batch", batch[k]),
                        ("frames", framed),
                    ] {
                        let e = t.max_abs_diff(&reference);
                        assert!(
                            e <= FAST_PATH_TOL,
                            "{convention:?} case {case} {kernel:?} {what}: {e:e}"
                        );
                    }
                    assert_eq!(frames.len(), chain.rows() + 1);
                    assert_frames_match_the_plain_products(&chain, q, &frames);
                    let mut called = Vec::new();
                    let t =
                        chain.forward_frames_into_with(kernel, q, 1.0, &mut |f| called.push(*f));
                    assert_eq!(
                        (t, &called),
                        (framed, &frames),
                        "callback and slice frames agree"
                    );
                }
            }
        }
    }
    assert!(
        aligned > 1000,
        "the generator should produce aligned steps, got {aligned}"
    );
}

/// Frame `i` is `base · A_1 ⋯ A_i` (no tool), by the textbook link matrices.
fn assert_frames_match_the_plain_products(chain: &Chain, q: &[f64], frames: &[Transform]) {
    let mut t = *chain.base();
    let mut qi = q.iter();
    assert!(frames[0].max_abs_diff(&t) <= FAST_PATH_TOL);
    for (i, row) in chain.dh_rows().enumerate() {
        let v = match row.kind {
            JointKind::Fixed => 0.0,
            _ => qi.next().copied().unwrap_or(0.0),
        };
        t = t * kinserve_kinematics::link_transform(chain.convention(), &row, v);
        let e = frames[i + 1].max_abs_diff(&t);
        assert!(e <= FAST_PATH_TOL, "frame {}: {e:e}", i + 1);
    }
}

#[test]
fn frames_match_the_plain_products_for_random_tables() {
    let mut rng = Rng(23);
    for convention in [Convention::Standard, Convention::Modified] {
        for n in [1, 3, 6, 9, 17, 30] {
            let chain = random_chain(&mut rng, convention, n);
            let q: Vec<f64> = (0..chain.dof()).map(|_| rng.range(-6.0, 6.0)).collect();
            for kernel in supported_kernels() {
                let (_, frames) = chain.forward_frames_with(kernel, &q, 1.0);
                assert_frames_match_the_plain_products(&chain, &q, &frames);
            }
        }
    }
}

#[test]
fn the_built_in_arms_compile_to_aligned_steps_only() {
    for name in ["puma560", "ur5e", "panda", "kuka_kr5", "stanford"] {
        let path = format!("{}/../../robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
        let robot = kinserve_model::load_robot_file(std::path::Path::new(&path)).unwrap();
        let chain = robot.chain();
        assert_eq!(chain.aligned_steps(), chain.dof(), "{name}");
    }
}

#[test]
fn missing_and_extra_joint_values_count_as_zero_and_are_ignored() {
    let mut rng = Rng(29);
    for n in [3, 9, 12] {
        let chain = random_aligned_chain(&mut rng, Convention::Standard, n);
        let dof = chain.dof();
        let mut full = vec![0.0; dof + 3];
        for v in full.iter_mut().take(dof / 2) {
            *v = rng.range(-3.0, 3.0);
        }
        let short = &full[..dof / 2];
        for kernel in supported_kernels() {
            let expect = forward_reference(&chain, &full[..dof], 1.0);
            assert!(chain.forward_with(kernel, short, 1.0).max_abs_diff(&expect) <= FAST_PATH_TOL);
            assert!(chain.forward_with(kernel, &full, 1.0).max_abs_diff(&expect) <= FAST_PATH_TOL);
            let (t, frames) = chain.forward_frames_with(kernel, short, 1.0);
            assert!(t.max_abs_diff(&expect) <= FAST_PATH_TOL);
            assert_eq!(frames.len(), chain.rows() + 1);
            // A slice too short gets the first frames only; the pose is still right.
            let mut two = [Transform::IDENTITY; 2];
            let t2 = chain.forward_frames_to_with(kernel, short, 1.0, &mut two);
            assert_eq!((t2, two), (t, [frames[0], frames[1]]));
        }
    }
}

#[test]
fn degrees_scale_applies_to_revolute_joints_only() {
    let mut rng = Rng(11);
    let chain = random_chain(&mut rng, Convention::Standard, 5); // R R R P F
    let q_deg = [30.0, -45.0, 90.0, 0.25];
    let k = std::f64::consts::PI / 180.0;
    let q_rad = [30.0 * k, -45.0 * k, 90.0 * k, 0.25];
    let a = chain.forward(&q_deg, k);
    let b = chain.forward(&q_rad, 1.0);
    assert!(a.max_abs_diff(&b) <= 1e-15);
}

#[test]
fn huge_joint_values_still_match_the_plain_product() {
    let mut rng = Rng(3);
    let chain = random_chain(&mut rng, Convention::Modified, 6);
    for x in [1e5, 1e6, -1e9, 123456.789] {
        let q = [x, 0.5, -x, 0.1, 2.0];
        let e = chain
            .forward(&q, 1.0)
            .max_abs_diff(&forward_reference(&chain, &q, 1.0));
        assert!(e <= 1e-9, "q={x}: {e:e}");
        for kernel in supported_kernels() {
            let e = chain
                .forward_with(kernel, &q, 1.0)
                .max_abs_diff(&forward_reference(&chain, &q, 1.0));
            assert!(e <= 1e-9, "q={x} {kernel:?}: {e:e}");
            let (t, _) = chain.forward_frames_with(kernel, &q, 1.0);
            assert!(t.max_abs_diff(&forward_reference(&chain, &q, 1.0)) <= 1e-9);
            // 17 poses: two blocks of 8 (one huge value in each) and a tail.
            let mut out = vec![Transform::IDENTITY; 17];
            let qs: Vec<f64> = q.iter().cycle().take(17 * 5).copied().collect();
            chain.forward_batch_with(kernel, &qs, 1.0, &mut out);
            for t in &out {
                assert!(t.max_abs_diff(&forward_reference(&chain, &q, 1.0)) <= 1e-9);
            }
        }
    }
}

#[test]
fn non_finite_joint_values_give_non_finite_poses_like_the_plain_product() {
    let mut rng = Rng(31);
    let chain = random_chain(&mut rng, Convention::Standard, 6);
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let q = [0.1, bad, 0.3, 0.2, 0.5];
        assert!(!forward_reference(&chain, &q, 1.0).translation[0].is_finite());
        for kernel in supported_kernels() {
            assert!(
                !chain.forward_with(kernel, &q, 1.0).translation[0].is_finite(),
                "{kernel:?}"
            );
            let mut out = vec![Transform::IDENTITY; 9];
            let qs: Vec<f64> = q.iter().cycle().take(9 * 5).copied().collect();
            chain.forward_batch_with(kernel, &qs, 1.0, &mut out);
            assert!(
                out.iter().all(|t| !t.translation[0].is_finite()),
                "{kernel:?}"
            );
        }
    }
}

#[test]
fn transform_inverse_and_conversions_agree() {
    let mut rng = Rng(5);
    for _ in 0..1000 {
        let rpy = [
            rng.range(-3.1, 3.1),
            rng.range(-1.5, 1.5),
            rng.range(-3.1, 3.1),
        ];
        let t = Transform::from_translation_rpy([rng.range(-2.0, 2.0), 0.3, -0.7], rpy);
        let back = t.rpy();
        for i in 0..3 {
            assert!((back[i] - rpy[i]).abs() < 1e-9, "rpy {rpy:?} -> {back:?}");
        }
        let q = t.quaternion();
        assert!(q[0] >= 0.0);
        let tq = Transform::from_translation_quaternion(t.translation, q).expect("non-zero");
        assert!(tq.max_abs_diff(&t) < 1e-12);
        let id = t * t.inverse();
        assert!(id.max_abs_diff(&Transform::IDENTITY) < 1e-12);
    }
}

/// The packed batch writes, bit for bit, the numbers of the transforms the
/// batch gives on the same kernel (the transforms are checked against the
/// plain product above): whole blocks, the tail, blocks redone by the exact
/// path (one huge angle), a chain without joints, and a partial trailing
/// pose in `out` left alone.
#[test]
fn packed_batches_hold_the_batch_poses_numbers_on_every_kernel() {
    let mut rng = Rng(41);
    for case in 0..60 {
        let convention = [Convention::Standard, Convention::Modified][case % 2];
        let chain = random_aligned_chain(&mut rng, convention, case % 9);
        let dof = chain.dof();
        let count = [0, 1, 7, 8, 9, 16, 17, 37][case % 8];
        let mut qs: Vec<f64> = (0..count * dof).map(|_| rng.range(-6.0, 6.0)).collect();
        if case % 3 == 0 && !qs.is_empty() {
            qs[0] = 1e7; // beyond the polynomial's range: the block is redone
        }
        let rows = qs.len().checked_div(dof).unwrap_or(count);
        for kernel in supported_kernels() {
            let mut poses = vec![Transform::IDENTITY; rows];
            chain.forward_batch_with(kernel, &qs, 1.0, &mut poses);
            for layout in [PackedLayout::Matrix12, PackedLayout::Position] {
                let stride = layout.stride();
                // One partial pose more than the configurations fill: untouched.
                let mut packed = vec![f64::NAN; rows * stride + stride - 1];
                chain.forward_batch_packed_with(kernel, &qs, 1.0, layout, &mut packed);
                let expected: Vec<f64> = poses
                    .iter()
                    .flat_map(|t| match layout {
                        PackedLayout::Matrix12 => t.matrix()[..3].concat(),
                        PackedLayout::Position => t.translation.to_vec(),
                    })
                    .collect();
                let (whole, partial) = packed.split_at(rows * stride);
                let same = whole
                    .iter()
                    .zip(&expected)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "case {case} {kernel:?} {layout:?}");
                assert!(partial.iter().all(|x| x.is_nan()), "case {case} {kernel:?}");
            }
        }
        // Into a new vector (best kernel): asked for 3 poses more than the
        // configurations hold, it holds as many poses as there are (a chain
        // without joints: as many as asked), the same numbers.
        for layout in [PackedLayout::Matrix12, PackedLayout::Position] {
            let stride = layout.stride();
            let fresh = chain.forward_batch_packed_vec(&qs, rows + 3, 1.0, layout);
            let poses = if dof == 0 { rows + 3 } else { rows };
            let mut packed = vec![0.0; poses * stride];
            chain.forward_batch_packed(&qs, 1.0, layout, &mut packed);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&fresh), bits(&packed), "case {case} {layout:?}");
        }
    }
}
