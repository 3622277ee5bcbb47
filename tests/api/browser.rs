//! End-to-end test of the web playground in headless Chromium.
//!
//! Drives Debian's `chromium` through `chromedriver` over the W3C WebDriver
//! HTTP API, with a small client written here on reqwest. The page is served
//! by the real server (`spawn_app`) and what it shows is checked against the
//! REST API.
//!
//! Needs `chromium` and `chromium-driver` (`.ci/run` installs them). Without
//! them the test fails when `CI=true` and is skipped with a message otherwise.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use crate::helpers::*;

/// The W3C key of a web element reference.
const ELEMENT_KEY: &str = "element-6066-11e4-a52e-4f735466cecf";
/// Longest wait for anything the page does (bounded polling, no timing asserts).
const WAIT: Duration = Duration::from_secs(20);
const POLL: Duration = Duration::from_millis(50);
const FK_TOL: f64 = 1e-9;

const SKIP_MESSAGE: &str = "SKIPPED: browser test needs chromium + chromium-driver (apt-get install chromium chromium-driver)";

// ------------------------------------------------------------ binaries --

/// `chromedriver` and the Chromium binary, or `None` when either is missing.
fn find_browser() -> Option<(PathBuf, PathBuf)> {
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
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("bind a free port")
        .port()
}

/// The cargo target directory (parent of `CARGO_TARGET_TMPDIR`).
fn target_dir() -> PathBuf {
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
    tmp.parent().unwrap_or(tmp).to_path_buf()
}

// ---------------------------------------------------------- the driver --

/// A running chromedriver; killed (with its process group) on drop.
struct Driver {
    child: Child,
    url: String,
    port: u16,
    log: PathBuf,
}

impl Driver {
    /// Starts chromedriver on a free port and waits for `/status` to be ready.
    async fn start(path: &Path, http: &reqwest::Client) -> Driver {
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

    async fn wait_ready(&mut self, http: &reqwest::Client) -> Result<(), String> {
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
struct Browser {
    http: reqwest::Client,
    /// `http://127.0.0.1:PORT/session/ID`.
    base: String,
    id: String,
    deleted: bool,
    /// Whether `goog:loggingPrefs` gave us the browser console log.
    log_endpoint: bool,
    driver: Driver,
    _profile: tempfile::TempDir,
}

#[derive(Clone, Debug)]
struct Element(String);

impl Browser {
    async fn start(driver_path: &Path, chromium: &Path) -> Browser {
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
    async fn try_cmd(&self, method: &str, path: &str, body: Value) -> Result<Value, String> {
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

    async fn cmd(&self, method: &str, path: &str, body: Value) -> Value {
        self.try_cmd(method, path, body)
            .await
            .unwrap_or_else(|e| panic!("WebDriver: {e}"))
    }

    async fn goto(&self, url: &str) {
        self.cmd("POST", "/url", json!({"url": url})).await;
    }

    /// Runs `script` (a function body; `arguments` holds `args`) and returns its value.
    async fn exec(&self, script: &str, args: Value) -> Value {
        self.cmd(
            "POST",
            "/execute/sync",
            json!({"script": script, "args": args}),
        )
        .await
    }

    async fn try_find(&self, css: &str) -> Option<Element> {
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

    async fn find(&self, css: &str) -> Element {
        match self.try_find(css).await {
            Some(e) => e,
            None => panic!("no element matches {css:?}"),
        }
    }

    /// Polls `find` until the element exists.
    async fn wait_find(&self, css: &str) -> Element {
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

    async fn text(&self, e: &Element) -> String {
        self.cmd("GET", &format!("/element/{}/text", e.0), Value::Null)
            .await
            .as_str()
            .unwrap_or_default()
            .to_string()
    }

    async fn click(&self, e: &Element) {
        self.cmd("POST", &format!("/element/{}/click", e.0), json!({}))
            .await;
    }

    async fn send_keys(&self, e: &Element, text: &str) {
        self.cmd(
            "POST",
            &format!("/element/{}/value", e.0),
            json!({"text": text}),
        )
        .await;
    }

    async fn set_window(&self, width: u32, height: u32) {
        self.cmd(
            "POST",
            "/window/rect",
            json!({"width": width, "height": height}),
        )
        .await;
    }

    /// Saves a screenshot of the viewport as PNG.
    async fn screenshot(&self, path: &Path) {
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
    async fn console_log(&self) -> Vec<Value> {
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
    async fn wait_until(&self, what: &str, script: &str, args: Value, describe: &str) {
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

    async fn close(mut self) {
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

fn delete_session_blocking(port: u16, id: &str) -> std::io::Result<()> {
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

fn base64_decode(s: &str) -> Vec<u8> {
    fn val(c: u8) -> Option<u32> {
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
fn console_errors(entries: &[Value], allowed: impl Fn(&str) -> bool) -> Vec<String> {
    entries
        .iter()
        .filter(|e| e["level"] == "SEVERE" || e["level"] == "ERROR")
        .map(|e| e["message"].as_str().unwrap_or_default().to_string())
        .filter(|m| !allowed(m))
        .collect()
}

/// `#pos` text "x, y, z" as numbers.
fn parse_pos(text: &str) -> [f64; 3] {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| {
            s.trim()
                .parse::<f64>()
                .unwrap_or_else(|e| panic!("#pos {text:?}: {e}"))
        })
        .collect();
    assert_eq!(v.len(), 3, "#pos has three numbers: {text:?}");
    [v[0], v[1], v[2]]
}

/// `data-fk-count` of the body.
async fn fk_count(b: &Browser) -> u64 {
    b.exec(
        "return Number(document.body.dataset.fkCount || 0);",
        json!([]),
    )
    .await
    .as_u64()
    .expect("fk count")
}

/// Waits until an FK reply for exactly `joints` (after reply number `after`) is shown.
async fn wait_fk_shown(b: &Browser, after: u64, joints: &[f64]) {
    b.wait_until(
        &format!("an FK reply for {joints:?} after reply #{after}"),
        "const [after, want] = arguments;
         const d = document.body.dataset;
         if (Number(d.fkCount || 0) <= after) return false;
         let got; try { got = JSON.parse(d.lastJoints || 'null'); } catch { return false; }
         return Array.isArray(got) && got.length === want.length && got.every((v, i) => v === want[i])
           && document.getElementById('pos').textContent !== '';",
        json!([after, joints]),
        "return {count: document.body.dataset.fkCount, last: document.body.dataset.lastJoints,
                 pos: document.getElementById('pos').textContent,
                 fkError: document.getElementById('fk-error').textContent};",
    )
    .await;
}

/// Checks `#pos` against the REST answer for the joints the page says it shows.
async fn assert_pos_matches_rest(app: &TestApp, b: &Browser, joints: &[f64]) {
    let shown: Vec<f64> = serde_json::from_str(
        b.exec("return document.body.dataset.lastJoints;", json!([]))
            .await
            .as_str()
            .expect("data-last-joints"),
    )
    .expect("data-last-joints is JSON");
    assert_eq!(shown, joints, "the page shows the joints that were set");
    let pos_text = b.text(&b.find("#pos").await).await;
    let pos = parse_pos(&pos_text);
    let resp = app
        .post(
            "/v1/robots/puma560/fk",
            &json!({"joints": joints, "angle_unit": "deg"}),
        )
        .await;
    assert_eq!(resp.status(), 200);
    let body: Value = resp.json().await.expect("fk json");
    let want = position(&body["pose"]);
    for k in 0..3 {
        assert_close(
            pos[k],
            want[k],
            FK_TOL,
            &format!("#pos[{k}] for {joints:?} (page {pos_text:?})"),
        );
    }
}

/// Pixel statistics of the `#view` canvas.
async fn canvas_stats(b: &Browser) -> Value {
    b.exec(
        r#"const c = document.getElementById('view');
        if (!c || !c.getContext) return null;
        const w = c.width, h = c.height;
        const d = c.getContext('2d').getImageData(0, 0, w, h).data;
        const legend = 32 * (window.devicePixelRatio || 1); // rows of the axis legend
        const colours = new Set();
        let link = 0, red = 0, green = 0, blue = 0, ink = 0, hash = 0;
        for (let i = 0; i < d.length; i += 4) {
          const r = d[i], g = d[i + 1], b = d[i + 2], a = d[i + 3];
          colours.add((r << 16) | (g << 8) | b);
          hash = (Math.imul(hash, 31) + ((r << 16) | (g << 8) | b) + a) | 0;
          if (a < 200) continue;
          if (0.299 * r + 0.587 * g + 0.114 * b < 150) ink++;
          if (Math.abs(r - 0x50) < 8 && Math.abs(g - 0x60) < 8 && Math.abs(b - 0x7a) < 8) link++;
          if (Math.floor(i / 4 / w) < legend) continue;
          if (r > 170 && g < 80 && b < 80) red++;
          if (g > 130 && r < 90 && b < 90) green++;
          if (b > 170 && r < 80 && g < 140) blue++;
        }
        return {w, h, colours: colours.size, link, red, green, blue, ink, hash};"#,
        json!([]),
    )
    .await
}

/// Sets slider `i` through script and fires `input` and `change` as a user would.
async fn move_slider(b: &Browser, i: usize, value: f64) {
    let ok = b
        .exec(
            "const [id, v] = arguments;
             const r = document.getElementById(id);
             if (!r) return false;
             r.value = String(v);
             r.dispatchEvent(new Event('input', {bubbles: true}));
             r.dispatchEvent(new Event('change', {bubbles: true}));
             return true;",
            json!([format!("joint-{i}"), value]),
        )
        .await;
    assert_eq!(ok, Value::Bool(true), "slider #joint-{i} exists");
}

async fn slider_values(b: &Browser) -> Vec<f64> {
    let v = b
        .exec(
            "return [...document.querySelectorAll('#joints input[type=range]')].map((r) => Number(r.value));",
            json!([]),
        )
        .await;
    serde_json::from_value(v).expect("slider values")
}

/// Horizontal overflow at the current width: `{inner, client, scroll, culprits}`.
async fn overflow_report(b: &Browser) -> Value {
    b.exec(
        "const de = document.documentElement;
         const culprits = [];
         for (const e of document.querySelectorAll('body *')) {
           const r = e.getBoundingClientRect();
           if (r.width > 0 && (r.right > de.clientWidth + 0.5 || r.left < -0.5)) {
             culprits.push(`${e.tagName.toLowerCase()}${e.id ? '#' + e.id : ''}${e.className && typeof e.className === 'string' ? '.' + e.className.split(' ').join('.') : ''} [${Math.round(r.left)}, ${Math.round(r.right)}]`);
           }
         }
         return {inner: window.innerWidth, client: de.clientWidth, scroll: de.scrollWidth,
                 body: document.body.scrollWidth, culprits: culprits.slice(0, 20)};",
        json!([]),
    )
    .await
}

// ------------------------------------------------------------------ test --

#[tokio::test]
async fn playground_in_headless_chromium_matches_the_rest_api() {
    let Some((driver, chromium)) = find_browser() else {
        if std::env::var("CI").as_deref() == Ok("true") {
            panic!(
                "CI=true but the browser test cannot run: chromium and/or chromedriver missing \
                 (apt-get install chromium chromium-driver; .ci/run does this)"
            );
        }
        // Straight to the process' stderr: the test harness would swallow
        // `eprintln!` of a passing test, and the skip must be visible.
        let _ = writeln!(std::io::stderr().lock(), "{SKIP_MESSAGE}");
        return;
    };
    let started = Instant::now();
    let app = spawn_app().await;
    let b = Browser::start(&driver, &chromium).await;
    if !b.log_endpoint {
        eprintln!(
            "note: chromedriver has no /se/log; console errors are caught by an injected hook only"
        );
    }

    // Load the page; hook console.error/onerror as a second line of defence
    // (the chromedriver log also sees errors raised before this runs).
    b.goto(&format!("{}/", app.http)).await;
    b.exec(
        "window.__errors = [];
         const orig = console.error.bind(console);
         console.error = (...a) => { window.__errors.push(a.map(String).join(' ')); orig(...a); };
         window.addEventListener('error', (e) => window.__errors.push(`error: ${e.message}`));
         window.addEventListener('unhandledrejection', (e) => window.__errors.push(`unhandled rejection: ${e.reason}`));
         return true;",
        json!([]),
    )
    .await;

    // Choose another robot, then PUMA 560 from the list (a real click on its option).
    b.wait_find("#robot-select option[value='puma560']").await;
    b.wait_until(
        "the first robot to be shown with a live stream",
        "return Number(document.body.dataset.fkCount || 0) > 0 && document.getElementById('ws-status').dataset.state === 'open';",
        json!([]),
        "return {count: document.body.dataset.fkCount, ws: document.getElementById('ws-status').textContent, err: document.getElementById('global-error').textContent};",
    )
    .await;
    b.click(&b.find("#robot-select option[value='ur5']").await)
        .await;
    b.wait_until(
        "ur5 to be selected",
        "return document.getElementById('robot-summary').textContent.startsWith('ur5:');",
        json!([]),
        "return document.getElementById('robot-summary').textContent;",
    )
    .await;
    b.click(&b.find("#robot-select option[value='puma560']").await)
        .await;
    b.wait_until(
        "puma560 to be selected with six sliders and a pose",
        "return document.getElementById('robot-select').value === 'puma560'
           && document.getElementById('robot-summary').textContent.startsWith('puma560:')
           && document.querySelectorAll('#joints input[type=range]').length === 6
           && document.body.dataset.lastJoints === '[0,0,0,0,0,0]'
           && document.getElementById('pos').textContent !== ''
           && document.getElementById('ws-status').dataset.state === 'open';",
        json!([]),
        "return {sel: document.getElementById('robot-select').value,
                 summary: document.getElementById('robot-summary').textContent,
                 sliders: document.querySelectorAll('#joints input[type=range]').length,
                 last: document.body.dataset.lastJoints, pos: document.getElementById('pos').textContent};",
    )
    .await;
    assert_pos_matches_rest(&app, &b, &[0.0; 6]).await;

    // The canvas shows the robot (link colour and triads outside the legend).
    b.wait_until(
        "the 3D view to draw the robot",
        "const c = document.getElementById('view');
         const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
         for (let i = 0; i < d.length; i += 4)
           if (Math.abs(d[i] - 0x50) < 8 && Math.abs(d[i + 1] - 0x60) < 8 && Math.abs(d[i + 2] - 0x7a) < 8) return true;
         return false;",
        json!([]),
        "const c = document.getElementById('view'); return {w: c.width, h: c.height};",
    )
    .await;
    let before = canvas_stats(&b).await;

    // Move sliders (script sets the value and fires input/change).
    let mut joints = [30.0, -45.5, 12.3, 100.0, -20.0, 7.5];
    let count = fk_count(&b).await;
    for (i, v) in joints.iter().enumerate() {
        move_slider(&b, i, *v).await;
    }
    assert_eq!(slider_values(&b).await, joints, "sliders hold the values");
    wait_fk_shown(&b, count, &joints).await;
    assert_pos_matches_rest(&app, &b, &joints).await;
    for (i, v) in joints.iter().enumerate() {
        let num = b
            .exec(
                "return document.getElementById(arguments[0]).value;",
                json!([format!("joint-{i}-value")]),
            )
            .await;
        assert_eq!(
            num.as_str().and_then(|s| s.parse::<f64>().ok()),
            Some(*v),
            "#joint-{i}-value follows its slider"
        );
    }

    // Keyboard: the slider moves with the arrow keys (WebDriver key events).
    let count = fk_count(&b).await;
    b.send_keys(&b.find("#joint-0").await, "\u{E014}").await; // ArrowRight
    joints[0] = 30.1; // one step of 0.1°
    assert_eq!(
        slider_values(&b).await,
        joints,
        "ArrowRight moves J1 one step"
    );
    wait_fk_shown(&b, count, &joints).await;
    assert_pos_matches_rest(&app, &b, &joints).await;

    // The canvas is not blank and it changed with the pose.
    let stats = {
        let deadline = Instant::now() + WAIT;
        loop {
            let s = canvas_stats(&b).await;
            if s["hash"] != before["hash"] || Instant::now() >= deadline {
                break s;
            }
            tokio::time::sleep(POLL).await;
        }
    };
    let n = |k: &str| stats[k].as_u64().unwrap_or(0);
    let pixels = n("w") * n("h");
    assert!(pixels > 0, "canvas has a size: {stats}");
    assert!(
        n("colours") > 50,
        "canvas has more than a flat fill: {stats}"
    );
    assert!(n("link") > 200, "links drawn in #50607a: {stats}");
    assert!(
        n("red") > 10 && n("green") > 10 && n("blue") > 10,
        "x/y/z triads drawn: {stats}"
    );
    assert!(
        n("ink") > pixels / 500,
        "enough dark pixels (robot, grid, labels): {stats}"
    );
    assert_ne!(
        stats["hash"], before["hash"],
        "the view redrew after the sliders moved: {before} vs {stats}"
    );

    // Fit keeps the drawing (no exception, still drawn).
    b.click(&b.find("#fit").await).await;

    let console = b.console_log().await;
    let errors = console_errors(&console, |_| false);
    assert!(errors.is_empty(), "console errors so far: {errors:?}");

    let shot_1280 = target_dir().join("playground-1280.png");
    b.screenshot(&shot_1280).await;
    if std::env::var("KINSERVE_UPDATE_SCREENSHOT").as_deref() == Ok("1") {
        let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs");
        std::fs::create_dir_all(&docs).expect("docs dir");
        std::fs::copy(&shot_1280, docs.join("playground.png")).expect("copy screenshot to docs");
    }

    // An invalid model: the field error is shown (list and editor marker).
    let bad = json!({
        "name": "browser-bad",
        "convention": "standard",
        "angle_unit": "deg",
        "length_unit": "m",
        "links": [
            {"joint": "revolute", "a": 0.5, "alpha": "x", "d": 0, "theta": 0},
            {"joint": "revolute", "a": 0.3, "alpha": 0, "d": 0, "theta": 0}
        ]
    });
    b.exec(
        "const ed = document.getElementById('model-editor');
         ed.value = arguments[0];
         ed.dispatchEvent(new Event('input', {bubbles: true}));
         return true;",
        json!([serde_json::to_string_pretty(&bad).unwrap()]),
    )
    .await;
    b.click(&b.find("#register").await).await;
    b.wait_until(
        "the field error for links[0].alpha",
        "return [...document.querySelectorAll('#field-errors li')].some((li) => li.textContent.startsWith('links[0].alpha: '))
           && document.getElementById('register-status').className === 'error'
           && document.getElementById('register').disabled === false;",
        json!([]),
        "return {errors: document.getElementById('field-errors').textContent,
                 status: document.getElementById('register-status').textContent};",
    )
    .await;
    let markers = b.text(&b.find("#editor-markers").await).await;
    assert!(
        markers.contains("links[0].alpha"),
        "editor marker names the field: {markers:?}"
    );
    // Line of `"alpha": "x"` in the pretty-printed text.
    let alpha_line = serde_json::to_string_pretty(&bad)
        .unwrap()
        .lines()
        .position(|l| l.contains("\"x\""))
        .unwrap()
        + 1;
    assert!(
        markers.contains(&format!("line {alpha_line}:")),
        "the marker points at line {alpha_line}: {markers:?}"
    );
    assert_eq!(
        app.get("/v1/robots/browser-bad").await.status(),
        404,
        "the invalid model was not registered"
    );
    // Chromium logs the rejected PUT (HTTP 400) as a failed resource load:
    // that one is expected, anything else is not.
    let console = b.console_log().await;
    let errors = console_errors(&console, |m| {
        m.contains("/v1/robots/browser-bad - Failed to load resource: the server responded with a status of 4")
    });
    assert!(
        errors.is_empty(),
        "console errors after registering: {errors:?}"
    );

    // Phone width: no horizontal scrolling.
    b.set_window(375, 812).await;
    b.wait_until(
        "the viewport to be 375 px wide",
        "return window.innerWidth === 375;",
        json!([]),
        "return {inner: window.innerWidth, outer: window.outerWidth};",
    )
    .await;
    // Let layout and the canvas' ResizeObserver settle, then measure.
    b.exec(
        "return new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(() => r(true))));",
        json!([]),
    )
    .await;
    let o = overflow_report(&b).await;
    assert!(
        o["scroll"].as_u64() <= o["client"].as_u64() && o["body"].as_u64() <= o["client"].as_u64(),
        "horizontal scroll at 375 px: {o}"
    );
    let canvas_w = b
        .exec(
            "return document.getElementById('view').getBoundingClientRect().width;",
            json!([]),
        )
        .await;
    assert!(
        canvas_w.as_f64().unwrap_or(0.0) <= 375.0,
        "canvas fits the phone width: {canvas_w}"
    );
    b.exec("window.scrollTo(0, 0); return true;", json!([]))
        .await;
    b.screenshot(&target_dir().join("playground-375.png")).await;

    // No console errors overall (hook and chromedriver log).
    let hooked = b.exec("return window.__errors || null;", json!([])).await;
    assert_eq!(hooked, json!([]), "errors caught by the page hook");
    let console = b.console_log().await;
    let errors = console_errors(&console, |_| false);
    assert!(errors.is_empty(), "console errors at the end: {errors:?}");

    let log_via_driver = b.log_endpoint;
    b.close().await;
    eprintln!(
        "browser test: ok in {:.1}s (console log via chromedriver: {}; screenshots in {})",
        started.elapsed().as_secs_f64(),
        if log_via_driver { "yes" } else { "no" },
        target_dir().display()
    );
}
