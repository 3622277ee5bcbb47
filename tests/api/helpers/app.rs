//! Spawning the real server on port 0 (in process) and clients for it.

use std::path::{Path, PathBuf};

use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use kinserve::config::ServeConfig;
use kinserve::{App, ShutdownHandle};
use tonic::transport::Channel;

/// A running server with its own temporary data directory.
pub struct TestApp {
    /// `http://127.0.0.1:PORT`.
    pub http: String,
    /// `ws://127.0.0.1:PORT`.
    pub ws: String,
    /// `http://127.0.0.1:PORT` of the gRPC listener.
    pub grpc: String,
    /// HTTP client.
    pub client: reqwest::Client,
    /// The data directory (kept alive as long as the app).
    #[allow(
        dead_code,
        reason = "for tests that inspect or damage the data directory"
    )]
    pub data_dir: PathBuf,
    _tmp: Option<tempfile::TempDir>,
    shutdown: ShutdownHandle,
    task: Option<tokio::task::JoinHandle<std::io::Result<()>>>,
}

/// Starts a server with the test configuration.
pub async fn spawn_app() -> TestApp {
    spawn_app_with(|_| {}).await
}

/// Starts a server after `configure` adjusted its configuration.
pub async fn spawn_app_with(configure: impl FnOnce(&mut ServeConfig)) -> TestApp {
    let tmp = tempfile::tempdir().expect("temp dir");
    let dir = tmp.path().to_path_buf();
    let mut app = spawn_in(&dir, configure).await;
    app._tmp = Some(tmp);
    app
}

/// Starts a server serving TLS (`configure` sets the certificate): ready
/// once the service says so (the plain readiness probe cannot speak TLS).
pub async fn spawn_tls_app(configure: impl FnOnce(&mut ServeConfig)) -> TestApp {
    let tmp = tempfile::tempdir().expect("temp dir");
    let mut config = ServeConfig::for_tests(tmp.path().to_path_buf());
    configure(&mut config);
    assert!(config.tls.enabled(), "spawn_tls_app without --tls-cert");
    let mut app = start(config).await;
    app._tmp = Some(tmp);
    app
}

/// Starts a server on an existing data directory (for restart tests).
pub async fn spawn_in(data_dir: &Path, configure: impl FnOnce(&mut ServeConfig)) -> TestApp {
    let mut config = ServeConfig::for_tests(data_dir.to_path_buf());
    configure(&mut config);
    let t = start(config).await;
    t.wait_ready().await;
    t
}

/// Builds and runs the server of `config` (not waiting for readiness over HTTP).
async fn start(config: ServeConfig) -> TestApp {
    let data_dir = config.data_dir.clone();
    let tls = config.tls.enabled();
    let app = App::build(config).await.expect("server builds");
    let service = app.service();
    let http_port = app.http_port();
    let grpc_port = app.grpc_port();
    let shutdown = app.shutdown_handle();
    let task = tokio::spawn(app.run_until_stopped());
    let t = TestApp {
        http: format!("http://127.0.0.1:{http_port}"),
        ws: format!("ws://127.0.0.1:{http_port}"),
        grpc: format!("http://127.0.0.1:{grpc_port}"),
        client: reqwest::Client::new(),
        data_dir,
        _tmp: None,
        shutdown,
        task: Some(task),
    };
    if tls {
        for _ in 0..500 {
            if service.is_ready() {
                break;
            }
            tokio::time::sleep(std::time::Duration::from_millis(10)).await;
        }
    }
    t
}

impl TestApp {
    /// Polls `/readyz` until 200 (at most ~5 s).
    pub async fn wait_ready(&self) {
        for _ in 0..500 {
            if let Ok(r) = self
                .client
                .get(format!("{}/readyz", self.http))
                .send()
                .await
                && r.status() == 200
            {
                return;
            }
            tokio::time::sleep(std::time::Duration::from_millis(10)).await;
        }
        panic!("server did not become ready");
    }

    /// `POST {path}` with a JSON body.
    pub async fn post(&self, path: &str, body: &serde_json::Value) -> reqwest::Response {
        self.client
            .post(format!("{}{path}", self.http))
            .json(body)
            .send()
            .await
            .expect("request sent")
    }

    /// `POST {path}` with `body` of `content_type`, asking for `accept`
    /// (no `Accept` header when empty): the binary batch bodies.
    pub async fn post_bytes(
        &self,
        path: &str,
        content_type: &str,
        accept: &str,
        body: Vec<u8>,
    ) -> reqwest::Response {
        let mut req = self
            .client
            .post(format!("{}{path}", self.http))
            .header("content-type", content_type)
            .body(body);
        if !accept.is_empty() {
            req = req.header("accept", accept);
        }
        req.send().await.expect("request sent")
    }

    /// `GET {path}`.
    pub async fn get(&self, path: &str) -> reqwest::Response {
        self.client
            .get(format!("{}{path}", self.http))
            .send()
            .await
            .expect("request sent")
    }

    /// A gRPC client connected to the server.
    pub async fn grpc_client(&self) -> KinematicsServiceClient<Channel> {
        KinematicsServiceClient::connect(self.grpc.clone())
            .await
            .expect("grpc connects")
    }

    /// Starts the graceful shutdown without waiting for it (the drain's grace
    /// period, then the listeners close).
    pub fn begin_shutdown(&self) {
        self.shutdown.shutdown();
    }

    /// Stops the server gracefully and waits for it to exit; returns its result.
    pub async fn stop(mut self) -> std::io::Result<()> {
        self.shutdown.shutdown();
        match self.task.take() {
            Some(t) => t.await.expect("server task did not panic"),
            None => Ok(()),
        }
    }
}

impl Drop for TestApp {
    fn drop(&mut self) {
        self.shutdown.shutdown();
    }
}
