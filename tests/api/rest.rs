//! REST contract tests.

use crate::helpers::*;
use serde_json::json;

#[tokio::test]
async fn puma560_home_pose_over_rest_matches_the_library() {
    let app = spawn_app().await;
    let r = app
        .post(
            "/v1/robots/puma560/fk",
            &json!({"joints": [0, 0, 0, 0, 0, 0]}),
        )
        .await;
    assert_eq!(r.status(), 200);
    let body: serde_json::Value = r.json().await.unwrap();
    assert_eq!(body["robot"], "puma560");
    assert_eq!(body["length_unit"], "m");
    let robot = kinserve::model::load_robot_file(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/robots/puma560.json"
    )))
    .unwrap();
    let expect = robot.fk_unchecked(&[0.0; 6]).position();
    let got = position(&body["pose"]);
    for i in 0..3 {
        assert_close(got[i], expect[i], 1e-12, "position");
    }
}
