//! The docs' checked examples: a `<!-- … example: REQUEST -->` marker
//! followed by a ```json block with the answer the server gives, found in
//! README.md and every `docs/*.md` (read at run time, so a new page is
//! checked without a change here).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use serde_json::Value;

/// README.md and `docs/*.md` (sorted), as `(path relative to the repository,
/// text)`, read once.
pub(crate) fn doc_pages() -> &'static [(String, String)] {
    static PAGES: OnceLock<Vec<(String, String)>> = OnceLock::new();
    PAGES.get_or_init(|| {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut paths: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
            .expect("docs/ exists")
            .map(|e| e.expect("docs/ entry").path())
            .filter(|p| p.extension().is_some_and(|e| e == "md"))
            .collect();
        paths.sort();
        std::iter::once(root.join("README.md"))
            .chain(paths)
            .map(|p| {
                let text = std::fs::read_to_string(&p).expect("doc page reads");
                let rel = p.strip_prefix(root).unwrap().display().to_string();
                (rel, text)
            })
            .collect()
    })
}

/// Every example after `marker` (e.g. `"<!-- error example: "`) in the
/// docs except docs/MIGRATION.md: the request text up to ` -->`, and the
/// first ```json block after it, parsed.
pub(crate) fn readme_examples(marker: &str) -> Vec<(&'static str, Value)> {
    doc_pages()
        .iter()
        .filter(|(path, _)| path != "docs/MIGRATION.md")
        .flat_map(|(_, text)| examples_in(text, marker))
        .collect()
}

/// Every example after `marker` in docs/MIGRATION.md (the new shapes), as
/// [`readme_examples`].
pub(crate) fn migration_examples(marker: &str) -> Vec<(&'static str, Value)> {
    doc_pages()
        .iter()
        .filter(|(path, _)| path == "docs/MIGRATION.md")
        .flat_map(|(_, text)| examples_in(text, marker))
        .collect()
}

fn examples_in(text: &'static str, marker: &str) -> Vec<(&'static str, Value)> {
    text.split(marker)
        .skip(1)
        .map(|part| {
            let (request, rest) = part.split_once(" -->").expect("example marker closes");
            let block = rest
                .split("```json")
                .nth(1)
                .expect("a ```json block follows the marker")
                .split("```")
                .next()
                .unwrap();
            let documented = serde_json::from_str(block).expect("docs example is JSON");
            (request, documented)
        })
        .collect()
}

/// The text of the first `fence` block (e.g. "```xml") after `marker` in the
/// docs (for examples whose request body is a document of its own).
pub(crate) fn readme_block_after(marker: &str, fence: &str) -> &'static str {
    doc_pages()
        .iter()
        .find_map(|(_, text)| {
            text.split_once(marker)
                .and_then(|(_, rest)| rest.split_once(fence))
                .and_then(|(_, block)| block.split_once("```"))
                .map(|(body, _)| body.trim_start_matches('\n'))
        })
        .expect("a block of that kind follows the marker")
}
