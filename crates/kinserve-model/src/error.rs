//! What validation reports: [`FieldViolation`]s (one broken rule of one field,
//! with its path) grouped in a [`ModelError`]. Depends on nothing else in the
//! crate; the server maps [`ModelError`] into its own error type.

use std::fmt;

/// A rule broken by one field of the input, e.g. `links[3].alpha` or
/// `configurations[17][2]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldViolation {
    /// Path of the offending field (`links[3].alpha`, `joints[2]`, `name`).
    pub field: String,
    /// What is wrong with it, in plain words.
    pub message: String,
}

impl FieldViolation {
    /// A violation of `field` described by `message`.
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            message: message.into(),
        }
    }

    /// The same violation with `prefix` put in front of its field path
    /// (`configurations[3]` + `[2]` → `configurations[3][2]`; `model` + `name` → `model.name`).
    pub fn prefixed(mut self, prefix: &str) -> Self {
        if prefix.is_empty() {
            return self;
        }
        self.field = if self.field.is_empty() {
            prefix.to_string()
        } else if self.field.starts_with('[') {
            format!("{prefix}{}", self.field)
        } else {
            format!("{prefix}.{}", self.field)
        };
        self
    }
}

impl fmt::Display for FieldViolation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.field.is_empty() {
            write!(f, "{}", self.message)
        } else {
            write!(f, "{}: {}", self.field, self.message)
        }
    }
}

/// Why a model, a JSON body or a joint vector was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ModelError {
    /// The input could not be read at all: not JSON, truncated, wrong types,
    /// an unreadable file.
    Malformed {
        /// Summary for humans.
        detail: String,
        /// Field-level details, when the fault can be placed.
        violations: Vec<FieldViolation>,
    },
    /// Well-formed input that breaks a rule: invalid DH model, wrong joint
    /// count, value out of limits, unknown or missing field.
    Invalid {
        /// Summary for humans.
        detail: String,
        /// One entry per offending field.
        violations: Vec<FieldViolation>,
    },
    /// Valid input whose answer would cost more than a documented limit to
    /// compute or to send, e.g. a closed form past its work limit (the server
    /// answers HTTP 413, gRPC RESOURCE_EXHAUSTED).
    TooLarge {
        /// Which limit, its value, and what to do instead.
        detail: String,
        /// The field at fault (e.g. `links`).
        field: Option<String>,
    },
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ModelError::Malformed { detail, .. } => write!(f, "malformed input: {detail}"),
            ModelError::Invalid { detail, .. } => write!(f, "invalid input: {detail}"),
            ModelError::TooLarge { detail, .. } => write!(f, "too large: {detail}"),
        }
    }
}

impl std::error::Error for ModelError {}

impl ModelError {
    /// An [`ModelError::Invalid`] with a single field violation.
    pub fn invalid_field(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self::invalid(vec![FieldViolation::new(field, message)])
    }

    /// An [`ModelError::Invalid`] from a list of violations (summary: the first one, and a count).
    pub fn invalid(violations: Vec<FieldViolation>) -> Self {
        let detail = summary(&violations);
        ModelError::Invalid { detail, violations }
    }

    /// A [`ModelError::Malformed`] with a single field violation.
    pub fn malformed_field(field: impl Into<String>, message: impl Into<String>) -> Self {
        let v = FieldViolation::new(field, message);
        ModelError::Malformed {
            detail: v.to_string(),
            violations: vec![v],
        }
    }

    /// A [`ModelError::Malformed`] that no field can be blamed for (e.g. an unreadable file).
    pub fn malformed(detail: impl Into<String>) -> Self {
        ModelError::Malformed {
            detail: detail.into(),
            violations: Vec::new(),
        }
    }

    /// A [`ModelError::TooLarge`] blaming `field`; `detail` says which limit and what to do.
    pub fn too_large(field: impl Into<String>, detail: impl Into<String>) -> Self {
        ModelError::TooLarge {
            detail: detail.into(),
            field: Some(field.into()),
        }
    }

    /// The field violations (none for [`ModelError::TooLarge`], whose field is its own).
    pub fn violations(&self) -> &[FieldViolation] {
        match self {
            ModelError::Malformed { violations, .. } | ModelError::Invalid { violations, .. } => {
                violations
            }
            ModelError::TooLarge { .. } => &[],
        }
    }
}

/// One line that sums up a list of violations: the first one, and how many more.
pub fn summary(violations: &[FieldViolation]) -> String {
    match violations {
        [] => "invalid input".to_string(),
        [one] => one.to_string(),
        [first, rest @ ..] => format!("{first} (and {} more)", rest.len()),
    }
}

/// Result with [`ModelError`].
pub type Result<T, E = ModelError> = std::result::Result<T, E>;
