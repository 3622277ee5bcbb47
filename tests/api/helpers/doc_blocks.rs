//! The fenced blocks of a Markdown page, with the HTML comment on the line
//! before each fence, and the comparison of a documented output with what a
//! command printed (numbers with a tolerance, the sign of an exact zero
//! kept). Used by `docs_examples.rs`; owns no I/O.

/// The marker on the line just before a fence.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Marker {
    /// `<!-- not run: reason -->`: the block is not executed.
    NotRun(String),
    /// `<!-- output -->`: what the nearest runnable block before prints.
    Output,
    /// `<!-- file: NAME -->`: written to `NAME` for the blocks after it.
    File(String),
    /// Any other comment (e.g. the contract tests' `error example:`).
    Other(String),
}

/// One fenced block.
#[derive(Clone, Debug)]
pub(crate) struct Block {
    /// 1-based line of the opening fence.
    pub line: usize,
    /// The info string's first word, lower case (`sh`, `json`, `` for none).
    pub lang: String,
    /// The content, with the fence's indentation removed.
    pub text: String,
    /// The comment on the line before the fence, if any.
    pub marker: Option<Marker>,
}

/// Every fenced block of `page`, in order. Panics on an unclosed fence.
pub(crate) fn fenced_blocks(page: &str) -> Vec<Block> {
    let lines: Vec<&str> = page.lines().collect();
    let mut blocks = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let trimmed = lines[i].trim_start();
        let Some(info) = trimmed.strip_prefix("```") else {
            i += 1;
            continue;
        };
        let indent = lines[i].len() - trimmed.len();
        let lang = info.split_whitespace().next().unwrap_or("").to_lowercase();
        let marker = i.checked_sub(1).and_then(|p| marker_of(lines[p]));
        let start = i;
        let mut text = String::new();
        i += 1;
        while i < lines.len() && lines[i].trim() != "```" {
            let l = lines[i];
            let cut = l.len() - l.trim_start().len();
            text.push_str(&l[cut.min(indent)..]);
            text.push('\n');
            i += 1;
        }
        assert!(
            i < lines.len(),
            "fence opened at line {} is never closed",
            start + 1
        );
        blocks.push(Block {
            line: start + 1,
            lang,
            text,
            marker,
        });
        i += 1;
    }
    blocks
}

/// The marker a line holds, if it is an HTML comment of its own.
fn marker_of(line: &str) -> Option<Marker> {
    let body = line
        .trim()
        .strip_prefix("<!--")?
        .strip_suffix("-->")?
        .trim();
    Some(if let Some(reason) = body.strip_prefix("not run:") {
        Marker::NotRun(reason.trim().to_string())
    } else if body == "output" {
        Marker::Output
    } else if let Some(name) = body.strip_prefix("file:") {
        Marker::File(name.trim().to_string())
    } else {
        Marker::Other(body.to_string())
    })
}

/// A token of an output: numbers are compared by value, the rest exactly.
#[derive(Clone, Debug, PartialEq)]
enum Token {
    /// A number as written (`-0.0`, `1e-9`) and its value.
    Num(String, f64),
    /// A run of letters, digits and `_` that does not start a number.
    Word(String),
    /// `...` or `…`: any run of tokens (in an expected output only).
    Any,
    /// Any other character.
    Punct(char),
}

/// Numbers agree when within `TOL` absolutely, or relatively for large ones.
const TOL: f64 = 1e-9;

fn tokens(text: &str) -> Vec<Token> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let prev_word = i > 0 && (chars[i - 1].is_alphanumeric() || chars[i - 1] == '_');
        if c.is_whitespace() {
            i += 1;
        } else if c == '…' {
            out.push(Token::Any);
            i += 1;
        } else if chars[i..].starts_with(&['.', '.', '.']) {
            out.push(Token::Any);
            i += 3;
        } else if !prev_word && starts_number(&chars[i..]) {
            let end = i + number_len(&chars[i..]);
            let s: String = chars[i..end].iter().collect();
            let v = s.parse().expect("a number token parses");
            out.push(Token::Num(s, v));
            i = end;
        } else if c.is_alphanumeric() || c == '_' {
            let end = i + chars[i..]
                .iter()
                .take_while(|c| c.is_alphanumeric() || **c == '_')
                .count();
            out.push(Token::Word(chars[i..end].iter().collect()));
            i = end;
        } else {
            out.push(Token::Punct(c));
            i += 1;
        }
    }
    out
}

fn starts_number(s: &[char]) -> bool {
    match s {
        [d, ..] if d.is_ascii_digit() => true,
        ['-', d, ..] => d.is_ascii_digit(),
        _ => false,
    }
}

/// Length of the number at the start of `s` (`-?d+(.d+)?([eE][+-]?d+)?`).
fn number_len(s: &[char]) -> usize {
    let digits = |from: usize| s[from..].iter().take_while(|c| c.is_ascii_digit()).count();
    let mut n = usize::from(s[0] == '-');
    n += digits(n);
    if s.get(n) == Some(&'.') && s.get(n + 1).is_some_and(|c| c.is_ascii_digit()) {
        n += 1 + digits(n + 1);
    }
    if matches!(s.get(n), Some('e' | 'E')) {
        let sign = usize::from(matches!(s.get(n + 1), Some('+' | '-')));
        let d = digits(n + 1 + sign);
        if d > 0 {
            n += 1 + sign + d;
        }
    }
    n
}

fn same(expected: &Token, actual: &Token) -> bool {
    match (expected, actual) {
        (Token::Num(es, e), Token::Num(as_, a)) => {
            if *e == 0.0 && *a == 0.0 {
                // An exact zero shows the sign the program printed.
                es.starts_with('-') == as_.starts_with('-')
            } else {
                (e - a).abs() <= TOL * e.abs().max(a.abs()).max(1.0)
            }
        }
        (e, a) => e == a,
    }
}

/// Whether `actual` matches `expected` from the given positions (`Any`
/// matches any run of tokens, shortest first).
fn matches_from(expected: &[Token], actual: &[Token]) -> bool {
    match expected.split_first() {
        None => actual.is_empty(),
        Some((Token::Any, rest)) => (0..=actual.len()).any(|k| matches_from(rest, &actual[k..])),
        Some((e, rest)) => actual
            .split_first()
            .is_some_and(|(a, arest)| same(e, a) && matches_from(rest, arest)),
    }
}

/// `Ok` when `actual` (what a block printed) is the documented `expected`
/// output: the same tokens, whitespace aside, numbers within 1e-9, and an
/// exact zero with the printed sign (`-0.0` is not `0`). In `expected`,
/// `...` (or `…`) stands for any text. The error names the first place
/// where the two part.
pub(crate) fn compare_output(expected: &str, actual: &str) -> Result<(), String> {
    let (e, a) = (tokens(expected), tokens(actual));
    if matches_from(&e, &a) {
        return Ok(());
    }
    let first = e
        .iter()
        .zip(&a)
        .position(|(e, a)| *e == Token::Any || !same(e, a))
        .unwrap_or(e.len().min(a.len()));
    Err(format!(
        "the output differs from the documented one at token {first} (documented {:?}, printed {:?})",
        e.get(first),
        a.get(first)
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_compare_with_a_tolerance_and_zero_keeps_its_sign() {
        assert!(compare_output("[0.5, 1.0]", "[0.5000000000001,1]").is_ok());
        assert!(compare_output("[0.5]", "[0.5001]").is_err());
        assert!(
            compare_output("[0, 1]", "[-0.0, 1]").is_err(),
            "-0.0 is not 0"
        );
        assert!(compare_output("[-0, 1]", "[-0.0, 1.0]").is_ok());
        assert!(
            compare_output("[0]", "[6.1e-17]").is_ok(),
            "not an exact zero"
        );
        assert!(compare_output("1796224074800288124", "1796224074800288125").is_ok());
    }

    #[test]
    fn wildcards_match_any_text_and_words_compare_exactly() {
        assert!(compare_output(r#"{"etag":"...","a":1}"#, r#"{"etag":"\"17\"","a":1}"#).is_ok());
        assert!(compare_output("a\n...\nz", "a\nb\nc\nz").is_ok());
        assert!(compare_output("a ... z", "a z").is_ok());
        assert!(compare_output("c12 | -s12", "c12 | s12").is_err());
        assert!(compare_output("planar_2dof", "planar_3dof").is_err());
        assert!(compare_output("a", "a b").is_err(), "nothing may follow");
    }

    #[test]
    fn blocks_carry_their_language_indentation_and_marker() {
        let page = "x\n<!-- not run: needs Docker -->\n```sh\ndocker ps\n```\n- item\n\n  ```json\n  {\"a\": 1}\n  ```\n<!-- output -->\n```\nok\n```\n";
        let b = fenced_blocks(page);
        assert_eq!(b.len(), 3);
        assert_eq!(b[0].marker, Some(Marker::NotRun("needs Docker".into())));
        assert_eq!((b[0].lang.as_str(), b[0].line), ("sh", 3));
        assert_eq!(b[1].text, "{\"a\": 1}\n");
        assert_eq!(b[1].marker, None);
        assert_eq!(b[2].marker, Some(Marker::Output));
        assert_eq!(b[2].lang, "");
    }
}
