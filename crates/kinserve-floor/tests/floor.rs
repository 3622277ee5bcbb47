//! `kinserve-floor` answers what the benchmarks send as kinserve does: the
//! real binary on free loopback ports, loaded by `kinserve-load`'s library
//! with every pose verified against the kinematics crates, REST answers
//! compared byte for byte. Never a timing threshold.

use clap::Parser;
use tokio::io::AsyncBufReadExt;

/// The benchmarks' one REST FK body (`scripts/bench-lib.sh`).
const FK_BODY: &str = r#"{"joints": [0.1, -0.5, 0.7, 0.2, 0.3, -0.1]}"#;

/// A running floor, stopped on drop.
struct Floor {
    _child: tokio::process::Child,
    _tmp: tempfile::TempDir,
    http: String,
    grpc: String,
    answer: Vec<u8>,
}

/// Starts the floor for `robot` on free ports, answering REST FK with `answer`.
async fn spawn_floor(robot: &str, answer: &[u8]) -> Floor {
    let tmp = tempfile::tempdir().expect("temp dir");
    let answer_file = tmp.path().join("fk.json");
    std::fs::write(&answer_file, answer).expect("answer file");
    let robot_file = format!("{}/../../robots/{robot}.json", env!("CARGO_MANIFEST_DIR"));
    let mut child = tokio::process::Command::new(env!("CARGO_BIN_EXE_kinserve-floor"))
        .args(["--robot-file", &robot_file, "--fk-answer"])
        .arg(&answer_file)
        .args(["--http-addr", "127.0.0.1:0", "--grpc-addr", "127.0.0.1:0"])
        .stderr(std::process::Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .expect("kinserve-floor starts");
    let stderr = child.stderr.take().expect("stderr");
    let line = tokio::io::BufReader::new(stderr)
        .lines()
        .next_line()
        .await
        .expect("reads the floor's stderr")
        .expect("the floor says where it listens");
    let (http, grpc) = line
        .strip_prefix("kinserve-floor: REST on ")
        .and_then(|l| l.split_once(", gRPC on "))
        .unwrap_or_else(|| panic!("unexpected first line {line:?}"));
    Floor {
        http: http.to_string(),
        grpc: grpc.to_string(),
        _child: child,
        _tmp: tmp,
        answer: answer.to_vec(),
    }
}

/// `kinserve-load --verify` on one target of `floor`: everything answered,
/// no error, every pose checked.
async fn assert_clean(floor: &Floor, target: &str, pose_format: &str) {
    let args = kinserve_load::LoadArgs::parse_from([
        "kinserve-load",
        "--target",
        target,
        "--robot",
        "puma560",
        "--concurrency",
        "2",
        "--duration",
        "300ms",
        "--warmup",
        "0s",
        "--batch-size",
        "50",
        "--pipeline",
        "8",
        "--max-requests",
        "200",
        "--verify",
        "--pose-format",
        pose_format,
        "--http-addr",
        &floor.http,
        "--grpc-addr",
        &floor.grpc,
    ]);
    let what = format!("floor {target}/{pose_format}");
    let report = kinserve_load::run(args).await.expect(&what);
    assert!(report.sent > 0, "{what}: nothing sent");
    assert_eq!(report.answered, report.sent, "{what}: unanswered");
    assert!(report.errors.is_empty(), "{what}: {:?}", report.errors);
    assert!(report.verified, "{what}: not verified");
    let expected = match target {
        "grpc-health" => 0,
        "grpc-batch" | "grpc-batch-packed" => report.sent * 50,
        _ => report.sent,
    };
    assert_eq!(report.poses, expected, "{what}: poses");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_floor_answers_every_benchmark_row_with_verified_poses() {
    let floor = spawn_floor("puma560", br#"{"robot":"puma560"}"#).await;
    for (target, format) in [
        ("grpc-health", "full"),
        ("grpc-stream", "full"),
        ("grpc-stream", "matrix"),
        ("grpc-batch", "full"),
        ("grpc-batch-packed", "matrix"),
        ("grpc-batch-packed", "position"),
    ] {
        assert_clean(&floor, target, format).await;
    }
}

#[tokio::test]
async fn the_floor_answers_rest_fk_with_the_given_bytes_and_refuses_bad_bodies() {
    let floor = spawn_floor("puma560", br#"{"robot":"puma560","pose":{}}"#).await;
    let client = reqwest::Client::new();
    let fk = |body: &'static str| {
        client
            .post(format!("http://{}/v1/robots/puma560/fk", floor.http))
            .header("content-type", "application/json")
            .body(body)
            .send()
    };
    let ok = fk(FK_BODY).await.unwrap();
    assert_eq!(ok.status(), 200);
    assert_eq!(
        ok.headers()["content-type"].to_str().unwrap(),
        "application/json"
    );
    assert_eq!(ok.bytes().await.unwrap(), floor.answer);
    // Five joints for a six-joint arm, and not JSON at all.
    for bad in [r#"{"joints": [0.1, 0.2, 0.3, 0.4, 0.5]}"#, "joints"] {
        assert_eq!(fk(bad).await.unwrap().status(), 422, "{bad}");
    }
    let health = client
        .get(format!("http://{}/healthz", floor.http))
        .send()
        .await
        .unwrap();
    assert_eq!(health.text().await.unwrap(), "ok");
}

#[tokio::test]
async fn the_floor_listens_on_loopback_only() {
    let out = tokio::process::Command::new(env!("CARGO_BIN_EXE_kinserve-floor"))
        .args(["--robot-file", "unused.json", "--fk-answer", "unused.json"])
        .args(["--http-addr", "0.0.0.0:0", "--grpc-addr", "127.0.0.1:0"])
        .output()
        .await
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("loopback addresses only"));
}
