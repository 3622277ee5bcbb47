//! Best-of-many FK timings on a shared machine: each figure is the fastest of
//! 300 short samples (2,000 single poses or one batch of 10,000), so other
//! processes on the same cores inflate it far less than a mean does. Also
//! checks every kernel against the plain product. Companion to
//! `cargo bench -p kinserve-kinematics --bench fk` (criterion, means); see BENCHMARKS.md.
//!
//! Run: `cargo run --release -p kinserve-kinematics --example fk_min`

use kinserve_kinematics::{Chain, Convention, DhRow, JointKind, Kernel, Transform, link_transform};
use std::hint::black_box;
use std::time::Instant;

/// A standard-DH row with the twist in degrees.
fn r(kind: JointKind, a: f64, alpha_deg: f64, d: f64) -> DhRow {
    DhRow {
        kind,
        a,
        alpha: alpha_deg.to_radians(),
        d,
        theta: 0.0,
    }
}

/// PUMA 560, UR5e and Panda as in `robots/` (twists in rad, as loaded).
fn chains() -> Vec<(&'static str, Chain)> {
    use JointKind::*;
    let puma = vec![
        r(Revolute, 0.0, 90.0, 0.67183),
        r(Revolute, 0.4318, 0.0, 0.0),
        r(Revolute, 0.0203, -90.0, 0.15005),
        r(Revolute, 0.0, 90.0, 0.4318),
        r(Revolute, 0.0, -90.0, 0.0),
        r(Revolute, 0.0, 0.0, 0.0),
    ];
    let ur5e = vec![
        r(Revolute, 0.0, 90.0, 0.1625),
        r(Revolute, -0.425, 0.0, 0.0),
        r(Revolute, -0.3922, 0.0, 0.0),
        r(Revolute, 0.0, 90.0, 0.1333),
        r(Revolute, 0.0, -90.0, 0.0997),
        r(Revolute, 0.0, 0.0, 0.0996),
    ];
    let h = std::f64::consts::FRAC_PI_2;
    let pr = |a: f64, al: f64, d: f64, k| DhRow {
        kind: k,
        a,
        alpha: al,
        d,
        theta: 0.0,
    };
    let panda = vec![
        pr(0.0, 0.0, 0.333, Revolute),
        pr(0.0, -h, 0.0, Revolute),
        pr(0.0, h, 0.316, Revolute),
        pr(0.0825, h, 0.0, Revolute),
        pr(-0.0825, -h, 0.384, Revolute),
        pr(0.0, h, 0.0, Revolute),
        pr(0.088, h, 0.0, Revolute),
        pr(0.0, 0.0, 0.107, Fixed),
    ];
    vec![
        (
            "puma560",
            Chain::new(Convention::Standard, &puma, Transform::IDENTITY, None),
        ),
        (
            "ur5e",
            Chain::new(Convention::Standard, &ur5e, Transform::IDENTITY, None),
        ),
        (
            "panda",
            Chain::new(Convention::Modified, &panda, Transform::IDENTITY, None),
        ),
    ]
}

/// The plain product of textbook link matrices.
fn reference(chain: &Chain, q: &[f64]) -> Transform {
    let mut t = *chain.base();
    let mut qi = q.iter();
    for row in chain.dh_rows() {
        let qj = match row.kind {
            JointKind::Fixed => 0.0,
            _ => *qi.next().unwrap(),
        };
        t = t * link_transform(chain.convention(), &row, qj);
    }
    match chain.tool() {
        Some(tool) => t * *tool,
        None => t,
    }
}

/// Deterministic joint values in [-3, 3) rad.
fn configs(n: usize, dof: usize) -> Vec<f64> {
    let mut s = 0x2545_F491_4F6C_DD1Du64;
    (0..n * dof)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 * 6.0 - 3.0
        })
        .collect()
}

/// Fastest of 300 samples of `iters` calls, in ns per call.
fn time<F: FnMut()>(iters: usize, mut f: F) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..300 {
        let t = Instant::now();
        for _ in 0..iters {
            f();
        }
        best = best.min(t.elapsed().as_nanos() as f64 / iters as f64);
    }
    best
}

fn main() {
    for (name, chain) in chains() {
        let dof = chain.dof();
        let n = 10_000;
        let qs = configs(n, dof);
        for k in Kernel::ALL {
            if !k.is_supported() {
                continue;
            }
            let mut out = vec![Transform::IDENTITY; n];
            chain.forward_batch_with(k, &qs, 1.0, &mut out);
            let mut worst: f64 = 0.0;
            for i in 0..n {
                let q = &qs[i * dof..(i + 1) * dof];
                let rf = reference(&chain, q);
                worst = worst
                    .max(out[i].max_abs_diff(&rf))
                    .max(chain.forward_with(k, q, 1.0).max_abs_diff(&rf))
                    .max(chain.forward_frames_with(k, q, 1.0).0.max_abs_diff(&rf));
            }
            let q = &qs[..dof];
            let single = time(2000, || {
                black_box(chain.forward_with(k, black_box(q), 1.0));
            });
            let frames = time(2000, || {
                black_box(
                    chain.forward_frames_into_with(k, black_box(q), 1.0, &mut |t| {
                        black_box(t);
                    }),
                );
            });
            let batch = time(1, || {
                chain.forward_batch_with(k, black_box(&qs), 1.0, &mut out);
                black_box(&out);
            }) / n as f64;
            println!(
                "{name:8} {:9} aligned {}/{dof} err {worst:.1e}  single {single:6.1} ns  frames {frames:6.1} ns  batch {batch:5.1} ns/pose",
                k.name(),
                chain.aligned_steps()
            );
        }
        let q = &qs[..dof];
        let plain = time(500, || {
            black_box(reference(&chain, black_box(q)));
        });
        println!("{name:8} plain {plain:.1} ns");
    }
}
