//! The one mapping from [`Error`] to gRPC status (with `google.rpc.BadRequest`
//! field violations), next to the REST one in `api::rest::problem`.

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
        Error::Overloaded => Code::ResourceExhausted,
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
/// `ErrorInfo.reason` of an IK target not reached.
pub const IK_NOT_CONVERGED: &str = "IK_NOT_CONVERGED";
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
        reason: IK_NOT_CONVERGED.into(),
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

/// The status for an error; field violations travel as `google.rpc.BadRequest`.
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
    if fields.is_empty() {
        return Status::new(code, e.to_string());
    }
    let mut details = ErrorDetails::new();
    for (field, message) in fields {
        details.add_bad_request_violation(field, message);
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
