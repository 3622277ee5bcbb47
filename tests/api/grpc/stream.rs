//! The bidirectional FK stream: order, invalid messages, slow readers,
//! backpressure, timeouts, the concurrency limit, cancellation and idle streams.

use kinserve::api::grpc::pb;
use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use kinserve::api::grpc::pb::stream_forward_kinematics_response::Result as StreamResult;
use tonic::Code;
use tonic::transport::Channel;

use crate::helpers::grpc::assert_pose_eq;
use crate::helpers::*;
use kinserve_testkit::RobotExt;

// ---------------------------------------------------------------- streaming

#[tokio::test]
async fn stream_answers_each_request_in_order_and_survives_invalid_messages() {
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 64).await;

    let ok_puma = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6];
    let requests = vec![
        stream_request(10, "puma560", &ok_puma, None),
        stream_request(7, "panda", &[0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.7], None),
        // Invalid in the middle: wrong count, NaN, out of limits, unknown robot, bad option.
        stream_request(7, "puma560", &[0.0; 5], None),
        stream_request(
            u64::MAX,
            "puma560",
            &[0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0],
            None,
        ),
        stream_request(0, "puma560", &[0.0, 0.0, 170.0, 0.0, 0.0, 0.0], deg()),
        stream_request(3, "no_such_robot", &[0.0], None),
        stream_request(
            4,
            "puma560",
            &ok_puma,
            Some(pb::FkOptions {
                angle_unit: 99,
                ..Default::default()
            }),
        ),
        // And valid again, with frames and a mm robot.
        stream_request(
            5,
            "alpha_ii",
            &[10.0, 20.0, 30.0, 40.0, 50.0],
            Some(pb::FkOptions {
                angle_unit: pb::AngleUnit::Deg as i32,
                frames: Some(true),
                check_limits: Some(true),
                ..Default::default()
            }),
        ),
        stream_request(6, "puma560", &ok_puma, None),
    ];
    for r in &requests {
        tx.send(r.clone()).await.unwrap();
    }
    drop(tx); // half-close: the server ends the stream after the last answer

    let mut responses = Vec::new();
    while let Some(m) = rx.message().await.expect("no stream error") {
        responses.push(m);
    }
    assert_eq!(responses.len(), requests.len(), "exactly one response each");
    let ids: Vec<u64> = responses.iter().map(|r| r.id).collect();
    let want: Vec<u64> = requests.iter().map(|r| r.id).collect();
    assert_eq!(ids, want, "in order, ids echoed");

    let expect_error = |i: usize, code: Code, fields: &[&str]| {
        let Some(StreamResult::Error(e)) = &responses[i].result else {
            panic!("response {i} should be an error: {:?}", responses[i]);
        };
        assert_eq!(e.code, code as i32, "response {i}: {e:?}");
        assert!(!e.message.is_empty());
        assert_eq!(rpc_status_fields(e), fields, "response {i}");
        assert!(responses[i].frames.is_empty());
    };
    expect_error(2, Code::InvalidArgument, &["joints"]);
    expect_error(3, Code::InvalidArgument, &["joints[1]"]);
    expect_error(4, Code::InvalidArgument, &["joints[2]"]);
    expect_error(5, Code::NotFound, &[]);
    expect_error(6, Code::InvalidArgument, &["options.angle_unit"]);

    // Poses agree with the unary RPC.
    for i in [0usize, 1, 7, 8] {
        let Some(StreamResult::Pose(p)) = &responses[i].result else {
            panic!("response {i} should be a pose: {:?}", responses[i]);
        };
        let req = &requests[i];
        let unary = fk(&mut c, fk_request(&req.robot, &req.joints, req.options))
            .await
            .unwrap();
        assert_same_pose(p, unary.pose.as_ref().unwrap(), &format!("response {i}"));
        assert_eq!(responses[i].length_unit, unary.length_unit);
        assert_eq!(responses[i].frames.len(), unary.frames.len());
        for (a, b) in responses[i].frames.iter().zip(&unary.frames) {
            assert_same_pose(a, b, "frame");
        }
    }
    assert_eq!(responses[7].length_unit, pb::LengthUnit::Mm as i32);
    assert_eq!(responses[7].frames.len(), 6);
}

#[tokio::test]
async fn stream_with_a_slow_reader_delivers_every_response_in_order() {
    const N: u64 = 2000;
    let app = spawn_app().await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, N as usize).await;
    let robots = ["puma560", "panda", "stanford", "alpha_ii"];
    let joints = |i: u64| -> (&'static str, Vec<f64>) {
        let t = (i % 97) as f64 / 97.0;
        match i % 4 {
            0 => ("puma560", vec![t, -t, t / 2.0, 0.1, -0.2, t]),
            1 => ("panda", vec![t, -t, 0.0, -1.0 - t, 0.0, 1.0 + t, 0.0]),
            2 => ("stanford", vec![t, -t, 0.5 + t / 2.0, t, 0.2, -t]),
            _ => ("alpha_ii", vec![t, 2.0 * t, -t, 0.3, t]),
        }
    };
    // Every 100th request is invalid (wrong joint count).
    for i in 0..N {
        let (robot, mut q) = joints(i);
        if i % 100 == 99 {
            q.pop();
        }
        tx.send(stream_request(i, robot, &q, None)).await.unwrap();
    }
    drop(tx);
    // Nothing read so far: the server had to stop and wait for this reader.
    let libs: Vec<_> = robots.iter().map(|r| library_robot(r)).collect();
    let mut n = 0u64;
    while let Some(m) = rx.message().await.expect("no stream error") {
        assert_eq!(m.id, n, "in order");
        let (robot, q) = joints(n);
        match (&m.result, n % 100 == 99) {
            (Some(StreamResult::Pose(p)), false) => {
                let lib = &libs[robots.iter().position(|r| *r == robot).unwrap()];
                assert_pose_eq(p, &lib.fk_unchecked(&q), 1e-12, &format!("id {n}"));
            }
            (Some(StreamResult::Error(e)), true) => {
                assert_eq!(e.code, Code::InvalidArgument as i32);
            }
            other => panic!("id {n}: unexpected {other:?}"),
        }
        n += 1;
    }
    assert_eq!(n, N, "every response arrived");
}

#[tokio::test]
async fn backpressure_reaches_the_sender_when_nobody_reads() {
    // The client sends one small request at a time (each its own DATA frame, as
    // a control loop would) and reads nothing. If the server buffered without
    // bound, the client could hand over all N requests (~2 MB). With flow control
    // end to end, the server stops reading once its bounded response queue and
    // the HTTP/2 windows are full, so the client's sender blocks part way; the
    // connection must survive that (h2 once closed it with GOAWAY
    // ENHANCE_YOUR_CALM "too_many_data_frames" after ~2,700 unread requests).
    // Then everything is read back, in order.
    // With HTTP/2's default window (--grpc-stream-window 65535) and the 16
    // times larger default (1 MiB), which lets the client send about 10,000
    // more of these ~90-byte frames ahead (10,047 against 20,819 when
    // written). The larger one also stays safe with the smallest frames a
    // client can send (7 bytes: an id alone, each answered with an error):
    // the connection window grows with it, so h2's small-frame budget still
    // holds a stalled window of them (with a 16 MiB connection window, as
    // before the setting, h2 closed this connection).
    let app = spawn_app_with(|c| c.grpc_stream_window = 65_535).await;
    let stalled = stall_then_read(&app, 30_000, small_fk_request, true).await;
    let app = spawn_app_with(|c| assert_eq!(c.grpc_stream_window, 1 << 20)).await;
    let stalled_wide = stall_then_read(&app, 30_000, small_fk_request, true).await;
    assert!(
        stalled_wide > stalled + 5_000,
        "1 MiB window stalled at {stalled_wide}, 64 KiB at {stalled}"
    );
    stall_then_read(&app, 200_000, id_only_request, false).await;
}

/// A stream's messages see the registry as it is when each is answered: a
/// robot replaced, deleted and registered again between two messages (the
/// stream keeps the entry it looked up only while the registry is unchanged).
#[tokio::test]
async fn a_robot_replaced_or_deleted_mid_stream_is_seen_by_the_next_message() {
    let app = spawn_app().await;
    let url = format!("{}/v1/robots/temp", app.http);
    assert_eq!(
        app.post("/v1/robots", &planar_model("temp")).await.status(),
        201
    );
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    let mut ask = async |id: u64, robot: &str, joints: &[f64]| {
        tx.send(stream_request(id, robot, joints, None))
            .await
            .unwrap();
        let reply = rx.message().await.unwrap().unwrap();
        assert_eq!(reply.id, id);
        match reply.result {
            Some(StreamResult::Pose(p)) => Ok(p.position.unwrap().x),
            Some(StreamResult::Error(e)) => Err(e.code),
            other => panic!("message {id}: {other:?}"),
        }
    };
    let tol = 1e-12;
    assert!(
        (ask(1, "temp", &[0.0, 0.0]).await.unwrap() - 0.8).abs() < tol,
        "a = 0.5 + 0.3"
    );
    assert!(
        (ask(2, "temp", &[0.0, 0.0]).await.unwrap() - 0.8).abs() < tol,
        "unchanged"
    );
    let mut longer = planar_model("temp");
    longer["links"][0]["a"] = 0.9.into();
    let r = app.client.put(&url).json(&longer).send().await.unwrap();
    assert!(r.status().is_success(), "{}", r.status());
    assert!(
        (ask(3, "temp", &[0.0, 0.0]).await.unwrap() - 1.2).abs() < tol,
        "replaced: a = 0.9 + 0.3"
    );
    let r = app.client.delete(&url).send().await.unwrap();
    assert_eq!(r.status(), 204);
    assert_eq!(
        ask(4, "temp", &[0.0, 0.0]).await,
        Err(Code::NotFound as i32),
        "deleted"
    );
    assert_eq!(
        app.post("/v1/robots", &planar_model("temp")).await.status(),
        201
    );
    assert!(
        (ask(5, "temp", &[0.0, 0.0]).await.unwrap() - 0.8).abs() < tol,
        "registered again"
    );
    // Another robot on the same stream, then this one again.
    assert!(ask(6, "puma560", &[0.0; 6]).await.is_ok());
    assert!((ask(7, "temp", &[0.0, 0.0]).await.unwrap() - 0.8).abs() < tol);
}

fn small_fk_request(i: u64) -> pb::StreamForwardKinematicsRequest {
    let q = [0.001 * (i % 1000) as f64, 0.0, 0.0, 0.0, 0.0, 0.0];
    stream_request(i, "puma560", &q, None)
}

/// A request of an id alone (no robot): a 2-byte message, a 7-byte DATA frame.
fn id_only_request(i: u64) -> pb::StreamForwardKinematicsRequest {
    pb::StreamForwardKinematicsRequest {
        id: i % 100 + 1,
        ..Default::default()
    }
}

/// Sends up to `n` requests on one stream while nothing is read, waits until
/// the sender makes no more progress, asserts it stalled before `n`, then
/// reads every reply (poses if `pose`, else errors) and returns where it stalled.
async fn stall_then_read(
    app: &TestApp,
    n: u64,
    request: fn(u64) -> pb::StreamForwardKinematicsRequest,
    pose: bool,
) -> u64 {
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 1).await;
    let sent = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let counter = sent.clone();
    let sender = tokio::spawn(async move {
        for i in 0..n {
            if tx.send(request(i)).await.is_err() {
                return;
            }
            counter.store(i + 1, std::sync::atomic::Ordering::SeqCst);
        }
    });
    // Wait until the sender makes no more progress (quiescence, not a deadline).
    let mut last = u64::MAX;
    for _ in 0..100 {
        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
        let now = sent.load(std::sync::atomic::Ordering::SeqCst);
        if now == last || now == n {
            break;
        }
        last = now;
    }
    let stalled_at = sent.load(std::sync::atomic::Ordering::SeqCst);
    assert!(
        stalled_at < n,
        "the client pushed all {n} requests with nobody reading: unbounded buffering"
    );
    // Now read: the sender resumes and every reply arrives, in order.
    let mut k = 0u64;
    while let Some(m) = rx.message().await.unwrap_or_else(|e| {
        panic!("stream error after {k} replies (stalled at {stalled_at}): {e:?}")
    }) {
        assert_eq!(m.id, request(k).id, "in order");
        match (&m.result, pose) {
            (Some(StreamResult::Pose(_)), true) | (Some(StreamResult::Error(_)), false) => {}
            other => panic!("reply {k}: {other:?}"),
        }
        k += 1;
    }
    assert_eq!(k, n);
    sender.await.unwrap();
    stalled_at
}

#[tokio::test]
async fn a_stream_outlives_the_request_timeout() {
    // The request timeout bounds unary calls; a live stream is bounded by its idle timeout only.
    let app = spawn_app_with(|c| c.request_timeout = std::time::Duration::from_millis(100)).await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    for id in 0..4 {
        tx.send(stream_request(id, "puma560", &[0.0; 6], None))
            .await
            .unwrap();
        assert_eq!(rx.message().await.unwrap().unwrap().id, id);
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
    drop(tx);
    assert!(rx.message().await.unwrap().is_none(), "clean end");
}

/// Calls ListRobots until it is admitted (a liveness check with a generous
/// bound, not a timing assertion). Every refusal must be RESOURCE_EXHAUSTED.
async fn eventually_admitted(c: &mut KinematicsServiceClient<Channel>) -> bool {
    for _ in 0..1000 {
        match c
            .stream_forward_kinematics(tokio_stream::iter(Vec::new()))
            .await
        {
            Ok(_) => return true,
            Err(e) => assert_eq!(e.code(), Code::ResourceExhausted, "{e:?}"),
        }
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    false
}

/// Asserts a new stream is refused (the budget is full) while unary calls
/// are served (streams do not take request permits).
async fn stream_refused_unary_served(c: &mut KinematicsServiceClient<Channel>) {
    let err = c
        .stream_forward_kinematics(tokio_stream::iter(Vec::new()))
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::ResourceExhausted, "{err:?}");
    c.list_robots(pb::ListRobotsRequest::default())
        .await
        .expect("unary calls do not wait for streams");
    c.forward_kinematics(fk_request("puma560", &[0.0; 6], None))
        .await
        .expect("unary calls do not wait for streams");
}

/// A TCP proxy to `target` for one connection; aborting the returned task cuts
/// the connection abruptly (a client that vanishes without a word).
async fn one_shot_proxy(target: &str) -> (String, tokio::task::JoinHandle<()>) {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let target = target.trim_start_matches("http://").to_string();
    let task = tokio::spawn(async move {
        let (mut inbound, _) = listener.accept().await.unwrap();
        let mut outbound = tokio::net::TcpStream::connect(target).await.unwrap();
        let _ = tokio::io::copy_bidirectional(&mut inbound, &mut outbound).await;
    });
    (format!("http://{addr}"), task)
}

#[tokio::test]
async fn over_the_stream_budget_streams_are_resource_exhausted_and_a_finished_stream_frees_its_slot()
 {
    // One stream at a time, one request in flight: the open stream holds the
    // only stream slot but no request permit.
    let app = spawn_app_with(|c| {
        c.max_streams = 1;
        c.max_concurrent_requests = 1;
    })
    .await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    tx.send(stream_request(1, "puma560", &[0.0; 6], None))
        .await
        .unwrap();
    assert_eq!(rx.message().await.unwrap().unwrap().id, 1);
    stream_refused_unary_served(&mut c).await;

    // The client drops both halves of the call (tonic: END_STREAM, then the
    // stream is reset because the response is no longer wanted).
    drop(rx);
    drop(tx);
    assert!(
        eventually_admitted(&mut c).await,
        "the dropped stream still holds its stream slot"
    );
}

#[tokio::test]
async fn cancelling_a_stream_blocked_on_a_slow_reader_releases_the_server_side_work() {
    // The server is blocked sending (the client never reads) when the client goes.
    let app = spawn_app_with(|c| c.max_streams = 1).await;
    let mut c = app.grpc_client().await;
    let (proxy, cut) = one_shot_proxy(&app.grpc).await;
    let mut via_proxy = KinematicsServiceClient::connect(proxy).await.unwrap();
    let (tx, rx) = open_stream(&mut via_proxy, 500).await;
    for i in 0..500 {
        tx.send(stream_request(i, "puma560", &[0.0; 6], None))
            .await
            .unwrap();
    }
    // Cut the connection with the request side still open: no END_STREAM, no
    // RST_STREAM, just gone.
    cut.abort();
    let _ = cut.await;
    assert!(
        eventually_admitted(&mut c).await,
        "the abandoned stream still holds its stream slot"
    );
    drop((tx, rx));
}

#[tokio::test]
async fn a_client_that_vanishes_mid_stream_releases_the_server_side_work() {
    // The server is waiting for the next request when the connection dies.
    let app = spawn_app_with(|c| c.max_streams = 1).await;
    let mut c = app.grpc_client().await;
    let (proxy, cut) = one_shot_proxy(&app.grpc).await;
    let mut via_proxy = KinematicsServiceClient::connect(proxy).await.unwrap();
    let (tx, mut rx) = open_stream(&mut via_proxy, 4).await;
    tx.send(stream_request(1, "puma560", &[0.0; 6], None))
        .await
        .unwrap();
    assert_eq!(rx.message().await.unwrap().unwrap().id, 1);
    stream_refused_unary_served(&mut c).await;
    cut.abort();
    let _ = cut.await;
    assert!(
        eventually_admitted(&mut c).await,
        "the abandoned stream still holds its stream slot"
    );
    drop((tx, rx));
}

#[tokio::test]
async fn an_idle_stream_is_closed_with_deadline_exceeded() {
    let app =
        spawn_app_with(|c| c.stream_idle_timeout = std::time::Duration::from_millis(200)).await;
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    tx.send(stream_request(1, "puma560", &[0.0; 6], None))
        .await
        .unwrap();
    assert_eq!(rx.message().await.unwrap().unwrap().id, 1);
    // Send nothing more: the server gives up on the stream.
    let err = rx.message().await.unwrap_err();
    assert_eq!(err.code(), Code::DeadlineExceeded, "{err:?}");
    drop(tx);
}
