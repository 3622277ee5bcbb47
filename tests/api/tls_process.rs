//! The real binary with TLS and required client certificates: `kinserve
//! healthcheck --tls` (with and without a client certificate), the client
//! certificate's subject in the access lines of both protocols and in the
//! audit line of a registry write (which still needs the API token), a
//! reload on SIGHUP, and a broken replacement that keeps the old certificate
//! with a warning.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::helpers::tls::*;
use crate::helpers::*;

const TOKEN: &str = "tls-audit-token";
const PLANNER: &str = "CN=planner, O=kinserve tests";

/// `kinserve healthcheck --tls` against `addr`, with the client certificate if given.
fn healthcheck(addr: &str, client: Option<(&Path, &Path)>) -> bool {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_kinserve"));
    cmd.env_clear()
        .args(["healthcheck", "--tls", "--timeout", "2s", "--addr", addr]);
    if let Some((cert, key)) = client {
        cmd.arg("--client-cert")
            .arg(cert)
            .arg("--client-key")
            .arg(key);
    }
    cmd.output().expect("healthcheck runs").status.success()
}

fn json_lines(stderr: &str) -> Vec<Value> {
    stderr
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_binary_logs_client_subjects_and_reloads_on_sighup() {
    let ca = TestCa::new("kinserve test CA");
    let dir = tempfile::tempdir().unwrap();
    let (cert, key) = write_pem(dir.path(), "server", &ca.server("generation-1"));
    let client = ca.client("planner");
    let (client_cert, client_key) = write_pem(dir.path(), "planner", &client);
    let ca_file = dir.path().join("clients-ca.pem");
    std::fs::write(&ca_file, ca.pem()).unwrap();
    let data = dir.path().join("data");
    let path = |p: &Path| p.to_str().unwrap().to_string();
    let (cert_s, key_s, ca_s) = (path(&cert), path(&key), path(&ca_file));
    let env = [
        ("RUST_LOG", "info"),
        ("KINSERVE_LOG_FORMAT", "json"),
        ("KINSERVE_API_TOKEN", TOKEN),
        ("KINSERVE_TLS_CERT", cert_s.as_str()),
        ("KINSERVE_TLS_KEY", key_s.as_str()),
        ("KINSERVE_TLS_CLIENT_CA", ca_s.as_str()),
        // Only SIGHUP reloads here.
        ("KINSERVE_TLS_RELOAD_INTERVAL", "0"),
    ];
    let probe_client = (client_cert.as_path(), client_key.as_path());
    let ready = move |s: &Server| healthcheck(&host_port(&s.http), Some(probe_client));
    let server = start_server_probed(&data, &env, None, Some(&ready)).await;
    let (http, grpc) = (host_port(&server.http), host_port(&server.grpc));
    assert!(
        !healthcheck(&http, None),
        "the probe without a client certificate is refused"
    );
    // A registry write over mutual TLS still needs the token.
    let config = client_config(&ca.pem(), Some(&client), &["http/1.1"]);
    let model = planar_model("mtls-robot").to_string();
    let put = |token| {
        let (config, model, http) = (config.clone(), model.clone(), http.clone());
        async move {
            let tls = tls_connect(&http, config).await.unwrap();
            h1_send(tls, "PUT", "/v1/robots/mtls-robot", &model, token).await
        }
    };
    assert_eq!(
        put(None).await,
        401,
        "a certificate does not replace the token"
    );
    assert_eq!(put(Some(TOKEN)).await, 201);
    let grpc_config = client_config(&ca.pem(), Some(&client), &["h2"]);
    let mut g = grpc_tls_client(&grpc, grpc_config).await;
    g.forward_kinematics(fk_request("planar_2dof", &[0.0, 0.0], None))
        .await
        .unwrap();
    // SIGHUP reloads.
    write_pem(dir.path(), "server", &ca.server("generation-2"));
    server.signal("HUP");
    let served = |config| {
        let http = http.clone();
        async move { server_cn(&tls_connect(&http, config).await.unwrap()) }
    };
    let deadline = Instant::now() + Duration::from_secs(5);
    while served(config.clone()).await != "CN=generation-2, O=kinserve tests" {
        assert!(Instant::now() < deadline, "SIGHUP did not reload");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    // A key that is not the certificate's: kept the old one, warned.
    std::fs::write(&key, ca.server("generation-3").key).unwrap();
    server.signal("HUP");
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(
        served(config.clone()).await,
        "CN=generation-2, O=kinserve tests"
    );
    assert!(healthcheck(&http, Some(probe_client)));
    let stderr = server.stderr();
    let lines = json_lines(&stderr);
    let warned = lines.iter().any(|l| {
        l["level"] == "WARN"
            && l["fields"]["message"]
                .as_str()
                .or(l["message"].as_str())
                .is_some_and(|m| m.contains("keeping the previous certificate"))
    });
    assert!(warned, "no warning for the broken certificate:\n{stderr}");
    let field = |l: &Value, k: &str| l.get(k).or_else(|| l["fields"].get(k)).cloned();
    let target = |l: &Value, t: &str| l["target"] == t;
    let access: Vec<_> = lines
        .iter()
        .filter(|l| target(l, "kinserve::access"))
        .collect();
    for protocol in ["http", "grpc"] {
        assert!(
            access
                .iter()
                .any(|l| field(l, "protocol") == Some(protocol.into())
                    && field(l, "client_cert") == Some(PLANNER.into())),
            "no {protocol} access line with the client's subject:\n{stderr}"
        );
    }
    let audit: Vec<_> = lines
        .iter()
        .filter(|l| target(l, "kinserve::audit"))
        .collect();
    assert!(
        audit
            .iter()
            .any(|l| field(l, "action") == Some("register".into())
                && field(l, "result") == Some("ok".into())
                && field(l, "client_cert") == Some(PLANNER.into())),
        "no audit line with the client's subject:\n{stderr}"
    );
    assert!(
        audit
            .iter()
            .any(|l| field(l, "result") == Some("refused".into())
                && field(l, "client_cert") == Some(PLANNER.into())),
        "the refused write names the client too:\n{stderr}"
    );
}
