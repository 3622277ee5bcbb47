//! `kinserve bench`: how fast FK of one model runs on this machine — single
//! pose, single pose with every frame, and a batch — with the kernel that ran,
//! so users with their own models get the figure without the repository or
//! criterion. Timing is `std::time::Instant` over calibrated loops; each figure
//! is the median of several samples (the machine may be busy).
//!
//! Owns the `bench` subcommand only; depends on the model and kinematics
//! crates and on [`crate::config::BenchArgs`]. Nothing here runs in the server.

use std::hint::black_box;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::config::{BenchArgs, BenchKernel};
use crate::kinematics::{Kernel, Transform};
use crate::model::Robot;

/// Time per sample; several samples per figure.
const SAMPLE: Duration = Duration::from_millis(40);
/// Samples per figure (the median is reported).
const SAMPLES: usize = 9;

/// What `--json` prints (times in ns).
#[derive(Debug, Serialize)]
struct Report {
    robot: String,
    simd: &'static str,
    single_ns: f64,
    frames_ns: f64,
    batch_ns_per_pose: f64,
}

/// Runs `kinserve bench` on `robot` (loaded by the CLI's one robot loader)
/// and returns the exit code.
pub fn run(robot: &Robot, args: &BenchArgs) -> ExitCode {
    let kernels = match kernels(args.kernel) {
        Ok(k) => k,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::FAILURE;
        }
    };
    for kernel in kernels {
        let report = measure(robot, args.batch, kernel);
        if args.json {
            match serde_json::to_string(&report) {
                Ok(s) => println!("{s}"),
                Err(e) => {
                    eprintln!("cannot print the result: {e}");
                    return ExitCode::FAILURE;
                }
            }
        } else {
            print_table(robot, &report, args.batch);
        }
    }
    ExitCode::SUCCESS
}

/// The kernels `--kernel` asks for, or why this CPU cannot run the one asked for.
fn kernels(choice: BenchKernel) -> Result<Vec<Kernel>, String> {
    let supported: Vec<Kernel> = Kernel::ALL
        .into_iter()
        .filter(|k| k.is_supported())
        .collect();
    match choice {
        BenchKernel::Best => Ok(vec![Kernel::best()]),
        BenchKernel::All => Ok(supported),
        BenchKernel::One(k) if k.is_supported() => Ok(vec![k]),
        BenchKernel::One(k) => Err(format!(
            "this CPU cannot run the {} kernel; it runs: {}",
            k.name(),
            supported
                .iter()
                .map(|k| k.name())
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// Deterministic joint values for `count` configurations: inside each joint's
/// limits where it has them, else within ±1 (rad or length unit).
fn configurations(robot: &Robot, count: usize) -> Vec<f64> {
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut unit = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut q = Vec::with_capacity(count * robot.dof());
    for _ in 0..count {
        for joint in robot.joints() {
            let (lo, hi) = joint.limits.unwrap_or((-1.0, 1.0));
            q.push(lo + (hi - lo) * unit());
        }
    }
    q
}

/// Median ns per call of `f`, which does `per_call` units of work (ns per unit).
fn time_ns(per_call: usize, mut f: impl FnMut()) -> f64 {
    // Calibrate: how many calls fill one sample.
    let mut calls = 1usize;
    loop {
        let t = Instant::now();
        for _ in 0..calls {
            f();
        }
        if t.elapsed() >= SAMPLE / 4 || calls >= 1 << 30 {
            break;
        }
        calls *= 2;
    }
    let calls = calls * 4;
    let mut samples: Vec<f64> = (0..SAMPLES)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..calls {
                f();
            }
            t.elapsed().as_nanos() as f64 / (calls * per_call) as f64
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    samples[SAMPLES / 2]
}

/// The three figures on `kernel` (supported by this CPU).
fn measure(robot: &Robot, batch: usize, kernel: Kernel) -> Report {
    let chain = robot.chain();
    let one = configurations(robot, 1);
    let many = configurations(robot, batch);
    let mut out = vec![Transform::IDENTITY; batch];
    let single_ns = time_ns(1, || {
        black_box(chain.forward_with(kernel, black_box(&one), 1.0));
    });
    let frames_ns = time_ns(1, || {
        black_box(
            chain.forward_frames_into_with(kernel, black_box(&one), 1.0, &mut |t| {
                black_box(t);
            }),
        );
    });
    let batch_ns_per_pose = time_ns(batch, || {
        chain.forward_batch_with(kernel, black_box(&many), 1.0, &mut out);
        black_box(&out);
    });
    Report {
        robot: robot.name().to_string(),
        simd: kernel.name(),
        single_ns,
        frames_ns,
        batch_ns_per_pose,
    }
}

fn print_table(robot: &Robot, r: &Report, batch: usize) {
    let chain = robot.chain();
    println!(
        "{}: {} joints, {} DH rows, kernel {} (median of {SAMPLES} samples)",
        r.robot,
        chain.dof(),
        chain.rows(),
        r.simd
    );
    println!("  single pose                {:8.1} ns", r.single_ns);
    println!(
        "  single pose, {:>2} frames     {:8.1} ns",
        chain.rows() + 1,
        r.frames_ns
    );
    println!(
        "  batch of {batch:<10}        {:8.1} ns/pose",
        r.batch_ns_per_pose
    );
}
