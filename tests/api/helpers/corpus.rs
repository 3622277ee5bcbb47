//! The bad-input corpus in `tests/corpus/` and small text builders for it.

use serde_json::Value;

pub(crate) fn corpus(name: &str) -> Vec<Value> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/corpus")
        .join(name);
    let doc: Value = serde_json::from_slice(&std::fs::read(&path).expect("corpus file"))
        .expect("corpus is JSON");
    doc["cases"].as_array().expect("cases").clone()
}

pub(crate) fn corpus_bytes(name: &str) -> Vec<u8> {
    std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/corpus")
            .join(name),
    )
    .expect("corpus data file")
}

pub(crate) fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex"))
        .collect()
}

pub(crate) fn join(n: usize, item: &str) -> String {
    vec![item; n].join(",")
}
