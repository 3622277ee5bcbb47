//! The `kinserve` command line: `fk`, `validate` and `bench`.

use crate::helpers::{assert_ok, kinserve, stdout_json};
use kinserve_testkit::RobotExt;

#[test]
fn fk_prints_the_rest_json_for_a_built_in() {
    let out = kinserve()
        .args(["fk", "--robot", "puma560", "--joints", "0,0,0,0,0,0"])
        .output()
        .unwrap();
    let v = stdout_json(&out);
    assert_eq!(v["robot"], "puma560");
    assert_eq!(v["length_unit"], "m");
    let robot =
        kinserve::model::load_robot_file(std::path::Path::new("robots/puma560.json")).unwrap();
    let p = robot.fk_unchecked(&[0.0; 6]).position();
    for i in 0..3 {
        assert!((v["pose"]["position"][i].as_f64().unwrap() - p[i]).abs() < 1e-12);
    }
    assert!(v.get("frames").is_none());
}

#[test]
fn fk_with_degrees_frames_and_a_model_file() {
    let out = kinserve()
        .args([
            "fk",
            "--model",
            "robots/planar_2dof.json",
            "--joints",
            "90,-90",
            "--deg",
            "--frames",
        ])
        .output()
        .unwrap();
    let v = stdout_json(&out);
    // a1 = 0.4, a2 = 0.3: x = a1 c1 + a2 c12 = 0.3, y = a1 s1 + a2 s12 = 0.4.
    assert!((v["pose"]["position"][0].as_f64().unwrap() - 0.3).abs() < 1e-12);
    assert!((v["pose"]["position"][1].as_f64().unwrap() - 0.4).abs() < 1e-12);
    assert_eq!(v["frames"].as_array().unwrap().len(), 3);
}

#[test]
fn fk_errors_go_to_stderr_with_a_non_zero_exit() {
    let out = kinserve()
        .args(["fk", "--robot", "puma560", "--joints", "0,0"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(out.stdout.is_empty());
    assert!(String::from_utf8_lossy(&out.stderr).contains("joints"));
    let out = kinserve()
        .args(["fk", "--robot", "../puma560", "--joints", "0"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let out = kinserve()
        .args(["fk", "--robot", "puma560", "--joints", "9,0,0,0,0,0"])
        .output()
        .unwrap();
    assert!(!out.status.success(), "9 rad is outside the waist limits");
    assert!(String::from_utf8_lossy(&out.stderr).contains("joints[0]"));
}

#[test]
fn validate_passes_every_robot_file_and_reports_bad_ones_by_field() {
    // Every model file (robots/ also holds a README.md).
    let files: Vec<String> = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/robots"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .map(|p| p.display().to_string())
        .collect();
    let out = kinserve().arg("validate").args(&files).output().unwrap();
    assert_ok(&out);

    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.json");
    std::fs::write(
        &bad,
        r#"{"name": "bad", "convention": "standard", "links": [{"joint": "revolute", "a": 1, "alpha": 0, "d": 0, "theta": 0, "limits": [2, 1]}]}"#,
    )
    .unwrap();
    let out = kinserve()
        .arg("validate")
        .arg(&bad)
        .arg("robots/puma560.json")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("links[0].limits"), "{err}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("puma560.json: ok"));
}

#[test]
fn closed_form_prints_the_rest_json_and_each_rendering() {
    let out = kinserve()
        .args(["closed-form", "--robot", "planar_2dof"])
        .output()
        .unwrap();
    let v = stdout_json(&out);
    assert_eq!(v["transform"]["text"][0][3], "a1*c1 + a2*c12");
    assert_eq!(v["symbols"]["a2"], 0.3);
    let text = kinserve()
        .args([
            "closed-form",
            "--model",
            "robots/scara_4dof.json",
            "--format",
            "text",
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&text.stdout);
    assert_eq!(
        text.lines().nth(2),
        Some("0 | 0 | -1 | d1 - d4 - d3"),
        "{text}"
    );
    let latex = kinserve()
        .args(["closed-form", "--robot", "alpha_ii", "--format", "latex"])
        .output()
        .unwrap();
    let latex = String::from_utf8_lossy(&latex.stdout);
    assert!(
        latex.starts_with("\\begin{bmatrix}") && latex.contains("c_{234}"),
        "{latex}"
    );
    let mathml = kinserve()
        .args(["closed-form", "--robot", "puma560", "--format", "mathml"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&mathml.stdout).starts_with("<math "));
}

#[test]
fn urdf_prints_the_document_and_errors_exit_non_zero() {
    let out = kinserve()
        .args(["urdf", "--robot", "alpha_ii"])
        .output()
        .unwrap();
    assert_ok(&out);
    let robot =
        kinserve::model::load_robot_file(std::path::Path::new("robots/alpha_ii.json")).unwrap();
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
        kinserve::model::to_urdf(&robot)
    );
    for args in [
        &["urdf", "--robot", "nope"][..],
        &["closed-form", "--robot", "../puma560"],
        &["closed-form", "--model", "no/such/file.json"],
    ] {
        let out = kinserve().args(args).output().unwrap();
        assert!(!out.status.success(), "{args:?}");
        assert!(out.stdout.is_empty(), "{args:?}");
        assert!(!out.stderr.is_empty(), "{args:?}");
    }
}

#[test]
fn bench_prints_positive_finite_figures_and_the_kernel() {
    for source in [["--robot", "puma560"], ["--model", "robots/panda.json"]] {
        let out = kinserve()
            .arg("bench")
            .args(source)
            .args(["--batch", "64", "--json"])
            .output()
            .unwrap();
        let v = stdout_json(&out);
        assert!(v["robot"] == "puma560" || v["robot"] == "panda", "{v}");
        let kernels: Vec<&str> = kinserve::kinematics::Kernel::ALL
            .iter()
            .map(|k| k.name())
            .collect();
        assert!(kernels.contains(&v["simd"].as_str().unwrap()), "{v}");
        for field in ["single_ns", "frames_ns", "batch_ns_per_pose"] {
            let x = v[field].as_f64().unwrap_or(f64::NAN);
            assert!(x.is_finite() && x > 0.0, "{field}: {v}");
        }
        assert_eq!(v.as_object().unwrap().len(), 5, "{v}");
    }
    let table = kinserve()
        .args(["bench", "--robot", "ur5e", "--batch", "16"])
        .output()
        .unwrap();
    assert!(table.status.success());
    assert!(String::from_utf8_lossy(&table.stdout).contains("ns/pose"));
    // Every kernel this CPU runs, one JSON line each, narrowest first, each
    // named; a kernel it cannot run (or no kernel at all) is refused by name.
    let all = kinserve()
        .args([
            "bench", "--robot", "ur5e", "--batch", "16", "--json", "--kernel", "all",
        ])
        .output()
        .unwrap();
    assert!(all.status.success());
    let names: Vec<String> = String::from_utf8_lossy(&all.stdout)
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            assert!(
                v["batch_ns_per_pose"].as_f64().is_some_and(|x| x > 0.0),
                "{v}"
            );
            v["simd"].as_str().unwrap().to_string()
        })
        .collect();
    let supported: Vec<String> = kinserve::kinematics::Kernel::ALL
        .iter()
        .filter(|k| k.is_supported())
        .map(|k| k.name().to_string())
        .collect();
    assert_eq!(names, supported);
    let portable = kinserve()
        .args([
            "bench", "--robot", "ur5e", "--batch", "16", "--json", "--kernel", "portable",
        ])
        .output()
        .unwrap();
    assert_eq!(stdout_json(&portable)["simd"], "portable");
    for (kernel, refused) in [
        ("sse9", "not a kernel: 'sse9'"),
        ("avx512", "cannot run the avx512 kernel"),
    ] {
        if kernel == "avx512" && kinserve::kinematics::Kernel::Avx512.is_supported() {
            continue;
        }
        let out = kinserve()
            .args(["bench", "--robot", "ur5e", "--kernel", kernel])
            .output()
            .unwrap();
        assert!(!out.status.success(), "{kernel}");
        assert!(
            String::from_utf8_lossy(&out.stderr).contains(refused),
            "{kernel}"
        );
    }
    let missing = kinserve()
        .args(["bench", "--robot", "no_such_robot"])
        .output()
        .unwrap();
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("no_such_robot"));
}

fn run_json(args: &[&str]) -> (bool, serde_json::Value, String) {
    let out = kinserve().args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let v = serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null);
    (out.status.success(), v, stderr)
}

#[test]
fn jacobian_prints_the_rest_json_per_radian() {
    let (ok, v, err) = run_json(&[
        "jacobian",
        "--robot",
        "planar_2dof",
        "--joints",
        "90,-90",
        "--deg",
    ]);
    assert!(ok, "{err}");
    assert_eq!(
        (v["robot"].as_str(), v["frame"].as_str()),
        (Some("planar_2dof"), Some("base"))
    );
    // a1 = 0.4, a2 = 0.3 at θ1 = 90°, θ2 = -90°: J = [[-a1 s1 - a2 s12, -a2 s12], [a1 c1 + a2 c12, a2 c12], …].
    let j = &v["jacobian"];
    let expect = [[-0.4, 0.0], [0.3, 0.3]];
    for (r, row) in expect.iter().enumerate() {
        for (c, x) in row.iter().enumerate() {
            assert!(
                (j[r][c].as_f64().unwrap() - x).abs() < 1e-12,
                "J[{r}][{c}] = {}",
                j[r][c]
            );
        }
    }
    assert_eq!(j[5], serde_json::json!([1.0, 1.0]));
    assert!((v["manipulability"].as_f64().unwrap() - 0.12).abs() < 1e-12);
    let (ok, v, _) = run_json(&[
        "jacobian",
        "--robot",
        "puma560",
        "--joints",
        "0,0,0,0,0,0",
        "--frame",
        "tool",
    ]);
    assert!(ok && v["frame"] == "tool" && v["jacobian"].as_array().unwrap().len() == 6);
}

#[test]
fn ik_reaches_an_fk_pose_and_an_unreachable_target_exits_1_with_the_best_attempt() {
    let (ok, fk, err) = run_json(&[
        "fk",
        "--robot",
        "ur5e",
        "--joints",
        "30,-80,70,-40,80,10",
        "--deg",
    ]);
    assert!(ok, "{err}");
    let p = &fk["pose"];
    let q = &p["quaternion"];
    let quaternion = format!("{},{},{},{}", q["w"], q["x"], q["y"], q["z"]);
    let position = csv(&p["position"]);
    let (ok, ik, err) = run_json(&[
        "ik",
        "--robot",
        "ur5e",
        "--position",
        &position,
        "--quaternion",
        &quaternion,
        "--deg",
    ]);
    assert!(ok, "{err}");
    assert_eq!(
        (ik["converged"].as_bool(), ik["angle_unit"].as_str()),
        (Some(true), Some("deg"))
    );
    let joints = csv(&ik["joints"]);
    let (ok, again, err) = run_json(&["fk", "--robot", "ur5e", "--joints", &joints, "--deg"]);
    assert!(ok, "joints within limits: {err}");
    for i in 0..3 {
        let (a, b) = (
            again["pose"]["position"][i].as_f64().unwrap(),
            p["position"][i].as_f64().unwrap(),
        );
        assert!((a - b).abs() <= 1e-9, "{a} vs {b}");
    }
    let (ok, best, err) = run_json(&[
        "ik",
        "--robot",
        "ur5e",
        "--position",
        "5,0,0",
        "--quaternion",
        "1,0,0,0",
        "--restarts",
        "2",
    ]);
    assert!(!ok && err.contains("did not converge"), "{err}");
    assert_eq!(best["converged"], false);
    assert!(best["position_error"].as_f64().unwrap() > 4.0);
    // Bad flags name the flag; bad values the field.
    let (ok, _, err) = run_json(&["ik", "--robot", "ur5e", "--position", "1,2"]);
    assert!(!ok && err.contains("--position"), "{err}");
    let (ok, _, err) = run_json(&["ik", "--robot", "ur5e", "--position", "0.3,0,0.2"]);
    assert!(!ok && err.contains("target.quaternion"), "{err}");
}

/// Out-of-range durations and limits stop `serve` at start-up with a clap
/// error naming the option (exit 2), whether given as a flag or in the
/// environment, and `ik --time-limit` likewise: no panic, no server.
#[test]
fn serve_refuses_out_of_range_durations_and_limits_by_name() {
    let refused = |c: &mut std::process::Command, flag: &str, value: &str, why: &str| {
        let out = c.output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(
            err.contains(&format!("invalid value '{value}' for '{flag} ")),
            "{err}"
        );
        assert!(err.contains(why), "{err}");
    };
    for (flag, value, why) in [
        ("--request-timeout", "1e30s", "at most 24h"),
        ("--ik-time-limit", "10000000000000000000s", "at most 60s"),
        (
            "--max-concurrent-requests",
            "18446744073709551615",
            "at most 1000000",
        ),
        ("--max-connections", "1000001", "at most 1000000"),
    ] {
        refused(
            kinserve().args(["serve", "--data-dir", "/nonexistent", flag, value]),
            flag,
            value,
            why,
        );
    }
    refused(
        kinserve()
            .args(["serve", "--data-dir", "/nonexistent"])
            .env("KINSERVE_WRITE_TIMEOUT", "1e30s"),
        "--write-timeout",
        "1e30s",
        "at most 24h",
    );
    refused(
        kinserve().args([
            "ik",
            "--robot",
            "planar_2dof",
            "--position",
            "0.3,0.4,0",
            "--position-only",
            "--time-limit",
            "2m",
        ]),
        "--time-limit",
        "2m",
        "at most 60s",
    );
}

/// A reader that stops early (`kinserve … | head -c 300`, `| true`) is a
/// normal end for the CLI: exit 0 and no panic, for every printing command.
#[test]
fn a_closed_output_pipe_is_a_normal_end() {
    for args in [
        &[
            "fk",
            "--robot",
            "puma560",
            "--frames",
            "--joints",
            "0,0,0,0,0,0",
        ][..],
        &["closed-form", "--robot", "puma560"][..],
        &["urdf", "--robot", "panda"][..],
    ] {
        let mut child = kinserve()
            .args(args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Hang up before the answer is written (the process is still starting).
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{args:?}: {:?} {stderr}", out.status);
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

/// The degrees hint speaks the command line's language: `--deg`.
#[test]
fn the_degrees_hint_names_the_flag() {
    let out = kinserve()
        .args(["fk", "--robot", "puma560", "--joints", "0,90,-90,0,0,0"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("pass --deg"), "{stderr}");
    assert!(!stderr.contains("angle_unit"), "{stderr}");
}

#[test]
fn serve_refuses_otlp_endpoints_it_cannot_export_to_and_ratios_outside_zero_to_one() {
    let dir = tempfile::tempdir().unwrap();
    let serve = |args: &[&str]| {
        kinserve()
            .args([
                "serve",
                "--http-addr",
                "127.0.0.1:0",
                "--grpc-addr",
                "127.0.0.1:0",
            ])
            .arg("--data-dir")
            .arg(dir.path())
            .args(args)
            .output()
            .unwrap()
    };
    let https = serve(&["--otlp-endpoint", "https://collector:4317"]);
    assert!(!https.status.success());
    let err = String::from_utf8_lossy(&https.stderr);
    assert!(
        err.contains("--otlp-endpoint") && err.contains("http://"),
        "{err}"
    );
    let ratio = serve(&["--trace-sample-ratio", "1.5"]);
    assert!(!ratio.status.success());
    let err = String::from_utf8_lossy(&ratio.stderr);
    assert!(err.contains("--trace-sample-ratio"), "{err}");
}

/// A JSON array as comma-separated text (a CLI list argument).
fn csv(v: &serde_json::Value) -> String {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(",")
}

#[test]
fn ik_all_prints_every_closed_form_solution_and_each_reaches_the_pose() {
    let (ok, fk, err) = run_json(&[
        "fk",
        "--robot",
        "puma560",
        "--joints",
        "20,-30,45,10,50,-20",
        "--deg",
    ]);
    assert!(ok, "{err}");
    let p = &fk["pose"];
    let q = &p["quaternion"];
    let quaternion = format!("{},{},{},{}", q["w"], q["x"], q["y"], q["z"]);
    let (ok, ik, err) = run_json(&[
        "ik",
        "--robot",
        "puma560",
        "--position",
        &csv(&p["position"]),
        "--quaternion",
        &quaternion,
        "--deg",
        "--all",
    ]);
    assert!(ok, "{err}");
    assert_eq!(ik["solver"], "analytic");
    let sols = ik["solutions"].as_array().expect("solutions");
    assert!(sols.len() >= 2, "{ik}");
    for s in sols {
        let (ok, again, err) = run_json(&[
            "fk",
            "--robot",
            "puma560",
            "--joints",
            &csv(&s["joints"]),
            "--deg",
        ]);
        assert!(ok, "within limits: {err}");
        for i in 0..3 {
            let (a, b) = (
                again["pose"]["position"][i].as_f64().unwrap(),
                p["position"][i].as_f64().unwrap(),
            );
            assert!((a - b).abs() <= 1e-9, "{a} vs {b}");
        }
    }
    // A solver the arm does not have is refused, naming the field.
    let out = kinserve()
        .args([
            "ik",
            "--robot",
            "panda",
            "--position",
            "0.3,0,0.5",
            "--quaternion",
            "1,0,0,0",
            "--solver",
            "analytic",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("solver"));
}

#[test]
fn ik_path_prints_the_steps_and_exits_1_when_it_stops() {
    let (ok, fk, err) = run_json(&[
        "fk",
        "--robot",
        "ur5e",
        "--joints",
        "0.4,-1.2,1.3,-0.7,1.2,0.3",
    ]);
    assert!(ok, "{err}");
    let p = &fk["pose"];
    let q = &p["quaternion"];
    let pos: Vec<f64> = p["position"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let up = format!(
        "{},{},{},{},{},{},{}",
        pos[0],
        pos[1],
        pos[2] + 0.03,
        q["w"],
        q["x"],
        q["y"],
        q["z"]
    );
    let (ok, path, err) = run_json(&[
        "ik-path",
        "--robot",
        "ur5e",
        "--start",
        "0.4,-1.2,1.3,-0.7,1.2,0.3",
        "--waypoint",
        &up,
        "--max-step-length",
        "0.01",
    ]);
    assert!(ok, "{err}");
    assert_eq!(
        (path["fraction"].as_f64(), path["stop"].is_null()),
        (Some(1.0), true)
    );
    assert_eq!(
        path["points"].as_array().unwrap().len(),
        4,
        "start + 3 steps of 1 cm"
    );
    let far = format!("3,0,0,{},{},{},{}", q["w"], q["x"], q["y"], q["z"]);
    let (ok, path, err) = run_json(&[
        "ik-path",
        "--robot",
        "ur5e",
        "--start",
        "0.4,-1.2,1.3,-0.7,1.2,0.3",
        "--waypoint",
        &far,
    ]);
    assert!(!ok && err.contains("stopped at step"), "{err}");
    assert!(path["stop"]["reason"].is_string() && path["fraction"].as_f64().unwrap() < 1.0);
}

/// Matrices print one row per line (and other lists of numbers on one line),
/// the JSON unchanged: `fk`, `jacobian` and `link-transforms` alike.
#[test]
fn matrices_print_one_row_per_line() {
    let out = kinserve()
        .args(["fk", "--robot", "puma560", "--joints", "0,0,0,0,0,0"])
        .output()
        .unwrap();
    let text = String::from_utf8(out.stdout.clone()).unwrap();
    let lines: Vec<&str> = text.lines().map(str::trim).collect();
    for row in [
        "[1.0, -0.0, 0.0, 0.4521],",
        "[0.0, 1.0, 0.0, -0.15005],",
        "[0.0, -0.0, 1.0, 1.10363],",
        "[0.0, 0.0, 0.0, 1.0]",
    ] {
        assert!(
            lines.contains(&row),
            "row {row} on a line of its own:\n{text}"
        );
    }
    assert!(
        lines.contains(&"\"position\": [0.4521, -0.15005, 1.10363],"),
        "{text}"
    );
    let printed = stdout_json(&out);
    assert_eq!(printed["pose"]["matrix"][0][3], 0.4521, "still JSON");
    let out = kinserve()
        .args(["jacobian", "--robot", "planar_2dof", "--joints", "0,0"])
        .output()
        .unwrap();
    let text = String::from_utf8(out.stdout.clone()).unwrap();
    let rows = text
        .lines()
        .filter(|l| l.trim().starts_with("[0.0, "))
        .count();
    assert!(rows >= 6, "six Jacobian rows, one per line:\n{text}");
    stdout_json(&out);
}

#[test]
fn ik_objectives_free_a_tilt_pull_a_posture_and_refuse_bad_axes() {
    // A SCARA pose tilted 0.3 rad about its x axis: unreachable in full,
    // reached with rx and ry left free (position to the tolerance).
    let (ok, fk, err) = run_json(&[
        "fk",
        "--robot",
        "scara_4dof",
        "--joints",
        "0.4,-0.7,0.1,0.2",
    ]);
    assert!(ok, "{err}");
    let m = &fk["pose"]["matrix"];
    let (s, c) = 0.3f64.sin_cos();
    let mut tilted = Vec::new();
    for i in 0..4 {
        let row: Vec<f64> = (0..4).map(|j| m[i][j].as_f64().unwrap()).collect();
        tilted.extend([
            row[0],
            c * row[1] + s * row[2],
            -s * row[1] + c * row[2],
            row[3],
        ]);
    }
    let matrix = tilted
        .iter()
        .map(f64::to_string)
        .collect::<Vec<_>>()
        .join(",");
    let full = [
        "ik",
        "--robot",
        "scara_4dof",
        "--matrix",
        &matrix,
        "--restarts",
        "5",
    ];
    let (ok, _, err) = run_json(&full);
    assert!(!ok && err.contains("did not converge"), "{err}");
    let (ok, ik, err) = run_json(&[&full[..], &["--free-axis", "rx,ry"]].concat());
    assert!(ok, "{err}");
    let left = ik["orientation_error"].as_f64().unwrap();
    assert!((left - 0.3).abs() < 1e-8, "{ik}");
    // A posture the arm can take: named on the command line, answered as usual.
    let (ok, ik, err) = run_json(&[
        "ik",
        "--robot",
        "panda",
        "--position",
        "0.4,0.2,0.5",
        "--position-only",
        "--deg",
        "--posture",
        "0,0,0,-90,0,90,45",
        "--posture-weights",
        "1,1,1,1,1,1,0",
    ]);
    assert!(ok && ik["converged"] == true, "{err}");
    // Bad objectives name what to fix.
    let (ok, _, err) = run_json(&[
        "ik",
        "--robot",
        "ur5e",
        "--position",
        "0.3,0,0.2",
        "--free-axis",
        "w",
    ]);
    assert!(!ok && err.contains("rx, ry or rz"), "{err}");
    let (ok, _, err) = run_json(&[
        "ik",
        "--robot",
        "panda",
        "--position",
        "0.4,0.2,0.5",
        "--position-only",
        "--posture",
        "0,0",
    ]);
    assert!(!ok && err.contains("posture.joints"), "{err}");
}
