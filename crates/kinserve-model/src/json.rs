//! JSON in: parsing with field paths ([`parse_json`]), JSON models
//! ([`Robot::from_json`]) and robot files ([`load_robot_file`]). Depends on
//! the error, spec and robot modules only (`robot.rs` must not depend on this
//! one).

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::error::{FieldViolation, ModelError, Result};
use crate::robot::{ModelLimits, Robot};
use crate::spec::RobotSpec;

/// Parses JSON into `T`, turning serde errors into [`ModelError`]s that name the field.
/// Every parse error is [`ModelError::Malformed`] (HTTP 400): syntax errors
/// (with line and column), wrong types, unknown or missing fields and unknown
/// enum values alike. Rules broken by a body that parses are
/// [`ModelError::Invalid`] (HTTP 422), from validation.
///
/// The happy path parses with plain serde_json; only a body that fails is
/// parsed again with field-path tracking (which allocates a string per
/// object key visited) to say where the problem is. Both parses read the
/// same bytes with the same rules, so they accept exactly the same bodies.
pub fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T> {
    match serde_json::from_slice(bytes) {
        Ok(value) => Ok(value),
        Err(_) => parse_json_with_path(bytes),
    }
}

/// [`parse_json`]'s error path: the same parse, tracking the field path.
fn parse_json_with_path<T: DeserializeOwned>(bytes: &[u8]) -> Result<T> {
    let de = &mut serde_json::Deserializer::from_slice(bytes);
    let value: T = serde_path_to_error::deserialize(&mut *de).map_err(json_error)?;
    de.end()
        .map_err(|e| ModelError::malformed_field("", format!("{e}")))?;
    Ok(value)
}

impl Robot {
    /// Parses a JSON model and validates it.
    pub fn from_json(bytes: &[u8], limits: &ModelLimits) -> Result<Robot> {
        let spec: RobotSpec = parse_json(bytes)?;
        Robot::from_spec(spec, limits)
    }
}

/// Longest field path reported for a JSON error (characters); longer ones are cut.
const MAX_PATH_CHARS: usize = 200;
/// Longest JSON error message reported (characters); longer ones are cut.
const MAX_MESSAGE_CHARS: usize = 300;

/// `s` cut to `max` characters, with `…` when something was cut (client text
/// echoed in an error stays small however large the input was).
fn clip(s: String, max: usize) -> String {
    match s.char_indices().nth(max) {
        None => s,
        Some((i, _)) => {
            let mut cut = s;
            cut.truncate(i);
            cut.push('…');
            cut
        }
    }
}

/// serde's "unknown field `jionts`, expected one of `joints`, …" (or
/// "unknown variant") with the nearest expected name put first: "unknown
/// field `jionts`: did you mean `joints`? (expected one of …)". `None` when
/// no expected name is close (at most a third of the name's length edited).
fn did_you_mean(message: &str) -> Option<String> {
    let rest = message
        .strip_prefix("unknown field ")
        .or_else(|| message.strip_prefix("unknown variant "))?;
    let mut quoted = rest.split('`').skip(1).step_by(2);
    let unknown = quoted.next()?;
    let wanted = unknown.to_lowercase();
    let (distance, best) = quoted
        .map(|c| (strsim::levenshtein(&wanted, &c.to_lowercase()), c))
        .min()?;
    if distance == 0 || distance > (unknown.chars().count() / 3).max(1) {
        return None;
    }
    let kind = if message.starts_with("unknown field") {
        "field"
    } else {
        "variant"
    };
    let expected = rest.split_once(", ").map_or("", |(_, e)| e);
    Some(format!(
        "unknown {kind} `{unknown}`: did you mean `{best}`? ({expected})"
    ))
}

fn json_error(e: serde_path_to_error::Error<serde_json::Error>) -> ModelError {
    let mut path = e.path().to_string();
    // serde_path_to_error writes `?` for a map key it could not read (e.g. a
    // single-quoted key) and `.` for the document itself: neither is a field.
    while path == "?" || path.ends_with(".?") {
        path.truncate(path.len() - 1);
        if path.ends_with('.') {
            path.pop();
        }
    }
    if path == "." {
        path.clear();
    }
    let inner = e.into_inner();
    let mut message = inner.to_string();
    // For data errors the path says where: strip serde_json's " at line L column C".
    // Syntax errors keep it (there is no field to name, and the position helps).
    let syntax = matches!(
        inner.classify(),
        serde_json::error::Category::Syntax | serde_json::error::Category::Eof
    );
    if !syntax && let Some(i) = message.find(" at line ") {
        message.truncate(i);
    }
    if let Some(better) = did_you_mean(&message) {
        message = better;
    }
    let structural = message.starts_with("unknown field") || message.starts_with("missing field");
    let names_a_field = structural || message.starts_with("duplicate field");
    if names_a_field && let Some(field) = message.split('`').nth(1) {
        let already = path.rsplit('.').next() == Some(field);
        if !already {
            path = if path.is_empty() {
                field.to_string()
            } else {
                format!("{path}.{field}")
            };
        }
    }
    // One policy for every body: what cannot be read into the schema (syntax,
    // wrong type, unknown or missing field, unknown enum value) is malformed
    // (HTTP 400); rules broken by a body that reads are invalid (HTTP 422).
    let v = FieldViolation::new(clip(path, MAX_PATH_CHARS), clip(message, MAX_MESSAGE_CHARS));
    ModelError::Malformed {
        detail: v.to_string(),
        violations: vec![v],
    }
}

/// Reads and validates a robot file (JSON, the schema of [`RobotSpec`]) with default limits.
pub fn load_robot_file(path: &Path) -> Result<Robot> {
    load_robot_file_with(path, &ModelLimits::default())
}

/// Reads and validates a robot file with the given limits: the one loader of
/// robot files (the CLI, the registry's built-ins and the tests all use it).
pub fn load_robot_file_with(path: &Path, limits: &ModelLimits) -> Result<Robot> {
    let bytes = read_robot_file(path)
        .map_err(|e| ModelError::malformed(format!("cannot read {}: {e}", path.display())))?;
    let spec: RobotSpec = parse_json(&bytes)?;
    Robot::from_spec(spec, limits)
}

/// Largest robot file read, in bytes (16 MiB; the largest valid model is far
/// smaller). A bigger file is refused without being read.
pub const MAX_ROBOT_FILE_BYTES: u64 = 16 << 20;

/// The bytes of the robot file at `path`, which must be a regular file (a
/// symbolic link to one is fine) of at most [`MAX_ROBOT_FILE_BYTES`]: a FIFO,
/// a device, a socket or a directory is refused without being opened (it
/// could block or never end), and an oversized file without being read. The
/// error says which rule the file broke.
pub fn read_robot_file(path: &Path) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    check_regular(&std::fs::metadata(path)?)?;
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    check_regular(&meta)?;
    let mut bytes = Vec::with_capacity(usize::try_from(meta.len()).unwrap_or(0));
    file.take(MAX_ROBOT_FILE_BYTES + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > MAX_ROBOT_FILE_BYTES {
        return Err(too_big(bytes.len() as u64));
    }
    Ok(bytes)
}

fn check_regular(meta: &std::fs::Metadata) -> std::io::Result<()> {
    let kind = meta.file_type();
    if !kind.is_file() {
        let what = if kind.is_dir() {
            "a directory"
        } else {
            special_kind(&kind)
        };
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("not a regular file ({what}); robot files must be regular files"),
        ));
    }
    if meta.len() > MAX_ROBOT_FILE_BYTES {
        return Err(too_big(meta.len()));
    }
    Ok(())
}

#[cfg(unix)]
fn special_kind(kind: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_fifo() {
        "a FIFO"
    } else if kind.is_socket() {
        "a socket"
    } else if kind.is_block_device() || kind.is_char_device() {
        "a device"
    } else {
        "a special file"
    }
}

#[cfg(not(unix))]
fn special_kind(_: &std::fs::FileType) -> &'static str {
    "a special file"
}

fn too_big(len: u64) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        format!(
            "{len} bytes, more than the {} MiB a robot file may have",
            MAX_ROBOT_FILE_BYTES >> 20
        ),
    )
}

#[cfg(test)]
mod did_you_mean_tests {
    use super::did_you_mean;

    #[test]
    fn the_nearest_expected_name_is_suggested_first() {
        let m = "unknown field `jionts`, expected one of `joints`, `angle_unit`, `frames`";
        assert_eq!(
            did_you_mean(m).as_deref(),
            Some(
                "unknown field `jionts`: did you mean `joints`? (expected one of `joints`, `angle_unit`, `frames`)"
            )
        );
        let v = "unknown variant `degs`, expected `rad` or `deg`";
        assert!(did_you_mean(v).unwrap().contains("did you mean `deg`?"));
        assert_eq!(
            did_you_mean("unknown field `zzzzzz`, expected `joints` or `frames`"),
            None,
            "nothing close"
        );
        assert_eq!(did_you_mean("missing field `joints`"), None);
    }
}
