//! The one mapping from [`Error`] to HTTP: RFC 9457 `application/problem+json`.

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::ik::IkItem;
use crate::error::Error;

/// A field-level error inside a problem.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ProblemField {
    /// Path of the field (`links[3].alpha`, `configurations[17][2]`).
    pub field: String,
    /// What is wrong.
    pub message: String,
}

/// RFC 9457 problem details.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Problem {
    /// Problem type URI (`urn:kinserve:problem:<kind>`).
    #[serde(rename = "type")]
    pub type_: String,
    /// Short summary of the problem type.
    pub title: String,
    /// HTTP status code.
    pub status: u16,
    /// Explanation of this occurrence.
    pub detail: String,
    /// Field-level errors, whenever a field is at fault.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub errors: Vec<ProblemField>,
    /// With `ik-not-converged`: the best attempt (joints in the request's
    /// angle unit, within the joint limits) and its errors.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub best_attempt: Option<IkItem>,
}

/// Status and title of an error (its kind is [`Error::kind`]). Exhaustive:
/// every error kind has its HTTP meaning here.
fn classify(e: &Error) -> (StatusCode, &'static str) {
    match e {
        Error::Malformed { .. } => (StatusCode::BAD_REQUEST, "Malformed request"),
        Error::Invalid { .. } => (StatusCode::UNPROCESSABLE_ENTITY, "Invalid input"),
        Error::NotFound { .. } => (StatusCode::NOT_FOUND, "Robot not found"),
        Error::NoRoute { .. } => (StatusCode::NOT_FOUND, "No such route"),
        Error::AlreadyExists { .. } => (StatusCode::CONFLICT, "Robot already exists"),
        Error::ReadOnly { .. } => (StatusCode::CONFLICT, "Built-in robot is read-only"),
        Error::Unauthenticated => (StatusCode::UNAUTHORIZED, "Authentication required"),
        Error::Forbidden { .. } => (StatusCode::FORBIDDEN, "Forbidden"),
        Error::Full { .. } => (StatusCode::INSUFFICIENT_STORAGE, "Registry full"),
        Error::TooLarge { .. } => (StatusCode::PAYLOAD_TOO_LARGE, "Request too large"),
        Error::UnsupportedMediaType { .. } => {
            (StatusCode::UNSUPPORTED_MEDIA_TYPE, "Unsupported media type")
        }
        Error::Overloaded { .. } => (StatusCode::SERVICE_UNAVAILABLE, "Server overloaded"),
        Error::Unavailable { .. } => (StatusCode::SERVICE_UNAVAILABLE, "Service unavailable"),
        Error::Storage { .. } => (StatusCode::INSUFFICIENT_STORAGE, "Storage failure"),
        Error::IkNotConverged { .. } => (
            StatusCode::UNPROCESSABLE_ENTITY,
            "Inverse kinematics did not converge",
        ),
        Error::PreconditionFailed { .. } => {
            (StatusCode::PRECONDITION_FAILED, "Precondition failed")
        }
        Error::StoreUnavailable { .. } => (
            StatusCode::SERVICE_UNAVAILABLE,
            "Registry store unavailable",
        ),
        Error::RequestTimeout { .. } => (StatusCode::REQUEST_TIMEOUT, "Request timeout"),
        Error::NotImplemented { .. } => (StatusCode::NOT_IMPLEMENTED, "Not implemented"),
        Error::Internal { .. } => (StatusCode::INTERNAL_SERVER_ERROR, "Internal error"),
    }
}

impl Problem {
    /// The problem document for an error.
    pub fn from_error(e: &Error) -> Problem {
        let (status, title) = classify(e);
        let kind = e.kind();
        let mut errors: Vec<ProblemField> = e
            .violations()
            .iter()
            .map(|v| ProblemField {
                field: v.field.clone(),
                message: v.message.clone(),
            })
            .collect();
        if let Error::TooLarge {
            field: Some(f),
            detail,
        } = e
        {
            errors.push(ProblemField {
                field: f.clone(),
                message: detail.clone(),
            });
        }
        Problem {
            type_: format!("urn:kinserve:problem:{kind}"),
            title: title.to_string(),
            status: status.as_u16(),
            detail: e.to_string(),
            errors,
            best_attempt: match e {
                Error::IkNotConverged { best, .. } => Some(IkItem::from(best.as_ref())),
                _ => None,
            },
        }
    }
}

/// An [`Error`] as an HTTP response.
#[derive(Debug)]
pub struct ApiError(pub Error);

impl From<Error> for ApiError {
    fn from(e: Error) -> Self {
        ApiError(e)
    }
}

impl Problem {
    /// A problem with no [`Error`] behind it (protocol-level failures such as
    /// 405 Method Not Allowed or a refused WebSocket upgrade).
    pub fn protocol(status: StatusCode, kind: &str, title: &str, detail: String) -> Problem {
        Problem {
            type_: format!("urn:kinserve:problem:{kind}"),
            title: title.to_string(),
            status: status.as_u16(),
            detail,
            errors: Vec::new(),
            best_attempt: None,
        }
    }
}

impl IntoResponse for Problem {
    fn into_response(self) -> Response {
        let status = StatusCode::from_u16(self.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        let body = serde_json::to_vec(&self).unwrap_or_default();
        let mut resp = (status, body).into_response();
        resp.headers_mut().insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/problem+json"),
        );
        resp
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut resp = Problem::from_error(&self.0).into_response();
        let h = resp.headers_mut();
        if matches!(self.0, Error::Unauthenticated) {
            h.insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
        }
        if let Some(wait) = self.0.retry_after() {
            h.insert(header::RETRY_AFTER, HeaderValue::from(wait.as_secs()));
        }
        resp
    }
}
