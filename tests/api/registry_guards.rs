//! Guards of the registry (issue 22, items 5–7): the robot cap holds under
//! concurrent creates (one server and replicas sharing a database) and gives
//! a failed write's slot back; a store over the cap at start-up is loaded and
//! reported; names a URDF cannot carry are refused with 422 on `links[i].name`,
//! and every odd name accepted comes back exactly from the URDF; registered
//! names may not pass for a built-in's; the 404 suggestions still work with
//! many robots; overload answers are logged at WARN, rate-limited.

use std::time::Instant;

use kinserve::api::grpc::pb;
use serde_json::{Value, json};
use tonic::Code;

use crate::helpers::*;
use crate::replicas::postgres;

/// Registered robots `app` lists (every page).
async fn registered(app: &TestApp) -> Vec<String> {
    let mut names = Vec::new();
    let mut token = String::new();
    loop {
        let page: Value = app
            .get(&format!("/v1/robots?page_size=1000&page_token={token}"))
            .await
            .json()
            .await
            .unwrap();
        for r in page["robots"].as_array().unwrap() {
            if r["source"] == "registered" {
                names.push(r["name"].as_str().unwrap().to_string());
            }
        }
        match page["next_page_token"].as_str() {
            Some(t) => token = t.to_string(),
            None => return names,
        }
    }
}

/// `n` creates of distinct names sent at once; the statuses, in name order.
async fn concurrent_creates(apps: &[&TestApp], prefix: &str, n: usize) -> Vec<u16> {
    let sends = (0..n).map(|k| {
        let app = apps[k % apps.len()];
        let body = planar_model(&format!("{prefix}-{k:03}"));
        async move { app.post("/v1/robots", &body).await.status().as_u16() }
    });
    futures_util::future::join_all(sends).await
}

fn count(statuses: &[u16], status: u16) -> usize {
    statuses.iter().filter(|s| **s == status).count()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn concurrent_creates_around_the_cap_never_leave_more_than_the_cap() {
    let tmp = tempfile::tempdir().unwrap();
    let app = spawn_in(tmp.path(), |c| c.max_robots = 20).await;
    for k in 0..18 {
        let r = app
            .post("/v1/robots", &planar_model(&format!("stored-{k:02}")))
            .await;
        assert_eq!(r.status(), 201);
    }
    let witness = Witness::start(&app.http);
    let statuses = concurrent_creates(&[&app], "rush", 50).await;
    witness.finish("50 concurrent creates at the cap").await;
    assert_eq!(count(&statuses, 201), 2, "{statuses:?}");
    assert_eq!(count(&statuses, 507), 48, "{statuses:?}");
    assert_eq!(registered(&app).await.len(), 20);
    let p = problem(app.post("/v1/robots", &planar_model("late")).await, 507).await;
    assert_eq!(p["type"], "urn:kinserve:problem:registry-full");
    app.stop().await.unwrap();
    let files = std::fs::read_dir(tmp.path().join("robots"))
        .unwrap()
        .count();
    assert_eq!(files, 20, "robot files on disk");
    let again = spawn_in(tmp.path(), |c| c.max_robots = 20).await;
    assert_eq!(registered(&again).await.len(), 20, "after a restart");
}

#[tokio::test]
async fn a_failed_write_gives_its_slot_back() {
    let tmp = tempfile::tempdir().unwrap();
    let app = spawn_in(tmp.path(), |c| c.max_robots = 2).await;
    assert_eq!(
        app.post("/v1/robots", &planar_model("first"))
            .await
            .status(),
        201
    );
    // Replace the robots directory by a plain file: every write fails.
    let dir = tmp.path().join("robots");
    let kept = std::fs::read(dir.join("first.json")).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::write(&dir, b"not a directory").unwrap();
    for k in 0..3 {
        let p = problem(
            app.post("/v1/robots", &planar_model(&format!("failed{k}")))
                .await,
            507,
        )
        .await;
        assert_eq!(p["type"], "urn:kinserve:problem:storage", "{p}");
    }
    std::fs::remove_file(&dir).unwrap();
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(dir.join("first.json"), kept).unwrap();
    // Three failed creates held no slot: the second robot still fits, a third does not.
    assert_eq!(
        app.post("/v1/robots", &planar_model("second"))
            .await
            .status(),
        201
    );
    let p = problem(app.post("/v1/robots", &planar_model("third")).await, 507).await;
    assert_eq!(p["type"], "urn:kinserve:problem:registry-full");
}

#[tokio::test]
async fn replicas_creating_together_cannot_overshoot_the_cap() {
    let Some(pg) = postgres("replicas_creating_together_cannot_overshoot_the_cap").await else {
        return;
    };
    let url = pg.url();
    let replica = |url: String| {
        spawn_app_with(move |c| {
            c.database_url = Some(url);
            c.max_robots = 20;
        })
    };
    let (a, b) = (replica(url.clone()).await, replica(url).await);
    for k in 0..18 {
        let r = a
            .post("/v1/robots", &planar_model(&format!("stored-{k:02}")))
            .await;
        assert_eq!(r.status(), 201);
    }
    crate::replicas::until_served(
        &b,
        "stored-17",
        crate::replicas::etag_on(&a, "stored-17").await.as_deref(),
    )
    .await;
    // Each replica's own snapshot says 18: without the database's count both
    // would let two creates through.
    let statuses = concurrent_creates(&[&a, &b], "rush", 50).await;
    assert_eq!(count(&statuses, 201), 2, "{statuses:?}");
    assert_eq!(count(&statuses, 507), 48, "{statuses:?}");
    let late = spawn_app_with({
        let url = pg.url();
        move |c| c.database_url = Some(url)
    })
    .await;
    assert_eq!(registered(&late).await.len(), 20, "rows in the database");
}

#[tokio::test]
async fn a_store_over_the_cap_at_start_up_is_loaded_and_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let robots = tmp.path().join("robots");
    std::fs::create_dir(&robots).unwrap();
    for name in ["over-a", "over-b", "over-c"] {
        let body = serde_json::to_vec(&planar_model(name)).unwrap();
        std::fs::write(robots.join(format!("{name}.json")), body).unwrap();
    }
    let server = start_server(
        tmp.path(),
        &[
            ("KINSERVE_MAX_ROBOTS", "2"),
            ("KINSERVE_LOG_FORMAT", "json"),
            ("KINSERVE_ACCESS_LOG", "false"),
        ],
        None,
    )
    .await;
    let client = reqwest::Client::new();
    for name in ["over-a", "over-b", "over-c"] {
        let r = client
            .get(format!("{}/v1/robots/{name}", server.http))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200, "{name} is served");
    }
    // A loop of refused creates: 507 every time, logged at WARN at most once a second.
    let start = Instant::now();
    for k in 0..40 {
        let r = client
            .post(format!("{}/v1/robots", server.http))
            .json(&planar_model(&format!("more-{k}")))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 507);
    }
    let secs = start.elapsed().as_secs_f64();
    let lines: Vec<Value> = server
        .stderr()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    let warned = lines
        .iter()
        .any(|l| l["level"] == "WARN" && l["registered"] == 3 && l["max_robots"] == 2);
    assert!(warned, "no WARN naming 3 robots over a cap of 2: {lines:?}");
    let overload: Vec<&Value> = lines
        .iter()
        .filter(|l| l["target"] == "kinserve::overload")
        .collect();
    assert!(!overload.is_empty(), "507 answers not logged: {lines:?}");
    assert!(
        overload
            .iter()
            .all(|l| l["level"] == "WARN" && l["kind"] == "http 507"),
        "{overload:?}"
    );
    assert!(
        overload.len() as f64 <= secs.ceil() + 1.0,
        "{} lines in {secs:.2} s",
        overload.len()
    );
    assert!(!lines.iter().any(|l| l["level"] == "ERROR"), "{lines:?}");
}

/// A model whose rows are called `names` (`None`: no name).
fn named_rows(robot: &str, names: &[Option<&str>]) -> Value {
    let links: Vec<Value> = names
        .iter()
        .map(|n| {
            let mut row = json!({"joint": "revolute", "a": 0.2, "alpha": 0, "d": 0, "theta": 0});
            if let Some(n) = n {
                row["name"] = json!(n);
            }
            row
        })
        .collect();
    json!({"name": robot, "convention": "standard", "links": links})
}

#[tokio::test]
async fn a_control_character_in_a_link_name_is_422_naming_the_field() {
    let app = spawn_app().await;
    for (i, bad) in [
        (1, "elbow\u{1}"),
        (3, "x\u{1b}[2J"),
        (0, "\u{202e}wrist"),
        (2, "\u{ffff}"),
    ] {
        let mut names = vec![Some("ok"); 4];
        names[i] = Some(bad);
        let p = problem(
            app.post("/v1/robots", &named_rows("bad-names", &names))
                .await,
            422,
        )
        .await;
        let fields: Vec<&str> = p["errors"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["field"].as_str().unwrap())
            .collect();
        assert_eq!(fields, [format!("links[{i}].name")], "{p}");
        let message = p["errors"][0]["message"].as_str().unwrap();
        assert!(
            message.contains("control characters"),
            "says what is allowed: {message}"
        );
        assert!(
            message.contains(&format!(
                "U+{:04X}",
                u32::from(bad.chars().find(|c| kinserve_model::forbidden(*c)).unwrap())
            )),
            "{message}"
        );
    }
    problem(app.get("/v1/robots/bad-names").await, 404).await;
    let mut robot = planar_pb("bad-names");
    robot.links[1].name = Some("elbow\u{1}".into());
    let e = app
        .grpc_client()
        .await
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(robot),
            replace: false,
            etag: String::new(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert!(e.message().contains("links[1].name"), "{}", e.message());
}

#[tokio::test]
async fn the_urdf_of_every_accepted_odd_name_parses_and_keeps_the_name() {
    let app = spawn_app().await;
    let odd = [
        "a<b>&c\"d'e",
        "]]>",
        "--",
        "<!-- x -->",
        "&amp;",
        "  spaced  ",
        "肩関節",
        "\u{1F916}",
        "\u{e000}\u{fffd}",
        "tool_joint",
    ];
    let names: Vec<Option<&str>> = odd.iter().map(|n| Some(*n)).collect();
    assert_eq!(
        app.post("/v1/robots", &named_rows("odd-names", &names))
            .await
            .status(),
        201
    );
    let r = app.get("/v1/robots/odd-names/urdf").await;
    assert_eq!(r.status(), 200);
    let xml = r.text().await.unwrap();
    let doc = roxmltree::Document::parse(&xml).unwrap_or_else(|e| panic!("{e}: {xml}"));
    let joints: Vec<&str> = doc
        .descendants()
        .filter(|n| n.has_tag_name("joint"))
        .filter_map(|n| n.attribute("name"))
        .collect();
    for name in odd {
        assert!(joints.contains(&name), "{name:?} not among {joints:?}");
    }
}

#[tokio::test]
async fn lookalikes_of_builtin_names_are_refused_naming_the_builtin() {
    let app = spawn_app().await;
    for name in ["puma-560", "puma_560", "pu-ma560", "ur-5e"] {
        let p = problem(app.post("/v1/robots", &planar_model(name)).await, 422).await;
        assert_eq!(p["errors"][0]["field"], "name", "{p}");
        let builtin = if name.starts_with('u') {
            "'ur5e'"
        } else {
            "'puma560'"
        };
        assert!(
            p["errors"][0]["message"]
                .as_str()
                .unwrap()
                .contains(builtin),
            "{name}: {p}"
        );
    }
    let e = app
        .grpc_client()
        .await
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(planar_pb("puma-560")),
            replace: false,
            etag: String::new(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert!(e.message().contains("puma560"), "{}", e.message());
    // Different letters or digits are a different robot.
    assert_eq!(
        app.post("/v1/robots", &planar_model("puma-561"))
            .await
            .status(),
        201
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn not_found_still_suggests_the_nearest_names_among_many_robots() {
    let app = spawn_app_with(|c| c.max_robots = 400).await;
    let sends = (0..300).map(|k| {
        let body = planar_model(&format!("cell-{k:03}"));
        let app = &app;
        async move { app.post("/v1/robots", &body).await.status().as_u16() }
    });
    let statuses = futures_util::future::join_all(sends).await;
    assert_eq!(count(&statuses, 201), 300);
    for (asked, expect) in [
        ("Puma-560", "puma560"),
        ("CELL_123", "cell-123"),
        ("cell1234", "cell-123"),
    ] {
        let p = problem(app.get(&format!("/v1/robots/{asked}")).await, 404).await;
        let detail = p["detail"].as_str().unwrap();
        assert!(detail.contains("did you mean"), "{asked}: {detail}");
        let first = detail.split('\'').nth(3);
        assert_eq!(first, Some(expect), "{asked}: best first in {detail}");
    }
    let p = problem(app.get("/v1/robots/zzzzzzzzzzzz").await, 404).await;
    assert!(
        !p["detail"].as_str().unwrap().contains("did you mean"),
        "{p}"
    );
    // A flood of lookups of unknown names does not slow a well-behaved client.
    let witness = Witness::start(&app.http);
    let mut statuses = Vec::new();
    for round in 0..20 {
        let flood = (0..100).map(|k| {
            let app = &app;
            async move {
                let path = format!("/v1/robots/cell-{round:02}{k:02}x");
                app.get(&path).await.status().as_u16()
            }
        });
        statuses.extend(futures_util::future::join_all(flood).await);
    }
    assert_eq!(count(&statuses, 404), 2000);
    witness
        .finish("2,000 lookups of unknown names among 300 robots")
        .await;
}
