//! The characters a model's strings may hold. Owns the safe set and its
//! checks only; the schema's validation (`robot.rs`) calls them.
//!
//! Every string of a model can reach an XML document (the URDF export writes
//! link and joint names into attributes), a JSON answer, a log line and a
//! terminal. XML 1.0 cannot carry C0 control characters at all (not even
//! escaped as `&#1;`), and control, bidirectional-override and separator
//! characters make names that look like other names in logs and terminals.
//! So link names are **labels**: 1–[`MAX_LINK_NAME_CHARS`] characters, none
//! of them [forbidden](forbidden); `description` and `source` are **text**:
//! the same set plus tab, line feed and carriage return, at most
//! [`MAX_TEXT_CHARS`] characters. (Robot names are stricter still:
//! [`crate::validate_name`].)
//!
//! [`MAX_LINK_NAME_CHARS`]: crate::MAX_LINK_NAME_CHARS
//! [`MAX_TEXT_CHARS`]: crate::MAX_TEXT_CHARS

use crate::{MAX_LINK_NAME_CHARS, MAX_TEXT_CHARS};

/// The rule in words, for error messages and docs.
pub const SAFE_SET: &str = "no control characters (U+0000-U+001F, U+007F-U+009F), \
    bidirectional-text controls (U+061C, U+200E, U+200F, U+202A-U+202E, U+2066-U+2069), \
    line or paragraph separators (U+2028, U+2029) or noncharacters \
    (U+FDD0-U+FDEF, U+FFFE, U+FFFF and the last two code points of every plane)";

/// Whether `c` is outside the safe set (in any string of a model; text
/// fields also allow tab, line feed and carriage return).
pub fn forbidden(c: char) -> bool {
    let u = u32::from(c);
    c.is_control()
        || matches!(
            u,
            0x061C | 0x200E | 0x200F | 0x202A..=0x202E | 0x2066..=0x2069 | 0x2028 | 0x2029
        )
        || (0xFDD0..=0xFDEF).contains(&u)
        || (u & 0xFFFE) == 0xFFFE
}

/// The first forbidden character of `s`, as "character 3 is U+0001"
/// (1-based position; the character itself is never echoed).
fn first_forbidden(s: &str, allowed: impl Fn(char) -> bool) -> Option<String> {
    s.chars()
        .enumerate()
        .find(|&(_, c)| forbidden(c) && !allowed(c))
        .map(|(i, c)| format!("character {} is U+{:04X}", i + 1, u32::from(c)))
}

/// Checks a link name: 1–64 characters of the safe set.
pub fn check_label(s: &str) -> Result<(), String> {
    let n = s.chars().count();
    if n == 0 {
        return Err("must not be empty: omit the field for a generated name".into());
    }
    if n > MAX_LINK_NAME_CHARS {
        return Err(format!(
            "must be at most {MAX_LINK_NAME_CHARS} characters, got {n}"
        ));
    }
    match first_forbidden(s, |_| false) {
        Some(at) => Err(format!(
            "may hold any characters but {SAFE_SET}; {at}: remove or replace it"
        )),
        None => Ok(()),
    }
}

/// Checks `description` / `source`: at most 4096 characters of the safe set,
/// tab, line feed and carriage return allowed.
pub fn check_text(s: &str) -> Result<(), String> {
    let n = s.chars().count();
    if n > MAX_TEXT_CHARS {
        return Err(format!(
            "must be at most {MAX_TEXT_CHARS} characters, got {n}"
        ));
    }
    match first_forbidden(s, |c| matches!(c, '\t' | '\n' | '\r')) {
        Some(at) => Err(format!(
            "may hold tab, line feed and carriage return but otherwise {SAFE_SET}; {at}: remove or replace it"
        )),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_refuse_what_xml_and_logs_cannot_carry() {
        for bad in [
            "a\u{1}b",
            "tab\there",
            "nl\n",
            "\u{7f}",
            "\u{85}",
            "\u{202e}evil",
            "x\u{2028}",
            "\u{fffe}",
            "\u{ffff}",
            "\u{fdd0}",
            "\u{1fffe}",
            "\u{10ffff}",
            "\u{2066}",
        ] {
            assert!(check_label(bad).is_err(), "{bad:?} accepted");
        }
        let e = check_label("ab\u{1}").unwrap_err();
        assert!(e.contains("character 3 is U+0001"), "{e}");
        assert!(!e.contains('\u{1}'), "the character is echoed: {e:?}");
    }

    #[test]
    fn labels_accept_ordinary_unicode_and_markup_characters() {
        for good in [
            "shoulder",
            "Gelenk Schulter",
            "肩",
            "<joint name=\"x\"/> & 'y'",
            "]]>--",
            "\u{1F916}",
            "\u{e000}",
            "\u{fffd}",
        ] {
            assert_eq!(check_label(good), Ok(()), "{good:?}");
        }
    }

    #[test]
    fn label_length_is_counted_in_characters() {
        assert!(check_label(&"é".repeat(64)).is_ok());
        assert!(check_label(&"é".repeat(65)).unwrap_err().contains("got 65"));
        assert!(check_label("").is_err());
    }

    #[test]
    fn text_allows_line_breaks_and_tabs_only() {
        assert_eq!(check_text("line one\r\nline\ttwo\n"), Ok(()));
        assert!(check_text("bell\u{7}").unwrap_err().contains("U+0007"));
        assert!(check_text(&"x".repeat(4097)).is_err());
    }
}
