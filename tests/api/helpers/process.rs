//! The real `kinserve` binary as a child process.

use std::io::Read;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Duration;

// ---------------------------------------------------------------- the binary

/// A free TCP port on 127.0.0.1 (bound, read, released).
pub(crate) fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A `kinserve serve` child process.
pub(crate) struct Server {
    child: Child,
    /// `http://127.0.0.1:PORT`.
    pub http: String,
    /// `http://127.0.0.1:PORT` of the gRPC listener.
    pub grpc: String,
    stderr: Arc<Mutex<Vec<u8>>>,
}

impl Server {
    /// Everything the process wrote to stderr so far.
    pub fn stderr(&self) -> String {
        String::from_utf8_lossy(&self.stderr.lock().unwrap()).into_owned()
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Resident memory now and at its peak (`VmRSS`, `VmHWM` of
    /// `/proc/PID/status`), in MiB.
    pub fn memory_mib(&self) -> (f64, f64) {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.pid()))
            .expect("/proc/PID/status is readable");
        let field = |name: &str| {
            status
                .lines()
                .find_map(|l| l.strip_prefix(name))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
                .expect("memory field present")
                / 1024.0
        };
        (field("VmRSS:"), field("VmHWM:"))
    }

    /// `ws://127.0.0.1:PORT` of the REST listener.
    pub fn ws(&self) -> String {
        self.http.replacen("http", "ws", 1)
    }

    /// Sends `signal` (`TERM`, `INT`, …) without waiting.
    pub fn signal(&self, signal: &str) {
        let _ = Command::new("kill")
            .args([&format!("-{signal}"), &self.child.id().to_string()])
            .status();
    }

    /// The exit status, once the process has ended within `limit`.
    pub fn wait_exit(&mut self, limit: Duration) -> Option<std::process::ExitStatus> {
        let start = std::time::Instant::now();
        while start.elapsed() < limit {
            if let Ok(Some(status)) = self.child.try_wait() {
                return Some(status);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        None
    }

    /// `kill -9`.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// SIGTERM (graceful), then wait for the exit.
    pub fn terminate(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        for _ in 0..1000 {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        self.kill();
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.kill();
    }
}

pub(crate) fn robots_dir() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/robots").to_owned()
}

/// Starts the binary on free ports with `data_dir`, extra `env`, and
/// optionally through `sh -c <wrapper>` (the wrapper gets the binary as `$0`);
/// waits until `/readyz` answers 200.
pub(crate) async fn start_server(
    data_dir: &Path,
    env: &[(&str, &str)],
    wrapper: Option<&str>,
) -> Server {
    start_server_probed(data_dir, env, wrapper, None).await
}

/// [`start_server`], ready once `ready` says so (instead of a plain `GET /readyz`).
pub(crate) async fn start_server_probed(
    data_dir: &Path,
    env: &[(&str, &str)],
    wrapper: Option<&str>,
    ready: Option<&(dyn Fn(&Server) -> bool + Sync)>,
) -> Server {
    let mut last = String::new();
    for _attempt in 0..3 {
        let (hp, gp) = (free_port(), free_port());
        let bin = env!("CARGO_BIN_EXE_kinserve");
        let mut cmd = match wrapper {
            Some(script) => {
                let mut c = Command::new("sh");
                c.args(["-c", script, bin]);
                c
            }
            None => {
                let mut c = Command::new(bin);
                c.arg("serve");
                c
            }
        };
        cmd.env_clear()
            .env("PATH", std::env::var("PATH").unwrap_or_default())
            .env("KINSERVE_HTTP_ADDR", format!("127.0.0.1:{hp}"))
            .env("KINSERVE_GRPC_ADDR", format!("127.0.0.1:{gp}"))
            .env("KINSERVE_DATA_DIR", data_dir)
            .env("KINSERVE_ROBOTS_DIR", robots_dir())
            .env("RUST_LOG", "warn")
            // As ServeConfig::for_tests: tests register robots without a
            // token unless they set one (`env` may override this).
            .env("KINSERVE_ALLOW_UNAUTHENTICATED_WRITES", "true")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        for (k, v) in env {
            cmd.env(k, v);
        }
        let mut child = cmd.spawn().expect("kinserve binary starts");
        // stderr goes to a pipe (not a file: a file size limit must not hit the logs).
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let sink = stderr.clone();
        let mut pipe = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            let mut buf = [0u8; 8192];
            while let Ok(n) = pipe.read(&mut buf) {
                if n == 0 {
                    break;
                }
                sink.lock().unwrap().extend_from_slice(&buf[..n]);
            }
        });
        let server = Server {
            child,
            http: format!("http://127.0.0.1:{hp}"),
            grpc: format!("http://127.0.0.1:{gp}"),
            stderr,
        };
        let client = reqwest::Client::new();
        let mut server = server;
        for _ in 0..1000 {
            if let Ok(Some(_)) = server.child.try_wait() {
                break;
            }
            if let Some(ready) = ready {
                if ready(&server) {
                    return server;
                }
            } else if let Ok(r) = client.get(format!("{}/readyz", server.http)).send().await
                && r.status() == 200
            {
                return server;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        last = server.stderr();
        server.kill();
    }
    panic!("kinserve did not start: {last}");
}
