//! Analytic IK speed: every principal solution of one target (checked by FK,
//! `AnalyticIk::solve_principal`, no allocation) and the full answer with
//! the 2π copies inside the shipped limits sorted by distance to a seed
//! (`AnalyticIk::solve`), over 64 targets (FK of random in-limit
//! configurations) of PUMA 560, ABB IRB 140 and KUKA KR 5 (spherical wrist)
//! and UR5e, UR10e (three parallel axes). Criterion reports the time per
//! target. Then, robust to a busy machine, the best mean per target over
//! 300 passes through the 64 targets (all principal solutions), printed as
//! `best-of analytic_ik/ROBOT: … µs per target (… solutions per target)`.
//! Run with `cargo bench -p kinserve-kinematics --bench analytic_ik`.

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use criterion::{Criterion, criterion_group};
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

/// Best mean time per target over 300 passes (a pass: every target once).
fn best_of() {
    for name in ["puma560", "abb_irb140", "kuka_kr5", "ur5e", "ur10e"] {
        let r = robot(name);
        let ik = AnalyticIk::new(r.chain()).expect("classified");
        let targets = targets(&r);
        let mut out = Principal::new();
        let mut best = f64::INFINITY;
        let mut found = 0;
        for _ in 0..300 {
            found = 0;
            let start = Instant::now();
            for t in &targets {
                ik.solve_principal(black_box(t), &[0.0; 6], 1e-9, &mut out);
                found += out.len();
            }
            best = best.min(start.elapsed().as_secs_f64() / targets.len() as f64);
        }
        println!(
            "best-of analytic_ik/{name}: {:.2} µs per target ({:.2} solutions per target)",
            best * 1e6,
            found as f64 / targets.len() as f64
        );
    }
}

criterion_group!(benches, analytic);

fn main() {
    benches();
    best_of();
    Criterion::default().configure_from_args().final_summary();
}
