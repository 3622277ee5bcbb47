//! Crash safety and storage faults, with the real `kinserve` binary where a
//! separate process is needed:
//!
//! * robots are registered, replaced and deleted in a loop by concurrent
//!   clients while the server is `kill -9`ed at a pseudo-random moment
//!   (seeded); after a restart every acknowledged change is there, intact, and
//!   nothing else is (no half-written or temporary files, no unacknowledged
//!   robot that was not in flight);
//! * a full disk (a file size limit: writes fail part way) and a data
//!   directory that cannot be written give 507 / UNAVAILABLE with a message,
//!   change nothing, and leave the existing models readable.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use kinserve::api::grpc::pb;
use serde_json::{Value, json};
use tonic::Code;

use crate::helpers::*;

// ---------------------------------------------------------------- kill -9 loop

/// xorshift64*: a small seeded generator (the seed is printed on failure).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// What a name may look like after a crash: the last acknowledged state, and
/// the state of the change in flight when the server died (if any).
#[derive(Clone, Debug, Default)]
struct NameState {
    acked: Option<Value>,
    pending: Option<Option<Value>>,
}

impl NameState {
    fn allows(&self, got: Option<&Value>) -> bool {
        let eq = |want: &Option<Value>| match (want, got) {
            (None, None) => true,
            (Some(w), Some(g)) => json_eq(w, g),
            _ => false,
        };
        eq(&self.acked) || self.pending.as_ref().is_some_and(eq)
    }
}

#[derive(Default)]
struct Ledger {
    names: HashMap<String, NameState>,
    acked_writes: usize,
}

fn crash_model(name: &str, round: usize, seq: u64, a: f64) -> Value {
    let mut m = planar_model(name);
    m["description"] = json!(format!("round {round}, write {seq}"));
    m["links"][1]["a"] = json!(a);
    m
}

/// One writer: PUTs and DELETEs its own names until a request fails (the server died).
async fn writer(
    http: String,
    ledger: Arc<Mutex<Ledger>>,
    task: usize,
    round: usize,
    seed: u64,
) -> usize {
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(10))
        .build()
        .unwrap();
    let mut rng = Rng(seed ^ (task as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let mut done = 0;
    for seq in 0.. {
        let name = format!("w{task}_{}", rng.below(6));
        let delete = rng.below(4) == 0;
        let a = 0.1 + rng.below(1000) as f64 / 1000.0;
        // As the server will hold it: parsed by serde_json like the server does
        // (its default float parsing may differ from the literal by one ULP).
        let new_state = (!delete).then(|| {
            let m = crash_model(&name, round, seq, a);
            serde_json::from_slice::<Value>(&serde_json::to_vec(&m).unwrap()).unwrap()
        });
        ledger
            .lock()
            .unwrap()
            .names
            .entry(name.clone())
            .or_default()
            .pending = Some(new_state.clone());
        let url = format!("{http}/v1/robots/{name}");
        let result = match &new_state {
            Some(m) => client.put(&url).json(m).send().await,
            None => client.delete(&url).send().await,
        };
        let resp = match result {
            Ok(r) => r,
            Err(_) => return done, // the server is gone: this change stays in flight
        };
        let status = resp.status().as_u16();
        // The acknowledged state is the one the server answered with.
        let acked = match new_state {
            Some(_) if status == 200 || status == 201 => match resp.json::<Value>().await {
                Ok(v) => Some(v),
                Err(_) => return done, // killed while sending the answer: still in flight
            },
            None if status == 204 || status == 404 => None,
            _ => panic!("{name}: unexpected status {status}"),
        };
        let mut l = ledger.lock().unwrap();
        let st = l.names.get_mut(&name).unwrap();
        st.pending = None;
        st.acked = acked;
        l.acked_writes += 1;
        done += 1;
    }
    done
}

/// Files of `<data>/robots`: (robot files, temporary files, anything else).
fn data_files(data: &Path) -> (Vec<PathBuf>, Vec<String>, Vec<String>) {
    let (mut robots, mut temps, mut other) = (Vec::new(), Vec::new(), Vec::new());
    for e in std::fs::read_dir(data.join("robots")).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') && name.contains(".json.tmp-") {
            temps.push(name);
        } else if name.ends_with(".json") && e.file_type().unwrap().is_file() {
            robots.push(e.path());
        } else {
            other.push(name);
        }
    }
    (robots, temps, other)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn acknowledged_registrations_survive_kill_9_and_nothing_else_appears() {
    const ROUNDS: usize = 10;
    const WRITERS: usize = 4;
    let base_seed: u64 = std::env::var("KINSERVE_CRASH_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x6b69_6e73_6572_7665);
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path();
    let ledger = Arc::new(Mutex::new(Ledger::default()));
    let (mut in_flight_total, mut temps_total, mut checked_total) = (0, 0, 0);
    for round in 0..ROUNDS {
        let seed = base_seed.wrapping_add(round as u64);
        let mut rng = Rng(seed | 1);
        let kill_after = 5 + rng.below(60) as usize;
        let mut server = start_server(data, &[], None).await;
        let start = ledger.lock().unwrap().acked_writes;
        let writers: Vec<_> = (0..WRITERS)
            .map(|t| tokio::spawn(writer(server.http.clone(), ledger.clone(), t, round, seed)))
            .collect();
        // Kill once `kill_after` more writes were acknowledged (or after a bound).
        for _ in 0..2000 {
            if ledger.lock().unwrap().acked_writes - start >= kill_after {
                break;
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        server.kill();
        for w in writers {
            w.await.expect("writer");
        }
        let ctx = format!("seed {seed}, round {round}, killed after {kill_after} acks");

        // On disk, before any restart: every robot file is whole and one of the
        // allowed states of its name; temporary files may be left over.
        let (robots, temps, other) = data_files(data);
        assert!(other.is_empty(), "{ctx}: unexpected files {other:?}");
        temps_total += temps.len();
        {
            let l = ledger.lock().unwrap();
            in_flight_total += l.names.values().filter(|s| s.pending.is_some()).count();
            for p in &robots {
                let name = p.file_stem().unwrap().to_string_lossy().into_owned();
                let v: Value = serde_json::from_slice(&std::fs::read(p).unwrap())
                    .unwrap_or_else(|e| panic!("{ctx}: {} is not whole JSON: {e}", p.display()));
                let st = l
                    .names
                    .get(&name)
                    .unwrap_or_else(|| panic!("{ctx}: {name} was never written"));
                assert!(
                    st.allows(Some(&v)),
                    "{ctx}: {name} on disk is {v}, allowed {st:?}"
                );
            }
        }

        // After a restart: every name is in an allowed state, and it becomes the
        // known state; no temporary file is left.
        let server = start_server(data, &[], None).await;
        let client = reqwest::Client::new();
        let names: Vec<String> = ledger.lock().unwrap().names.keys().cloned().collect();
        for name in &names {
            let r = client
                .get(format!("{}/v1/robots/{name}", server.http))
                .send()
                .await
                .unwrap();
            let got = match r.status().as_u16() {
                200 => Some(r.json::<Value>().await.unwrap()),
                404 => None,
                s => panic!("{ctx}: GET {name}: {s}"),
            };
            let mut l = ledger.lock().unwrap();
            let st = l.names.get_mut(name).unwrap();
            assert!(
                st.allows(got.as_ref()),
                "{ctx}: {name} after restart is {got:?}, allowed {st:?}"
            );
            *st = NameState {
                acked: got,
                pending: None,
            };
            checked_total += 1;
        }
        let list: Value = client
            .get(format!("{}/v1/robots", server.http))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        let l = ledger.lock().unwrap();
        for r in list["robots"].as_array().unwrap() {
            if r["source"] == "registered" {
                let name = r["name"].as_str().unwrap();
                assert!(
                    l.names.get(name).is_some_and(|s| s.acked.is_some()),
                    "{ctx}: {name} is listed"
                );
            }
        }
        let (robots, temps, other) = data_files(data);
        assert!(
            temps.is_empty(),
            "{ctx}: temporary files after restart: {temps:?}"
        );
        assert!(other.is_empty(), "{ctx}: {other:?}");
        let present = l.names.values().filter(|s| s.acked.is_some()).count();
        assert_eq!(robots.len(), present, "{ctx}: one file per robot");
        drop(l);
        drop(server);
    }
    let acked = ledger.lock().unwrap().acked_writes;
    println!(
        "kill -9: {ROUNDS} rounds, {acked} acknowledged writes, {in_flight_total} in flight at the kills, \
         {temps_total} temporary files left by the kills (removed at restart), {checked_total} name checks after restart, 0 lost"
    );
}

// ---------------------------------------------------------------- full disk, read-only data

/// A model whose pretty JSON is over 4 KiB (a long description).
fn big_model(name: &str) -> Value {
    let mut m = planar_model(name);
    m["description"] = json!("x".repeat(4000));
    m
}

fn temp_files(data: &Path) -> Vec<String> {
    data_files(data).1
}

/// A file size limit makes every write over 4 KiB fail part way (EFBIG, as a
/// full disk would with ENOSPC): such registrations are 507 (REST) /
/// UNAVAILABLE (gRPC) with a message, change nothing, leave no temporary file;
/// existing models stay readable and smaller writes keep working.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_disk_is_507_and_unavailable_and_changes_nothing() {
    if Command::new("prlimit").arg("--version").output().is_err() {
        kinserve_testkit::skip_unless_ci(
            "full-disk test",
            "prlimit is not installed",
            "apt-get install util-linux",
        );
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path();
    // SIGXFSZ ignored (inherited through exec), so a write over the limit fails with EFBIG.
    let wrapper = r#"trap '' XFSZ; exec prlimit --fsize=4096 -- "$0" serve"#;
    let server = start_server(data, &[], Some(wrapper)).await;
    let client = reqwest::Client::new();
    let url = |p: &str| format!("{}{p}", server.http);
    let r = client
        .post(url("/v1/robots"))
        .json(&planar_model("small"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);

    let r = client
        .post(url("/v1/robots"))
        .json(&big_model("big"))
        .send()
        .await
        .unwrap();
    let p = problem(r, 507).await;
    assert_eq!(p["type"], "urn:kinserve:problem:storage");
    let detail = p["detail"].as_str().unwrap();
    assert!(
        detail.contains("write") && detail.contains("robots/.big.json.tmp-"),
        "{p}"
    );
    assert!(
        !detail.contains(&data.display().to_string()),
        "no host path: {p}"
    );
    problem(client.get(url("/v1/robots/big")).send().await.unwrap(), 404).await;
    // Replacing an existing robot by a big version fails the same way; the old one stays.
    let r = client
        .put(url("/v1/robots/small"))
        .json(&big_model("small"))
        .send()
        .await
        .unwrap();
    problem(r, 507).await;
    let got: Value = client
        .get(url("/v1/robots/small"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(json_eq(&got, &planar_model("small")), "{got}");
    let r = client
        .post(url("/v1/robots/small/fk"))
        .json(&json!({"joints": [0, 0]}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    // gRPC: UNAVAILABLE with a message.
    let mut g =
        pb::kinematics_service_client::KinematicsServiceClient::connect(server.grpc.clone())
            .await
            .unwrap();
    let mut robot = pb::Robot {
        name: "big_grpc".into(),
        description: Some("x".repeat(4000)),
        convention: pb::Convention::Standard as i32,
        ..Default::default()
    };
    robot.links.push(pb::Link {
        joint: pb::JointType::Revolute as i32,
        a: Some(1.0),
        alpha: Some(0.0),
        d: Some(0.0),
        theta: Some(0.0),
        ..Default::default()
    });
    let err = g
        .register_robot(pb::RegisterRobotRequest {
            robot: Some(robot),
            replace: false,
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::Unavailable, "{err:?}");
    assert!(err.message().contains("storage"), "{err:?}");
    assert!(temp_files(data).is_empty(), "{:?}", temp_files(data));
    // Small writes still work.
    let r = client
        .post(url("/v1/robots"))
        .json(&planar_model("after"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    drop(server);

    // Restarted without the limit: exactly what was acknowledged.
    let server = start_server(data, &[], None).await;
    let get = |n: &str| client.get(format!("{}/v1/robots/{n}", server.http)).send();
    assert_eq!(get("small").await.unwrap().status(), 200);
    assert_eq!(get("after").await.unwrap().status(), 200);
    assert_eq!(get("big").await.unwrap().status(), 404);
    assert_eq!(get("big_grpc").await.unwrap().status(), 404);
    let (robots, temps, other) = data_files(data);
    assert_eq!(robots.len(), 2);
    assert!(temps.is_empty() && other.is_empty());
}

/// A data directory that cannot be written (its `robots` directory replaced by
/// a plain file: works even as root, where permissions do not stop writes):
/// every change is 507 / UNAVAILABLE with a message, reads and FK go on, and
/// writes work again once the directory is back, without a restart.
#[tokio::test]
async fn an_unwritable_data_directory_is_507_and_unavailable_and_reads_go_on() {
    let tmp = tempfile::tempdir().unwrap();
    let app = spawn_in(tmp.path(), |c| c.api_token = Some("t0ken".into())).await;
    let auth = "Bearer t0ken";
    let put = |name: &str, body: &Value| {
        app.client
            .put(format!("{}/v1/robots/{name}", app.http))
            .header("authorization", auth)
            .json(body)
            .send()
    };
    assert_eq!(
        put("kept", &planar_model("kept")).await.unwrap().status(),
        201
    );

    let dir = tmp.path().join("robots");
    let aside = tmp.path().join("robots.aside");
    std::fs::rename(&dir, &aside).unwrap();
    std::fs::write(&dir, b"not a directory").unwrap();

    let mut changed = planar_model("kept");
    changed["links"][0]["a"] = json!(0.9);
    for r in [
        put("kept", &changed).await.unwrap(),
        put("fresh", &planar_model("fresh")).await.unwrap(),
        app.client
            .post(format!("{}/v1/robots", app.http))
            .header("authorization", auth)
            .json(&planar_model("posted"))
            .send()
            .await
            .unwrap(),
        app.client
            .delete(format!("{}/v1/robots/kept", app.http))
            .header("authorization", auth)
            .send()
            .await
            .unwrap(),
    ] {
        let p = problem(r, 507).await;
        assert_eq!(p["type"], "urn:kinserve:problem:storage");
        let detail = p["detail"].as_str().unwrap();
        assert!(detail.contains("robots/"), "names the file: {p}");
        assert!(
            !detail.contains(&tmp.path().display().to_string()),
            "no host path: {p}"
        );
    }
    let mut g = app.grpc_client().await;
    let mut req = tonic::Request::new(pb::DeleteRobotRequest {
        name: "kept".into(),
        ..Default::default()
    });
    req.metadata_mut()
        .insert("authorization", auth.parse().unwrap());
    let err = g.delete_robot(req).await.unwrap_err();
    assert_eq!(err.code(), Code::Unavailable, "{err:?}");
    assert!(!err.message().is_empty());
    // Reads and FK are untouched.
    let got: Value = app.get("/v1/robots/kept").await.json().await.unwrap();
    assert!(json_eq(&got, &planar_model("kept")), "{got}");
    assert_eq!(
        app.post("/v1/robots/kept/fk", &json!({"joints": [0, 0]}))
            .await
            .status(),
        200
    );
    problem(app.get("/v1/robots/fresh").await, 404).await;
    let fk = g
        .forward_kinematics(pb::ForwardKinematicsRequest {
            robot: "kept".into(),
            joints: vec![0.0, 0.0],
            options: None,
        })
        .await;
    assert!(fk.is_ok(), "{fk:?}");

    // The directory comes back: writes work again.
    std::fs::remove_file(&dir).unwrap();
    std::fs::rename(&aside, &dir).unwrap();
    assert_eq!(put("kept", &changed).await.unwrap().status(), 200);
    assert_eq!(
        put("fresh", &planar_model("fresh")).await.unwrap().status(),
        201
    );
    app.stop().await.unwrap();
    let app = spawn_in(tmp.path(), |_| {}).await;
    let got: Value = app.get("/v1/robots/kept").await.json().await.unwrap();
    assert!(json_eq(&got, &changed), "{got}");
    assert_eq!(app.get("/v1/robots/fresh").await.status(), 200);
}

/// The first SIGTERM (or Ctrl-C) starts the drain (`/readyz` 503 during the
/// 5 s grace); a second one stops the server at once, exit code 0.
#[tokio::test]
async fn a_second_signal_ends_the_drain_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let mut server = start_server(tmp.path(), &[], None).await;
    server.signal("TERM");
    tokio::time::sleep(std::time::Duration::from_millis(300)).await;
    let r = reqwest::get(format!("{}/readyz", server.http))
        .await
        .unwrap();
    assert_eq!(r.status(), 503, "draining after the first signal");
    server.signal("INT");
    let start = std::time::Instant::now();
    let status = server
        .wait_exit(std::time::Duration::from_secs(3))
        .expect("the second signal stops the server well before the 5 s grace ends");
    assert!(status.success(), "{status:?}");
    println!("stopped {:?} after the second signal", start.elapsed());
    assert!(
        server.stderr().contains("second signal"),
        "{}",
        server.stderr()
    );
}
