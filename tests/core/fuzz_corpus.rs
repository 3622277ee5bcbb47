//! Replays the fuzzing corpus in an ordinary `cargo test`: every file under
//! `fuzz/corpus/<target>/`, `fuzz/regressions/<target>/` and (when a fuzzing run
//! left any) `fuzz/artifacts/<target>/` goes through the same property check
//! as the `cargo fuzz` target of that name (`kinserve_testkit::fuzzing`).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use kinserve_testkit::fuzzing::{check_fk_request, check_ik_request, check_model};

fn files(target: &str) -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut out = Vec::new();
    for kind in ["corpus", "regressions", "artifacts"] {
        let Ok(entries) = std::fs::read_dir(root.join(kind).join(target)) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            let hidden = p
                .file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with('.'));
            if p.is_file() && !hidden {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Runs `check` on every file of `target`, collecting every failure before failing.
fn replay(target: &str, check: fn(&[u8])) {
    let files = files(target);
    assert!(
        !files.is_empty(),
        "no corpus for fuzz target '{target}' under fuzz/"
    );
    let mut failed = Vec::new();
    for f in &files {
        // A running fuzzer may replace files while we read.
        let Ok(bytes) = std::fs::read(f) else {
            continue;
        };
        if let Err(e) = catch_unwind(AssertUnwindSafe(|| check(&bytes))) {
            let msg = e
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            failed.push(format!("{}: {msg}", f.display()));
        }
    }
    assert!(
        failed.is_empty(),
        "{} of {} inputs of '{target}' break a property:\n{}",
        failed.len(),
        files.len(),
        failed.join("\n")
    );
}

#[test]
fn model_corpus_replays_clean() {
    replay("model", check_model);
}

#[test]
fn fk_request_corpus_replays_clean() {
    replay("fk_request", check_fk_request);
}

#[test]
fn ik_request_corpus_replays_clean() {
    replay("ik_request", check_ik_request);
}

/// Found by schemathesis: serde's derive reads a struct from an array of its
/// field values too, so `"tool": [null, null]` registered a robot although the
/// schema says object. Every model object must now be a JSON object.
#[test]
fn model_objects_written_as_arrays_are_refused() {
    use kinserve::model::{ModelError, ModelLimits, Robot};
    let link = r#"{"joint": "revolute", "a": 1, "alpha": 0, "d": 0, "theta": 0}"#;
    let ok = format!(r#"{{"name": "r", "convention": "standard", "links": [{link}]}}"#);
    assert!(Robot::from_json(ok.as_bytes(), &ModelLimits::default()).is_ok());
    let bad = [
        format!(
            r#"{{"name": "r", "convention": "standard", "tool": [null, null], "links": [{link}]}}"#
        ),
        format!(
            r#"{{"name": "r", "convention": "standard", "base": [[0, 0, 0]], "links": [{link}]}}"#
        ),
        r#"{"name": "r", "convention": "standard", "links": [[null, "revolute", 1, 0, 0, 0]]}"#
            .to_string(),
        format!(
            r#"{{"name": "r", "convention": "standard", "base": {{"quaternion": [1, 0, 0, 0]}}, "links": [{link}]}}"#
        ),
        format!(r#"["r", null, null, "standard", "rad", "m", null, null, [{link}]]"#),
    ];
    for b in &bad {
        match Robot::from_json(b.as_bytes(), &ModelLimits::default()) {
            Err(ModelError::Malformed { detail, .. }) => {
                assert!(detail.contains("expected a JSON object"), "{b}: {detail}")
            }
            other => panic!("{b}: expected a malformed-input error, got {other:?}"),
        }
    }
}
