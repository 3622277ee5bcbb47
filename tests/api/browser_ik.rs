//! The playground's IK in headless Chromium: dragging the tool triad with
//! real pointer events (W3C actions) moves the arm by IK over the WebSocket,
//! and the pose the page then shows is the dragged target (and the REST FK of
//! the joints it shows); a key nudges the tool; the manipulability gauge is
//! shown; a target out of reach says "IK failed" and draws the best attempt.
//!
//! Skipped (with a message) without chromium / chromedriver, failed under `CI=true`.

use serde_json::{Value, json};

use crate::helpers::browser::*;
use crate::helpers::*;

/// The tool handle's position on the canvas (CSS px) and the canvas size,
/// once the view has drawn its latest state (the page marks the canvas
/// `data-drawn="pending"` from a change until the frame showing it).
async fn tool_handle(b: &Browser) -> (f64, f64, f64, f64) {
    b.wait_until(
        "the view to draw its latest state",
        "return document.getElementById('view').dataset.drawn === 'done';",
        json!([]),
        "return document.getElementById('view').dataset;",
    )
    .await;
    let v = b
        .exec(
            "const c = document.getElementById('view'); const r = c.getBoundingClientRect();
             return [Number(c.dataset.toolX), Number(c.dataset.toolY), r.width, r.height];",
            json!([]),
        )
        .await;
    let v: Vec<f64> = serde_json::from_value(v).expect("handle numbers");
    assert!(
        v.iter().all(|x| x.is_finite()),
        "tool handle on screen: {v:?}"
    );
    (v[0], v[1], v[2], v[3])
}

/// Presses on the tool handle, moves by `steps` (CSS px each), releases.
async fn drag_tool(b: &Browser, steps: &[(i64, i64)]) {
    let (x, y, w, h) = tool_handle(b).await;
    let canvas = b.find("#view").await;
    let origin = json!({ELEMENT_KEY: canvas.0});
    // Offsets from the element's centre (W3C), then relative moves.
    let mut actions = vec![
        json!({"type": "pointerMove", "duration": 0, "origin": origin,
               "x": (x - w / 2.0).round() as i64, "y": (y - h / 2.0).round() as i64}),
        json!({"type": "pointerDown", "button": 0}),
    ];
    for (dx, dy) in steps {
        actions.push(
            json!({"type": "pointerMove", "duration": 30, "origin": "pointer", "x": dx, "y": dy}),
        );
    }
    actions.push(json!({"type": "pointerUp", "button": 0}));
    b.cmd(
        "POST",
        "/actions",
        json!({"actions": [{"type": "pointer", "id": "mouse", "parameters": {"pointerType": "mouse"}, "actions": actions}]}),
    )
    .await;
    b.cmd("DELETE", "/actions", Value::Null).await;
}

/// Waits until the IK answer for the last dragged target is shown (FK of its
/// joints displayed), and returns that target.
async fn wait_ik_shown(b: &Browser) -> [f64; 3] {
    b.wait_until(
        "the IK answer for the last target to be shown",
        "const d = document.body.dataset;
         return d.ikResult === 'converged' && d.ikTarget === d.dragTarget
           && d.lastJoints === d.ikJoints && document.getElementById('pos').textContent !== '';",
        json!([]),
        "const d = document.body.dataset; return {ik: d.ikResult, target: d.ikTarget, drag: d.dragTarget,
           joints: d.ikJoints, last: d.lastJoints, status: document.getElementById('ik-status').textContent};",
    )
    .await;
    let t = b
        .exec(
            "return JSON.parse(document.body.dataset.dragTarget);",
            json!([]),
        )
        .await;
    serde_json::from_value(t).expect("target")
}

/// `#pos` as numbers.
async fn shown_position(b: &Browser) -> [f64; 3] {
    let v = b
        .exec(
            "return document.getElementById('pos').textContent.split(',').map(Number);",
            json!([]),
        )
        .await;
    serde_json::from_value(v).expect("#pos numbers")
}

/// The shown position equals `target` (IK tolerance 1e-9 m, printed in full)
/// and the REST FK of the joints the page shows.
async fn assert_shows(app: &TestApp, b: &Browser, target: [f64; 3], what: &str) {
    let pos = shown_position(b).await;
    for k in 0..3 {
        assert_close(
            pos[k],
            target[k],
            1e-9,
            &format!("{what}: #pos[{k}] vs target"),
        );
    }
    let joints: Value = serde_json::from_str(
        b.exec("return document.body.dataset.lastJoints;", json!([]))
            .await
            .as_str()
            .unwrap(),
    )
    .unwrap();
    let fk = fk_ok(
        app,
        "puma560",
        json!({"joints": joints, "angle_unit": "deg"}),
    )
    .await;
    let want = position(&fk["pose"]);
    for k in 0..3 {
        assert_close(
            pos[k],
            want[k],
            1e-9,
            &format!("{what}: #pos[{k}] vs REST FK"),
        );
    }
}

#[tokio::test]
async fn dragging_the_tool_moves_the_arm_by_ik_to_the_dragged_target() {
    let Some((driver, chromium)) = browser_or_skip() else {
        return;
    };
    let app = spawn_app().await;
    let b = Browser::start(&driver, &chromium).await;
    b.goto(&format!("{}/", app.http)).await;
    b.wait_until(
        "PUMA 560 shown with a live stream",
        "return document.getElementById('robot-select').value === 'puma560'
           && document.getElementById('ws-status').dataset.state === 'open'
           && document.body.dataset.lastJoints === '[0,0,0,0,0,0]';",
        json!([]),
        "return {ws: document.getElementById('ws-status').textContent, last: document.body.dataset.lastJoints};",
    )
    .await;
    // At the home pose (θ5 = 0, a wrist singularity) the gauge is empty and
    // the warning shows (the first reading used to fill it: issue 26).
    b.wait_until(
        "the gauge at the home pose",
        "return document.getElementById('manip-value').textContent !== ''
           && document.getElementById('manip').dataset.reference !== undefined;",
        json!([]),
        "return {manip: document.getElementById('manip-value').textContent};",
    )
    .await;
    let home = b
        .exec(
            "return {meter: document.getElementById('manip').value,
                     warn: document.getElementById('singular-warning').hidden,
                     reference: Number(document.getElementById('manip').dataset.reference)};",
            json!([]),
        )
        .await;
    assert!(
        home["meter"].as_f64().unwrap() < 0.1,
        "red at the singular home pose: {home}"
    );
    assert_eq!(home["warn"], false, "the singularity warning shows: {home}");
    assert!(home["reference"].as_f64().unwrap() > 0.0, "{home}");
    // Away from the wrist singularity of the home pose (θ5 = 0): set θ5 = 40°.
    b.exec(
        "const r = document.getElementById('joint-4'); r.value = '40';
         r.dispatchEvent(new Event('input', {bubbles: true})); return true;",
        json!([]),
    )
    .await;
    b.wait_until(
        "θ5 = 40° shown with the gauge",
        "return document.body.dataset.lastJoints === '[0,0,0,0,40,0]'
           && document.getElementById('manip-value').textContent !== ''
           && document.getElementById('view').dataset.toolX !== undefined;",
        json!([]),
        "return {last: document.body.dataset.lastJoints, manip: document.getElementById('manip-value').textContent};",
    )
    .await;
    let gauge = b
        .exec(
            "return {meter: document.getElementById('manip').value,
                     warn: document.getElementById('singular-warning').hidden};",
            json!([]),
        )
        .await;
    assert!(gauge["meter"].as_f64().unwrap() > 0.0, "{gauge}");
    assert_eq!(
        gauge["warn"], true,
        "no singularity warning at θ5 = 40°: {gauge}"
    );
    let start = shown_position(&b).await;

    // Drag the tool 60 px right and 40 px up in six moves.
    drag_tool(
        &b,
        &[(10, -7), (10, -7), (10, -6), (10, -7), (10, -6), (10, -7)],
    )
    .await;
    let target = wait_ik_shown(&b).await;
    let moved = (0..3)
        .map(|k| (target[k] - start[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(moved > 0.01, "the drag moved the target by {moved} m");
    assert_shows(&app, &b, target, "after the drag").await;

    // The tool stays selected: PageUp nudges it up by 1 % of the robot's size.
    let canvas = b.find("#view").await;
    b.cmd(
        "POST",
        &format!("/element/{}/value", canvas.0),
        json!({"text": "\u{E00E}"}), // PageUp
    )
    .await;
    b.wait_until(
        "the nudged target",
        "const [z] = arguments; const t = JSON.parse(document.body.dataset.dragTarget);
         return t[2] > z;",
        json!([target[2]]),
        "return document.body.dataset.dragTarget;",
    )
    .await;
    let nudged = wait_ik_shown(&b).await;
    assert_close(nudged[0], target[0], 0.0, "nudge keeps x");
    assert_close(nudged[1], target[1], 0.0, "nudge keeps y");
    assert_shows(&app, &b, nudged, "after the nudge").await;

    // Far out of reach: "IK failed", the best attempt drawn, the arm unchanged.
    let before = shown_position(&b).await;
    // Zoom out (each '-' is ×1.15 the distance), then drag to the canvas' right edge.
    let (x0, y0, _, _) = tool_handle(&b).await;
    b.cmd(
        "POST",
        &format!("/element/{}/value", canvas.0),
        json!({"text": "-".repeat(12)}),
    )
    .await;
    b.wait_until(
        "the zoomed-out view to be drawn",
        "const [x, y] = arguments; const d = document.getElementById('view').dataset;
         return d.drawn === 'done' && Math.hypot(Number(d.toolX) - x, Number(d.toolY) - y) > 20;",
        json!([x0, y0]),
        "return document.getElementById('view').dataset;",
    )
    .await;
    let (x, _, w, _) = tool_handle(&b).await;
    drag_tool(&b, &[((w - 4.0 - x).round() as i64, 0)]).await;
    b.wait_until(
        "IK failed with a ghost",
        "return document.body.dataset.ikResult === 'failed'
           && document.getElementById('ik-status').textContent.startsWith('IK failed')
           && document.getElementById('view').dataset.ghost === 'shown';",
        json!([]),
        "return {ik: document.body.dataset.ikResult, status: document.getElementById('ik-status').textContent,
                 ghost: document.getElementById('view').dataset.ghost, target: document.body.dataset.dragTarget,
                 pos: document.getElementById('pos').textContent, view: document.getElementById('view').dataset};",
    )
    .await;
    assert_eq!(
        shown_position(&b).await,
        before,
        "a failed IK leaves the shown pose"
    );
    b.close().await;
}

/// A URDF pasted into the page is imported as a robot (`PUT` with
/// `application/xml`), selected, and computes the same FK as the arm it came
/// from; a URDF the import refuses shows the server's reason.
#[tokio::test]
async fn a_urdf_pasted_into_the_page_is_imported_and_shown() {
    let Some((driver, chromium)) = browser_or_skip() else {
        return;
    };
    let app = spawn_app().await;
    let urdf = app.get("/v1/robots/ur5e/urdf").await.text().await.unwrap();
    let b = Browser::start(&driver, &chromium).await;
    b.goto(&format!("{}/", app.http)).await;
    b.wait_until(
        "the page is up",
        "return document.getElementById('robot-select').value === 'puma560';",
        json!([]),
        "return {};",
    )
    .await;
    b.exec(
        "document.getElementById('urdf-text').value = arguments[0];
         document.getElementById('urdf-name').value = 'page-arm';
         document.getElementById('import-urdf').click(); return true;",
        json!([urdf]),
    )
    .await;
    b.wait_until(
        "the imported arm selected",
        "return document.getElementById('import-status').dataset.kind === 'ok'
           && document.getElementById('robot-select').value === 'page-arm';",
        json!([]),
        "return {status: document.getElementById('import-status').textContent};",
    )
    .await;
    // The server has it, with ur5e's FK.
    let q = json!({"joints": [0.3, -1.1, 0.9, -0.4, 1.2, 0.5]});
    let a: Value = app
        .post("/v1/robots/page-arm/fk", &q)
        .await
        .json()
        .await
        .unwrap();
    let b5: Value = app
        .post("/v1/robots/ur5e/fk", &q)
        .await
        .json()
        .await
        .unwrap();
    crate::helpers::pose::assert_pose_eq(&a["pose"], &b5["pose"], 1e-12, "page import vs ur5e");
    // A refusal shows the reason.
    b.exec(
        "document.getElementById('urdf-text').value = '<html/>';
         document.getElementById('urdf-name').value = 'not-urdf';
         document.getElementById('import-urdf').click(); return true;",
        json!([]),
    )
    .await;
    b.wait_until(
        "the refusal shown",
        "return document.getElementById('import-status').dataset.kind === 'error'
           && document.getElementById('import-status').textContent.includes('not URDF');",
        json!([]),
        "return {status: document.getElementById('import-status').textContent};",
    )
    .await;
}
