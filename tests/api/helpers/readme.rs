//! The README's (and the migration note's) checked examples: a
//! `<!-- … example: REQUEST -->` marker followed by a ```json block with the
//! answer the server gives.

use serde_json::Value;

/// The README, as built into the test binary.
const README: &str = include_str!("../../../README.md");

/// docs/MIGRATION.md, as built into the test binary.
const MIGRATION: &str = include_str!("../../../docs/MIGRATION.md");

/// Every example after `marker` (e.g. `"<!-- error example: "`) in the
/// README: the request text up to ` -->`, and the first ```json block after
/// it, parsed.
pub(crate) fn readme_examples(marker: &str) -> Vec<(&'static str, Value)> {
    examples_in(README, marker)
}

/// Every example after `marker` in docs/MIGRATION.md (the new shapes), as
/// [`readme_examples`].
pub(crate) fn migration_examples(marker: &str) -> Vec<(&'static str, Value)> {
    examples_in(MIGRATION, marker)
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
            let documented = serde_json::from_str(block).expect("README example is JSON");
            (request, documented)
        })
        .collect()
}

/// The text of the first `fence` block (e.g. "```xml") after `marker` in the
/// README (for examples whose request body is a document of its own).
pub(crate) fn readme_block_after(marker: &str, fence: &str) -> &'static str {
    README
        .split_once(marker)
        .and_then(|(_, rest)| rest.split_once(fence))
        .and_then(|(_, block)| block.split_once("```"))
        .map(|(body, _)| body.trim_start_matches('\n'))
        .expect("a block of that kind follows the marker")
}
