//! The kinserve side of `scripts/bench-ik-peers.py`: random reachable targets
//! of one robot file (FK of random in-limit configurations, a fixed seed),
//! solved by the numeric solver ([`IkSolver`], no deadline) and, where the arm
//! is classified, the closed form ([`AnalyticIk::solve`], every solution in
//! the limits), each solve timed alone (µs of the thread's CPU time, and wall time). Prints one JSON
//! document: the chain (rows in internal units, base, tool, limits), its URDF
//! (`kinserve_model::to_urdf`, what `kinserve urdf` prints), and per target
//! the configuration, the target (row-major 4×4) and both answers. A summary
//! line per solver goes to stderr.
//!
//! ```text
//! cargo run --release -p kinserve-kinematics --example ik_peers -- \
//!     --robot robots/panda.json [--n 1000] [--from 0] [--to N] [--seed S] [--tolerance 1e-6]
//! ```
//! `--from`/`--to` select a slice of the `n` targets (the same targets for any
//! slice), so a caller can alternate solvers in rounds.

use std::path::Path;
use std::time::Instant;

use kinserve_kinematics::analytic_ik::{AnalyticIk, AnalyticOptions};
use kinserve_kinematics::ik::{IkOptions, IkSolver};
use kinserve_kinematics::{Convention, JointKind, Transform};
use kinserve_model::{Robot, load_robot_file, to_urdf};
use serde_json::{Value, json};

/// Deterministic numbers in [0, 1) (SplitMix64).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

struct Args {
    robot: String,
    n: usize,
    from: usize,
    to: Option<usize>,
    seed: u64,
    tolerance: f64,
}

fn args() -> Args {
    let mut a = Args {
        robot: String::new(),
        n: 1000,
        from: 0,
        to: None,
        seed: 0x1d_2023,
        tolerance: 1e-6,
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let v = it.next().unwrap_or_else(|| panic!("{k} needs a value"));
        match k.as_str() {
            "--robot" => a.robot = v,
            "--n" => a.n = v.parse().expect("--n"),
            "--from" => a.from = v.parse().expect("--from"),
            "--to" => a.to = Some(v.parse().expect("--to")),
            "--seed" => a.seed = v.parse().expect("--seed"),
            "--tolerance" => a.tolerance = v.parse().expect("--tolerance"),
            _ => panic!("unknown argument {k}"),
        }
    }
    assert!(!a.robot.is_empty(), "--robot FILE is required");
    a
}

/// A random configuration within the limits (unlimited revolute: ±π;
/// unlimited prismatic: ±0.5 length units).
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

/// CPU time of this thread, µs (`CLOCK_THREAD_CPUTIME_ID`: time the thread
/// was descheduled on the shared machine does not count).
fn cpu_us() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec for the call to write.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 * 1e6 + ts.tv_nsec as f64 * 1e-3
}

fn flat(t: &Transform) -> Vec<f64> {
    t.matrix().iter().flatten().copied().collect()
}

fn chain_json(r: &Robot) -> Value {
    let c = r.chain();
    let rows: Vec<Value> = c
        .dh_rows()
        .map(|row| {
            let kind = match row.kind {
                JointKind::Revolute => "revolute",
                JointKind::Prismatic => "prismatic",
                JointKind::Fixed => "fixed",
            };
            json!({"kind": kind, "a": row.a, "alpha": row.alpha, "d": row.d, "theta": row.theta})
        })
        .collect();
    let limits: Vec<Value> = r
        .joints()
        .iter()
        .map(|j| j.limits.map_or(Value::Null, |(lo, hi)| json!([lo, hi])))
        .collect();
    json!({
        "name": r.name(),
        "dof": r.dof(),
        "modified": c.convention() == Convention::Modified,
        "rows": rows,
        "base": flat(c.base()),
        "tool": c.tool().map(flat),
        "limits": limits,
        "urdf": to_urdf(r),
        "analytic_class": AnalyticIk::new(c).ok().map(|a| a.class().name()),
    })
}

/// Mean, median and p99 of `t` (µs) with the success count.
fn summary(label: &str, name: &str, t: &mut [f64], ok: usize) {
    if t.is_empty() {
        return;
    }
    let mean = t.iter().sum::<f64>() / t.len() as f64;
    t.sort_by(f64::total_cmp);
    let at = |p: f64| t[((t.len() - 1) as f64 * p).round() as usize];
    eprintln!(
        "{name:>24} {label:>8}: {ok}/{} solved, mean {mean:7.1} µs, median {:6.1}, p99 {:7.1}, max {:7.1} (mean/median {:.2})",
        t.len(),
        at(0.5),
        at(0.99),
        t[t.len() - 1],
        mean / at(0.5)
    );
}

fn main() {
    let a = args();
    let r = load_robot_file(Path::new(&a.robot)).expect("robot file loads");
    let limits: Vec<_> = r.joints().iter().map(|j| j.limits).collect();
    let solver = IkSolver::new(r.chain(), &limits);
    let analytic = AnalyticIk::new(r.chain()).ok().filter(|_| r.dof() == 6);
    let opts = IkOptions {
        tolerance: a.tolerance,
        ..IkOptions::default()
    };
    let aopts = AnalyticOptions {
        tolerance: a.tolerance,
        ..AnalyticOptions::default()
    };
    let mut rng = Rng(a.seed);
    let configs: Vec<Vec<f64>> = (0..a.n).map(|_| config(&r, &mut rng)).collect();
    let to = a.to.unwrap_or(a.n).min(a.n);
    let (mut nt, mut nok, mut at, mut aok) = (vec![], 0, vec![], 0);
    let mut cases = vec![];
    for q in &configs[a.from.min(to)..to] {
        let target = r.chain().forward(q, 1.0);
        let (t0, c0) = (Instant::now(), cpu_us());
        let s = solver.solve(&target, None, &opts);
        let (wall, us) = (t0.elapsed().as_secs_f64() * 1e6, cpu_us() - c0);
        nt.push(us);
        nok += usize::from(s.converged);
        let numeric = json!({"q": s.q, "converged": s.converged, "us": us, "wall_us": wall,
            "attempts": s.attempts, "iterations": s.iterations});
        let analytic = analytic.as_ref().map(|ik| {
            let (t0, c0) = (Instant::now(), cpu_us());
            let ans = ik.solve(&target, &limits, None, &aopts);
            let (wall, us) = (t0.elapsed().as_secs_f64() * 1e6, cpu_us() - c0);
            at.push(us);
            aok += usize::from(!ans.solutions.is_empty());
            json!({"q": ans.solutions.first().map(|s| s.q.to_vec()),
                "solutions": ans.solutions.len(), "us": us, "wall_us": wall})
        });
        cases.push(json!({"q_true": q, "target": flat(&target),
            "numeric": numeric, "analytic": analytic}));
    }
    summary("numeric", r.name(), &mut nt, nok);
    summary("analytic", r.name(), &mut at, aok);
    let mut out = chain_json(&r);
    out["cases"] = Value::Array(cases);
    println!("{out}");
}
