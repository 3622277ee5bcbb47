//! FK speed: single 6-DoF pose (fast path, portable fallback, plain product)
//! and a batch of 10,000 poses. Run with `cargo bench --bench fk`.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kinserve::kinematics::{Kernel, Transform};
use kinserve::model::load_robot_file;
use kinserve_testkit::forward_reference;

fn robot(name: &str) -> kinserve::model::Robot {
    let path = format!("{}/robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
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

fn single(c: &mut Criterion) {
    for name in ["puma560", "panda"] {
        let r = robot(name);
        let chain = r.chain();
        let q = configs(1, r.dof());
        let mut g = c.benchmark_group(format!("single/{name}"));
        g.bench_function("fast", |b| b.iter(|| chain.forward(black_box(&q), 1.0)));
        g.bench_function("frames", |b| {
            b.iter(|| {
                chain.forward_frames_into(black_box(&q), 1.0, &mut |t| {
                    black_box(t);
                })
            })
        });
        g.bench_function("plain_product", |b| {
            b.iter(|| forward_reference(chain, black_box(&q), 1.0))
        });
        g.finish();
    }
}

fn batch(c: &mut Criterion) {
    const N: usize = 10_000;
    for name in ["puma560", "panda"] {
        let r = robot(name);
        let chain = r.chain();
        let q = configs(N, r.dof());
        let mut out = vec![Transform::IDENTITY; N];
        let mut g = c.benchmark_group(format!("batch10k/{name}"));
        g.throughput(Throughput::Elements(N as u64));
        g.bench_function("simd", |b| {
            b.iter(|| chain.forward_batch(black_box(&q), 1.0, &mut out))
        });
        g.bench_function("portable", |b| {
            b.iter(|| chain.forward_batch_with(Kernel::Portable, black_box(&q), 1.0, &mut out))
        });
        g.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(50).measurement_time(std::time::Duration::from_secs(3));
    targets = single, batch
}
criterion_main!(benches);
