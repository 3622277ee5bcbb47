//! The fast FK paths against the plain product of link matrices, and the
//! vectorised sine/cosine against `std`.

use kinserve::kinematics::sincos::{POLY_LIMIT, sincos_slice, sincos_slice_with};
use kinserve::kinematics::{Chain, Convention, DhRow, JointKind, Kernel, Transform};
use kinserve_testkit::{forward_reference, supported_kernels};

/// Deterministic pseudo-random numbers in [0, 1) (SplitMix64).
pub struct Rng(pub u64);
impl Rng {
    pub fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

/// Absolute error bound of the polynomial sine/cosine against `std`, for |x| ≤ 1e5 rad.
/// Cody–Waite reduction leaves ~|x|·2^-53·(π/2 split error) and the polynomial ~1 ulp.
const SINCOS_ABS_BOUND: f64 = 4e-16;

#[test]
fn sincos_matches_std_over_range() {
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
    let mut s = vec![0.0; xs.len()];
    let mut c = vec![0.0; xs.len()];
    for simd in [true, false] {
        if simd {
            sincos_slice(&xs, &mut s, &mut c);
        } else {
            sincos_slice_with(Kernel::Portable, &xs, &mut s, &mut c);
        }
        let mut worst: f64 = 0.0;
        for i in 0..xs.len() {
            let (es, ec) = xs[i].sin_cos();
            worst = worst.max((s[i] - es).abs()).max((c[i] - ec).abs());
        }
        assert!(
            worst <= SINCOS_ABS_BOUND,
            "simd={simd}: max abs error {worst:e} > {SINCOS_ABS_BOUND:e}"
        );
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
        for n in [1, 2, 5, 6, 7, 12, 30] {
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
                    let (framed, frames) = chain.forward_frames(q, 1.0);
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
        let mut out = vec![Transform::IDENTITY; 8];
        let qs: Vec<f64> = q.iter().cycle().take(8 * 5).copied().collect();
        chain.forward_batch(&qs, 1.0, &mut out);
        assert!(out[7].max_abs_diff(&forward_reference(&chain, &q, 1.0)) <= 1e-9);
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
