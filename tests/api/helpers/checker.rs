//! A parallel client checking correct FK over REST, gRPC and a WebSocket
//! while a hostile test runs.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use futures_util::SinkExt;
use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use kinserve::model::{AngleUnit, FkOptions};
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;

use crate::helpers::*;

/// Generous bound for "eventually" (liveness, not performance).
pub(crate) const EVENTUALLY: Duration = Duration::from_secs(10);

// ---------------------------------------------------------------- parallel FK client

/// Joint configurations (degrees) the parallel client cycles through.
pub(crate) const CHECK_CONFIGS: [[f64; 6]; 4] = [
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [10.0, -20.0, 30.0, -40.0, 50.0, -60.0],
    [-90.0, 45.0, 12.5, 100.0, -30.0, 170.0],
    [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
];

pub(crate) fn reference_matrices() -> Vec<Vec<f64>> {
    let robot = kinserve::model::load_robot_file(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/puma560.json"),
    )
    .unwrap();
    let opts = FkOptions {
        angle_unit: AngleUnit::Deg,
        check_limits: true,
    };
    CHECK_CONFIGS
        .iter()
        .map(|q| {
            let t = robot.fk(q, &opts).unwrap();
            t.matrix().iter().flatten().copied().collect()
        })
        .collect()
}

pub(crate) fn same_matrix(got: &[f64], want: &[f64]) -> bool {
    got.len() == 16
        && got
            .iter()
            .zip(want)
            .all(|(a, b)| (a - b).abs() <= 1e-12 * b.abs().max(1.0))
}

/// What the parallel client saw.
#[derive(Debug, Default)]
pub struct CheckReport {
    pub rest: usize,
    pub grpc: usize,
    pub ws: usize,
    pub failures: Vec<String>,
}

/// A client computing correct FK over REST, gRPC and a WebSocket in a loop,
/// checking every pose against the library, until stopped.
pub struct Checker {
    stop: Arc<AtomicBool>,
    task: tokio::task::JoinHandle<CheckReport>,
}

impl Checker {
    /// Starts the client; returns once its WebSocket is open (so that it
    /// holds its stream slot before an attack starts).
    pub async fn start(http: &str, grpc: &str, ws: &str) -> Checker {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let (http, grpc, ws) = (http.to_owned(), grpc.to_owned(), ws.to_owned());
        let (opened, ws_open) = tokio::sync::oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let want = reference_matrices();
            let client = reqwest::Client::new();
            let mut g = KinematicsServiceClient::connect(grpc).await.unwrap();
            let url = format!("{ws}/v1/robots/puma560/fk/stream");
            let (mut sock, _) = tokio_tungstenite::connect_async(url.as_str())
                .await
                .unwrap();
            let _ = opened.send(());
            let mut r = CheckReport::default();
            let mut i = 0usize;
            // At least one full round, then until told to stop.
            while i < CHECK_CONFIGS.len() || !flag.load(Ordering::Acquire) {
                let k = i % CHECK_CONFIGS.len();
                let q = CHECK_CONFIGS[k];
                i += 1;
                // REST
                let body = json!({"joints": q, "angle_unit": "deg"});
                match client
                    .post(format!("{http}/v1/robots/puma560/fk"))
                    .json(&body)
                    .send()
                    .await
                {
                    Ok(resp) if resp.status() == 200 => {
                        let v: Value = resp.json().await.unwrap_or(Value::Null);
                        if same_matrix(&matrix16(&v["pose"]), &want[k]) {
                            r.rest += 1;
                        } else {
                            r.failures.push(format!("REST wrong pose for {q:?}: {v}"));
                        }
                    }
                    Ok(resp) => r.failures.push(format!("REST status {}", resp.status())),
                    Err(e) => r.failures.push(format!("REST error {e}")),
                }
                // gRPC
                let req = pb::ForwardKinematicsRequest {
                    robot: "puma560".into(),
                    joints: q.to_vec(),
                    options: Some(pb::FkOptions {
                        angle_unit: pb::AngleUnit::Deg as i32,
                        ..Default::default()
                    }),
                };
                match g.forward_kinematics(req).await {
                    Ok(resp) => {
                        let m = resp.into_inner().pose.map(|p| p.matrix).unwrap_or_default();
                        if same_matrix(&m, &want[k]) {
                            r.grpc += 1;
                        } else {
                            r.failures.push(format!("gRPC wrong pose for {q:?}"));
                        }
                    }
                    Err(e) => r.failures.push(format!("gRPC error {e:?}")),
                }
                // WebSocket
                let msg = json!({"id": i, "joints": q, "angle_unit": "deg"}).to_string();
                if let Err(e) = sock.send(Message::Text(msg.into())).await {
                    r.failures.push(format!("WS send error {e}"));
                    break;
                }
                match tokio::time::timeout(EVENTUALLY, next_text(&mut sock)).await {
                    Ok(Some(v)) if v["id"] == json!(i) => {
                        if same_matrix(&matrix16(&v["pose"]), &want[k]) {
                            r.ws += 1;
                        } else {
                            r.failures.push(format!("WS wrong reply {v}"));
                        }
                    }
                    other => {
                        r.failures.push(format!("WS no reply: {other:?}"));
                        break;
                    }
                }
            }
            r
        });
        let _ = ws_open.await;
        Checker { stop, task }
    }

    /// Stops the client and asserts every answer it got was correct.
    pub async fn finish(self) -> CheckReport {
        self.stop.store(true, Ordering::Release);
        let r = self.task.await.expect("checker task");
        assert!(
            r.failures.is_empty(),
            "the parallel FK client saw failures: {:#?}",
            r.failures
        );
        assert!(r.rest > 0 && r.grpc > 0 && r.ws > 0, "{r:?}");
        r
    }
}
