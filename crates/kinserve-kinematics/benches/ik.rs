//! Velocity and inverse kinematics speed: the geometric Jacobian against FK
//! with every frame (criterion), and IK solve times per solve — median, p90,
//! p99 and convergence rate over 500 random in-limit configurations of each
//! shipped 6- and 7-joint arm, unseeded and seeded (tracking a moving target
//! from the previous answer). Run with `cargo bench -p kinserve-kinematics --bench ik`.

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use criterion::{Criterion, criterion_group};
use kinserve_kinematics::ik::{IkOptions, IkSolver};
use kinserve_kinematics::{JacobianFrame, JointKind, Transform};
use kinserve_model::{Robot, load_robot_file};

fn robot(name: &str) -> Robot {
    let path = format!("{}/../../robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
    load_robot_file(Path::new(&path)).expect("robot file loads")
}

/// Deterministic numbers in [0, 1) (xorshift).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A random configuration within the limits (unlimited: ±π, prismatic ±0.5).
fn config(r: &Robot, rng: &mut Rng) -> Vec<f64> {
    r.joints()
        .iter()
        .map(|j| match (j.limits, j.kind) {
            (Some((lo, hi)), _) => lo + (hi - lo) * rng.next(),
            (None, JointKind::Prismatic) => rng.next() - 0.5,
            (None, _) => std::f64::consts::PI * (2.0 * rng.next() - 1.0),
        })
        .collect()
}

fn limits(r: &Robot) -> Vec<Option<(f64, f64)>> {
    r.joints().iter().map(|j| j.limits).collect()
}

fn jacobian(c: &mut Criterion) {
    for name in ["puma560", "panda"] {
        let r = robot(name);
        let chain = r.chain();
        let q = config(&r, &mut Rng(0x2545_F491_4F6C_DD1D));
        let mut cols = vec![[0.0; 6]; r.dof()];
        let mut g = c.benchmark_group(format!("jacobian/{name}"));
        g.bench_function("frames_fk", |b| {
            b.iter(|| {
                chain.forward_frames_into(black_box(&q), 1.0, &mut |t| {
                    black_box(t);
                })
            })
        });
        g.bench_function("jacobian_base", |b| {
            b.iter(|| chain.jacobian_into(black_box(&q), 1.0, JacobianFrame::Base, &mut cols))
        });
        g.bench_function("jacobian_tool", |b| {
            b.iter(|| chain.jacobian_into(black_box(&q), 1.0, JacobianFrame::Tool, &mut cols))
        });
        let (_, jac) = chain.jacobian(&q, 1.0, JacobianFrame::Base);
        g.bench_function("measures_svd", |b| b.iter(|| black_box(&jac).measures()));
        g.finish();
    }
}

fn ik_criterion(c: &mut Criterion) {
    let r = robot("puma560");
    let solver = IkSolver::new(r.chain(), &limits(&r));
    let mut rng = Rng(0x1234_5678_9ABC_DEF1);
    let targets: Vec<Transform> = (0..64)
        .map(|_| r.chain().forward(&config(&r, &mut rng), 1.0))
        .collect();
    let opts = IkOptions::default();
    let mut g = c.benchmark_group("ik/puma560");
    let mut i = 0;
    g.bench_function("unseeded_mean_over_64_targets", |b| {
        b.iter(|| {
            i = (i + 1) % targets.len();
            solver.solve(black_box(&targets[i]), None, &opts)
        })
    });
    g.finish();
}

/// Median, p90 and p99 of `times` (µs).
fn quantiles(times: &mut [f64]) -> (f64, f64, f64) {
    times.sort_by(f64::total_cmp);
    let at = |p: f64| times[((times.len() - 1) as f64 * p).round() as usize];
    (at(0.5), at(0.9), at(0.99))
}

/// Per-solve timings over 500 configurations per arm, unseeded and tracking.
fn ik_stats() {
    const N: usize = 500;
    println!("\nIK per solve, {N} random in-limit configurations per arm (µs):");
    println!(
        "| arm | dof | unseeded converged | median | p90 | p99 | tracking converged | median | p90 | p99 |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    let arms = [
        "abb_irb140",
        "cylindrical_wrist_6dof",
        "inline_6dof",
        "kuka_kr5",
        "puma560",
        "stanford",
        "ur3e",
        "ur5",
        "ur5e",
        "ur10e",
        "ur20",
        "panda",
        "kinova_gen3",
    ];
    let opts = IkOptions::default();
    for name in arms {
        let r = robot(name);
        let solver = IkSolver::new(r.chain(), &limits(&r));
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        let (mut cold, mut cold_ok) = (Vec::with_capacity(N), 0);
        for _ in 0..N {
            let target = r.chain().forward(&config(&r, &mut rng), 1.0);
            let t0 = Instant::now();
            let s = solver.solve(&target, None, &opts);
            cold.push(t0.elapsed().as_secs_f64() * 1e6);
            cold_ok += usize::from(s.converged);
        }
        // Tracking: a smooth joint-space path, 0.2 sin(0.005 k + i) about a
        // random start (at most 1 mrad per joint per step, a 1 kHz loop at
        // 1 rad/s; kept within the limits), each solve seeded with the previous answer.
        let q0 = config(&r, &mut rng);
        let mut seed = q0.clone();
        let (mut warm, mut warm_ok) = (Vec::with_capacity(N), 0);
        for k in 0..N {
            let q: Vec<f64> = q0
                .iter()
                .zip(r.joints())
                .enumerate()
                .map(|(i, (x, j))| {
                    let v = x + 0.2 * (0.005 * k as f64 + i as f64).sin();
                    j.limits.map_or(v, |(lo, hi)| v.clamp(lo, hi))
                })
                .collect();
            let target = r.chain().forward(&q, 1.0);
            let t0 = Instant::now();
            let s = solver.solve(&target, Some(&seed), &opts);
            warm.push(t0.elapsed().as_secs_f64() * 1e6);
            warm_ok += usize::from(s.converged);
            seed = s.q;
        }
        let (c50, c90, c99) = quantiles(&mut cold);
        let (w50, w90, w99) = quantiles(&mut warm);
        println!(
            "| {name} | {} | {:.1} % | {c50:.1} | {c90:.1} | {c99:.1} | {:.1} % | {w50:.2} | {w90:.2} | {w99:.2} |",
            r.dof(),
            100.0 * cold_ok as f64 / N as f64,
            100.0 * warm_ok as f64 / N as f64,
        );
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(50).measurement_time(std::time::Duration::from_secs(3));
    targets = jacobian, ik_criterion
}

fn main() {
    benches();
    ik_stats();
    Criterion::default().configure_from_args().final_summary();
}
