//! Analytic IK speed: every principal solution of one target (checked by FK,
//! `AnalyticIk::solve_principal`, no allocation) and the full answer with
//! the 2π copies inside the shipped limits sorted by distance to a seed
//! (`AnalyticIk::solve`), over 64 targets (FK of random in-limit
//! configurations) of PUMA 560, ABB IRB 140 and KUKA KR 5 (spherical wrist)
//! and UR5e, UR10e (three parallel axes). Criterion reports the time per
//! target. Run with `cargo bench -p kinserve-kinematics --bench analytic_ik`.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use kinserve_kinematics::Transform;
use kinserve_kinematics::analytic_ik::{AnalyticIk, AnalyticOptions, Principal};
use kinserve_model::{Robot, load_robot_file};

fn robot(name: &str) -> Robot {
    let path = format!("{}/../../robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
    load_robot_file(Path::new(&path)).expect("robot file loads")
}

/// 64 targets: FK of deterministic in-limit configurations (xorshift).
fn targets(r: &Robot) -> Vec<Transform> {
    let mut s = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..64)
        .map(|_| {
            let q: Vec<f64> = r
                .joints()
                .iter()
                .map(|j| {
                    let (lo, hi) = j.limits.unwrap_or((-3.0, 3.0));
                    lo + (hi - lo) * next()
                })
                .collect();
            r.chain().forward(&q, 1.0)
        })
        .collect()
}

fn analytic(c: &mut Criterion) {
    for name in ["puma560", "abb_irb140", "kuka_kr5", "ur5e", "ur10e"] {
        let r = robot(name);
        let ik = AnalyticIk::new(r.chain()).expect("classified");
        let targets = targets(&r);
        let limits: Vec<_> = r.joints().iter().map(|j| j.limits).collect();
        let mut g = c.benchmark_group(format!("analytic_ik/{name}"));
        let mut out = Principal::new();
        let mut i = 0;
        g.bench_function("all_principal", |b| {
            b.iter(|| {
                i = (i + 1) % targets.len();
                ik.solve_principal(black_box(&targets[i]), &[0.0; 6], 1e-9, &mut out);
                out.len()
            })
        });
        let seed = [0.1; 6];
        let opts = AnalyticOptions::default();
        g.bench_function("all_with_copies_in_limits", |b| {
            b.iter(|| {
                i = (i + 1) % targets.len();
                ik.solve(black_box(&targets[i]), &limits, Some(&seed), &opts)
                    .solutions
                    .len()
            })
        });
        g.finish();
    }
}

criterion_group!(benches, analytic);
criterion_main!(benches);
