//! Listing robots a page at a time (AIP-158: `page_size`, `page_token`,
//! `next_page_token`), the same on REST and gRPC: pages follow one another
//! without gaps or repeats, sizes are bounded, bad tokens are refused.

use kinserve::api::grpc::pb;
use serde_json::Value;
use tonic::Code;

use crate::helpers::*;

async fn rest_page(app: &TestApp, query: &str) -> (u16, Value) {
    let r = app.get(&format!("/v1/robots?{query}")).await;
    (r.status().as_u16(), r.json().await.unwrap())
}

#[tokio::test]
async fn pages_walk_the_whole_list_on_rest_and_grpc() {
    let app = spawn_app().await;
    let (_, all) = rest_page(&app, "").await;
    let all: Vec<String> = all["robots"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["name"].as_str().unwrap().to_string())
        .collect();
    assert!(all.len() > 7, "{all:?}");
    // REST, 3 at a time.
    let (mut rest, mut token) = (Vec::new(), String::new());
    loop {
        let (status, page) = rest_page(&app, &format!("page_size=3&page_token={token}")).await;
        assert_eq!(status, 200, "{page}");
        let names = page["robots"].as_array().unwrap();
        assert!(names.len() <= 3);
        rest.extend(
            names
                .iter()
                .map(|r| r["name"].as_str().unwrap().to_string()),
        );
        match page["next_page_token"].as_str() {
            Some(t) => token = t.to_string(),
            None => break,
        }
    }
    assert_eq!(rest, all);
    // gRPC, 4 at a time.
    let mut client = app.grpc_client().await;
    let (mut grpc, mut token) = (Vec::new(), String::new());
    loop {
        let page = client
            .list_robots(pb::ListRobotsRequest {
                page_size: 4,
                page_token: token.clone(),
            })
            .await
            .unwrap()
            .into_inner();
        assert!(page.robots.len() <= 4);
        grpc.extend(page.robots.into_iter().map(|r| r.name));
        if page.next_page_token.is_empty() {
            break;
        }
        token = page.next_page_token;
    }
    assert_eq!(grpc, all);
}

#[tokio::test]
async fn sizes_are_bounded_and_bad_tokens_refused_naming_the_field() {
    let app = spawn_app().await;
    // Any int64 is a documented value (schemathesis sends 2^31 and more).
    for size in ["1000000", "2147483648", "9223372036854775807"] {
        let (status, page) = rest_page(&app, &format!("page_size={size}")).await;
        assert_eq!(status, 200, "a size over the maximum is lowered to it");
        assert!(page["robots"].as_array().unwrap().len() <= 1000);
    }
    for query in [
        "page_token=not-ours",
        "page_token=n.zz",
        "page_size=-1",
        "page_size=x",
        "colour=red",
    ] {
        let r = app.get(&format!("/v1/robots?{query}")).await;
        let p = problem(r, 400).await;
        let field = p["errors"][0]["field"].as_str().unwrap_or("");
        assert!(
            ["page_token", "page_size", "query"].contains(&field),
            "{query}: {p}"
        );
    }
    let mut client = app.grpc_client().await;
    let e = client
        .list_robots(pb::ListRobotsRequest {
            page_size: 0,
            page_token: "not-ours".into(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert_eq!(status_fields(&e), ["page_token"]);
    let e = client
        .list_robots(pb::ListRobotsRequest {
            page_size: -5,
            page_token: String::new(),
        })
        .await
        .unwrap_err();
    assert_eq!(status_fields(&e), ["page_size"]);
}
