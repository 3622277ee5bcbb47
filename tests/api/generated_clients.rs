//! Clients generated from the server's own OpenAPI document work against the
//! real server: `openapi-generator validate` finds no error in the document;
//! a Python client from openapi-generator (`-g python`) and TypeScript types
//! from openapi-typescript used with openapi-fetch (compiled with
//! `tsc --strict`) list robots, compute FK (reading `pose.position` directly),
//! a batch in a compact format, a Jacobian and an IK answer, and register and
//! delete a robot, each value checked against the kinematics library.
//!
//! This module owns running the tools and the expected values; the client
//! programs are `tests/clients/python/check.py` and `tests/clients/ts/check.ts`
//! (and the pinned npm project around the latter). The tools come from
//! `.ci/run`: PyPI `openapi-generator-cli` (its wheel carries the generator's
//! jar; Java runs it) and the client's runtime packages
//! (`tests/clients/python/requirements.txt`), and `npm ci` in
//! `tests/clients/ts`. A test whose tools are missing says SKIPPED, and fails
//! under `CI`.

use std::path::{Path, PathBuf};
use std::process::Output;

use kinserve_testkit::RobotExt;
use serde_json::{Value, json};
use tokio::process::Command;

use crate::helpers::*;

/// The server's API token: the clients must send it to register and delete.
const TOKEN: &str = "generated-clients-token";

/// `tests/clients`.
fn clients_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/clients")
}

/// `openapi-generator-cli ARGS` through the Python that has the package (the
/// same `python3` as the other contract tools, whatever is on `PATH`).
fn generator(args: &[&str]) -> Command {
    let mut cmd = Command::new("python3");
    cmd.args(["-c", "import openapi_generator_cli as g; g.cli()"])
        .args(args);
    cmd
}

/// Whether the command runs and exits 0.
async fn succeeds(cmd: &mut Command) -> bool {
    cmd.output().await.is_ok_and(|o| o.status.success())
}

/// `true` when the tools are there. Otherwise fails under CI, else prints
/// a SKIPPED line and gives `false` (`kinserve_testkit::skip_unless_ci`).
fn have_or_skip(present: bool, what: &str) -> bool {
    if !present {
        kinserve_testkit::skip_unless_ci(
            "generated clients test",
            &format!("{what} is not installed"),
            ".ci/run installs it",
        );
    }
    present
}

/// Runs `cmd` and asserts it exits 0, showing its output otherwise.
async fn run_ok(cmd: &mut Command, what: &str) -> Output {
    let out = cmd.output().await.unwrap_or_else(|e| panic!("{what}: {e}"));
    assert!(
        out.status.success(),
        "{what} failed ({}):\n--- stdout\n{}\n--- stderr\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// A server that needs [`TOKEN`] for writes, and its OpenAPI document written
/// to `dir/openapi.json`.
async fn app_and_document(dir: &Path) -> (TestApp, PathBuf) {
    let app = spawn_app_with(|c| c.api_token = Some(TOKEN.into())).await;
    let r = app.get("/openapi.json").await;
    assert_eq!(r.status(), 200);
    let path = dir.join("openapi.json");
    std::fs::write(&path, r.bytes().await.unwrap()).unwrap();
    (app, path)
}

/// The top three rows of a 4×4 matrix, row-major (the `matrix` format).
fn matrix12(m: &[[f64; 4]; 4]) -> Vec<f64> {
    m[..3].iter().flatten().copied().collect()
}

/// What the client programs read (`EXPECTED.json`): where the server is, the
/// requests to make and the answers, from the kinematics library (the
/// Jacobian from the server's own REST answer).
async fn expected(app: &TestApp, register_as: &str) -> Value {
    let q = [0.3, -0.4, 0.6, 0.2, -0.5, 0.7];
    let puma = library_robot("puma560");
    let tool = puma.fk_unchecked(&q);
    let target = puma.fk_unchecked(&[-0.2, 0.3, 0.4, -0.1, 0.6, 0.2]);
    let [w, x, y, z] = target.quaternion();
    let jac: Value = app
        .post("/v1/robots/puma560/jacobian", &json!({"joints": q}))
        .await
        .json()
        .await
        .unwrap();
    let configurations = [[0.0, 0.0], [0.5, 0.1], [-1.2, 2.0]];
    let planar = library_robot("planar_2dof");
    let matrices: Vec<Vec<f64>> = configurations
        .iter()
        .map(|c| matrix12(&planar.fk_unchecked(c).matrix()))
        .collect();
    // planar_model: links of 0.5 and 0.3 m; at 30° and 20° (deg).
    let (a1, a12) = (30f64.to_radians(), 50f64.to_radians());
    let registered = [
        0.5 * a1.cos() + 0.3 * a12.cos(),
        0.5 * a1.sin() + 0.3 * a12.sin(),
        0.0,
    ];
    json!({
        "base": app.http,
        "token": TOKEN,
        "fk": {"robot": "puma560", "joints": q, "position": tool.position(), "matrix": tool.matrix()},
        "jacobian": {
            "robot": "puma560", "joints": q, "jacobian": jac["jacobian"],
            "manipulability": jac["manipulability"], "position": tool.position(),
            "singular": jac["singular"],
        },
        "ik": {
            "robot": "puma560", "dof": 6, "position": target.position(),
            "quaternion": {"w": w, "x": x, "y": y, "z": z}, "tolerance": 1e-9,
        },
        "register": {"model": planar_model(register_as), "joints": [30, 20], "position": registered},
        "batch": {"robot": "planar_2dof", "configurations": configurations, "matrices": matrices},
    })
}

/// Writes [`expected`] to `dir/expected.json`.
async fn write_expected(app: &TestApp, dir: &Path, register_as: &str) -> PathBuf {
    let path = dir.join("expected.json");
    let value = expected(app, register_as).await;
    std::fs::write(&path, serde_json::to_vec_pretty(&value).unwrap()).unwrap();
    path
}

async fn have_generator() -> bool {
    let python_runtime = "import pydantic, urllib3, dateutil, typing_extensions";
    have_or_skip(
        succeeds(&mut generator(&["version"])).await
            && succeeds(Command::new("python3").args(["-c", python_runtime])).await,
        "openapi-generator-cli or the Python client's packages \
         (pip install -r tests/clients/python/requirements.txt)",
    )
}

#[tokio::test]
async fn openapi_generator_finds_no_error_in_the_document() {
    if !have_generator().await {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (_app, doc) = app_and_document(dir.path()).await;
    let out = run_ok(
        generator(&["validate", "-i"]).arg(&doc),
        "openapi-generator-cli validate",
    )
    .await;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("Validating spec") && !text.contains("[error]"),
        "{text}"
    );
}

#[tokio::test]
async fn a_generated_python_client_works_against_the_server() {
    if !have_generator().await {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (app, doc) = app_and_document(dir.path()).await;
    let client = dir.path().join("python");
    run_ok(
        generator(&[
            "generate",
            "-g",
            "python",
            "--package-name",
            "kinserve_client",
        ])
        .args(["--global-property", "apiTests=false,modelTests=false"])
        .args(["--global-property", "apiDocs=false,modelDocs=false"])
        .arg("-i")
        .arg(&doc)
        .arg("-o")
        .arg(&client),
        "openapi-generator-cli generate -g python",
    )
    .await;
    let expected = write_expected(&app, dir.path(), "client-python").await;
    run_ok(
        Command::new("python3")
            .arg(clients_dir().join("python/check.py"))
            .arg(&expected)
            .env("PYTHONPATH", &client),
        "tests/clients/python/check.py",
    )
    .await;
}

#[tokio::test]
async fn a_typescript_client_from_openapi_typescript_compiles_strictly_and_works() {
    let project = clients_dir().join("ts");
    let bin = project.join("node_modules/.bin");
    let present = succeeds(Command::new("node").arg("--version")).await
        && bin.join("tsc").exists()
        && bin.join("openapi-typescript").exists();
    if !have_or_skip(present, "node or tests/clients/ts/node_modules (npm ci)") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (app, doc) = app_and_document(dir.path()).await;
    // The project in the temp dir, with the generated types beside check.ts.
    let work = dir.path().join("ts");
    std::fs::create_dir(&work).unwrap();
    for file in ["package.json", "tsconfig.json", "check.ts"] {
        std::fs::copy(project.join(file), work.join(file)).unwrap();
    }
    std::os::unix::fs::symlink(project.join("node_modules"), work.join("node_modules")).unwrap();
    run_ok(
        Command::new(bin.join("openapi-typescript"))
            .arg(&doc)
            .arg("-o")
            .arg(work.join("schema.ts")),
        "openapi-typescript",
    )
    .await;
    run_ok(
        Command::new(bin.join("tsc"))
            .args(["-p", "tsconfig.json", "--strict"])
            .current_dir(&work),
        "tsc --strict",
    )
    .await;
    let expected = write_expected(&app, dir.path(), "client-ts").await;
    run_ok(
        Command::new("node")
            .arg(work.join("dist/check.js"))
            .arg(&expected),
        "tests/clients/ts/check.ts",
    )
    .await;
}
