//! The one error type of kinserve. Every layer returns it; the REST adapter maps
//! it to problem+json (`api::rest::problem`) and the gRPC adapter to a status
//! (`api::grpc::status`), each in one exhaustive `match`.

pub use kinserve_model::FieldViolation;
use kinserve_model::{IkAnswer, ModelError, summary};

/// Everything that can go wrong in kinserve, by what the client should do about it.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The input could not be read at all: not JSON, truncated, wrong types,
    /// unknown fields (HTTP 400, gRPC INVALID_ARGUMENT).
    #[error("malformed input: {detail}")]
    Malformed {
        /// Summary for humans.
        detail: String,
        /// Field-level details, when the fault can be placed.
        violations: Vec<FieldViolation>,
    },
    /// Well-formed input that breaks a rule: invalid DH model, wrong joint
    /// count, value out of limits (HTTP 422, gRPC INVALID_ARGUMENT).
    #[error("invalid input: {detail}")]
    Invalid {
        /// Summary for humans.
        detail: String,
        /// One entry per offending field.
        violations: Vec<FieldViolation>,
    },
    /// No robot of that name (HTTP 404, gRPC NOT_FOUND).
    #[error("robot '{name}' not found{}", did_you_mean(suggestions))]
    NotFound {
        /// The robot name asked for.
        name: String,
        /// The nearest names that exist (case-insensitive edit distance), best first.
        suggestions: Vec<String>,
    },
    /// No such route or method (HTTP 404, gRPC UNIMPLEMENTED).
    #[error("no route for '{path}'")]
    NoRoute {
        /// The path asked for (cut to 200 characters).
        path: String,
    },
    /// A robot of that name exists already (HTTP 409, gRPC ALREADY_EXISTS).
    #[error(
        "robot '{name}' already exists: replace it with PUT /v1/robots/{name} (gRPC: RegisterRobot with replace: true), or delete it first"
    )]
    AlreadyExists {
        /// The name that is taken.
        name: String,
    },
    /// Built-in robots cannot be replaced or deleted (HTTP 409, gRPC FAILED_PRECONDITION).
    #[error("robot '{name}' is built in and read-only")]
    ReadOnly {
        /// The built-in robot's name.
        name: String,
    },
    /// Refused by policy whatever the token, e.g. a registry write from a web
    /// page of another origin (HTTP 403, gRPC PERMISSION_DENIED).
    #[error("forbidden: {detail}")]
    Forbidden {
        /// Why, and how to allow it.
        detail: String,
    },
    /// The registry holds as many registered robots as it may (HTTP 507,
    /// gRPC RESOURCE_EXHAUSTED).
    #[error("registry full: {detail}")]
    Full {
        /// The limit and how to make room.
        detail: String,
    },
    /// Missing or wrong bearer token (HTTP 401, gRPC UNAUTHENTICATED).
    #[error("missing or invalid bearer token")]
    Unauthenticated,
    /// A body, batch or message over its configured limit (HTTP 413, gRPC RESOURCE_EXHAUSTED).
    #[error("too large: {detail}")]
    TooLarge {
        /// Which limit was exceeded and its value.
        detail: String,
        /// The field at fault, if any (e.g. `configurations`).
        field: Option<String>,
    },
    /// The request body is not JSON (HTTP 415, gRPC INVALID_ARGUMENT).
    #[error("unsupported media type: {detail}")]
    UnsupportedMediaType {
        /// What was sent and what is accepted.
        detail: String,
    },
    /// A budget of the server's is spent, or the client holds its share of
    /// it; retry later (HTTP 503 + Retry-After, gRPC RESOURCE_EXHAUSTED).
    #[error("server overloaded: {detail}")]
    Overloaded {
        /// Which budget (and its flag), how much of it the client holds, and
        /// what to do.
        detail: String,
    },
    /// The server is starting or shutting down (HTTP 503, gRPC UNAVAILABLE).
    #[error("service unavailable: {detail}")]
    Unavailable {
        /// Why.
        detail: String,
    },
    /// The model store could not persist or remove a robot, e.g. disk full or
    /// read-only data directory; nothing was changed (HTTP 507, gRPC UNAVAILABLE).
    #[error("storage failure: {detail}")]
    Storage {
        /// What failed, naming the file relative to the data directory
        /// (`robots/<file>`): no secrets, no host paths.
        detail: String,
    },
    /// Inverse kinematics found no configuration within the tolerance: the
    /// target is out of reach, out of the joint limits, or the time cap cut
    /// the solve short (HTTP 422 `ik-not-converged` with the best attempt;
    /// gRPC FAILED_PRECONDITION with the best attempt in the details).
    #[error("inverse kinematics did not converge: {detail}")]
    IkNotConverged {
        /// The best attempt's errors, in words.
        detail: String,
        /// The best attempt (joints in the request's angle unit, within limits).
        best: Box<IkAnswer>,
    },
    /// A conditional write whose condition does not hold: `If-Match` names
    /// another version (or the robot is gone), or `If-None-Match: *` finds it
    /// (HTTP 412, gRPC FAILED_PRECONDITION). Nothing was changed.
    #[error("precondition failed for robot '{name}': {detail}")]
    PreconditionFailed {
        /// The robot name.
        name: String,
        /// What was expected and what is there.
        detail: String,
    },
    /// The shared store (the database) cannot be reached, or did not answer in
    /// time; reads and FK go on from the snapshot, writes are refused
    /// (HTTP 503 + Retry-After, gRPC UNAVAILABLE). Whether a write that timed
    /// out was committed is unknown: read the robot (or retry with `If-Match`).
    #[error("registry store unavailable: {detail}")]
    StoreUnavailable {
        /// What failed (never the database URL or its password).
        detail: String,
    },
    /// The client did not send its request (the body) in time; the connection
    /// is closed (HTTP 408, gRPC DEADLINE_EXCEEDED).
    #[error("request timeout: {detail}")]
    RequestTimeout {
        /// What did not arrive, and the limit.
        detail: String,
    },
    /// The request uses an HTTP feature the server does not implement, such as
    /// a transfer coding other than `chunked` (HTTP 501, gRPC UNIMPLEMENTED).
    #[error("not implemented: {detail}")]
    NotImplemented {
        /// What is not supported.
        detail: String,
    },
    /// A bug: a panic caught in a handler (HTTP 500, gRPC INTERNAL).
    #[error("internal error: {detail}")]
    Internal {
        /// Short description.
        detail: String,
    },
}

impl Error {
    /// How long the client should wait before sending the request again,
    /// for the errors after which it may: REST's `Retry-After` header and
    /// gRPC's `google.rpc.RetryInfo` detail say the same.
    ///
    /// ```
    /// use kinserve::error::Error;
    /// let busy = Error::Overloaded { detail: "all 2 streams are open".into() };
    /// assert_eq!(busy.retry_after(), Some(std::time::Duration::from_secs(1)));
    /// assert_eq!(Error::Unauthenticated.retry_after(), None);
    /// ```
    pub fn retry_after(&self) -> Option<std::time::Duration> {
        match self {
            Error::Overloaded { .. } | Error::Unavailable { .. } => {
                Some(std::time::Duration::from_secs(1))
            }
            Error::StoreUnavailable { .. } => Some(std::time::Duration::from_secs(2)),
            _ => None,
        }
    }

    /// The problem kind: REST's `urn:kinserve:problem:<kind>` and, in
    /// SCREAMING_SNAKE (`invalid-input` -> `INVALID_INPUT`), the `reason` of
    /// the `google.rpc.ErrorInfo` every gRPC error status carries, so that
    /// clients tell problems apart the same way on both protocols.
    /// Exhaustive: every error has its kind here.
    ///
    /// ```
    /// let busy = kinserve::error::Error::Overloaded { detail: "all 2 streams are open".into() };
    /// assert_eq!(busy.kind(), "overloaded");
    /// ```
    pub fn kind(&self) -> &'static str {
        match self {
            Error::Malformed { .. } => "malformed-request",
            Error::Invalid { .. } => "invalid-input",
            Error::NotFound { .. } => "not-found",
            Error::NoRoute { .. } => "no-route",
            Error::AlreadyExists { .. } => "already-exists",
            Error::ReadOnly { .. } => "read-only",
            Error::Unauthenticated => "unauthenticated",
            Error::Forbidden { .. } => "forbidden",
            Error::Full { .. } => "registry-full",
            Error::TooLarge { .. } => "too-large",
            Error::UnsupportedMediaType { .. } => "unsupported-media-type",
            Error::Overloaded { .. } => "overloaded",
            Error::Unavailable { .. } => "unavailable",
            Error::Storage { .. } => "storage",
            Error::IkNotConverged { .. } => "ik-not-converged",
            Error::PreconditionFailed { .. } => "precondition-failed",
            Error::StoreUnavailable { .. } => "store-unavailable",
            Error::RequestTimeout { .. } => "request-timeout",
            Error::NotImplemented { .. } => "not-implemented",
            Error::Internal { .. } => "internal",
        }
    }

    /// An [`Error::Invalid`] with a single field violation.
    pub fn invalid_field(field: impl Into<String>, message: impl Into<String>) -> Self {
        ModelError::invalid_field(field, message).into()
    }

    /// An [`Error::Invalid`] from a list of violations (summary: the first one, and a count).
    pub fn invalid(violations: Vec<FieldViolation>) -> Self {
        ModelError::invalid(violations).into()
    }

    /// An [`Error::Malformed`] with a single field violation.
    pub fn malformed_field(field: impl Into<String>, message: impl Into<String>) -> Self {
        ModelError::malformed_field(field, message).into()
    }

    /// Field violations carried by this error (empty for kinds without fields).
    pub fn violations(&self) -> &[FieldViolation] {
        match self {
            Error::Malformed { violations, .. } | Error::Invalid { violations, .. } => violations,
            _ => &[],
        }
    }

    /// The same error with every field path prefixed (see [`FieldViolation::prefixed`]).
    pub fn prefixed(self, prefix: &str) -> Self {
        match self {
            Error::Invalid { violations, .. } => {
                Error::invalid(violations.into_iter().map(|v| v.prefixed(prefix)).collect())
            }
            Error::Malformed { violations, detail } if !violations.is_empty() => {
                let violations: Vec<_> =
                    violations.into_iter().map(|v| v.prefixed(prefix)).collect();
                let _ = detail;
                Error::Malformed {
                    detail: summary(&violations),
                    violations,
                }
            }
            other => other,
        }
    }
}

impl Error {
    /// An [`Error::IkNotConverged`] carrying `best`; `length_unit` names the
    /// unit of its position error.
    pub fn ik_not_converged(best: IkAnswer, length_unit: &str) -> Self {
        let orientation = best
            .orientation_error
            .map(|e| format!(", orientation error {e:.3e} rad"))
            .unwrap_or_default();
        // A best attempt this far off is not a tolerance question: the target
        // is out of the arm's reach (or of its joint limits).
        let far = if length_unit == "mm" { 1.0 } else { 1e-3 };
        let reach = if best.position_error > far {
            "; the target looks out of reach: move it closer or check its units and frame"
        } else {
            ""
        };
        Error::IkNotConverged {
            detail: format!(
                "best attempt has position error {:.3e} {length_unit}{orientation} after {} iterations{reach}",
                best.position_error, best.iterations
            ),
            best: Box::new(best),
        }
    }
}

impl From<ModelError> for Error {
    fn from(e: ModelError) -> Self {
        match e {
            ModelError::Malformed { detail, violations } => Error::Malformed { detail, violations },
            ModelError::Invalid { detail, violations } => Error::Invalid { detail, violations },
            ModelError::TooLarge { detail, field } => Error::TooLarge { detail, field },
        }
    }
}

/// "; did you mean 'a' or 'b'?" for a non-empty list, else nothing.
fn did_you_mean(suggestions: &[String]) -> String {
    match suggestions {
        [] => String::new(),
        [one] => format!("; did you mean '{one}'?"),
        [init @ .., last] => {
            let init: Vec<String> = init.iter().map(|s| format!("'{s}'")).collect();
            format!("; did you mean {} or '{last}'?", init.join(", "))
        }
    }
}

/// Result with kinserve's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
