//! Replicas on one PostgreSQL when things break: the database stopped and
//! started again (FK, list and get go on, writes are 503 within 2 s, readiness
//! stays, writes resume and replicas converge), `kill -9` of a replica in the
//! middle of writes (nothing acknowledged is lost, nothing half-written shows),
//! and the password file (never in the logs).

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use kinserve::api::grpc::pb;
use serde_json::{Value, json};
use tonic::Code;

use crate::etags::{etag_of, planar_version, put_with};
use crate::helpers::*;
use crate::replicas::{etag_on, eventually, postgres, replica, until_served};

/// The value of the sample `line_prefix` in a Prometheus text.
fn sample(text: &str, line_prefix: &str) -> Option<f64> {
    text.lines()
        .find_map(|l| l.strip_prefix(line_prefix)?.trim().parse().ok())
}

/// A `kinserve serve` process on `pg` with an empty data dir.
async fn server_on(url: &str, data: &std::path::Path, extra: &[(&str, &str)]) -> Server {
    let mut env = vec![("KINSERVE_DATABASE_URL", url)];
    env.extend_from_slice(extra);
    start_server(data, &env, None).await
}

/// The product refuses a write within 2 s while the database is down; the
/// test bound is five times that (a loaded two-core runner), still far below
/// a write that waits for the database. Each measured time is reported.
const REFUSAL_LIMIT: Duration = Duration::from_secs(2);
const REFUSAL_BOUND: Duration = Duration::from_secs(10);

/// A write that must be refused quickly while the database is down: 503
/// problem+json with Retry-After, within [`REFUSAL_BOUND`]. Returns how
/// long it took.
async fn refused_quickly(client: &reqwest::Client, base: &str, name: &str) -> Duration {
    let start = Instant::now();
    let r = put_with(client, base, name, &planar_model(name), &[]).await;
    let took = start.elapsed();
    assert!(r.headers().contains_key("retry-after"), "{:?}", r.headers());
    let p = problem(r, 503).await;
    assert_eq!(p["type"], "urn:kinserve:problem:store-unavailable", "{p}");
    kinserve_testkit::report(&format!(
        "write refused with the database down after {took:?} (product limit {REFUSAL_LIMIT:?})"
    ));
    assert!(
        took <= REFUSAL_BOUND,
        "a refused write took {took:?} (limit {REFUSAL_LIMIT:?}, test bound {REFUSAL_BOUND:?})"
    );
    took
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_the_database_down_reads_and_fk_go_on_and_writes_resume_when_it_is_back() {
    let Some(pg) = postgres("replicas_outage::database_down").await else {
        return;
    };
    let data = tempfile::tempdir().unwrap();
    let a = server_on(&pg.url(), data.path(), &[]).await;
    let b = replica(&pg, Duration::from_secs(30)).await;
    let client = reqwest::Client::new();
    let v = etag_of(&put_with(&client, &a.http, "arm", &planar_model("arm"), &[]).await);
    until_served(&b, "arm", Some(&v)).await;

    tokio::task::block_in_place(|| pg.stop_server());
    // At once, before the replicas may have noticed: still bounded.
    let first = refused_quickly(&client, &a.http, "during-outage").await;
    // FK, get and list go on; liveness too.
    for base in [&a.http, &b.http] {
        let fk = client
            .post(format!("{base}/v1/robots/arm/fk"))
            .json(&json!({"joints": [0, 0]}))
            .send()
            .await
            .unwrap();
        assert_eq!(fk.status(), 200);
        assert_eq!(
            client
                .get(format!("{base}/v1/robots/arm"))
                .send()
                .await
                .unwrap()
                .status(),
            200
        );
        assert_eq!(
            client
                .get(format!("{base}/v1/robots"))
                .send()
                .await
                .unwrap()
                .status(),
            200
        );
        assert_eq!(
            client
                .get(format!("{base}/healthz"))
                .send()
                .await
                .unwrap()
                .status(),
            200
        );
    }
    // Readiness stays, and says the store is down.
    let (ready, noticed) = eventually("readyz says down", || async {
        let r = b.get("/readyz").await;
        assert_eq!(r.status(), 200);
        let v: Value = r.json().await.unwrap();
        (v["store"]["state"] == "down").then_some(v)
    })
    .await;
    eprintln!("first refused write {first:?}; down noticed after {noticed:?}: {ready}");
    let later = refused_quickly(&b.client, &b.http, "during-outage").await;
    eprintln!("refused write once noticed: {later:?}");
    let err = b
        .grpc_client()
        .await
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(planar_pb("grpc-outage")),
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::Unavailable, "{err:?}");
    let (text, _) = eventually("metrics say down", || async {
        let t = client
            .get(format!("{}/metrics", a.http))
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        (sample(&t, "kinserve_store_up{store=\"postgres\"}") == Some(0.0)).then_some(t)
    })
    .await;
    assert!(
        sample(
            &text,
            "kinserve_store_snapshot_age_seconds{store=\"postgres\"}"
        )
        .is_some()
    );

    tokio::task::block_in_place(|| pg.start_server());
    let start = Instant::now();
    let (v2, _) = eventually("writes resume on A", || async {
        let r = put_with(&client, &a.http, "arm", &planar_version("arm", 0.2), &[]).await;
        (r.status() == 200).then(|| etag_of(&r))
    })
    .await;
    eprintln!("writes resumed {:?} after the restart", start.elapsed());
    until_served(&b, "arm", Some(&v2)).await;
    let (v3, _) = eventually("writes resume on B", || async {
        let r = put_with(&b.client, &b.http, "after", &planar_model("after"), &[]).await;
        (r.status() == 201).then(|| etag_of(&r))
    })
    .await;
    let a_app_view = |name: &'static str| {
        let url = format!("{}/v1/robots/{name}", a.http);
        let client = client.clone();
        async move {
            let r = client.get(url).send().await.unwrap();
            (r.status() == 200).then(|| etag_of(&r))
        }
    };
    eventually("A sees B's write", || async {
        (a_app_view("after").await == Some(v3.clone())).then_some(())
    })
    .await;
    assert_eq!(
        etag_on(&b, "during-outage").await,
        None,
        "refused writes left nothing"
    );
    let ready: Value = b.get("/readyz").await.json().await.unwrap();
    assert_eq!(ready["store"]["state"], "up", "{ready}");
}

/// Four writers create robots through replica A as fast as it answers; A is
/// killed with SIGKILL in the middle. Every write A acknowledged is in the
/// database with the ETag A gave, and a replica started afterwards loads
/// every row whole (a write A did not acknowledge may be there, complete).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kill_9_of_a_replica_during_writes_loses_nothing_acknowledged() {
    let Some(pg) = postgres("replicas_outage::kill_9").await else {
        return;
    };
    let data = tempfile::tempdir().unwrap();
    let mut a = server_on(&pg.url(), data.path(), &[]).await;
    let b = replica(&pg, Duration::from_secs(30)).await;
    let acked: Arc<Mutex<Vec<(String, String, f64)>>> = Arc::default();
    let writers: Vec<_> = (0..4)
        .map(|t| {
            let (base, acked) = (a.http.clone(), acked.clone());
            tokio::spawn(async move {
                let client = reqwest::Client::new();
                for i in 0..10_000u32 {
                    let name = format!("w{t}-{i}");
                    let len = 0.1 + f64::from(i % 100) / 1000.0;
                    let body = planar_version(&name, len);
                    let sent = client
                        .put(format!("{base}/v1/robots/{name}"))
                        .json(&body)
                        .send();
                    match tokio::time::timeout(Duration::from_secs(5), sent).await {
                        Ok(Ok(r)) if r.status() == 201 => {
                            acked.lock().unwrap().push((name, etag_of(&r), len));
                        }
                        _ => return i,
                    }
                }
                10_000
            })
        })
        .collect();
    eventually("40 acknowledged writes", || async {
        (acked.lock().unwrap().len() >= 40).then_some(())
    })
    .await;
    a.kill();
    let attempted: Vec<u32> = futures_util::future::join_all(writers)
        .await
        .into_iter()
        .map(Result::unwrap)
        .collect();
    let acked = acked.lock().unwrap().clone();
    eprintln!(
        "killed after {} acknowledged writes (per writer: {attempted:?})",
        acked.len()
    );

    let late = replica(&pg, Duration::from_secs(30)).await;
    for (name, etag, len) in &acked {
        assert_eq!(
            etag_on(&late, name).await.as_ref(),
            Some(etag),
            "{name} lost"
        );
        let got: Value = late
            .get(&format!("/v1/robots/{name}"))
            .await
            .json()
            .await
            .unwrap();
        assert_eq!(got["links"][1]["a"], *len, "{name}");
    }
    // Every row is whole: the late replica loaded all of them.
    let rows: usize = pg
        .psql("SELECT count(*) FROM kinserve_robots")
        .parse()
        .unwrap();
    let list: Value = late
        .get("/v1/robots?page_size=1000")
        .await
        .json()
        .await
        .unwrap();
    let registered = list["robots"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["source"] == "registered")
        .count();
    assert_eq!(registered, rows, "every row loaded whole");
    assert!(
        rows >= acked.len() && rows <= acked.len() + 4,
        "{rows} rows, {} acked",
        acked.len()
    );
    // The replica that lived through the crash converged too.
    let (_, took) = eventually("B converged", || async {
        let l: Value = b
            .get("/v1/robots?page_size=1000")
            .await
            .json()
            .await
            .unwrap();
        (l == list).then_some(())
    })
    .await;
    eprintln!("surviving replica converged {took:?} after the check started");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_password_can_come_from_a_file_and_never_reaches_the_logs() {
    let Some(pg) = postgres("replicas_outage::password_file").await else {
        return;
    };
    let data = tempfile::tempdir().unwrap();
    let pwfile = data.path().join("db-password");
    std::fs::write(&pwfile, format!("{PG_PASSWORD}\n")).unwrap();
    let pwpath = pwfile.display().to_string();
    let a = server_on(
        &pg.url_without_password(),
        data.path(),
        &[
            ("KINSERVE_DATABASE_PASSWORD_FILE", &pwpath),
            ("RUST_LOG", "debug"),
        ],
    )
    .await;
    let client = reqwest::Client::new();
    let r = put_with(&client, &a.http, "arm", &planar_model("arm"), &[]).await;
    assert_eq!(r.status(), 201);
    tokio::task::block_in_place(|| pg.stop_server());
    eventually("the server notices", || async {
        a.stderr().contains("lost the database").then_some(())
    })
    .await;
    tokio::task::block_in_place(|| pg.start_server());
    eventually("writes resume", || async {
        let r = put_with(&client, &a.http, "arm2", &planar_model("arm2"), &[]).await;
        (r.status() == 201).then_some(())
    })
    .await;
    let logs = a.stderr();
    assert!(
        !logs.contains(PG_PASSWORD),
        "the password is in the logs:\n{logs}"
    );
    assert!(
        !logs.contains("postgres://"),
        "the URL is in the logs:\n{logs}"
    );
    assert!(logs.contains("database reachable"), "{logs}");
}
