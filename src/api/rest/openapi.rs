//! Completes the generated OpenAPI document so that generators and validators
//! accept it and people can read it: a description on every response (by
//! status, from the one error mapping), an example on every problem response
//! (built by `Problem::from_error`, so it is what the server really sends),
//! `servers` and described `tags`. Owns nothing but the document; depends on
//! the REST problem mapping and the error type.

use serde_json::Value;
use utoipa::Modify;
use utoipa::openapi::path::Operation;
use utoipa::openapi::server::Server;
use utoipa::openapi::tag::Tag;
use utoipa::openapi::{OpenApi, RefOr};

use super::problem::Problem;
use crate::error::Error;

/// Tags of the API, with what each groups.
const TAGS: &[(&str, &str)] = &[
    (
        "fk",
        "Forward kinematics: one configuration, a batch, or a WebSocket stream.",
    ),
    (
        "robots",
        "The robot registry: list, read, register, replace, delete.",
    ),
    (
        "velocity",
        "Velocity kinematics: the geometric Jacobian with manipulability, condition number and singularity, one configuration or a batch.",
    ),
    (
        "ik",
        "Inverse kinematics: joints that reach a target pose (numerical, limits respected), one target or a batch tracking a path.",
    ),
    ("health", "Liveness and readiness probes."),
    ("operations", "Metrics for operators."),
];

/// The modifier: see the module documentation.
pub struct Complete;

impl Modify for Complete {
    fn modify(&self, doc: &mut OpenApi) {
        doc.servers = Some(vec![
            Server::builder()
                .url("/")
                .description(Some("the server that serves this document"))
                .build(),
            Server::builder()
                .url("http://localhost:8080")
                .description(Some("a local `cargo run --release`"))
                .build(),
        ]);
        doc.tags = Some(
            TAGS.iter()
                .map(|(name, what)| Tag::builder().name(*name).description(Some(*what)).build())
                .collect(),
        );
        for item in doc.paths.paths.values_mut() {
            for op in [
                &mut item.get,
                &mut item.put,
                &mut item.post,
                &mut item.delete,
                &mut item.patch,
            ]
            .into_iter()
            .flatten()
            {
                complete_operation(op);
            }
        }
    }
}

fn complete_operation(op: &mut Operation) {
    for (code, response) in op.responses.responses.iter_mut() {
        let RefOr::T(response) = response else {
            continue;
        };
        if response.description.is_empty() {
            response.description = describe(code).to_string();
        }
        for (media, content) in response.content.iter_mut() {
            let RefOr::T(content) = content else {
                continue;
            };
            if media == "application/problem+json" && content.example.is_none() {
                content.example = problem_example(code);
            }
        }
    }
}

/// What a status means on this API.
pub fn describe(code: &str) -> &'static str {
    match code {
        "200" => "OK: the result.",
        "201" => "Created: the robot as registered; `Location` names it.",
        "204" => "Done; no content.",
        "400" => {
            "Malformed request: the body cannot be read into the request's schema (not JSON, wrong type, unknown or missing field, unknown enum value) or the name is empty."
        }
        "401" => "Missing or wrong bearer token (only when the server has an API token).",
        "403" => {
            "Forbidden: a registry write to a server without an API token (its registry is read-only unless started with --allow-unauthenticated-writes), or a registry write (or, with --cors-origin set, a WebSocket) from a web page of an origin not allowed by --cors-origin."
        }
        "404" => "No robot of that name (the nearest names are suggested) or no such route.",
        "409" => "Conflict: the name is taken, or the robot is built in and read-only.",
        "412" => {
            "Precondition failed: `If-Match` names another version (or the robot is gone), or `If-None-Match: *` found it; nothing was changed."
        }
        "413" => "Too large: the body or the batch is over its limit.",
        "406" => {
            "Not acceptable: `Accept` names none of the route's answer formats (the batch routes answer `application/json`, `application/x-protobuf` and, FK and Jacobian, `application/octet-stream`)."
        }
        "415" => {
            "Unsupported media type: send `application/json` (the batch routes also take `application/x-protobuf` and, FK and Jacobian, `application/octet-stream`)."
        }
        "426" => "The connection cannot be upgraded to a WebSocket.",
        "422" => {
            "Invalid input: the body reads but breaks a rule (invalid model, wrong joint count, value outside the limits); every broken rule is listed."
        }
        "500" => "A bug: the handler failed; the server goes on.",
        "503" => {
            "Overloaded (retry after `Retry-After`), timed out, starting or shutting down, or (writes) the registry database is unavailable."
        }
        "507" => {
            "Storage failure (nothing changed), or the registry holds --max-robots registered robots."
        }
        _ => "See the status code.",
    }
}

/// A problem the server really sends for `code` (from the one error mapping).
fn problem_example(code: &str) -> Option<Value> {
    let e = match code {
        "400" => Error::malformed_field("joints[1]", "invalid type: string \"x\", expected f64"),
        "401" => Error::Unauthenticated,
        "403" => Error::Forbidden {
            detail: "registry writes from the web origin 'https://stranger.example' are refused: start the server with --cors-origin https://stranger.example to allow it".into(),
        },
        "404" => Error::NotFound {
            name: "Puma-560".into(),
            suggestions: vec!["puma560".into()],
        },
        "409" => Error::AlreadyExists {
            name: "my-arm".into(),
        },
        "412" => Error::PreconditionFailed {
            name: "my-arm".into(),
            detail: "the ETag given does not match; its current ETag is \"18\": read it again (GET) and retry with its ETag".into(),
        },
        "413" => Error::TooLarge {
            detail: "a batch holds at most 10000 configurations, got 20000".into(),
            field: Some("configurations".into()),
        },
        "415" => Error::UnsupportedMediaType {
            detail: "send Content-Type: application/json".into(),
        },
        "422" => Error::invalid_field(
            "joints[1]",
            "2.5 rad is outside the limits [-1.91986, 1.91986] rad of joint 'shoulder' ([-110, 110] deg in the model)",
        ),
        "500" => Error::Internal {
            detail: "the handler failed unexpectedly; this is a bug".into(),
        },
        "406" => {
            let p = Problem::protocol(
                axum::http::StatusCode::NOT_ACCEPTABLE,
                "not-acceptable",
                "Not acceptable",
                "Accept 'text/csv' names no format this route answers in: ask for application/json (the default), application/x-protobuf or application/octet-stream".into(),
            );
            return serde_json::to_value(p).ok();
        }
        "426" => {
            let p = Problem::protocol(
                axum::http::StatusCode::UPGRADE_REQUIRED,
                "websocket-upgrade",
                "WebSocket upgrade failed",
                "Connection header did not include 'upgrade'".into(),
            );
            return serde_json::to_value(p).ok();
        }
        "503" => Error::Overloaded {
            detail: "client 203.0.113.9 holds 512 of the server's 1024 requests in flight, its \
                     share (--client-share-percent of --max-concurrent-requests): wait until one \
                     has ended, or retry in a second"
                .into(),
        },
        "507" => Error::Storage {
            detail: "cannot write robot 'my-arm': no space left on device".into(),
        },
        _ => return None,
    };
    serde_json::to_value(Problem::from_error(&e)).ok()
}
