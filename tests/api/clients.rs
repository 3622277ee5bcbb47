//! The client libraries (`clients/python`, `clients/typescript`) against the
//! real server: the pytest suite (both transports, sync and async, numpy
//! shapes, typed errors, streams, README examples, `mypy --strict`) and the
//! TypeScript suite (`tsc --strict`, `node --test`, README examples), with
//! the expected poses from the kinematics library; every `solutions: "all"`
//! answer the Python suite gets is handed back (`KINSERVE_OUT`) and each
//! solution checked here by the library's FK. Also: the OpenAPI snapshot
//! `clients/openapi.json` the clients are generated from is the server's
//! document (`KINSERVE_UPDATE_CLIENTS=1` rewrites it).
//!
//! This module owns starting the server and the tools; the suites are in
//! `clients/*/tests`. The tools come from `.ci/run` (`pip install
//! './clients/python[test]'`, `npm ci` in `clients/typescript`); without them
//! a test says SKIPPED, and fails under `CI`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use kinserve_testkit::RobotExt;
use serde_json::{Value, json};
use tokio::process::Command;

use crate::helpers::*;

/// The server's API token: the clients send it to register and delete.
const TOKEN: &str = "client-libraries-token";

/// Idle streams close after this on the TypeScript suite's server (its
/// reconnect test waits it out).
const STREAM_IDLE: Duration = Duration::from_secs(2);
/// The Python suite never waits for an idle close: its server keeps streams
/// far longer, so a loaded CI machine pausing a stream test for two seconds
/// (seen once: a latest-wins stream closed under it) cannot fail the suite.
const STREAM_IDLE_PYTHON: Duration = Duration::from_secs(120);

fn clients_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("clients")
}

async fn succeeds(cmd: &mut Command) -> bool {
    cmd.output().await.is_ok_and(|o| o.status.success())
}

/// Runs `cmd` and asserts it exits 0, showing its output otherwise.
async fn run_ok(cmd: &mut Command, what: &str) {
    let out = cmd.output().await.unwrap_or_else(|e| panic!("{what}: {e}"));
    assert!(
        out.status.success(),
        "{what} failed ({}):\n--- stdout\n{}\n--- stderr\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A server needing [`TOKEN`] for writes, and `expected.json` in `dir`: the
/// FK of puma560 from the kinematics library. Its IK time cap is far out of
/// reach, so that answers the suites compare across calls cannot differ by
/// where a loaded machine cut a solve short. Streams idle for `stream_idle`
/// are closed.
async fn app_and_expected(dir: &Path, stream_idle: Duration) -> (TestApp, PathBuf) {
    let app = spawn_app_with(|c| {
        c.api_token = Some(TOKEN.into());
        c.stream_idle_timeout = stream_idle;
        c.ik_time_limit = std::time::Duration::from_secs(30);
    })
    .await;
    let q = [0.3, -0.4, 0.6, 0.2, -0.5, 0.7];
    let puma = library_robot("puma560");
    let tool = puma.fk_unchecked(&q);
    // The IK target of the every-solution tests (20, -30, 45, 10, 50, -20 deg).
    let q_ik = [20.0f64, -30.0, 45.0, 10.0, 50.0, -20.0].map(f64::to_radians);
    let expected = json!({
        "fk": {"robot": "puma560", "joints": q, "matrix": tool.matrix()},
        "ik": {"robot": "puma560", "joints": q_ik, "matrix": puma.fk_unchecked(&q_ik).matrix()},
    });
    let path = dir.join("expected.json");
    std::fs::write(&path, serde_json::to_vec_pretty(&expected).unwrap()).unwrap();
    (app, path)
}

fn with_server(cmd: &mut Command, app: &TestApp, expected: &Path, stream_idle: Duration) {
    let grpc = app.grpc.trim_start_matches("http://").to_string();
    cmd.env("KINSERVE_URL", &app.http)
        .env("KINSERVE_GRPC", grpc)
        .env("KINSERVE_TOKEN", TOKEN)
        .env("KINSERVE_EXPECTED", expected)
        .env("KINSERVE_OUT", expected.parent().expect("a directory"))
        .env("KINSERVE_REPO", env!("CARGO_MANIFEST_DIR"))
        .env(
            "KINSERVE_STREAM_IDLE_MS",
            stream_idle.as_millis().to_string(),
        );
}

#[tokio::test]
async fn the_openapi_snapshot_of_the_clients_is_the_servers_document() {
    let app = spawn_app().await;
    let live: Value = app.get("/openapi.json").await.json().await.unwrap();
    let path = clients_dir().join("openapi.json");
    if std::env::var_os("KINSERVE_UPDATE_CLIENTS").is_some_and(|v| v == "1") {
        let text = serde_json::to_string_pretty(&live).unwrap() + "\n";
        std::fs::write(&path, text).unwrap();
    }
    let snapshot: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    assert!(
        snapshot == live,
        "clients/openapi.json is not the server's /openapi.json: run \
         KINSERVE_UPDATE_CLIENTS=1 cargo test --test api clients, then rebuild the clients"
    );
}

/// FK agreement asked of every IK solution the Python suite got (length
/// unit, matrix entries).
const FK_TOL: f64 = 1e-10;

/// The `solutions: "all"` answer the Python suite wrote (`KINSERVE_OUT`):
/// every solution, checked here by the kinematics library's FK against the
/// target, and within the joint limits. Returns how many there were.
fn check_handed_off_solutions(path: &Path) -> usize {
    let text = std::fs::read(path)
        .unwrap_or_else(|e| panic!("{}: the Python suite writes it: {e}", path.display()));
    let doc: Value = serde_json::from_slice(&text).unwrap();
    let robot = library_robot(doc["robot"].as_str().unwrap());
    let floats = |v: &Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let target: Vec<Vec<f64>> = doc["target"]
        .as_array()
        .unwrap()
        .iter()
        .map(floats)
        .collect();
    let solutions = doc["solutions"].as_array().unwrap();
    for s in solutions {
        let q = floats(s);
        let opts = kinserve::model::FkOptions::default();
        assert!(
            robot.check_joints(&q, &opts).is_ok(),
            "within the limits: {q:?}"
        );
        let m = robot.fk_unchecked(&q).matrix();
        for (i, row) in target.iter().enumerate() {
            for (j, want) in row.iter().enumerate() {
                assert!(
                    (m[i][j] - want).abs() < FK_TOL,
                    "{}: the library's FK of {q:?} is {m:?}, not the target",
                    path.display()
                );
            }
        }
    }
    solutions.len()
}

#[tokio::test]
async fn the_python_client_passes_its_suite_against_the_server() {
    let present = succeeds(
        Command::new("python3").args(["-c", "import kinserve_client, pytest, anyio, mypy"]),
    )
    .await;
    if !present {
        kinserve_testkit::skip_unless_ci(
            "python client test",
            "kinserve-client with its test extras is not installed",
            "pip install './clients/python[test]' (.ci/run does)",
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (app, expected) = app_and_expected(dir.path(), STREAM_IDLE_PYTHON).await;
    let project = clients_dir().join("python");
    let mut pytest = Command::new("python3");
    pytest
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"])
        .current_dir(&project);
    with_server(&mut pytest, &app, &expected, STREAM_IDLE_PYTHON);
    run_ok(&mut pytest, "pytest clients/python").await;
    for transport in ["rest", "grpc"] {
        let n = check_handed_off_solutions(&dir.path().join(format!("ik_all_{transport}.json")));
        assert!(n >= 2, "{transport}: {n} solutions");
    }
    run_ok(
        Command::new("python3")
            .args(["-m", "mypy", "--strict", "--cache-dir"])
            .arg(dir.path().join("mypy"))
            .current_dir(&project),
        "mypy --strict clients/python",
    )
    .await;
}

#[tokio::test]
async fn the_typescript_client_compiles_strictly_and_passes_its_suite() {
    let project = clients_dir().join("typescript");
    let tsc = project.join("node_modules/.bin/tsc");
    let present = succeeds(Command::new("node").arg("--version")).await
        && tsc.exists()
        && project
            .join("node_modules/.bin/openapi-typescript")
            .exists();
    if !present {
        kinserve_testkit::skip_unless_ci(
            "typescript client test",
            "node or clients/typescript/node_modules is not installed",
            "npm ci in clients/typescript (.ci/run does)",
        );
        return;
    }
    run_ok(
        Command::new("node")
            .arg("scripts/generate.mjs")
            .current_dir(&project),
        "clients/typescript generate (openapi-typescript)",
    )
    .await;
    run_ok(
        Command::new(&tsc)
            .args(["-p", "tsconfig.json", "--strict"])
            .current_dir(&project),
        "tsc --strict clients/typescript",
    )
    .await;
    let dir = tempfile::tempdir().unwrap();
    let (app, expected) = app_and_expected(dir.path(), STREAM_IDLE).await;
    let mut node = Command::new("node");
    node.args([
        "--experimental-websocket",
        "--test",
        "dist/test/client.test.js",
    ])
    .current_dir(&project);
    with_server(&mut node, &app, &expected, STREAM_IDLE);
    run_ok(&mut node, "node --test clients/typescript").await;
}
