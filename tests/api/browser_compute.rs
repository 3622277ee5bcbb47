//! The playground and the compute pool's per-client share. On a two-core
//! server one client (an IP address) holds one computation at a time and a
//! second is refused at once (503 `overloaded` + Retry-After), so the page
//! sends its compute requests (batches, IK, paths, closed forms, URDF
//! imports) one at a time, and retries such a refusal after Retry-After.
//! What the page fetched is read from the browser's resource timing (every
//! response status, page load included). Headless Chromium, as `browser.rs`
//! (SKIPPED without it, failing under `CI=true`).

use std::time::{Duration, Instant};

use serde_json::{Value, json};

use crate::helpers::browser::*;
use crate::helpers::*;

/// Two compute permits, one per client: the two-core default, on any machine.
fn one_computation_per_client(c: &mut kinserve::config::ServeConfig) {
    c.compute_threads = 2;
    c.client_share_percent = 50;
}

/// Loads `/?robot=ur5e` and waits until what the page computes on selection
/// (the closed-form panel, the manipulability gauge's scale) has arrived.
async fn open_ur5e(app: &TestApp, b: &Browser) {
    b.goto(&format!("{}/?robot=ur5e", app.http)).await;
    b.wait_until(
        "ur5e shown with its closed form and gauge scale",
        "return document.getElementById('robot-select').value === 'ur5e'
           && document.getElementById('pos').textContent !== ''
           && document.getElementById('closed-form-transform') !== null
           && document.getElementById('manip').dataset.reference !== undefined;",
        json!([]),
        "return {closedForm: document.getElementById('closed-form-status').textContent,
                 reference: document.getElementById('manip').dataset.reference || null};",
    )
    .await;
}

/// `[path, status]` of every `fetch` the page made, in the order they started.
async fn fetched(b: &Browser) -> Vec<(String, u64)> {
    let v = b
        .exec(
            "return performance.getEntriesByType('resource')
               .filter((e) => e.initiatorType === 'fetch')
               .sort((x, y) => x.startTime - y.startTime)
               .map((e) => [new URL(e.name).pathname, e.responseStatus]);",
            json!([]),
        )
        .await;
    serde_json::from_value(v).expect("[path, status] pairs")
}

#[tokio::test]
async fn the_pages_compute_requests_go_one_at_a_time_and_none_is_refused() {
    let Some((driver, chromium)) = browser_or_skip() else {
        return;
    };
    let app = spawn_app_with(one_computation_per_client).await;
    let b = Browser::start(&driver, &chromium).await;
    open_ur5e(&app, &b).await;

    // Five compute requests at once, the first a path of 600 steps.
    let out = b
        .exec(
            "return (async () => {
             const api = await import('/playground/api.js');
             const start = [0, -90, 90, -90, -90, 0];
             const p = (await api.fkBatch('ur5e', [start])).poses[0].position;
             const configs = Array.from({length: 64}, (_, k) => start.map((v) => v + k));
             const jobs = [
               api.ikPath('ur5e', {start, angle_unit: 'deg', position_only: true, max_step_length: 0.0005,
                                   waypoints: [{position: [p[0], p[1] + 0.3, p[2]]}]}),
               api.jacobianBatch('ur5e', configs),
               api.fkBatch('ur5e', configs),
               api.solveIk('ur5e', {target: {position: p}, position_only: true, seed: start, angle_unit: 'deg'}),
               api.closedForm('puma560'),
             ];
             const settled = await Promise.allSettled(jobs);
             const [path, jac, fk, ik, cf] = settled.map((s) => s.value);
             return {
               failed: settled.filter((s) => s.status !== 'fulfilled').map((s) => String(s.reason)),
               points: path && path.points.length, fraction: path && path.fraction,
               jacobians: jac && jac.results.length, poses: fk && fk.poses.length,
               converged: ik && ik.converged, links: cf && cf.link_transforms.length,
             };
             })();",
            json!([]),
        )
        .await;
    assert_eq!(out["failed"], json!([]), "{out}");
    assert_eq!(out["fraction"], 1.0, "{out}");
    assert!(out["points"].as_u64().unwrap() > 500, "a long path: {out}");
    assert_eq!(out["jacobians"], 64, "{out}");
    assert_eq!(out["poses"], 64, "{out}");
    assert_eq!(out["converged"], true, "{out}");
    assert_eq!(out["links"], 6, "{out}");

    // Nothing the page sent, on selection or since, was refused.
    let all = fetched(&b).await;
    assert!(all.len() >= 8, "the page's fetches: {all:?}");
    let refused: Vec<_> = all.iter().filter(|(_, s)| *s != 200).collect();
    assert!(
        refused.is_empty(),
        "refused or failed: {refused:?} of {all:?}"
    );
    b.close().await;
}

#[tokio::test]
async fn a_refused_compute_request_is_retried_after_retry_after() {
    let Some((driver, chromium)) = browser_or_skip() else {
        return;
    };
    // An IK batch may run for half the request timeout: 1.5 s.
    let app = spawn_app_with(|c| {
        one_computation_per_client(c);
        c.request_timeout = Duration::from_secs(3);
    })
    .await;
    let b = Browser::start(&driver, &chromium).await;
    open_ur5e(&app, &b).await;
    b.exec(
        "performance.clearResourceTimings(); return true;",
        json!([]),
    )
    .await;

    // Another tab at the same address holds the share: an IK batch of
    // targets out of reach, which runs until its time limit. A probe of ours
    // tells when it runs (the probe is refused); a batch that came while a
    // probe held the share was refused itself, and is sent again.
    let far = json!({"position": [3.0, 0.0, 0.2]});
    // 10,000 (the most a batch takes): even a release build's batch outlasts its 1.5 s.
    let hold_body =
        json!({"targets": vec![far; 10_000], "position_only": true, "solver": "numeric"});
    let client = reqwest::Client::new();
    let url = format!("{}/v1/robots/ur5e/ik/batch", app.http);
    let send_hold = || {
        let request = client.post(&url).json(&hold_body).send();
        tokio::spawn(async move { request.await.map(|r| r.status()) })
    };
    let reachable = json!({"target": {"position": [0.4, 0.1, 0.4]}, "position_only": true});
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut hold = send_hold();
    loop {
        assert!(Instant::now() < deadline, "the batch never held the share");
        if hold.is_finished() {
            let status = (&mut hold)
                .await
                .expect("the batch task")
                .expect("an answer");
            assert_eq!(status, 503, "a batch that ended at once was refused");
            hold = send_hold();
        }
        if app.post("/v1/robots/ur5e/ik", &reachable).await.status() == 503 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }

    // The page's IK is refused, waits Retry-After (1 s), and is answered.
    let out = b
        .exec(
            "const [body] = arguments;
             return (async () => {
               const api = await import('/playground/api.js');
               const t0 = performance.now();
               const ans = await api.solveIk('ur5e', body);
               return {converged: ans.converged, ms: performance.now() - t0};
             })();",
            json!([reachable]),
        )
        .await;
    let held = hold
        .await
        .expect("the batch task")
        .expect("the batch answered");
    assert_eq!(out["converged"], true, "{out}");
    let ik: Vec<u64> = fetched(&b)
        .await
        .into_iter()
        .filter(|(p, _)| p == "/v1/robots/ur5e/ik")
        .map(|(_, s)| s)
        .collect();
    let (last, refusals) = ik.split_last().expect("the page asked");
    assert_eq!(*last, 200, "answered at last: {ik:?} (batch: {held})");
    assert!(!refusals.is_empty(), "refused first: {ik:?}");
    assert!(refusals.iter().all(|s| *s == 503), "{ik:?}");
    let ms = out["ms"].as_f64().unwrap();
    assert!(
        ms >= 1000.0 * refusals.len() as f64 - 5.0,
        "{ms} ms for {} refusals: each waits Retry-After",
        refusals.len()
    );
    assert_no_console_errors_but_refusals(&b).await;
    b.close().await;
}

/// The console holds no error but the refusals' own "503" lines.
async fn assert_no_console_errors_but_refusals(b: &Browser) {
    let log: Vec<Value> = b.console_log().await;
    let errors = console_errors(&log, |m| m.contains("503"));
    assert!(errors.is_empty(), "console errors: {errors:?}");
}
