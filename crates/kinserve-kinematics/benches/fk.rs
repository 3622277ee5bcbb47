//! FK speed: single pose (best kernel, each kernel, plain product), single pose
//! with every frame, and a batch of 10,000 poses (best kernel, each kernel), for
//! PUMA 560 and UR5e (6R, standard DH) and Panda (7R + flange, modified DH).
//! Run with `cargo bench -p kinserve-kinematics --bench fk`; ids are `single/ROBOT/...` and
//! `batch10k/ROBOT/...`, where `fast`/`simd` is the kernel `Kernel::best` picks.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kinserve_kinematics::{Kernel, Transform};
use kinserve_model::load_robot_file;
use kinserve_testkit::forward_reference;

fn robot(name: &str) -> kinserve_model::Robot {
    let path = format!("{}/../../robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
    load_robot_file(Path::new(&path)).expect("robot file loads")
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

const ROBOTS: [&str; 3] = ["puma560", "ur5e", "panda"];

/// Every kernel this CPU can run, by name.
fn kernels() -> impl Iterator<Item = Kernel> {
    Kernel::ALL.into_iter().filter(|k| k.is_supported())
}

fn single(c: &mut Criterion) {
    eprintln!("kernel picked at run time: {}", Kernel::best().name());
    for name in ROBOTS {
        let r = robot(name);
        let chain = r.chain();
        let q = configs(1, r.dof());
        let mut g = c.benchmark_group(format!("single/{name}"));
        g.bench_function("fast", |b| b.iter(|| chain.forward(black_box(&q), 1.0)));
        for k in kernels() {
            g.bench_function(k.name(), |b| {
                b.iter(|| chain.forward_with(k, black_box(&q), 1.0))
            });
        }
        g.bench_function("frames", |b| {
            b.iter(|| {
                chain.forward_frames_into(black_box(&q), 1.0, &mut |t| {
                    black_box(t);
                })
            })
        });
        let mut frames = vec![Transform::IDENTITY; chain.rows() + 1];
        g.bench_function("frames_to_slice", |b| {
            b.iter(|| chain.forward_frames_to(black_box(&q), 1.0, &mut frames))
        });
        g.bench_function("plain_product", |b| {
            b.iter(|| forward_reference(chain, black_box(&q), 1.0))
        });
        g.finish();
    }
}

fn batch(c: &mut Criterion) {
    const N: usize = 10_000;
    for name in ROBOTS {
        let r = robot(name);
        let chain = r.chain();
        let q = configs(N, r.dof());
        let mut out = vec![Transform::IDENTITY; N];
        let mut g = c.benchmark_group(format!("batch10k/{name}"));
        g.throughput(Throughput::Elements(N as u64));
        g.bench_function("simd", |b| {
            b.iter(|| chain.forward_batch(black_box(&q), 1.0, &mut out))
        });
        for k in kernels() {
            g.bench_function(k.name(), |b| {
                b.iter(|| chain.forward_batch_with(k, black_box(&q), 1.0, &mut out))
            });
        }
        g.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(50).measurement_time(std::time::Duration::from_secs(3));
    targets = single, batch
}
criterion_main!(benches);
