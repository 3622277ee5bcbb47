//! Distributed traces of the real binary: an in-process OTLP collector (the
//! collector's `TraceService` over gRPC, or `POST /v1/traces` over HTTP)
//! receives the spans of REST and gRPC calls that carry a caller's
//! `traceparent`: the caller's trace id, the caller's span as the server
//! span's parent, the inner spans (body read, validation, compute, compute
//! pool, encode, store write) under it, the robot and batch size as
//! attributes and no joint value; the server's `traceparent` answered. With
//! no `--otlp-endpoint` nothing is exported and no exporter thread runs.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use opentelemetry_proto::tonic::collector::trace::v1::trace_service_server::{
    TraceService, TraceServiceServer,
};
use opentelemetry_proto::tonic::collector::trace::v1::{
    ExportTraceServiceRequest, ExportTraceServiceResponse,
};
use opentelemetry_proto::tonic::common::v1::any_value::Value as AnyValue;
use opentelemetry_proto::tonic::trace::v1::Span;
use serde_json::{Value, json};

use crate::helpers::*;

/// The spans a collector received, and how many export requests it got.
#[derive(Clone, Default)]
struct Received(Arc<Mutex<(Vec<Span>, usize)>>);

impl Received {
    fn add(&self, req: ExportTraceServiceRequest) {
        let mut got = self.0.lock().unwrap();
        got.1 += 1;
        for rs in req.resource_spans {
            for ss in rs.scope_spans {
                got.0.extend(ss.spans);
            }
        }
    }

    fn exports(&self) -> usize {
        self.0.lock().unwrap().1
    }

    fn spans_of(&self, trace: &[u8]) -> Vec<Span> {
        let got = self.0.lock().unwrap();
        got.0
            .iter()
            .filter(|s| s.trace_id == trace)
            .cloned()
            .collect()
    }

    fn all(&self) -> Vec<Span> {
        self.0.lock().unwrap().0.clone()
    }

    /// The spans of `trace` once `want` of them have arrived (within 20 s).
    async fn wait_for(&self, trace: &[u8], want: impl Fn(&[Span]) -> bool) -> Vec<Span> {
        for _ in 0..200 {
            let spans = self.spans_of(trace);
            if want(&spans) {
                return spans;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        let names: Vec<String> = self.all().iter().map(|s| s.name.clone()).collect();
        panic!(
            "the spans of trace {} did not all arrive; received: {names:?}",
            hex(trace)
        );
    }
}

#[tonic::async_trait]
impl TraceService for Received {
    async fn export(
        &self,
        req: tonic::Request<ExportTraceServiceRequest>,
    ) -> Result<tonic::Response<ExportTraceServiceResponse>, tonic::Status> {
        self.add(req.into_inner());
        Ok(tonic::Response::new(ExportTraceServiceResponse {
            partial_success: None,
        }))
    }
}

/// An OTLP/gRPC collector on a free port: its URL and what it receives.
async fn grpc_collector() -> (String, Received) {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    let received = Received::default();
    let service = TraceServiceServer::new(received.clone());
    tokio::spawn(
        tonic::transport::Server::builder()
            .add_service(service)
            .serve_with_incoming(tokio_stream::wrappers::TcpListenerStream::new(listener)),
    );
    (url, received)
}

/// An OTLP/HTTP collector (`POST /v1/traces`, protobuf) on a free port.
async fn http_collector() -> (String, Received) {
    use prost::Message;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    let received = Received::default();
    let sink = received.clone();
    let app = axum::Router::new().route(
        "/v1/traces",
        axum::routing::post(move |body: axum::body::Bytes| {
            let sink = sink.clone();
            async move {
                let req = ExportTraceServiceRequest::decode(body).expect("an OTLP protobuf body");
                sink.add(req);
                (
                    [("content-type", "application/x-protobuf")],
                    ExportTraceServiceResponse {
                        partial_success: None,
                    }
                    .encode_to_vec(),
                )
            }
        }),
    );
    tokio::spawn(async move { axum::serve(listener, app).await });
    (url, received)
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

/// A caller's context: trace id and span id, as hex.
struct Caller {
    trace: &'static str,
    span: &'static str,
}

impl Caller {
    fn traceparent(&self) -> String {
        format!("00-{}-{}-01", self.trace, self.span)
    }
}

const REST_CALLER: Caller = Caller {
    trace: "4bf92f3577b34da6a3ce929d0e0e4736",
    span: "00f067aa0ba902b7",
};
const GRPC_CALLER: Caller = Caller {
    trace: "0af7651916cd43dd8448eb211c80319c",
    span: "b7ad6b7169203331",
};
const BATCH_CALLER: Caller = Caller {
    trace: "5b8aa5a2d2c872e8321cf37308d69df2",
    span: "051581bf3cb55c13",
};
const STORE_CALLER: Caller = Caller {
    trace: "11111111111111111111111111111111",
    span: "2222222222222222",
};

/// A joint value to look for in the spans (it must never be there).
const JOINT: f64 = 0.123_456_789;

fn attr<'s>(span: &'s Span, key: &str) -> Option<&'s AnyValue> {
    span.attributes
        .iter()
        .find(|kv| kv.key == key)
        .and_then(|kv| kv.value.as_ref())
        .and_then(|v| v.value.as_ref())
}

fn named<'s>(spans: &'s [Span], name: &str) -> &'s Span {
    spans
        .iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("no span {name} in {:?}", names(spans)))
}

fn names(spans: &[Span]) -> Vec<&str> {
    spans.iter().map(|s| s.name.as_str()).collect()
}

/// The server span's `traceparent` answered: (trace id, span id) as hex.
fn answered(value: Option<&str>) -> (String, String) {
    let v = value.expect("a traceparent in the answer");
    let parts: Vec<&str> = v.split('-').collect();
    assert_eq!(parts.len(), 4, "{v}");
    assert_eq!(parts[0], "00", "{v}");
    (parts[1].to_string(), parts[2].to_string())
}

/// No attribute of any span holds a joint value or the request body.
fn assert_no_joint_values(spans: &[Span]) {
    for s in spans {
        for kv in &s.attributes {
            let text = format!("{:?}", kv.value);
            assert!(
                !text.contains("0.123456") && !text.contains("joints"),
                "span {} attribute {} = {text}",
                s.name,
                kv.key
            );
        }
    }
}

async fn rest_fk(server: &Server, caller: &Caller) -> reqwest::Response {
    let resp = reqwest::Client::new()
        .post(format!("{}/v1/robots/puma560/fk", server.http))
        .header("traceparent", caller.traceparent())
        .header("tracestate", "vendor=opaque")
        .json(&json!({"joints": [JOINT, 0, 0, 0, 0, 0]}))
        .send()
        .await
        .unwrap();
    assert_eq!(resp.status(), 200);
    resp
}

async fn grpc_fk(server: &Server, caller: &Caller) -> tonic::metadata::MetadataMap {
    let mut client =
        kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient::connect(
            server.grpc.clone(),
        )
        .await
        .unwrap();
    let mut req = tonic::Request::new(fk_request(
        "puma560",
        &[JOINT, 0.0, 0.0, 0.0, 0.0, 0.0],
        None,
    ));
    req.metadata_mut()
        .insert("traceparent", caller.traceparent().parse().unwrap());
    client
        .forward_kinematics(req)
        .await
        .unwrap()
        .metadata()
        .clone()
}

fn exporting_env(endpoint: &str, protocol: &'static str) -> Vec<(&'static str, String)> {
    vec![
        ("KINSERVE_OTLP_ENDPOINT", endpoint.to_string()),
        ("KINSERVE_OTLP_PROTOCOL", protocol.to_string()),
        // Export within 100 ms instead of the SDK's 5 s.
        ("OTEL_BSP_SCHEDULE_DELAY", "100".to_string()),
        ("RUST_LOG", "info".to_string()),
        ("KINSERVE_LOG_FORMAT", "json".to_string()),
    ]
}

async fn start(dir: &std::path::Path, env: &[(&'static str, String)]) -> Server {
    let env: Vec<(&str, &str)> = env.iter().map(|(k, v)| (*k, v.as_str())).collect();
    start_server(dir, &env, None).await
}

/// Threads of the process whose name starts with `prefix` (`/proc/PID/task/*/comm`).
fn threads_named(pid: u32, prefix: &str) -> usize {
    std::fs::read_dir(format!("/proc/{pid}/task"))
        .map(|tasks| {
            tasks
                .filter_map(|t| t.ok())
                .filter_map(|t| std::fs::read_to_string(t.path().join("comm")).ok())
                .filter(|name| name.starts_with(prefix))
                .count()
        })
        .unwrap_or(0)
}

/// The batch processor's thread ("OpenTelemetry.Traces.BatchProcessor", cut to 15 bytes).
const EXPORTER_THREAD: &str = "OpenTelemetry.T";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rest_and_grpc_spans_reach_the_collector_as_children_of_the_callers_spans() {
    let (endpoint, received) = grpc_collector().await;
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), &exporting_env(&endpoint, "grpc")).await;
    assert_eq!(threads_named(server.pid(), EXPORTER_THREAD), 1);

    // REST: the server span is the caller's child; its id is answered.
    let resp = rest_fk(&server, &REST_CALLER).await;
    let header = |name: &str| {
        resp.headers()
            .get(name)
            .map(|v| v.to_str().unwrap().to_string())
    };
    let (trace, server_span) = answered(header("traceparent").as_deref());
    assert_eq!(trace, REST_CALLER.trace);
    assert_ne!(server_span, REST_CALLER.span);
    assert_eq!(header("tracestate").as_deref(), Some("vendor=opaque"));
    let want = [
        "POST /v1/robots/{name}/fk",
        "read body",
        "validate",
        "compute",
        "encode",
    ];
    let spans = received
        .wait_for(&unhex(REST_CALLER.trace), |s| {
            want.iter().all(|w| s.iter().any(|x| x.name == *w))
        })
        .await;
    let root = named(&spans, want[0]);
    assert_eq!(root.parent_span_id, unhex(REST_CALLER.span));
    assert_eq!(root.span_id, unhex(&server_span));
    assert_eq!(root.kind, 2, "SPAN_KIND_SERVER");
    assert_eq!(
        attr(root, "kinserve.robot"),
        Some(&AnyValue::StringValue("puma560".into()))
    );
    assert_eq!(
        attr(root, "http.response.status_code"),
        Some(&AnyValue::IntValue(200))
    );
    for inner in &want[1..] {
        assert_eq!(named(&spans, inner).parent_span_id, root.span_id, "{inner}");
    }

    // gRPC: the same from the call's metadata.
    let metadata = grpc_fk(&server, &GRPC_CALLER).await;
    let (trace, server_span) = answered(metadata.get("traceparent").map(|v| v.to_str().unwrap()));
    assert_eq!(trace, GRPC_CALLER.trace);
    let spans = received
        .wait_for(&unhex(GRPC_CALLER.trace), |s| {
            s.len() >= 4
                && s.iter()
                    .any(|x| x.name == "kinematics.v1.KinematicsService/ForwardKinematics")
        })
        .await;
    let root = spans
        .iter()
        .find(|s| s.name == "kinematics.v1.KinematicsService/ForwardKinematics")
        .unwrap_or_else(|| panic!("no gRPC server span in {:?}", names(&spans)));
    assert_eq!(root.parent_span_id, unhex(GRPC_CALLER.span));
    assert_eq!(root.span_id, unhex(&server_span));
    assert_eq!(root.kind, 2);
    assert_eq!(
        attr(root, "rpc.system"),
        Some(&AnyValue::StringValue("grpc".into()))
    );
    assert_eq!(
        attr(root, "kinserve.robot"),
        Some(&AnyValue::StringValue("puma560".into()))
    );
    for inner in ["validate", "compute", "encode"] {
        assert_eq!(named(&spans, inner).parent_span_id, root.span_id, "{inner}");
    }
    assert_no_joint_values(&received.all());

    // The access log names the trace.
    tokio::time::sleep(Duration::from_millis(200)).await;
    let lines: Vec<Value> = server
        .stderr()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .filter(|l: &Value| l["target"] == "kinserve::access")
        .collect();
    for (protocol, trace) in [("http", REST_CALLER.trace), ("grpc", GRPC_CALLER.trace)] {
        assert!(
            lines
                .iter()
                .any(|l| l["protocol"] == protocol && l["trace_id"] == trace),
            "no {protocol} access line with trace_id {trace}: {lines:?}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn batches_carry_their_span_onto_the_compute_pool_and_store_writes_are_spanned() {
    let (endpoint, received) = grpc_collector().await;
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), &exporting_env(&endpoint, "grpc")).await;
    let client = reqwest::Client::new();
    // Past the size computed on the request's thread: the batch goes to the pool.
    let n = kinserve::service::FK_BATCH_INLINE + 1;
    let mut configurations = vec![json!([0, 0, 0, 0, 0, 1]); n];
    configurations[0] = json!([JOINT, 0, 0, 0, 0, 0]);
    let batch = client
        .post(format!("{}/v1/robots/puma560/fk/batch", server.http))
        .header("traceparent", BATCH_CALLER.traceparent())
        .json(&json!({ "configurations": configurations }))
        .send()
        .await
        .unwrap();
    assert_eq!(batch.status(), 200);
    // The request's own span ends after the answer is written (a streamed
    // one here), possibly in a later export than the pool's spans: wait for all.
    let spans = received
        .wait_for(&unhex(BATCH_CALLER.trace), |s| {
            ["compute pool", "compute", "POST /v1/robots/{name}/fk/batch"]
                .iter()
                .all(|name| s.iter().any(|x| x.name == *name))
        })
        .await;
    let root = named(&spans, "POST /v1/robots/{name}/fk/batch");
    assert_eq!(root.parent_span_id, unhex(BATCH_CALLER.span));
    assert_eq!(
        attr(root, "kinserve.batch_size"),
        Some(&AnyValue::IntValue(n as i64))
    );
    let pool = named(&spans, "compute pool");
    assert_eq!(pool.parent_span_id, root.span_id);
    // The work on the blocking thread is the pool span's child.
    assert_eq!(named(&spans, "compute").parent_span_id, pool.span_id);
    assert_eq!(named(&spans, "validate").parent_span_id, pool.span_id);

    let put = client
        .put(format!("{}/v1/robots/traced", server.http))
        .header("traceparent", STORE_CALLER.traceparent())
        .json(&planar_model("traced"))
        .send()
        .await
        .unwrap();
    assert_eq!(put.status(), 201);
    let spans = received
        .wait_for(&unhex(STORE_CALLER.trace), |s| {
            ["store write", "PUT /v1/robots/{name}"]
                .iter()
                .all(|name| s.iter().any(|x| x.name == *name))
        })
        .await;
    let root = named(&spans, "PUT /v1/robots/{name}");
    let write = named(&spans, "store write");
    assert_eq!(write.parent_span_id, root.span_id);
    assert_eq!(
        attr(write, "operation"),
        Some(&AnyValue::StringValue("put".into()))
    );
    assert_eq!(
        attr(root, "kinserve.robot"),
        Some(&AnyValue::StringValue("traced".into()))
    );
    assert_no_joint_values(&received.all());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn spans_are_exported_over_otlp_http_too() {
    let (endpoint, received) = http_collector().await;
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), &exporting_env(&endpoint, "http")).await;
    let resp = rest_fk(&server, &REST_CALLER).await;
    let (_, server_span) = answered(
        resp.headers()
            .get("traceparent")
            .map(|v| v.to_str().unwrap()),
    );
    let spans = received
        .wait_for(&unhex(REST_CALLER.trace), |s| {
            s.iter().any(|x| x.name == "POST /v1/robots/{name}/fk")
        })
        .await;
    let root = named(&spans, "POST /v1/robots/{name}/fk");
    assert_eq!(root.parent_span_id, unhex(REST_CALLER.span));
    assert_eq!(root.span_id, unhex(&server_span));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_an_otlp_endpoint_nothing_is_exported_and_no_exporter_runs() {
    let (endpoint, received) = grpc_collector().await;
    let dir = tempfile::tempdir().unwrap();
    // The SDK's own variables point at a live collector: they must not turn export on.
    let env = vec![
        ("OTEL_EXPORTER_OTLP_ENDPOINT", endpoint.clone()),
        ("OTEL_EXPORTER_OTLP_TRACES_ENDPOINT", endpoint),
        ("OTEL_BSP_SCHEDULE_DELAY", "100".to_string()),
        ("RUST_LOG", "info".to_string()),
        ("KINSERVE_LOG_FORMAT", "json".to_string()),
    ];
    let server = start(dir.path(), &env).await;
    let resp = rest_fk(&server, &REST_CALLER).await;
    assert!(resp.headers().get("traceparent").is_none());
    let metadata = grpc_fk(&server, &GRPC_CALLER).await;
    assert!(metadata.get("traceparent").is_none());
    tokio::time::sleep(Duration::from_millis(1500)).await;
    assert_eq!(
        received.exports(),
        0,
        "nothing is sent without --otlp-endpoint"
    );
    assert_eq!(threads_named(server.pid(), EXPORTER_THREAD), 0);
    let stderr = server.stderr();
    assert!(
        stderr.contains("trace export off"),
        "no start-up line saying export is off:\n{stderr}"
    );
    // The caller's trace id is still in the access log, for correlation.
    let has_trace = |protocol: &str, trace: &str| {
        stderr
            .lines()
            .filter_map(|l| serde_json::from_str::<Value>(l).ok())
            .any(|l| {
                l["target"] == "kinserve::access"
                    && l["protocol"] == protocol
                    && l["trace_id"] == trace
            })
    };
    assert!(has_trace("http", REST_CALLER.trace), "{stderr}");
    assert!(has_trace("grpc", GRPC_CALLER.trace), "{stderr}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sample_ratio_of_zero_drops_new_traces_but_follows_a_sampled_caller() {
    let (endpoint, received) = grpc_collector().await;
    let dir = tempfile::tempdir().unwrap();
    let mut env = exporting_env(&endpoint, "grpc");
    env.push(("KINSERVE_TRACE_SAMPLE_RATIO", "0".to_string()));
    let server = start(dir.path(), &env).await;
    let client = reqwest::Client::new();
    // No caller: a new trace, not sampled (flags 00), still answered.
    let alone = client
        .post(format!("{}/v1/robots/puma560/fk", server.http))
        .json(&json!({"joints": [0, 0, 0, 0, 0, 0]}))
        .send()
        .await
        .unwrap();
    let value = alone.headers()["traceparent"].to_str().unwrap().to_string();
    assert!(value.ends_with("-00"), "{value}");
    let (unsampled, _) = answered(Some(&value));
    // A sampled caller's decision is followed.
    rest_fk(&server, &REST_CALLER).await;
    received
        .wait_for(&unhex(REST_CALLER.trace), |s| {
            s.iter().any(|x| x.name == "POST /v1/robots/{name}/fk")
        })
        .await;
    assert!(received.spans_of(&unhex(&unsampled)).is_empty());
}

const WS_CALLER: Caller = Caller {
    trace: "33333333333333333333333333333333",
    span: "4444444444444444",
};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_websocket_upgrade_joins_the_callers_trace_and_its_stream_is_spanned() {
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    let (endpoint, received) = grpc_collector().await;
    let dir = tempfile::tempdir().unwrap();
    let server = start(dir.path(), &exporting_env(&endpoint, "grpc")).await;
    let mut req = format!("{}/v1/robots/puma560/fk/stream", server.ws())
        .into_client_request()
        .unwrap();
    req.headers_mut()
        .insert("traceparent", WS_CALLER.traceparent().parse().unwrap());
    let (mut sock, resp) = tokio_tungstenite::connect_async(req).await.unwrap();
    let (trace, upgrade_span) = answered(
        resp.headers()
            .get("traceparent")
            .map(|v| v.to_str().unwrap()),
    );
    assert_eq!(trace, WS_CALLER.trace);
    let reply = ws_ask(
        &mut sock,
        &json!({"id": 1, "joints": [JOINT, 0, 0, 0, 0, 0]}),
    )
    .await;
    assert!(reply.get("pose").is_some(), "{reply}");
    drop(sock);
    let spans = received
        .wait_for(&unhex(WS_CALLER.trace), |s| {
            ["stream", "GET /v1/robots/{name}/fk/stream"]
                .iter()
                .all(|name| s.iter().any(|x| x.name == *name))
        })
        .await;
    let root = named(&spans, "GET /v1/robots/{name}/fk/stream");
    assert_eq!(root.parent_span_id, unhex(WS_CALLER.span));
    assert_eq!(root.span_id, unhex(&upgrade_span));
    assert_eq!(
        attr(root, "http.response.status_code"),
        Some(&AnyValue::IntValue(101))
    );
    let stream = named(&spans, "stream");
    assert_eq!(stream.parent_span_id, root.span_id);
    assert_eq!(
        attr(stream, "protocol"),
        Some(&AnyValue::StringValue("websocket".into()))
    );
    assert_no_joint_values(&received.all());
}
