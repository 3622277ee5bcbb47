//! End-to-end test of the web playground in headless Chromium.
//!
//! Drives Debian's `chromium` through `chromedriver` over the W3C WebDriver
//! HTTP API, with a small client written here on reqwest. The page is served
//! by the real server (`spawn_app`) and what it shows is checked against the
//! REST API.
//!
//! Needs `chromium` and `chromium-driver` (`.ci/run` installs them). Without
//! them the test fails when `CI=true` and is skipped with a message otherwise.

use std::path::Path;
use std::time::Instant;

use serde_json::{Value, json};

use crate::helpers::browser::*;
use crate::helpers::*;

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
    let Some((driver, chromium)) = browser_or_skip() else {
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
