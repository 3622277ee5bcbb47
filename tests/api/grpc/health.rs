//! gRPC health, shutdown (health flips, streams end) and server reflection
//! (v1 and v1alpha).

use std::collections::BTreeSet;

use prost::Message;
use tonic::Code;

use crate::helpers::*;

// ---------------------------------------------------------------- health and shutdown

#[tokio::test]
async fn health_reports_serving_for_the_server_and_the_service() {
    use tonic_health::pb::HealthCheckRequest;
    use tonic_health::pb::health_check_response::ServingStatus;
    use tonic_health::pb::health_client::HealthClient;

    let app = spawn_app().await;
    let mut h = HealthClient::new(channel(&app).await);
    for service in ["", "kinematics.v1.KinematicsService"] {
        let r = h
            .check(HealthCheckRequest {
                service: service.into(),
            })
            .await
            .unwrap()
            .into_inner();
        assert_eq!(r.status, ServingStatus::Serving as i32, "'{service}'");
    }
    let err = h
        .check(HealthCheckRequest {
            service: "no.such.Service".into(),
        })
        .await
        .unwrap_err();
    assert_eq!(err.code(), Code::NotFound);
}

#[tokio::test]
async fn shutdown_flips_health_to_not_serving_and_ends_fk_streams() {
    use tonic_health::pb::HealthCheckRequest;
    use tonic_health::pb::health_check_response::ServingStatus;
    use tonic_health::pb::health_client::HealthClient;

    let app = spawn_app_with(|c| c.shutdown_timeout = std::time::Duration::from_secs(2)).await;
    let mut h = HealthClient::new(channel(&app).await);
    let mut watches = Vec::new();
    for service in ["", "kinematics.v1.KinematicsService"] {
        let mut w = h
            .watch(HealthCheckRequest {
                service: service.into(),
            })
            .await
            .unwrap()
            .into_inner();
        let first = w.message().await.unwrap().unwrap();
        assert_eq!(first.status, ServingStatus::Serving as i32, "'{service}'");
        watches.push((service, w));
    }
    let mut c = app.grpc_client().await;
    let (tx, mut rx) = open_stream(&mut c, 4).await;
    tx.send(stream_request(1, "puma560", &[0.0; 6], None))
        .await
        .unwrap();
    assert_eq!(rx.message().await.unwrap().unwrap().id, 1);

    let stopping = tokio::spawn(app.stop());

    for (service, mut w) in watches {
        let next = w.message().await;
        match next {
            Ok(Some(m)) => assert_eq!(
                m.status,
                ServingStatus::NotServing as i32,
                "'{service}' while shutting down"
            ),
            other => {
                panic!("'{service}': expected NOT_SERVING before the watch ends, got {other:?}")
            }
        }
    }
    let err = match rx.message().await {
        Ok(Some(m)) => panic!("unexpected response {m:?}"),
        Ok(None) => panic!("stream ended without UNAVAILABLE"),
        Err(e) => e,
    };
    assert_eq!(err.code(), Code::Unavailable, "{err:?}");
    drop(tx);
    stopping.await.unwrap().unwrap();
}

// ---------------------------------------------------------------- reflection

macro_rules! reflection_suite {
    ($name:ident, $module:path) => {
        #[tokio::test]
        async fn $name() {
            use r::server_reflection_client::ServerReflectionClient;
            use r::server_reflection_request::MessageRequest;
            use r::server_reflection_response::MessageResponse;
            use $module as r;

            let app = spawn_app().await;
            let mut client = ServerReflectionClient::new(channel(&app).await);
            let ask = |m: MessageRequest| r::ServerReflectionRequest {
                host: String::new(),
                message_request: Some(m),
            };
            let requests = vec![
                ask(MessageRequest::ListServices(String::new())),
                ask(MessageRequest::FileContainingSymbol(
                    "kinematics.v1.KinematicsService".into(),
                )),
                ask(MessageRequest::FileContainingSymbol(
                    "kinematics.v1.KinematicsService.StreamForwardKinematics".into(),
                )),
                ask(MessageRequest::FileContainingSymbol(
                    "kinematics.v1.StreamForwardKinematicsResponse".into(),
                )),
                ask(MessageRequest::FileByFilename(
                    "google/rpc/status.proto".into(),
                )),
                ask(MessageRequest::FileContainingSymbol(
                    "no.such.Symbol".into(),
                )),
            ];
            let n = requests.len();
            let mut responses = client
                .server_reflection_info(tokio_stream::iter(requests))
                .await
                .unwrap()
                .into_inner();
            let mut got = Vec::new();
            let end = loop {
                match responses.message().await {
                    Ok(Some(m)) => got.push(m.message_response.expect("a response")),
                    other => break other,
                }
            };
            // tonic-reflection answers an unknown symbol by ending the stream with
            // NOT_FOUND (not with an ErrorResponse message): accept either form.
            match end {
                Err(e) => {
                    assert_eq!(e.code(), Code::NotFound, "{e:?}");
                    assert_eq!(got.len(), n - 1);
                }
                Ok(None) => {
                    assert_eq!(got.len(), n);
                    let MessageResponse::ErrorResponse(e) = &got[n - 1] else {
                        panic!("unknown symbol: {:?}", got[n - 1]);
                    };
                    assert_eq!(e.error_code, Code::NotFound as i32);
                }
                Ok(Some(_)) => unreachable!(),
            }

            let MessageResponse::ListServicesResponse(list) = &got[0] else {
                panic!("list: {:?}", got[0]);
            };
            let services: BTreeSet<&str> = list.service.iter().map(|s| s.name.as_str()).collect();
            for s in ["kinematics.v1.KinematicsService", "grpc.health.v1.Health"] {
                assert!(services.contains(s), "{s} in {services:?}");
            }

            let files = |i: usize| -> Vec<prost_types::FileDescriptorProto> {
                let MessageResponse::FileDescriptorResponse(f) = &got[i] else {
                    panic!("response {i}: {:?}", got[i]);
                };
                f.file_descriptor_proto
                    .iter()
                    .map(|b| prost_types::FileDescriptorProto::decode(b.as_slice()).unwrap())
                    .collect()
            };
            for i in 1..=3 {
                let fds = files(i);
                let kin = fds
                    .iter()
                    .find(|f| f.name() == "kinematics/v1/kinematics.proto")
                    .unwrap_or_else(|| {
                        panic!(
                            "response {i}: {:?}",
                            fds.iter().map(|f| f.name()).collect::<Vec<_>>()
                        )
                    });
                assert_eq!(kin.package(), "kinematics.v1");
                let svc = kin
                    .service
                    .iter()
                    .find(|s| s.name() == "KinematicsService")
                    .expect("service in file");
                let methods: BTreeSet<&str> = svc.method.iter().map(|m| m.name()).collect();
                let want: BTreeSet<&str> = [
                    "ListRobots",
                    "GetRobot",
                    "RegisterRobot",
                    "ImportUrdf",
                    "DeleteRobot",
                    "ForwardKinematics",
                    "ForwardKinematicsBatch",
                    "StreamForwardKinematics",
                    "GetClosedForm",
                    "GetUrdf",
                    "Jacobian",
                    "JacobianBatch",
                    "LinkTransforms",
                    "InverseKinematics",
                    "InverseKinematicsBatch",
                    "InverseKinematicsPath",
                ]
                .into();
                assert_eq!(methods, want);
                let stream = svc
                    .method
                    .iter()
                    .find(|m| m.name() == "StreamForwardKinematics")
                    .unwrap();
                assert!(stream.client_streaming() && stream.server_streaming());
                assert!(
                    kin.dependency
                        .iter()
                        .any(|d| d == "google/rpc/status.proto")
                );
            }
            // The imported file (for the oneof's google.rpc.Status) resolves too.
            let status = files(4);
            assert!(status.iter().any(|f| f.name() == "google/rpc/status.proto"));
        }
    };
}

reflection_suite!(
    reflection_v1_lists_services_and_finds_the_kinematics_file,
    tonic_reflection::pb::v1
);
reflection_suite!(
    reflection_v1alpha_lists_services_and_finds_the_kinematics_file,
    tonic_reflection::pb::v1alpha
);
