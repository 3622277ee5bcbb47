//! The playground opens the robot its address names (`/?robot=ur5e`), keeps
//! the address in step with the robot picked, and falls back to the default
//! for a name the server does not know. Headless Chromium, as
//! `browser.rs` (SKIPPED without it, failing under `CI=true`).

use serde_json::json;

use crate::helpers::browser::*;
use crate::helpers::*;

/// Waits until the page shows `robot` (summary and selection) with a pose.
async fn wait_shown(b: &Browser, robot: &str) {
    b.wait_until(
        &format!("{robot} to be shown"),
        "return document.getElementById('robot-select').value === arguments[0]
           && document.getElementById('robot-summary').textContent.startsWith(arguments[0] + ':')
           && document.getElementById('pos').textContent !== '';",
        json!([robot]),
        "return {sel: document.getElementById('robot-select').value,
                 summary: document.getElementById('robot-summary').textContent,
                 err: document.getElementById('global-error').textContent};",
    )
    .await;
}

/// `location.search` of the page.
async fn search(b: &Browser) -> String {
    let v = b.exec("return location.search;", json!([])).await;
    v.as_str().unwrap_or_default().to_string()
}

#[tokio::test]
async fn playground_opens_the_robot_named_in_its_address() {
    let Some((driver, chromium)) = browser_or_skip() else {
        return;
    };
    let app = spawn_app().await;
    let b = Browser::start(&driver, &chromium).await;

    b.goto(&format!("{}/?robot=ur5e", app.http)).await;
    wait_shown(&b, "ur5e").await;
    assert_eq!(search(&b).await, "?robot=ur5e");

    // Picking another robot updates the address (bookmarkable, shareable).
    b.wait_find("#robot-select option[value='panda']").await;
    b.click(&b.find("#robot-select option[value='panda']").await)
        .await;
    wait_shown(&b, "panda").await;
    assert_eq!(search(&b).await, "?robot=panda");

    // An unknown name falls back to the default robot, and says which is shown.
    b.goto(&format!("{}/?robot=no-such-arm", app.http)).await;
    wait_shown(&b, "puma560").await;
    assert_eq!(search(&b).await, "?robot=puma560");

    // No parameter: the default, and the address names it.
    b.goto(&format!("{}/", app.http)).await;
    wait_shown(&b, "puma560").await;
    assert_eq!(search(&b).await, "?robot=puma560");
    b.close().await;
}
