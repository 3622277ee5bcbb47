//! kinserve's side of `scripts/bench-peers.sh` (the Pinocchio C++ comparison):
//! exports a robot's DH table, base, tool, configurations and kinserve's poses
//! as plain text for `scripts/peers/pinocchio_fk.cpp` (which checks its own
//! poses against them before timing), and times the core FK on the same
//! configurations in-process: single pose, batch per pose, and every frame.
//!
//! ```text
//! cargo run --release -p kinserve-kinematics --example peer_fk -- export DIR ROBOT...
//! cargo run --release -p kinserve-kinematics --example peer_fk -- time DIR ROBOT...
//! ```
//!
//! `export` writes `DIR/ROBOT.txt` (format below; lengths in the model's unit,
//! angles in rad); `time` reads the configurations back from it and prints
//! `kinserve ROBOT single|batch|frames NS` lines (ns per pose, median of
//! [`SAMPLES`] samples). File format, one item per line, numbers `%.17g`:
//!
//! ```text
//! robot NAME
//! convention standard|modified
//! rows N              then N lines: R|P|F a alpha d theta
//! base 12 numbers     rotation rows then translation (world <- frame 0)
//! tool 12 numbers     (flange <- tool; identity when the model has none)
//! configs N DOF       then N lines of DOF joint values (rad or length unit)
//! poses N             then N lines of 12 numbers: kinserve's tool pose per configuration
//! frames K ROWS+1     then K lines of (ROWS+1)*12 numbers: every frame of the first K configurations
//! ```

use std::fmt::Write as _;
use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};

use kinserve_kinematics::{Convention, JointKind, Transform};
use kinserve_model::{Robot, load_robot_file};

/// Configurations per robot (the batch size and the check set).
const CONFIGS: usize = 10_000;
/// Configurations whose every frame is exported.
const FRAME_CHECKS: usize = 16;
/// Configurations the single-pose loops cycle through.
const SINGLE_SET: usize = 16;
/// Time per sample.
const SAMPLE: Duration = Duration::from_millis(40);
/// Samples per figure (the median is printed).
const SAMPLES: usize = 7;

fn robot(name: &str) -> Robot {
    let path = format!("{}/../../robots/{name}.json", env!("CARGO_MANIFEST_DIR"));
    load_robot_file(Path::new(&path)).unwrap_or_else(|e| panic!("robot {name}: {e}"))
}

/// Deterministic joint values: inside each joint's limits where it has them,
/// else within ±π (revolute) or ±0.5 (prismatic), in internal units.
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
            let (lo, hi) = match (joint.limits, joint.kind) {
                (Some(l), _) => l,
                (None, JointKind::Revolute) => (-std::f64::consts::PI, std::f64::consts::PI),
                (None, _) => (-0.5, 0.5),
            };
            q.push(lo + (hi - lo) * unit());
        }
    }
    q
}

fn push_transform(out: &mut String, t: &Transform) {
    for row in &t.rotation {
        for v in row {
            write!(out, " {v:e}").unwrap();
        }
    }
    for v in &t.translation {
        write!(out, " {v:e}").unwrap();
    }
}

fn export(dir: &Path, name: &str) {
    let robot = robot(name);
    let chain = robot.chain();
    let mut s = String::new();
    writeln!(s, "robot {name}").unwrap();
    let conv = match chain.convention() {
        Convention::Standard => "standard",
        Convention::Modified => "modified",
    };
    writeln!(s, "convention {conv}\nrows {}", chain.rows()).unwrap();
    for r in chain.dh_rows() {
        let k = match r.kind {
            JointKind::Revolute => "R",
            JointKind::Prismatic => "P",
            JointKind::Fixed => "F",
        };
        writeln!(s, "{k} {:e} {:e} {:e} {:e}", r.a, r.alpha, r.d, r.theta).unwrap();
    }
    s.push_str("base");
    push_transform(&mut s, chain.base());
    s.push_str("\ntool");
    push_transform(&mut s, chain.tool().unwrap_or(&Transform::IDENTITY));
    let dof = chain.dof();
    let q = configurations(&robot, CONFIGS);
    writeln!(s, "\nconfigs {CONFIGS} {dof}").unwrap();
    for c in q.chunks(dof) {
        let line: Vec<String> = c.iter().map(|v| format!("{v:e}")).collect();
        writeln!(s, "{}", line.join(" ")).unwrap();
    }
    writeln!(s, "poses {CONFIGS}").unwrap();
    for c in q.chunks(dof) {
        push_transform(&mut s, &chain.forward(c, 1.0));
        s.push('\n');
    }
    writeln!(s, "frames {FRAME_CHECKS} {}", chain.rows() + 1).unwrap();
    for c in q.chunks(dof).take(FRAME_CHECKS) {
        let (_, frames) = chain.forward_frames(c, 1.0);
        for f in &frames {
            push_transform(&mut s, f);
        }
        s.push('\n');
    }
    let path = dir.join(format!("{name}.txt"));
    std::fs::write(&path, s).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// Reads the configurations back from an exported file (so both sides time
/// the very same numbers).
fn read_configs(dir: &Path, name: &str) -> (usize, Vec<f64>) {
    let path = dir.join(format!("{name}.txt"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines().skip_while(|l| !l.starts_with("configs "));
    let head: Vec<usize> = lines.next().expect("configs line")[8..]
        .split(' ')
        .map(|v| v.parse().expect("count"))
        .collect();
    let (n, dof) = (head[0], head[1]);
    let q = lines
        .take(n)
        .flat_map(|l| l.split(' ').map(|v| v.parse::<f64>().expect("number")))
        .collect::<Vec<_>>();
    assert_eq!(q.len(), n * dof, "{name}: configuration count");
    (dof, q)
}

/// Median ns per unit of work of `f` (`per_call` units per call).
fn time_ns(per_call: usize, mut f: impl FnMut()) -> f64 {
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

fn time(dir: &Path, name: &str) {
    let robot = robot(name);
    let chain = robot.chain();
    let (dof, q) = read_configs(dir, name);
    let n = q.len() / dof;
    let set: Vec<&[f64]> = q.chunks(dof).take(SINGLE_SET).collect();
    let mut i = 0usize;
    let single = time_ns(1, || {
        i = (i + 1) % SINGLE_SET;
        black_box(chain.forward(black_box(set[i]), 1.0));
    });
    let mut out = vec![Transform::IDENTITY; n];
    let batch = time_ns(n, || {
        chain.forward_batch(black_box(&q), 1.0, &mut out);
        black_box(&out);
    });
    let mut frames = vec![Transform::IDENTITY; chain.rows() + 1];
    let all = time_ns(1, || {
        i = (i + 1) % SINGLE_SET;
        black_box(chain.forward_frames_to(black_box(set[i]), 1.0, &mut frames));
        black_box(&frames);
    });
    println!("kinserve {name} single {single:.2}");
    println!("kinserve {name} batch {batch:.2}");
    println!("kinserve {name} frames {all:.2}");
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: peer_fk export|time DIR ROBOT...";
    let (mode, dir, robots) = match args.as_slice() {
        [m, d, r @ ..] if !r.is_empty() => (m.as_str(), Path::new(d), r),
        _ => {
            eprintln!("{usage}");
            std::process::exit(2);
        }
    };
    for name in robots {
        match mode {
            "export" => export(dir, name),
            "time" => time(dir, name),
            _ => {
                eprintln!("{usage}");
                std::process::exit(2);
            }
        }
    }
}
