//! Headless Chromium over the W3C WebDriver HTTP API, for the playground
//! tests (`tests/api/browser.rs`, `tests/api/browser_ik.rs`): finding
//! `chromium` and `chromedriver`, a driver process, a session with a small
//! client written on reqwest, and console-log filtering.
//!
//! Needs `chromium` and `chromium-driver` (`.ci/run` installs them). Without
//! them a test fails when `CI=true` and is skipped with a message otherwise
//! ([`browser_or_skip`]).

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

/// The W3C key of a web element reference.
pub(crate) const ELEMENT_KEY: &str = "element-6066-11e4-a52e-4f735466cecf";
/// Longest wait for anything the page does (bounded polling, no timing asserts).
/// Generous: a busy two-core CI machine running the hostile tests beside
/// Chromium once took over 20 s to show an IK answer.
pub(crate) const WAIT: Duration = Duration::from_secs(60);
pub(crate) const POLL: Duration = Duration::from_millis(50);
pub(crate) const FK_TOL: f64 = 1e-9;

/// How to install what the browser tests need (their SKIPPED line and, under
/// CI, their failure say it).
pub(crate) const SKIP_FIX: &str = "apt-get install chromium chromium-driver; .ci/run installs them";

// ------------------------------------------------------------ binaries --

/// `chromedriver` and the Chromium binary, or `None` when either is missing.
pub(crate) fn find_browser() -> Option<(PathBuf, PathBuf)> {
    let on_path = |name: &str| -> Option<PathBuf> {
        std::env::var_os("PATH").and_then(|paths| {
            std::env::split_paths(&paths)
                .map(|d| d.join(name))
                .find(|p| p.is_file())
        })
    };
    let driver = Some(PathBuf::from("/usr/bin/chromedriver"))
        .filter(|p| p.is_file())
        .or_else(|| on_path("chromedriver"))?;
    let chromium = Some(PathBuf::from("/usr/bin/chromium"))
        .filter(|p| p.is_file())
        .or_else(|| on_path("chromium"))?;
    Some((driver, chromium))
}

/// A port that was free a moment ago.
pub(crate) fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("bind a free port")
        .port()
}

/// The cargo target directory (parent of `CARGO_TARGET_TMPDIR`).
pub(crate) fn target_dir() -> PathBuf {
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
    tmp.parent().unwrap_or(tmp).to_path_buf()
}

// ---------------------------------------------------------- the driver --

/// A running chromedriver; killed (with its process group) on drop.
pub(crate) struct Driver {
    child: Child,
    url: String,
    port: u16,
    log: PathBuf,
}

impl Driver {
    /// Starts chromedriver on a free port and waits for `/status` to be ready.
    pub(crate) async fn start(path: &Path, http: &reqwest::Client) -> Driver {
        let mut last_err = String::new();
        for attempt in 0..3 {
            let port = free_port();
            let log = std::env::temp_dir().join(format!(
                "kinserve-chromedriver-{}-{attempt}.log",
                std::process::id()
            ));
            let mut cmd = Command::new(path);
            cmd.arg(format!("--port={port}"))
                .arg(format!("--log-path={}", log.display()))
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null());
            #[cfg(unix)]
            {
                use std::os::unix::process::CommandExt;
                // Its own process group, so that Chromium goes down with it.
                cmd.process_group(0);
            }
            let child = cmd
                .spawn()
                .unwrap_or_else(|e| panic!("cannot start {}: {e}", path.display()));
            let mut d = Driver {
                child,
                url: format!("http://127.0.0.1:{port}"),
                port,
                log,
            };
            match d.wait_ready(http).await {
                Ok(()) => return d,
                Err(e) => last_err = e, // dropping `d` kills it; try another port
            }
        }
        panic!("chromedriver did not become ready: {last_err}");
    }

    pub(crate) async fn wait_ready(&mut self, http: &reqwest::Client) -> Result<(), String> {
        let deadline = Instant::now() + WAIT;
        let mut last = String::from("no answer");
        while Instant::now() < deadline {
            if let Ok(Some(status)) = self.child.try_wait() {
                return Err(format!("chromedriver exited: {status}"));
            }
            match http.get(format!("{}/status", self.url)).send().await {
                Ok(r) => match r.json::<Value>().await {
                    Ok(v) if v["value"]["ready"] == true => return Ok(()),
                    Ok(v) => last = v.to_string(),
                    Err(e) => last = e.to_string(),
                },
                Err(e) => last = e.to_string(),
            }
            tokio::time::sleep(POLL).await;
        }
        Err(format!("/status not ready after {WAIT:?}: {last}"))
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        #[cfg(unix)]
        {
            // SIGKILL to the whole group (chromedriver and any Chromium left).
            // Best effort: `kill` is in procps, which a bare image may lack;
            // the child itself is killed below in any case.
            let _ = Command::new("kill")
                .args(["-KILL", "--", &format!("-{}", self.child.id())])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .status();
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.log);
    }
}

/// A WebDriver session in headless Chromium. Dropping it deletes the session
/// (closing Chromium), then kills chromedriver, then removes the profile.
pub(crate) struct Browser {
    http: reqwest::Client,
    /// `http://127.0.0.1:PORT/session/ID`.
    base: String,
    id: String,
    deleted: bool,
    /// Whether `goog:loggingPrefs` gave us the browser console log.
    pub(crate) log_endpoint: bool,
    driver: Driver,
    _profile: tempfile::TempDir,
}

#[derive(Clone, Debug)]
pub(crate) struct Element(pub(crate) String);

impl Browser {
    pub(crate) async fn start(driver_path: &Path, chromium: &Path) -> Browser {
        let http = reqwest::Client::builder()
            .timeout(Duration::from_secs(60))
            .build()
            .expect("http client");
        let driver = Driver::start(driver_path, &http).await;
        let profile = tempfile::tempdir().expect("temp profile dir");
        let caps = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:loggingPrefs": {"browser": "ALL"},
            "goog:chromeOptions": {
                "binary": chromium.to_string_lossy(),
                "args": [
                    "--headless=new",
                    "--no-sandbox",
                    "--disable-gpu",
                    "--disable-dev-shm-usage",
                    "--disable-background-networking",
                    "--disable-component-update",
                    "--disable-sync",
                    "--no-first-run",
                    "--window-size=1280,800",
                    format!("--user-data-dir={}", profile.path().display()),
                ],
            },
        }}});
        let resp = http
            .post(format!("{}/session", driver.url))
            .json(&caps)
            .send()
            .await
            .expect("POST /session");
        let status = resp.status();
        let v: Value = resp.json().await.expect("session reply is JSON");
        assert!(
            status.is_success(),
            "new session failed ({status}): {v} (chromedriver log: {})",
            std::fs::read_to_string(&driver.log).unwrap_or_default()
        );
        let id = v["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no sessionId in {v}"))
            .to_string();
        let base = format!("{}/session/{id}", driver.url);
        let mut b = Browser {
            http,
            base,
            id,
            deleted: false,
            log_endpoint: false,
            driver,
            _profile: profile,
        };
        // Probe the (non-W3C) log endpoint once; it also drains startup noise.
        b.log_endpoint = b
            .try_cmd("POST", "/se/log", json!({"type": "browser"}))
            .await
            .is_ok();
        b
    }

    /// One WebDriver command; `Err` carries the WebDriver error.
    pub(crate) async fn try_cmd(
        &self,
        method: &str,
        path: &str,
        body: Value,
    ) -> Result<Value, String> {
        let url = format!("{}{path}", self.base);
        let req = match method {
            "GET" => self.http.get(url),
            "DELETE" => self.http.delete(url),
            _ => self.http.post(url).json(&body),
        };
        let resp = req
            .send()
            .await
            .map_err(|e| format!("{method} {path}: {e}"))?;
        let status = resp.status();
        let v: Value = resp
            .json()
            .await
            .map_err(|e| format!("{method} {path}: reply is not JSON: {e}"))?;
        if status.is_success() {
            Ok(v["value"].clone())
        } else {
            Err(format!("{method} {path} -> {status}: {}", v["value"]))
        }
    }

    pub(crate) async fn cmd(&self, method: &str, path: &str, body: Value) -> Value {
        self.try_cmd(method, path, body)
            .await
            .unwrap_or_else(|e| panic!("WebDriver: {e}"))
    }

    pub(crate) async fn goto(&self, url: &str) {
        self.cmd("POST", "/url", json!({"url": url})).await;
    }

    /// Runs `script` (a function body; `arguments` holds `args`) and returns its value.
    pub(crate) async fn exec(&self, script: &str, args: Value) -> Value {
        self.cmd(
            "POST",
            "/execute/sync",
            json!({"script": script, "args": args}),
        )
        .await
    }

    pub(crate) async fn try_find(&self, css: &str) -> Option<Element> {
        let v = self
            .try_cmd(
                "POST",
                "/element",
                json!({"using": "css selector", "value": css}),
            )
            .await;
        v.ok()?[ELEMENT_KEY]
            .as_str()
            .map(|s| Element(s.to_string()))
    }

    pub(crate) async fn find(&self, css: &str) -> Element {
        match self.try_find(css).await {
            Some(e) => e,
            None => panic!("no element matches {css:?}"),
        }
    }

    /// Polls `find` until the element exists.
    pub(crate) async fn wait_find(&self, css: &str) -> Element {
        let deadline = Instant::now() + WAIT;
        loop {
            if let Some(e) = self.try_find(css).await {
                return e;
            }
            if Instant::now() >= deadline {
                let page = self
                    .exec(
                        "return document.body ? document.body.innerText.slice(0, 2000) : null;",
                        json!([]),
                    )
                    .await;
                let log = self.console_log().await;
                panic!(
                    "no element matches {css:?} after {WAIT:?}; page text: {page}; console: {log:?}"
                );
            }
            tokio::time::sleep(POLL).await;
        }
    }

    pub(crate) async fn text(&self, e: &Element) -> String {
        self.cmd("GET", &format!("/element/{}/text", e.0), Value::Null)
            .await
            .as_str()
            .unwrap_or_default()
            .to_string()
    }

    pub(crate) async fn click(&self, e: &Element) {
        self.cmd("POST", &format!("/element/{}/click", e.0), json!({}))
            .await;
    }

    pub(crate) async fn send_keys(&self, e: &Element, text: &str) {
        self.cmd(
            "POST",
            &format!("/element/{}/value", e.0),
            json!({"text": text}),
        )
        .await;
    }

    pub(crate) async fn set_window(&self, width: u32, height: u32) {
        self.cmd(
            "POST",
            "/window/rect",
            json!({"width": width, "height": height}),
        )
        .await;
    }

    /// Saves a screenshot of the viewport as PNG.
    pub(crate) async fn screenshot(&self, path: &Path) {
        let b64 = self.cmd("GET", "/screenshot", Value::Null).await;
        let png = base64_decode(b64.as_str().expect("screenshot is a string"));
        assert!(
            png.starts_with(b"\x89PNG\r\n\x1a\n"),
            "screenshot is not a PNG"
        );
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).expect("screenshot dir");
        }
        std::fs::write(path, png).expect("write screenshot");
    }

    /// Browser console entries since the last call (the log is drained on read).
    pub(crate) async fn console_log(&self) -> Vec<Value> {
        if !self.log_endpoint {
            return Vec::new();
        }
        self.cmd("POST", "/se/log", json!({"type": "browser"}))
            .await
            .as_array()
            .cloned()
            .unwrap_or_default()
    }

    /// Polls `script` until it returns `true`; panics with `what` and the
    /// last value of `describe` after [`WAIT`].
    pub(crate) async fn wait_until(&self, what: &str, script: &str, args: Value, describe: &str) {
        let deadline = Instant::now() + WAIT;
        loop {
            if self.exec(script, args.clone()).await == Value::Bool(true) {
                return;
            }
            if Instant::now() >= deadline {
                let state = self.exec(describe, args.clone()).await;
                let log = self.console_log().await;
                panic!(
                    "timed out after {WAIT:?} waiting for {what}; page state: {state}; console: {log:?}"
                );
            }
            tokio::time::sleep(POLL).await;
        }
    }

    pub(crate) async fn close(mut self) {
        self.cmd("DELETE", "", Value::Null).await;
        self.deleted = true;
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        if !self.deleted {
            // Synchronous best-effort `DELETE /session/{id}` (we may be
            // unwinding inside the runtime, so no async client here).
            let _ = delete_session_blocking(self.driver.port, &self.id);
        }
        // Then `driver` drops (kills chromedriver's group), then the profile.
    }
}

pub(crate) fn delete_session_blocking(port: u16, id: &str) -> std::io::Result<()> {
    let mut s = TcpStream::connect(("127.0.0.1", port))?;
    s.set_read_timeout(Some(Duration::from_secs(10)))?;
    s.set_write_timeout(Some(Duration::from_secs(10)))?;
    write!(
        s,
        "DELETE /session/{id} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
    )?;
    // Read until the reply is complete (chromedriver may keep the connection
    // open), so that Chromium has quit before chromedriver is killed.
    let mut buf = Vec::new();
    let mut chunk = [0u8; 4096];
    loop {
        let n = s.read(&mut chunk)?;
        if n == 0 {
            return Ok(());
        }
        buf.extend_from_slice(&chunk[..n]);
        let text = String::from_utf8_lossy(&buf);
        if let Some(end) = text.find("\r\n\r\n") {
            let len = text[..end]
                .lines()
                .find_map(|l| {
                    let (k, v) = l.split_once(':')?;
                    k.eq_ignore_ascii_case("content-length")
                        .then(|| v.trim().parse::<usize>().ok())?
                })
                .unwrap_or(0);
            if buf.len() >= end + 4 + len {
                return Ok(());
            }
        }
    }
}

pub(crate) fn base64_decode(s: &str) -> Vec<u8> {
    pub(crate) fn val(c: u8) -> Option<u32> {
        match c {
            b'A'..=b'Z' => Some((c - b'A') as u32),
            b'a'..=b'z' => Some((c - b'a' + 26) as u32),
            b'0'..=b'9' => Some((c - b'0' + 52) as u32),
            b'+' => Some(62),
            b'/' => Some(63),
            _ => None,
        }
    }
    let mut out = Vec::with_capacity(s.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in s.bytes() {
        if c == b'=' {
            break;
        }
        let Some(v) = val(c) else { continue }; // line breaks
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    out
}

// ------------------------------------------------------------- page bits --

/// Console entries that are errors (level SEVERE), minus those `allowed` says are expected.
pub(crate) fn console_errors(entries: &[Value], allowed: impl Fn(&str) -> bool) -> Vec<String> {
    entries
        .iter()
        .filter(|e| e["level"] == "SEVERE" || e["level"] == "ERROR")
        .map(|e| e["message"].as_str().unwrap_or_default().to_string())
        .filter(|m| !allowed(m))
        .collect()
}

/// The browser binaries, or `None` after printing SKIPPED (a failure under
/// CI, where the test must run: `kinserve_testkit::skip_unless_ci`).
pub(crate) fn browser_or_skip() -> Option<(PathBuf, PathBuf)> {
    let found = find_browser();
    if found.is_none() {
        kinserve_testkit::skip_unless_ci(
            "browser test",
            "chromium and/or chromedriver missing",
            SKIP_FIX,
        );
    }
    found
}
