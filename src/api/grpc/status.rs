//! The one mapping from [`Error`] to gRPC status, next to the REST one in
//! `api::rest::problem`. Every error status carries `google.rpc.ErrorInfo`
//! (domain [`ERROR_DOMAIN`], reason the problem kind in SCREAMING_SNAKE:
//! [`reason_of`]), field violations travel as `google.rpc.BadRequest`, and an
//! IK target not reached adds its best attempt.

use prost::Message;
use tonic::{Code, Status};
use tonic_types::{ErrorDetails, StatusExt};

use crate::error::Error;

/// gRPC code of an error. Exhaustive: every error kind has its gRPC meaning here.
pub fn code_of(e: &Error) -> Code {
    match e {
        Error::Malformed { .. } => Code::InvalidArgument,
        Error::Invalid { .. } => Code::InvalidArgument,
        Error::NotFound { .. } => Code::NotFound,
        Error::NoRoute { .. } => Code::Unimplemented,
        Error::AlreadyExists { .. } => Code::AlreadyExists,
        Error::ReadOnly { .. } => Code::FailedPrecondition,
        Error::Unauthenticated => Code::Unauthenticated,
        Error::Forbidden { .. } => Code::PermissionDenied,
        Error::Full { .. } => Code::ResourceExhausted,
        Error::TooLarge { .. } => Code::ResourceExhausted,
        Error::UnsupportedMediaType { .. } => Code::InvalidArgument,
        Error::Overloaded { .. } => Code::ResourceExhausted,
        Error::Unavailable { .. } => Code::Unavailable,
        Error::Storage { .. } => Code::Unavailable,
        Error::IkNotConverged { .. } => Code::FailedPrecondition,
        Error::PreconditionFailed { .. } => Code::FailedPrecondition,
        Error::StoreUnavailable { .. } => Code::Unavailable,
        Error::RequestTimeout { .. } => Code::DeadlineExceeded,
        Error::NotImplemented { .. } => Code::Unimplemented,
        Error::Internal { .. } => Code::Internal,
    }
}

/// Domain of kinserve's `google.rpc.ErrorInfo` details.
pub const ERROR_DOMAIN: &str = "kinserve";
/// `ErrorInfo.reason` of an IK target not reached (`reason_of` an
/// [`Error::IkNotConverged`]).
pub const IK_NOT_CONVERGED: &str = "IK_NOT_CONVERGED";

/// `ErrorInfo.reason` of an error: its problem kind ([`Error::kind`], REST's
/// `urn:kinserve:problem:<kind>`) in SCREAMING_SNAKE, `invalid-input` ->
/// `INVALID_INPUT`.
pub fn reason_of(e: &Error) -> String {
    e.kind().to_ascii_uppercase().replace('-', "_")
}
/// Type URL of the best attempt packed in the details of `IK_NOT_CONVERGED`.
pub const IK_RESULT_TYPE_URL: &str = "type.googleapis.com/kinematics.v1.InverseKinematicsResult";

/// FAILED_PRECONDITION with `google.rpc.ErrorInfo` (reason
/// [`IK_NOT_CONVERGED`], the errors in its metadata) and the best attempt as a
/// `kinematics.v1.InverseKinematicsResult`, both in the status details.
fn ik_not_converged(code: Code, message: String, best: &crate::model::IkAnswer) -> Status {
    let mut metadata = std::collections::HashMap::new();
    metadata.insert(
        "position_error".to_string(),
        best.position_error.to_string(),
    );
    if let Some(o) = best.orientation_error {
        metadata.insert("orientation_error".to_string(), o.to_string());
    }
    metadata.insert("iterations".to_string(), best.iterations.to_string());
    let info = tonic_types::pb::ErrorInfo {
        reason: IK_NOT_CONVERGED.to_string(),
        domain: ERROR_DOMAIN.into(),
        metadata,
    };
    let result = kinserve_api::pb::InverseKinematicsResult::from(best);
    let status = tonic_types::Status {
        code: code as i32,
        message: message.clone(),
        details: vec![
            prost_types::Any {
                type_url: "type.googleapis.com/google.rpc.ErrorInfo".into(),
                value: info.encode_to_vec(),
            },
            prost_types::Any {
                type_url: IK_RESULT_TYPE_URL.into(),
                value: result.encode_to_vec(),
            },
        ],
    };
    Status::with_details(code, message, status.encode_to_vec().into())
}

/// The status for an error: `google.rpc.ErrorInfo` always, field violations
/// as `google.rpc.BadRequest`, and `google.rpc.RetryInfo` when the client may
/// send the request again ([`Error::retry_after`], REST's `Retry-After`).
pub fn to_status(e: &Error) -> Status {
    let code = code_of(e);
    if let Error::IkNotConverged { best, .. } = e {
        return ik_not_converged(code, e.to_string(), best);
    }
    let mut fields: Vec<(String, String)> = e
        .violations()
        .iter()
        .map(|v| (v.field.clone(), v.message.clone()))
        .collect();
    if let Error::TooLarge {
        field: Some(f),
        detail,
    } = e
    {
        fields.push((f.clone(), detail.clone()));
    }
    let mut details = ErrorDetails::new();
    details.set_error_info(reason_of(e), ERROR_DOMAIN, std::collections::HashMap::new());
    for (field, message) in fields {
        details.add_bad_request_violation(field, message);
    }
    if let Some(wait) = e.retry_after() {
        details.set_retry_info(Some(wait));
    }
    Status::with_error_details(code, e.to_string(), details)
}

/// The same error as a `google.rpc.Status` message (for stream responses).
pub fn to_rpc_status(e: &Error) -> tonic_types::Status {
    let status = to_status(e);
    let plain = || tonic_types::Status {
        code: status.code() as i32,
        message: status.message().to_string(),
        details: Vec::new(),
    };
    if status.details().is_empty() {
        return plain();
    }
    tonic_types::Status::decode(status.details()).unwrap_or_else(|_| plain())
}

impl From<Error> for Status {
    fn from(e: Error) -> Self {
        to_status(&e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::rest::problem::Problem;
    use crate::model::{IkAnswer, IkSolverUsed};

    /// The position of an error in [`Error`]: exhaustive, so a new variant
    /// fails to compile here until [`one_of_each`] gets one too.
    fn ordinal(e: &Error) -> usize {
        match e {
            Error::Malformed { .. } => 0,
            Error::Invalid { .. } => 1,
            Error::NotFound { .. } => 2,
            Error::NoRoute { .. } => 3,
            Error::AlreadyExists { .. } => 4,
            Error::ReadOnly { .. } => 5,
            Error::Unauthenticated => 6,
            Error::Forbidden { .. } => 7,
            Error::Full { .. } => 8,
            Error::TooLarge { .. } => 9,
            Error::UnsupportedMediaType { .. } => 10,
            Error::Overloaded { .. } => 11,
            Error::Unavailable { .. } => 12,
            Error::Storage { .. } => 13,
            Error::IkNotConverged { .. } => 14,
            Error::PreconditionFailed { .. } => 15,
            Error::StoreUnavailable { .. } => 16,
            Error::RequestTimeout { .. } => 17,
            Error::NotImplemented { .. } => 18,
            Error::Internal { .. } => 19,
        }
    }

    fn one_of_each() -> Vec<Error> {
        let d = || "why".to_string();
        let best = IkAnswer {
            joints: vec![0.0; 2],
            converged: false,
            position_error: 0.5,
            orientation_error: None,
            iterations: 3,
            pose: Default::default(),
            solver: IkSolverUsed::Numeric,
            branch: None,
            singular: Vec::new(),
            solutions: None,
            truncated: false,
        };
        vec![
            Error::malformed_field("joints", "expected an array"),
            Error::invalid_field("joints[1]", "outside the limits"),
            Error::NotFound {
                name: "x".into(),
                suggestions: vec![],
            },
            Error::NoRoute { path: "/x".into() },
            Error::AlreadyExists { name: "x".into() },
            Error::ReadOnly { name: "x".into() },
            Error::Unauthenticated,
            Error::Forbidden { detail: d() },
            Error::Full { detail: d() },
            Error::TooLarge {
                detail: d(),
                field: Some("configurations".into()),
            },
            Error::UnsupportedMediaType { detail: d() },
            Error::Overloaded { detail: d() },
            Error::Unavailable { detail: d() },
            Error::Storage { detail: d() },
            Error::ik_not_converged(best, "m"),
            Error::PreconditionFailed {
                name: "x".into(),
                detail: d(),
            },
            Error::StoreUnavailable { detail: d() },
            Error::RequestTimeout { detail: d() },
            Error::NotImplemented { detail: d() },
            Error::Internal { detail: d() },
        ]
    }

    #[test]
    fn every_error_status_carries_error_info_naming_the_rest_problem_type() {
        let errors = one_of_each();
        let mut seen: Vec<usize> = errors.iter().map(ordinal).collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..20).collect::<Vec<_>>(), "one error of each kind");
        for e in &errors {
            let problem = Problem::from_error(e);
            let kind = problem.type_.strip_prefix("urn:kinserve:problem:").unwrap();
            for (how, status) in [
                ("unary", to_status(e)),
                ("stream", {
                    let s = to_rpc_status(e);
                    Status::with_details(
                        Code::from_i32(s.code),
                        s.message.clone(),
                        s.encode_to_vec().into(),
                    )
                }),
            ] {
                let info = status
                    .get_details_error_info()
                    .unwrap_or_else(|| panic!("{how} {e:?}: no ErrorInfo"));
                assert_eq!(info.domain, ERROR_DOMAIN, "{e:?}");
                assert_eq!(
                    info.reason.to_ascii_lowercase().replace('_', "-"),
                    kind,
                    "{how} {e:?}"
                );
                assert_eq!(status.code(), code_of(e), "{how} {e:?}");
                // Field violations still travel as BadRequest.
                let fields: Vec<String> = status
                    .get_details_bad_request()
                    .map(|b| b.field_violations.into_iter().map(|v| v.field).collect())
                    .unwrap_or_default();
                let want: Vec<String> = problem.errors.iter().map(|f| f.field.clone()).collect();
                assert_eq!(fields, want, "{how} {e:?}");
            }
        }
        assert_eq!(reason_of(&errors[1]), "INVALID_INPUT");
        assert_eq!(reason_of(&errors[14]), IK_NOT_CONVERGED);
    }
}
