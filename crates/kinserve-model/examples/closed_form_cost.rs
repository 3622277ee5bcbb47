//! CPU cost of `ClosedForm::of` against its counted work, on the issue-22
//! attack model (8 twisted revolute rows + 248 identity fixed rows) and on
//! other tables that grow. Run:
//! `cargo run --release -p kinserve-model --example closed_form_cost`.

use std::f64::consts::FRAC_PI_2;
use std::time::Instant;

use kinserve_model::{ClosedForm, ModelLimits, Robot};

/// A revolute row; `fixed` rows the same with `"joint": "fixed"`.
fn row(joint: &str, a: f64, alpha: f64, d: f64, theta: f64) -> String {
    format!(r#"{{"joint": "{joint}", "a": {a}, "alpha": {alpha}, "d": {d}, "theta": {theta}}}"#)
}

fn robot(convention: &str, rows: &[String]) -> Robot {
    let json = format!(
        r#"{{"name": "cost", "convention": "{convention}", "links": [{}]}}"#,
        rows.join(",")
    );
    Robot::from_json(json.as_bytes(), &ModelLimits::default()).unwrap()
}

fn twisted(n: usize, identity: usize) -> Vec<String> {
    let mut rows: Vec<String> = (0..n)
        .map(|_| row("revolute", 0.1, 0.3, 0.05, 0.0))
        .collect();
    rows.extend((0..identity).map(|_| row("fixed", 0.0, 0.0, 0.0, 0.0)));
    rows
}

fn cases() -> Vec<(String, Robot)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    let mut out: Vec<(String, Robot)> = files
        .iter()
        .map(|f| {
            let robot = kinserve_model::load_robot_file(f).unwrap();
            (format!("shipped {}", robot.name()), robot)
        })
        .collect();
    for n in 4..=9 {
        out.push((
            format!("std twisted {n}"),
            robot("standard", &twisted(n, 0)),
        ));
        out.push((
            format!("mdh twisted {n}"),
            robot("modified", &twisted(n, 0)),
        ));
    }
    out.push((
        "attack 8 + 248 identity".into(),
        robot("standard", &twisted(8, 248)),
    ));
    for n in [12, 16, 20, 24, 28] {
        let rows: Vec<String> = (0..n)
            .map(|i| {
                row(
                    "revolute",
                    0.1,
                    if i % 2 == 0 { FRAC_PI_2 } else { -FRAC_PI_2 },
                    0.1,
                    0.0,
                )
            })
            .collect();
        out.push((format!("snake ±90° {n}"), robot("standard", &rows)));
    }
    for n in [20, 40, 64] {
        let rows: Vec<String> = (0..n)
            .map(|_| row("revolute", 0.1, 0.0, 0.0, 0.0))
            .collect();
        out.push((format!("parallel {n}"), robot("standard", &rows)));
    }
    for n in [3, 4, 5, 6] {
        // Revolute rows between twisted fixed rows: nothing to fold.
        let rows: Vec<String> = (0..n)
            .flat_map(|_| {
                [
                    row("revolute", 0.1, 0.3, 0.05, 0.0),
                    row("fixed", 0.2, 0.7, 0.1, 0.4),
                ]
            })
            .collect();
        out.push((
            format!("revolute/fixed twisted x{n}"),
            robot("standard", &rows),
        ));
    }
    for n in [4, 8, 12, 16] {
        // A run of twisted fixed rows: the run alone grows.
        let mut rows = twisted(3, 0);
        rows.extend((0..n).map(|_| row("fixed", 0.2, 0.7, 0.1, 0.4)));
        out.push((
            format!("3 twisted + {n} twisted fixed"),
            robot("standard", &rows),
        ));
    }
    for n in [4, 6, 8, 10] {
        // Pairs of parallel revolute rows joined by twists: angle sums to find.
        let rows: Vec<String> = (0..n)
            .flat_map(|_| {
                [
                    row("revolute", 0.1, 0.0, 0.05, 0.0),
                    row("revolute", 0.2, 0.3, 0.1, 0.0),
                ]
            })
            .collect();
        out.push((
            format!("parallel pairs, twisted x{n}"),
            robot("standard", &rows),
        ));
    }
    for n in [6, 8, 10] {
        // Prismatic and revolute rows, twisted.
        let rows: Vec<String> = (0..n)
            .map(|i| {
                row(
                    if i % 2 == 0 { "prismatic" } else { "revolute" },
                    0.1,
                    0.4,
                    0.2,
                    0.3,
                )
            })
            .collect();
        out.push((
            format!("prismatic/revolute twisted {n}"),
            robot("modified", &rows),
        ));
    }
    out
}

/// Least wall time of `f` over a few runs (ms): the machine is shared.
fn best_ms<T>(mut f: impl FnMut() -> T) -> (T, f64) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..5 {
        let t = Instant::now();
        out = Some(f());
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (out.unwrap(), best)
}

fn main() {
    println!(
        "{:<32} {:>10} {:>9} {:>9} {:>7} {:>10}",
        "model", "work", "of ms", "check ms", "ns/op", "bytes"
    );
    for (name, robot) in cases() {
        let (checked, check_ms) = best_ms(|| ClosedForm::check(&robot));
        let (cf, of_ms) = best_ms(|| ClosedForm::of(&robot));
        match (checked, cf) {
            (Ok(work), Ok(cf)) => {
                let bytes = serde_json::to_string(&cf).unwrap().len();
                let ns = of_ms * 1e6 / work as f64;
                println!(
                    "{name:<32} {work:>10} {of_ms:>9.2} {check_ms:>9.2} {ns:>7.1} {bytes:>10}"
                );
            }
            (_, Err(e)) => println!("{name:<32} refused in {of_ms:.2} ms: {e}"),
            (Err(e), Ok(_)) => println!("{name:<32} check refused, of served: {e}"),
        }
    }
}
