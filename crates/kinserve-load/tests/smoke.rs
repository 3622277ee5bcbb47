//! Smoke load test: the real `kinserve-load` binary against the real server on
//! port 0 (started in this process), every target, with `--verify`. Asserts
//! zero errors and that every request was answered; never a timing threshold.

use kinserve::config::ServeConfig;
use kinserve::{App, ShutdownHandle};

/// A running server with its own temporary data directory; stopped on drop.
struct TestApp {
    http: String,
    grpc: String,
    _tmp: tempfile::TempDir,
    shutdown: ShutdownHandle,
}

impl Drop for TestApp {
    fn drop(&mut self) {
        self.shutdown.shutdown();
    }
}

/// Starts the server with the test configuration and waits until `/readyz` is 200.
async fn spawn_app() -> TestApp {
    let app = spawn_app_with(|_| {}).await;
    let http = app.http.clone();
    let client = reqwest::Client::new();
    for _ in 0..500 {
        if let Ok(r) = client.get(format!("{http}/readyz")).send().await
            && r.status() == 200
        {
            return app;
        }
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    panic!("server not ready at {http}");
}

/// Starts the server with the test configuration changed by `configure`; its
/// listeners are bound when this returns (connections wait in the backlog
/// until it runs).
async fn spawn_app_with(configure: impl FnOnce(&mut ServeConfig)) -> TestApp {
    let tmp = tempfile::tempdir().expect("temp dir");
    // One load generator is one client: its share is the whole of each
    // budget here (the shares are tested in the server's hostile tests).
    let mut config = ServeConfig {
        client_share_percent: 100,
        ..ServeConfig::for_tests(tmp.path().join("data"))
    };
    configure(&mut config);
    let app = App::build(config).await.expect("server builds");
    let http = format!("http://127.0.0.1:{}", app.http_port());
    let grpc = format!("http://127.0.0.1:{}", app.grpc_port());
    let shutdown = app.shutdown_handle();
    tokio::spawn(app.run_until_stopped());
    TestApp {
        http,
        grpc,
        _tmp: tmp,
        shutdown,
    }
}

/// `kinserve-load` aimed at `app`: a short closed-loop run of at most 200
/// requests over two connections, verified, reported as JSON.
fn load_command(app: &TestApp, target: &str, robot: &str) -> tokio::process::Command {
    let http = app.http.trim_start_matches("http://");
    let grpc = app.grpc.trim_start_matches("http://");
    let mut cmd = tokio::process::Command::new(env!("CARGO_BIN_EXE_kinserve-load"));
    cmd.args(["--target", target, "--robot", robot, "--concurrency", "2"])
        .args([
            "--duration",
            "400ms",
            "--warmup",
            "0s",
            "--batch-size",
            "50",
        ])
        .args([
            "--pipeline",
            "8",
            "--max-requests",
            "200",
            "--verify",
            "--json",
        ])
        .args(["--http-addr", http, "--grpc-addr", grpc]);
    cmd
}

/// Runs `kinserve-load --verify` on one target and asserts a clean report:
/// everything answered, no error, the expected number of poses.
async fn run_clean(app: &TestApp, target: &str, robot: &str, pose_format: &str) {
    let mut cmd = load_command(app, target, robot);
    cmd.args(["--pose-format", pose_format]);
    assert_clean_report(
        cmd,
        &format!("{target}/{robot}/{pose_format}"),
        target,
        pose_format,
    )
    .await;
}

/// Runs `cmd` (from [`load_command`]) and asserts a clean report.
async fn assert_clean_report(
    cmd: tokio::process::Command,
    what: &str,
    target: &str,
    pose_format: &str,
) {
    assert_clean_report_of(cmd, what, target, pose_format, 1).await
}

/// [`assert_clean_report`] of a run whose stream messages carry `per_message`
/// configurations each.
async fn assert_clean_report_of(
    mut cmd: tokio::process::Command,
    what: &str,
    target: &str,
    pose_format: &str,
    per_message: u64,
) {
    let out = cmd.output().await.expect("kinserve-load runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{what}: exit {:?}\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_str(&stdout).expect("JSON report");
    let sent = report["sent"].as_u64().unwrap();
    assert!(sent > 0, "{what}: nothing sent");
    assert_eq!(
        report["answered"].as_u64().unwrap(),
        sent,
        "{what}: unanswered requests"
    );
    assert_eq!(report["errors"], serde_json::json!({}), "{what}: errors");
    assert_eq!(report["verified"], true);
    assert_eq!(report["pose_format"], pose_format);
    let poses = report["poses"].as_u64().unwrap();
    match target {
        "rest-health" | "grpc-health" => assert_eq!(poses, 0),
        "rest-batch" | "rest-batch-packed" | "grpc-batch" | "grpc-batch-packed" => {
            assert_eq!(poses, sent * 50, "{what}: poses per batch")
        }
        _ => assert_eq!(poses, sent * per_message, "{what}: poses per message"),
    }
    assert_eq!(report["per_message"].as_u64(), Some(per_message), "{what}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_load_target_runs_clean_with_verification() {
    let app = spawn_app().await;
    let targets = [
        "rest-health",
        "rest",
        "rest-batch",
        "rest-batch-packed",
        "ws",
        "grpc-health",
        "grpc",
        "grpc-batch",
        "grpc-batch-packed",
        "grpc-stream",
    ];
    for target in targets {
        for robot in ["puma560", "stanford"] {
            run_clean(&app, target, robot, "full").await;
        }
    }
}

/// `--pose-format matrix` on every FK target (each protocol: REST single and
/// batch, WebSocket, gRPC unary, batch and stream), `position` on the
/// batches; `--verify` checks the compact numbers against the library.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn compact_pose_formats_run_clean_with_verification_on_every_protocol() {
    let app = spawn_app().await;
    for target in [
        "rest",
        "rest-batch",
        "rest-batch-packed",
        "ws",
        "grpc",
        "grpc-batch",
        "grpc-batch-packed",
        "grpc-stream",
    ] {
        run_clean(&app, target, "panda", "matrix").await;
    }
    for target in [
        "rest-batch",
        "rest-batch-packed",
        "grpc-batch",
        "grpc-batch-packed",
        "ws",
    ] {
        run_clean(&app, target, "puma560", "position").await;
    }
}

/// `--per-message 5`: every stream message carries five configurations
/// (`configurations`; on gRPC also `packed_configurations` with `--packed`)
/// and is answered with five poses, each verified, on the WebSocket and the
/// gRPC stream, in the full and the compact formats.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stream_messages_of_many_configurations_run_clean_with_verification() {
    let app = spawn_app().await;
    for (target, robot, pose_format) in [
        ("ws", "puma560", "full"),
        ("ws", "panda", "matrix"),
        ("ws", "stanford", "position"),
        ("grpc-stream", "puma560", "full"),
        ("grpc-stream", "panda", "matrix"),
        ("grpc-stream", "stanford", "position"),
    ] {
        let mut cmd = load_command(&app, target, robot);
        cmd.args(["--pose-format", pose_format, "--per-message", "5"]);
        let what = format!("{target}/{robot}/{pose_format} x5");
        assert_clean_report_of(cmd, &what, target, pose_format, 5).await;
    }
    for (robot, pose_format) in [("panda", "matrix"), ("stanford", "full")] {
        let mut cmd = load_command(&app, "grpc-stream", robot);
        cmd.args([
            "--pose-format",
            pose_format,
            "--per-message",
            "5",
            "--packed",
        ]);
        let what = format!("grpc-stream/{robot}/{pose_format} x5 packed");
        assert_clean_report_of(cmd, &what, "grpc-stream", pose_format, 5).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn open_loop_mode_runs_and_an_unknown_robot_fails_the_run() {
    let app = spawn_app().await;
    let http = app.http.trim_start_matches("http://").to_string();
    let grpc = app.grpc.trim_start_matches("http://").to_string();
    // Open loop at a modest rate: everything sent is answered.
    let out = tokio::process::Command::new(env!("CARGO_BIN_EXE_kinserve-load"))
        .args([
            "--target",
            "rest",
            "--concurrency",
            "2",
            "--duration",
            "500ms",
            "--warmup",
            "0s",
            "--rate",
            "200",
        ])
        .args([
            "--verify",
            "--json",
            "--http-addr",
            &http,
            "--grpc-addr",
            &grpc,
        ])
        .output()
        .await
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["mode"], "open@200");
    assert!(report["sent"].as_u64().unwrap() > 0);
    // An unknown robot is an error and a non-zero exit.
    let out = tokio::process::Command::new(env!("CARGO_BIN_EXE_kinserve-load"))
        .args([
            "--target",
            "grpc",
            "--robot",
            "no-such-robot",
            "--duration",
            "200ms",
            "--warmup",
            "0s",
        ])
        .args(["--http-addr", &http, "--grpc-addr", &grpc])
        .output()
        .await
        .expect("runs");
    assert!(!out.status.success());
}

/// A test CA (PEM) and a server certificate for `localhost` signed by it,
/// written as `ca.pem`, `server.crt` and `server.key` in `dir`.
fn write_test_certificates(dir: &std::path::Path) {
    use rcgen::{
        BasicConstraints, CertificateParams, CertifiedIssuer, DnType, IsCa, KeyPair,
        KeyUsagePurpose,
    };
    let mut ca = CertificateParams::new(vec![]).unwrap();
    ca.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    ca.distinguished_name
        .push(DnType::CommonName, "kinserve-load test CA");
    ca.key_usages = vec![KeyUsagePurpose::KeyCertSign];
    let issuer = CertifiedIssuer::self_signed(ca, KeyPair::generate().unwrap()).unwrap();
    std::fs::write(dir.join("ca.pem"), issuer.pem()).unwrap();
    let leaf = CertificateParams::new(vec!["localhost".to_string()]).unwrap();
    let key = KeyPair::generate().unwrap();
    let cert = leaf.signed_by(&key, &issuer).unwrap();
    std::fs::write(dir.join("server.crt"), cert.pem()).unwrap();
    std::fs::write(dir.join("server.key"), key.serialize_pem()).unwrap();
}

/// With `--tls-ca` every gRPC target runs clean against a server with
/// `--tls-cert` / `--tls-key` (the robot fetched over gRPC through the same
/// TLS); a CA that did not sign the server's certificate fails the run; a
/// REST target with `--tls-ca` is refused naming the flag.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_grpc_targets_run_clean_over_tls_with_the_servers_ca() {
    let certs = tempfile::tempdir().unwrap();
    write_test_certificates(certs.path());
    let dir = certs.path().to_path_buf();
    let app = spawn_app_with(|c| {
        c.tls.tls_cert = Some(dir.join("server.crt"));
        c.tls.tls_key = Some(dir.join("server.key"));
    })
    .await;
    let ca = certs.path().join("ca.pem");
    for target in ["grpc-health", "grpc", "grpc-batch", "grpc-stream"] {
        let mut cmd = load_command(&app, target, "puma560");
        cmd.arg("--tls-ca").arg(&ca);
        assert_clean_report(cmd, &format!("{target} over TLS"), target, "full").await;
    }
    // Plain gRPC to the TLS listener, and TLS trusting another CA, both fail.
    let other = tempfile::tempdir().unwrap();
    write_test_certificates(other.path());
    for tls_ca in [None, Some(other.path().join("ca.pem"))] {
        let mut cmd = load_command(&app, "grpc", "puma560");
        if let Some(ca) = &tls_ca {
            cmd.arg("--tls-ca").arg(ca);
        }
        let out = cmd.output().await.expect("runs");
        assert!(
            !out.status.success(),
            "gRPC with CA {tls_ca:?} to a server of another CA succeeded"
        );
    }
    let mut cmd = load_command(&app, "rest", "puma560");
    let out = cmd.arg("--tls-ca").arg(&ca).output().await.expect("runs");
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--tls-ca"), "{stderr}");
}
