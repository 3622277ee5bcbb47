//! `/metrics`: Prometheus conventions (`# HELP` and `# TYPE` on every family),
//! and what each front door records — gRPC calls by method and code,
//! WebSocket messages and stream lifetimes, poses by robot and protocol, store
//! write latency, build info and process metrics.

use std::collections::BTreeSet;

use futures_util::SinkExt;
use kinserve::api::grpc::pb;
use serde_json::json;
use tokio_tungstenite::tungstenite::Message;

use crate::helpers::*;

/// The value of the sample `name{labels}` (labels as printed, sorted by the exporter).
fn sample(text: &str, name_and_labels: &str) -> Option<f64> {
    text.lines()
        .find_map(|l| l.strip_prefix(name_and_labels)?.strip_prefix(' '))
        .and_then(|v| v.trim().parse().ok())
}

fn families(text: &str, prefix: &str) -> BTreeSet<String> {
    text.lines()
        .filter_map(|l| l.strip_prefix(prefix))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_front_door_is_measured_and_every_family_has_help() {
    let app = spawn_app().await;
    // REST: an FK and a registration.
    let r = app
        .post(
            "/v1/robots/puma560/fk",
            &json!({"joints": [0, 0, 0, 0, 0, 0]}),
        )
        .await;
    assert_eq!(r.status(), 200);
    assert_eq!(
        app.post("/v1/robots", &planar_model("metered"))
            .await
            .status(),
        201
    );
    // WebSocket: one good and one bad message, then close.
    let mut ws = open_ws(&app, "puma560").await;
    for m in [
        json!({"id": 1, "joints": [0, 0, 0, 0, 0, 0]}),
        json!({"id": 2, "joints": [0]}),
    ] {
        ws.send(Message::Text(m.to_string().into())).await.unwrap();
        next_text(&mut ws).await.unwrap();
    }
    ws.close(None).await.unwrap();
    drop(ws);
    // gRPC: one OK and one INVALID_ARGUMENT.
    let mut client = app.grpc_client().await;
    client
        .forward_kinematics(fk_request(
            "stanford",
            &[0.0, 0.0, 0.5, 0.0, 0.0, 0.0],
            None,
        ))
        .await
        .unwrap();
    client
        .forward_kinematics(fk_request("stanford", &[0.0], None))
        .await
        .unwrap_err();
    client
        .list_robots(pb::ListRobotsRequest::default())
        .await
        .unwrap();
    tokio::time::sleep(std::time::Duration::from_millis(200)).await;

    let text = app.get("/metrics").await.text().await.unwrap();
    let typed = families(&text, "# TYPE ");
    let helped = families(&text, "# HELP ");
    let missing: Vec<_> = typed.difference(&helped).collect();
    assert!(missing.is_empty(), "families without # HELP: {missing:?}");
    let at_least_one = [
        r#"kinserve_grpc_requests_total{method="ForwardKinematics",code="OK"}"#,
        r#"kinserve_grpc_requests_total{method="ForwardKinematics",code="INVALID_ARGUMENT"}"#,
        r#"kinserve_grpc_requests_total{method="ListRobots",code="OK"}"#,
        r#"kinserve_ws_messages_total{result="ok"}"#,
        r#"kinserve_ws_messages_total{result="error"}"#,
        r#"kinserve_poses_computed_total{robot="puma560",protocol="rest"}"#,
        r#"kinserve_poses_computed_total{robot="puma560",protocol="websocket"}"#,
        r#"kinserve_poses_computed_total{robot="stanford",protocol="grpc"}"#,
        r#"kinserve_store_write_duration_seconds_count{op="put"}"#,
        r#"kinserve_stream_duration_seconds_count{protocol="websocket"}"#,
        "process_resident_memory_bytes",
        "process_open_fds",
    ];
    for s in at_least_one {
        let v = sample(&text, s).unwrap_or_else(|| panic!("{s} not in /metrics:\n{text}"));
        assert!(v >= 1.0, "{s} = {v}");
    }
    let version = format!(
        r#"kinserve_build_info{{version="{}"}}"#,
        env!("CARGO_PKG_VERSION")
    );
    assert_eq!(sample(&text, &version), Some(1.0), "{text}");
    assert!(
        text.contains("kinserve_grpc_request_duration_seconds_bucket"),
        "{text}"
    );
    assert!(
        text.contains(r#"kinserve_robots{source="registered"}"#),
        "{text}"
    );
}

/// Every metric the Grafana dashboard (`deploy/grafana/kinserve.json`) queries
/// is one of the families the server documents and exports (histogram
/// suffixes stripped); the test above checks that they are exported.
#[test]
fn the_grafana_dashboard_queries_only_exported_metrics() {
    let exported: BTreeSet<String> = kinserve::telemetry::FAMILIES
        .iter()
        .map(|(name, _)| name.to_string())
        .collect();
    let dashboard: serde_json::Value =
        serde_json::from_str(include_str!("../../deploy/grafana/kinserve.json")).unwrap();
    let mut queried = BTreeSet::new();
    for panel in dashboard["panels"].as_array().unwrap() {
        for target in panel["targets"].as_array().unwrap() {
            let expr = target["expr"].as_str().unwrap();
            for word in expr.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_')) {
                if word.starts_with("kinserve_") || word.starts_with("process_") {
                    let family = ["_bucket", "_count", "_sum"]
                        .iter()
                        .fold(word, |w, s| w.strip_suffix(s).unwrap_or(w));
                    queried.insert(family.to_string());
                }
            }
        }
    }
    assert!(queried.len() >= 10, "{queried:?}");
    let unknown: Vec<_> = queried.difference(&exported).collect();
    assert!(
        unknown.is_empty(),
        "the dashboard queries unknown metrics: {unknown:?}"
    );
}
