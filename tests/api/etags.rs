//! ETags on one node (the file store): `ETag` / `Last-Modified` on reads,
//! `If-Match` / `If-None-Match: *` on writes over REST, `etag` over gRPC, the
//! race of writers holding the same ETag, and ETags across a restart.

use kinserve::api::grpc::pb;
use reqwest::header::{ETAG, LAST_MODIFIED};
use serde_json::{Value, json};
use tonic::Code;

use crate::helpers::*;

/// The `ETag` of a response (panics if absent).
pub(crate) fn etag_of(r: &reqwest::Response) -> String {
    r.headers()
        .get(ETAG)
        .expect("an ETag header")
        .to_str()
        .unwrap()
        .to_string()
}

/// `PUT /v1/robots/{name}` with `body` and extra headers.
pub(crate) async fn put_with(
    client: &reqwest::Client,
    base: &str,
    name: &str,
    body: &Value,
    headers: &[(&str, &str)],
) -> reqwest::Response {
    let mut req = client.put(format!("{base}/v1/robots/{name}")).json(body);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    req.send().await.unwrap()
}

/// `DELETE /v1/robots/{name}` with extra headers.
pub(crate) async fn delete_with(
    client: &reqwest::Client,
    base: &str,
    name: &str,
    headers: &[(&str, &str)],
) -> reqwest::Response {
    let mut req = client.delete(format!("{base}/v1/robots/{name}"));
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    req.send().await.unwrap()
}

/// The planar model with its second link `a` set to `a` (a distinct version).
pub(crate) fn planar_version(name: &str, a: f64) -> Value {
    let mut m = planar_model(name);
    m["links"][1]["a"] = json!(a);
    m
}

fn revision(etag: &str) -> u64 {
    etag.trim_matches('"')
        .parse()
        .expect("a numeric strong ETag")
}

#[tokio::test]
async fn reads_carry_etag_and_last_modified_and_writes_return_the_new_etag() {
    let app = spawn_app().await;
    let r = put_with(&app.client, &app.http, "arm", &planar_model("arm"), &[]).await;
    assert_eq!(r.status(), 201);
    let written = etag_of(&r);
    let r = app.get("/v1/robots/arm").await;
    assert_eq!(r.status(), 200);
    assert_eq!(
        etag_of(&r),
        written,
        "GET gives the ETag the write returned"
    );
    let modified = r.headers().get(LAST_MODIFIED).unwrap().to_str().unwrap();
    let modified = httpdate::parse_http_date(modified).expect("an HTTP date");
    let age = std::time::SystemTime::now()
        .duration_since(modified)
        .unwrap_or_default();
    assert!(
        age.as_secs() < 3600,
        "Last-Modified is the write time: {age:?} ago"
    );

    let r = put_with(
        &app.client,
        &app.http,
        "arm",
        &planar_version("arm", 0.2),
        &[],
    )
    .await;
    assert_eq!(r.status(), 200);
    let replaced = etag_of(&r);
    assert!(
        revision(&replaced) > revision(&written),
        "{written} -> {replaced}"
    );

    // Built-ins: a content ETag, no Last-Modified.
    let r = app.get("/v1/robots/puma560").await;
    assert!(etag_of(&r).starts_with("\"builtin-"), "{:?}", r.headers());
    assert!(r.headers().get(LAST_MODIFIED).is_none());
}

#[tokio::test]
async fn if_match_replaces_and_deletes_only_the_version_named() {
    let app = spawn_app().await;
    let (c, base) = (&app.client, app.http.as_str());
    let v1 = etag_of(&put_with(c, base, "arm", &planar_version("arm", 0.1), &[]).await);
    let v2 = etag_of(&put_with(c, base, "arm", &planar_version("arm", 0.2), &[]).await);

    // A stale ETag: 412 problem+json, nothing changed.
    let r = put_with(
        c,
        base,
        "arm",
        &planar_version("arm", 0.3),
        &[("If-Match", &v1)],
    )
    .await;
    let p = problem(r, 412).await;
    assert_eq!(p["type"], "urn:kinserve:problem:precondition-failed");
    assert!(p["detail"].as_str().unwrap().contains(&v2), "{p}");
    let got: Value = app.get("/v1/robots/arm").await.json().await.unwrap();
    assert_eq!(got["links"][1]["a"], 0.2);
    problem(delete_with(c, base, "arm", &[("If-Match", &v1)]).await, 412).await;

    // The current one (in a list, with a weak tag that never matches): replaced.
    let list = format!("W/{v2}, \"1\", {v2}");
    let r = put_with(
        c,
        base,
        "arm",
        &planar_version("arm", 0.3),
        &[("If-Match", &list)],
    )
    .await;
    assert_eq!(r.status(), 200);
    let v3 = etag_of(&r);
    assert_ne!(v3, v2);
    // Only a weak tag: strong comparison never matches.
    let weak = format!("W/{v3}");
    problem(
        put_with(c, base, "arm", &planar_model("arm"), &[("If-Match", &weak)]).await,
        412,
    )
    .await;
    // `*`: any version, but the robot must exist.
    let r = put_with(
        c,
        base,
        "arm",
        &planar_version("arm", 0.4),
        &[("If-Match", "*")],
    )
    .await;
    assert_eq!(r.status(), 200);
    let v4 = etag_of(&r);
    problem(
        put_with(
            c,
            base,
            "ghost",
            &planar_model("ghost"),
            &[("If-Match", "*")],
        )
        .await,
        412,
    )
    .await;
    problem(app.get("/v1/robots/ghost").await, 404).await;

    assert_eq!(
        delete_with(c, base, "arm", &[("If-Match", &v4)])
            .await
            .status(),
        204
    );
    problem(app.get("/v1/robots/arm").await, 404).await;
}

#[tokio::test]
async fn if_none_match_star_creates_only() {
    let app = spawn_app().await;
    let (c, base) = (&app.client, app.http.as_str());
    let r = put_with(
        c,
        base,
        "arm",
        &planar_version("arm", 0.1),
        &[("If-None-Match", "*")],
    )
    .await;
    assert_eq!(r.status(), 201);
    let r = put_with(
        c,
        base,
        "arm",
        &planar_version("arm", 0.2),
        &[("If-None-Match", "*")],
    )
    .await;
    let p = problem(r, 412).await;
    assert!(
        p["detail"].as_str().unwrap().contains("must not exist"),
        "{p}"
    );
    let got: Value = app.get("/v1/robots/arm").await.json().await.unwrap();
    assert_eq!(got["links"][1]["a"], 0.1, "the first version stays");
    // A built-in stays read-only whatever the condition says.
    let r = put_with(
        c,
        base,
        "puma560",
        &builtin_file("puma560"),
        &[("If-Match", "*")],
    )
    .await;
    problem(r, 409).await;
}

#[tokio::test]
async fn malformed_or_contradictory_conditions_are_400_naming_the_header() {
    let app = spawn_app().await;
    let (c, base) = (&app.client, app.http.as_str());
    put_with(c, base, "arm", &planar_model("arm"), &[]).await;
    let cases: &[(&[(&str, &str)], &str)] = &[
        (&[("If-Match", "17")], "If-Match"),
        (&[("If-None-Match", "\"17\"")], "If-None-Match"),
        (
            &[("If-Match", "*"), ("If-None-Match", "*")],
            "If-None-Match",
        ),
    ];
    for (headers, field) in cases {
        let p = problem(
            put_with(c, base, "arm", &planar_model("arm"), headers).await,
            400,
        )
        .await;
        assert_eq!(fields(&p), [*field], "{headers:?}: {p}");
    }
    let p = problem(
        delete_with(c, base, "arm", &[("If-None-Match", "*")]).await,
        400,
    )
    .await;
    assert_eq!(fields(&p), ["If-None-Match"], "{p}");
    // Nothing was changed by any of them.
    assert_eq!(app.get("/v1/robots/arm").await.status(), 200);
}

/// Writers that read the same version race to replace it: exactly one wins,
/// every other gets 412, and the winner's model is the one stored.
#[tokio::test]
async fn of_writers_racing_with_the_same_if_match_exactly_one_wins() {
    let app = spawn_app().await;
    let v0 = etag_of(&put_with(&app.client, &app.http, "arm", &planar_model("arm"), &[]).await);
    let writers = (0..8).map(|i| {
        let (c, base, v0) = (app.client.clone(), app.http.clone(), v0.clone());
        tokio::spawn(async move {
            let body = planar_version("arm", 0.1 + f64::from(i) / 100.0);
            let r = put_with(&c, &base, "arm", &body, &[("If-Match", &v0)]).await;
            let status = r.status().as_u16();
            let etag = r
                .headers()
                .get(ETAG)
                .map(|v| v.to_str().unwrap().to_string());
            (i, status, etag)
        })
    });
    let results: Vec<_> = futures_util::future::join_all(writers)
        .await
        .into_iter()
        .map(Result::unwrap)
        .collect();
    let winners: Vec<_> = results.iter().filter(|(_, s, _)| *s == 200).collect();
    assert_eq!(winners.len(), 1, "{results:?}");
    assert!(
        results.iter().all(|(_, s, _)| *s == 200 || *s == 412),
        "{results:?}"
    );
    let (i, _, etag) = winners[0];
    let r = app.get("/v1/robots/arm").await;
    assert_eq!(Some(etag_of(&r)), *etag);
    let got: Value = r.json().await.unwrap();
    assert_eq!(got["links"][1]["a"], 0.1 + f64::from(*i) / 100.0);
}

/// Issue 13 item 8: racing unconditional PUTs and DELETEs on one name; every
/// PUT answer is the body that client wrote (never 404, never another
/// client's body), with distinct ETags.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn racing_writes_each_answer_what_they_wrote() {
    let app = spawn_app().await;
    let writers = (0..8u32).map(|w| {
        let (c, base) = (app.client.clone(), app.http.clone());
        tokio::spawn(async move {
            let mut answers = Vec::new();
            for k in 0..40u32 {
                if w == 0 && k % 2 == 1 {
                    let _ = delete_with(&c, &base, "raced", &[]).await;
                    continue;
                }
                let a = 0.1 + f64::from(w * 100 + k) / 10_000.0;
                let r = put_with(&c, &base, "raced", &planar_version("raced", a), &[]).await;
                let status = r.status().as_u16();
                let etag = r
                    .headers()
                    .get(ETAG)
                    .map(|v| v.to_str().unwrap().to_string());
                let got: Value = r.json().await.unwrap();
                answers.push((a, status, etag, got));
            }
            answers
        })
    });
    let mut etags = std::collections::HashSet::new();
    for answers in futures_util::future::join_all(writers).await {
        for (a, status, etag, got) in answers.unwrap() {
            assert!(status == 200 || status == 201, "{status}: {got}");
            assert_eq!(got["links"][1]["a"], a, "the answer is what was written");
            assert!(etags.insert(etag.expect("an ETag")), "ETags are distinct");
        }
    }
}

#[tokio::test]
async fn etags_survive_a_restart_of_the_file_store() {
    let tmp = tempfile::tempdir().unwrap();
    let app = spawn_in(tmp.path(), |_| {}).await;
    let v = etag_of(&put_with(&app.client, &app.http, "arm", &planar_model("arm"), &[]).await);
    app.stop().await.unwrap();
    let app = spawn_in(tmp.path(), |_| {}).await;
    let r = app.get("/v1/robots/arm").await;
    assert_eq!(etag_of(&r), v, "same version, same ETag");
    let r = put_with(
        &app.client,
        &app.http,
        "arm",
        &planar_version("arm", 0.2),
        &[("If-Match", &v)],
    )
    .await;
    assert_eq!(r.status(), 200);
    assert!(revision(&etag_of(&r)) > revision(&v));
}

#[tokio::test]
async fn grpc_etags_mean_what_rest_etags_mean() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let reg = |etag: &str, a: f64, replace: bool| {
        let mut robot = planar_pb("arm");
        robot.links[1].a = Some(a);
        pb::RegisterRobotRequest {
            robot: Some(robot),
            replace,
            etag: etag.to_string(),
        }
    };
    let v1 = c
        .register_robot(reg("", 0.1, false))
        .await
        .unwrap()
        .into_inner()
        .etag;
    let rest = etag_of(&app.get("/v1/robots/arm").await);
    assert_eq!(v1, rest, "one ETag on both front doors");
    let got = c
        .get_robot(pb::GetRobotRequest { name: "arm".into() })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(got.etag, v1);

    let r = c
        .register_robot(reg(&v1, 0.2, true))
        .await
        .unwrap()
        .into_inner();
    assert!(!r.created);
    let v2 = r.etag;
    assert_ne!(v2, v1);
    // Stale: FAILED_PRECONDITION, nothing changed.
    let err = c.register_robot(reg(&v1, 0.3, true)).await.unwrap_err();
    assert_eq!(err.code(), Code::FailedPrecondition, "{err:?}");
    assert_eq!(etag_of(&app.get("/v1/robots/arm").await), v2);
    // An etag without replace contradicts create-only.
    let err = c.register_robot(reg(&v2, 0.3, false)).await.unwrap_err();
    assert_eq!(err.code(), Code::InvalidArgument, "{err:?}");
    assert_eq!(status_fields(&err), ["etag"]);

    let del = |etag: &str| pb::DeleteRobotRequest {
        name: "arm".into(),
        etag: etag.to_string(),
    };
    let err = c.delete_robot(del(&v1)).await.unwrap_err();
    assert_eq!(err.code(), Code::FailedPrecondition, "{err:?}");
    c.delete_robot(del(&v2)).await.unwrap();
    problem(app.get("/v1/robots/arm").await, 404).await;
}

#[tokio::test]
async fn grpc_writers_racing_with_the_same_etag_exactly_one_wins() {
    let app = spawn_app().await;
    let v0 = etag_of(&put_with(&app.client, &app.http, "arm", &planar_model("arm"), &[]).await);
    let writers = (0..8).map(|i| {
        let (grpc, v0) = (app.grpc.clone(), v0.clone());
        tokio::spawn(async move {
            let mut c = pb::kinematics_service_client::KinematicsServiceClient::connect(grpc)
                .await
                .unwrap();
            let mut robot = planar_pb("arm");
            robot.links[1].a = Some(0.1 + f64::from(i) / 100.0);
            let req = pb::RegisterRobotRequest {
                robot: Some(robot),
                replace: true,
                etag: v0,
            };
            c.register_robot(req)
                .await
                .map(|r| r.into_inner().etag)
                .map_err(|s| s.code())
        })
    });
    let results: Vec<_> = futures_util::future::join_all(writers)
        .await
        .into_iter()
        .map(Result::unwrap)
        .collect();
    let won: Vec<_> = results.iter().filter_map(|r| r.as_ref().ok()).collect();
    assert_eq!(won.len(), 1, "{results:?}");
    assert!(
        results
            .iter()
            .all(|r| matches!(r, Ok(_) | Err(Code::FailedPrecondition))),
        "{results:?}"
    );
    assert_eq!(etag_of(&app.get("/v1/robots/arm").await), *won[0]);
}

#[tokio::test]
async fn cors_lets_browsers_send_conditions_and_read_etags() {
    let app = spawn_app().await;
    let r = app
        .client
        .request(
            reqwest::Method::OPTIONS,
            format!("{}/v1/robots/arm", app.http),
        )
        .header("Origin", "http://example.test")
        .header("Access-Control-Request-Method", "PUT")
        .header("Access-Control-Request-Headers", "if-match, if-none-match")
        .send()
        .await
        .unwrap();
    let allowed = r
        .headers()
        .get("access-control-allow-headers")
        .unwrap()
        .to_str()
        .unwrap();
    assert!(
        allowed.contains("if-match") && allowed.contains("if-none-match"),
        "{allowed}"
    );
    let r = app
        .client
        .get(format!("{}/v1/robots/puma560", app.http))
        .header("Origin", "http://example.test")
        .send()
        .await
        .unwrap();
    let exposed = r
        .headers()
        .get("access-control-expose-headers")
        .unwrap()
        .to_str()
        .unwrap();
    assert!(
        exposed.contains("etag") && exposed.contains("last-modified"),
        "{exposed}"
    );
}
