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
        Error::Internal { .. } => Code::Internal,
    }
}

/// The status for an error; field violations travel as `google.rpc.BadRequest`.
pub fn to_status(e: &Error) -> Status {
    let code = code_of(e);
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
