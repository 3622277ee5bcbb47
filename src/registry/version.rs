//! Versions of registered robots and the conditions a write may put on them:
//! the revision behind `ETag` / `If-Match` (HTTP) and the `etag` fields (gRPC).
//! Owns the entity-tag syntax both front doors share; depends on the error
//! type only (no store, no protocol crate).

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crate::error::{Error, Result};

/// The version of a registered robot: a revision that grows on every change of
/// that robot (the ETag), and when that change was made (`Last-Modified`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Version {
    /// Increases on every change (create, replace, delete) of the robot.
    pub revision: u64,
    /// When the change was made.
    pub updated: SystemTime,
}

impl Version {
    /// The strong entity tag of this version, quotes included (`"17"`).
    pub fn etag(&self) -> String {
        format!("\"{}\"", self.revision)
    }
}

/// A revision for a change made now to a robot whose last known revision is
/// `known`: the wall clock in nanoseconds since the epoch, but always greater
/// than `known` (so revisions grow even if the clock steps back).
pub fn next_revision(known: Option<u64>) -> u64 {
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    known.map_or(now, |k| now.max(k.saturating_add(1)))
}

/// The time a nanosecond revision of the local stores stands for.
pub fn revision_time(revision: u64) -> SystemTime {
    UNIX_EPOCH + Duration::from_nanos(revision)
}

/// What a write requires of the robot's current state.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Condition {
    /// Nothing: create or replace.
    #[default]
    Any,
    /// The robot must not exist (`If-None-Match: *`; POST / `replace: false`).
    Absent,
    /// The robot must exist, in any version (`If-Match: *`).
    Present,
    /// The robot must exist at one of these revisions (`If-Match: "17"`); an
    /// empty list (only weak or foreign tags were given) never holds.
    Revision(Vec<u64>),
}

impl Condition {
    /// Whether the condition holds for a robot whose current revision is
    /// `current` (`None`: it does not exist).
    pub fn holds(&self, current: Option<u64>) -> bool {
        match (self, current) {
            (Condition::Any, _) => true,
            (Condition::Absent, c) => c.is_none(),
            (Condition::Present, c) => c.is_some(),
            (Condition::Revision(_), None) => false,
            (Condition::Revision(revs), Some(c)) => revs.contains(&c),
        }
    }

    /// [`Condition::holds`] as a result: [`Error::PreconditionFailed`] saying
    /// what was expected and what is there.
    pub fn check(&self, name: &str, current: Option<u64>) -> Result<()> {
        if self.holds(current) {
            return Ok(());
        }
        let is = match current {
            Some(r) => format!("its current ETag is \"{r}\""),
            None => "it does not exist".to_string(),
        };
        let wanted = match self {
            Condition::Absent => "it must not exist (create only)".to_string(),
            Condition::Present => "it must exist".to_string(),
            Condition::Revision(r) if r.is_empty() => {
                "no strong ETag of this server was given".to_string()
            }
            _ => "the ETag given does not match".to_string(),
        };
        Err(Error::PreconditionFailed {
            name: name.to_string(),
            detail: format!("{wanted}; {is}: read it again (GET) and retry with its ETag"),
        })
    }

    /// The condition of an `If-Match` value (HTTP header or gRPC `etag`): `*`,
    /// or a comma-separated list of entity tags (`"17"`, `"17", "18"`). Weak
    /// tags (`W/"17"`) and tags this server never issues match nothing (strong
    /// comparison, RFC 9110 §13.1.1). `field` names the input in the error
    /// when the value is not entity-tag syntax.
    pub fn if_match(value: &str, field: &str) -> Result<Condition> {
        let value = value.trim();
        if value == "*" {
            return Ok(Condition::Present);
        }
        let mut revisions = Vec::new();
        for tag in value.split(',').map(str::trim) {
            let (weak, opaque) = match tag.strip_prefix("W/") {
                Some(rest) => (true, rest),
                None => (false, tag),
            };
            let inner = opaque
                .strip_prefix('"')
                .and_then(|t| t.strip_suffix('"'))
                .filter(|t| !t.contains('"'))
                .ok_or_else(|| {
                    Error::malformed_field(
                        field,
                        format!(
                            "'{}' is not an entity tag: send * or the ETag exactly as the server gave it, quotes included (\"17\")",
                            tag.chars().take(64).collect::<String>()
                        ),
                    )
                })?;
            if let (false, Ok(r)) = (weak, inner.parse::<u64>()) {
                revisions.push(r);
            }
        }
        Ok(Condition::Revision(revisions))
    }
}

/// A short, stable entity tag for content that has no revision (a built-in
/// robot): FNV-1a of its bytes, `"builtin-<16 hex digits>"`.
pub fn content_etag(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("\"builtin-{h:016x}\"")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn if_match_reads_star_lists_weak_and_foreign_tags() {
        assert_eq!(Condition::if_match("*", "f").unwrap(), Condition::Present);
        assert_eq!(
            Condition::if_match(" \"17\" , \"18\"", "f").unwrap(),
            Condition::Revision(vec![17, 18])
        );
        assert_eq!(
            Condition::if_match("W/\"17\", \"builtin-00ff\"", "f").unwrap(),
            Condition::Revision(vec![])
        );
        let e = Condition::if_match("17", "If-Match").unwrap_err();
        assert_eq!(e.violations()[0].field, "If-Match");
    }

    #[test]
    fn conditions_hold_only_for_the_states_they_name() {
        assert!(Condition::Any.holds(None) && Condition::Any.holds(Some(3)));
        assert!(Condition::Absent.holds(None) && !Condition::Absent.holds(Some(3)));
        assert!(!Condition::Present.holds(None) && Condition::Present.holds(Some(3)));
        let r = Condition::Revision(vec![3, 5]);
        assert!(r.holds(Some(5)) && !r.holds(Some(4)) && !r.holds(None));
        assert!(!Condition::Revision(vec![]).holds(Some(0)));
    }

    #[test]
    fn next_revision_always_grows() {
        let far = u64::MAX - 10;
        assert_eq!(next_revision(Some(far)), far + 1);
        let a = next_revision(None);
        assert!(next_revision(Some(a)) > a);
    }
}
