//! Built-in robots ship inside the binary: the CLI and the server find them
//! from any working directory, and `--robots-dir` adds or overrides robots.

use kinserve::model::{ModelLimits, load_robot_file};
use kinserve::registry::builtin;
use kinserve_testkit::RobotExt;

use crate::helpers::{kinserve_elsewhere, stdout_json};

fn repo_robots() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots")
}

#[test]
fn every_robot_file_is_embedded_and_matches_its_file() {
    let mut files: Vec<String> = std::fs::read_dir(repo_robots())
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "json")
                .then(|| p.file_stem().unwrap().to_string_lossy().into_owned())
        })
        .collect();
    files.sort();
    let embedded: Vec<&str> = builtin::embedded_names().collect();
    assert_eq!(embedded, files);
    let limits = ModelLimits::default();
    for (label, robot) in builtin::embedded(&limits) {
        let robot = robot.unwrap_or_else(|e| panic!("{label}: {e}"));
        let file = load_robot_file(&repo_robots().join(format!("{}.json", robot.name()))).unwrap();
        assert_eq!(robot.spec(), file.spec(), "{label}");
    }
}

#[test]
fn fk_finds_a_built_in_robot_from_any_directory() {
    let dir = tempfile::tempdir().unwrap();
    let out = kinserve_elsewhere(dir.path())
        .args([
            "fk",
            "--robot",
            "puma560",
            "--joints",
            "0.1,0.2,0.3,0.4,0.5,0.6",
        ])
        .output()
        .unwrap();
    let v = stdout_json(&out);
    let robot = load_robot_file(&repo_robots().join("puma560.json")).unwrap();
    let p = robot
        .fk_unchecked(&[0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
        .position();
    for (i, want) in p.iter().enumerate() {
        let got = v["pose"]["position"][i].as_f64().unwrap();
        assert!(
            (got - want).abs() <= 1e-12,
            "position[{i}]: {got} vs {want}"
        );
    }
}

#[test]
fn an_unknown_built_in_names_the_ones_there_are() {
    let dir = tempfile::tempdir().unwrap();
    let out = kinserve_elsewhere(dir.path())
        .args(["fk", "--robot", "no-such-arm", "--joints", "0"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no built-in robot 'no-such-arm'"), "{err}");
    assert!(err.contains("puma560") && err.contains("--model"), "{err}");
}

#[test]
fn robots_dir_adds_and_overrides_built_ins() {
    let dir = tempfile::tempdir().unwrap();
    // A new robot, and a file named like a built-in that holds a different arm.
    let planar = std::fs::read_to_string(repo_robots().join("planar_2dof.json")).unwrap();
    let mine = planar.replace("\"planar_2dof\"", "\"my_arm\"");
    std::fs::write(dir.path().join("my_arm.json"), &mine).unwrap();
    let puma_as_planar = planar.replace("\"planar_2dof\"", "\"puma560\"");
    std::fs::write(dir.path().join("puma560.json"), &puma_as_planar).unwrap();
    for (name, dof) in [("my_arm", 2), ("puma560", 2), ("ur5e", 6)] {
        let joints = vec!["0"; dof].join(",");
        let out = kinserve_elsewhere(dir.path())
            .args([
                "fk",
                "--robot",
                name,
                "--joints",
                &joints,
                "--robots-dir",
                ".",
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let registry = kinserve::registry::Registry::new(Box::new(kinserve::registry::MemoryStore));
    let report = registry.load_builtins(Some(dir.path()), &ModelLimits::default());
    assert!(report.skipped.is_empty(), "{:?}", report.skipped);
    assert_eq!(report.loaded, builtin::embedded_names().count() + 1);
    assert_eq!(
        registry.get("puma560").unwrap().robot.dof(),
        2,
        "overridden"
    );
    assert!(registry.get("my_arm").is_some(), "added");
}

#[test]
fn a_missing_model_file_is_said_plainly() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        vec!["fk", "--model", "nope.json", "--joints", "0"],
        vec!["validate", "nope.json"],
    ] {
        let out = kinserve_elsewhere(dir.path()).args(&args).output().unwrap();
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("nope.json: no such file"), "{args:?}: {err}");
        assert!(!err.contains("malformed"), "{args:?}: {err}");
    }
}
