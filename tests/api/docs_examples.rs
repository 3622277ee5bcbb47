//! Docs that cannot drift: every fenced block of README.md and `docs/*.md`
//! is run against a real server, compared with the output the page shows,
//! or marked `<!-- not run: reason -->` (docs/verification.md, "The docs
//! run as written", states the rules; pages are found at run time, so a new
//! page is walked without a change here).
//!
//! Each page gets its own server (a token set, ports free) and scratch
//! directory; its shell blocks run with `bash -eo pipefail` in page order
//! with `BASE`, `GRPC`, `KINSERVE_API_TOKEN` set and the `kinserve` binary of
//! this build first on `PATH`; Python blocks with `python3`, JavaScript
//! blocks as modules with `node`. Tools missing from the machine (grpcurl,
//! jq, python3, node) skip the blocks that need them with a SKIPPED line,
//! and fail the test under `CI=true`.

use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::Duration;

use kinserve::model::{ModelLimits, Robot};
use kinserve_testkit::{report, skip_unless_ci};
use tokio::process::Command;

use crate::helpers::doc_blocks::{Block, Marker, compare_output, fenced_blocks};
use crate::helpers::*;

/// The token the docs' servers are started with (`$KINSERVE_API_TOKEN`).
const TOKEN: &str = "docs-test-token";

/// Longest one block may run.
const BLOCK_TIMEOUT: Duration = Duration::from_secs(120);

/// The test's name in SKIPPED lines.
const TEST: &str = "docs_examples";

/// How a block is executed.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Runner {
    Bash,
    Python,
    Node,
}

impl Runner {
    fn of(lang: &str) -> Option<Runner> {
        match lang {
            "sh" | "bash" | "shell" => Some(Runner::Bash),
            "python" | "py" | "python3" => Some(Runner::Python),
            "js" | "javascript" | "mjs" => Some(Runner::Node),
            _ => None,
        }
    }
}

/// What one executed block printed.
struct Ran {
    line: usize,
    stdout: String,
}

/// The runnable block an `<!-- output -->` block refers to.
enum Last {
    /// None yet on this page.
    Nothing,
    /// It failed or was skipped (reported already).
    Unavailable,
    /// It ran.
    Ran(Ran),
}

/// One page's walk: its failures, and counts for the summary.
#[derive(Default)]
struct Walk {
    failures: Vec<String>,
    ran: usize,
    compared: usize,
    skipped: usize,
}

/// Tools a block needs besides bash, by the words it uses.
fn tools_needed(runner: Runner, text: &str) -> Vec<&'static str> {
    let mut tools = match runner {
        Runner::Bash => vec![],
        Runner::Python => vec!["python3"],
        Runner::Node => vec!["node"],
    };
    for tool in ["grpcurl", "jq", "curl", "python3", "node"] {
        let used = text
            .split(|c: char| !(c.is_alphanumeric() || c == '-' || c == '_'))
            .any(|w| w == tool);
        if used && !tools.contains(&tool) {
            tools.push(tool);
        }
    }
    tools
}

/// Whether `tool` is on `PATH`.
fn on_path(tool: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|dir| dir.join(tool).is_file()))
}

/// Node's `--experimental-websocket` where `WebSocket` is not a global yet
/// (Node 20 and 21).
fn node_flags() -> Vec<&'static str> {
    let out = std::process::Command::new("node").arg("--version").output();
    let major: u32 = out
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .and_then(|v| {
            v.trim()
                .trim_start_matches('v')
                .split('.')
                .next()?
                .parse()
                .ok()
        })
        .unwrap_or(22);
    if major < 22 {
        vec!["--experimental-websocket"]
    } else {
        vec![]
    }
}

/// README.md, then `docs/*.md` sorted: (path relative to the repository, text).
fn pages() -> Vec<(String, String)> {
    doc_pages().to_vec()
}

/// A scratch directory for one page: `robots/` links to the repository's.
fn scratch_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("scratch dir");
    let robots = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots");
    std::os::unix::fs::symlink(robots, dir.path().join("robots")).expect("robots link");
    dir
}

/// `PATH` with this build's `kinserve` first.
fn path_with_kinserve() -> std::ffi::OsString {
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_kinserve"));
    let mut dirs = vec![bin.parent().unwrap().to_path_buf()];
    if let Some(p) = std::env::var_os("PATH") {
        dirs.extend(std::env::split_paths(&p));
    }
    std::env::join_paths(dirs).expect("PATH joins")
}

/// Runs one block's text in `cwd` against `app`: its stdout, or why it failed.
async fn run_block(
    runner: Runner,
    text: &str,
    cwd: &Path,
    app: &TestApp,
) -> Result<String, String> {
    let (file, program, mut args) = match runner {
        Runner::Bash => (".block.sh", "bash", vec!["-eo", "pipefail"]),
        Runner::Python => (".block.py", "python3", vec![]),
        Runner::Node => (".block.mjs", "node", node_flags()),
    };
    std::fs::write(cwd.join(file), text).expect("block written");
    args.push(file);
    let grpc = app.grpc.trim_start_matches("http://");
    let mut cmd = Command::new(program);
    cmd.args(&args)
        .current_dir(cwd)
        .env("BASE", &app.http)
        .env("GRPC", grpc)
        .env("KINSERVE_API_TOKEN", TOKEN)
        .env("PATH", path_with_kinserve())
        .env_remove("KINSERVE_ROBOTS_DIR")
        .stdin(Stdio::null())
        .kill_on_drop(true);
    let out = tokio::time::timeout(BLOCK_TIMEOUT, cmd.output())
        .await
        .map_err(|_| format!("did not finish within {BLOCK_TIMEOUT:?}"))?
        .map_err(|e| format!("{program} could not start: {e}"))?;
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    if !out.status.success() {
        return Err(format!(
            "exited with {}\n--- stdout\n{stdout}--- stderr\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    Ok(stdout)
}

/// Whether the block after `i` (skipping nothing) is its documented output.
fn has_output(blocks: &[Block], i: usize) -> bool {
    blocks
        .get(i + 1)
        .is_some_and(|b| b.marker == Some(Marker::Output))
}

/// Checks a block that is data, not a program: JSON must parse (a robot
/// model must validate); the rest must be marked.
fn check_data(page: &str, block: &Block, walk: &mut Walk) {
    let at = format!("{page}:{}", block.line);
    match (block.lang.as_str(), &block.marker) {
        ("json", _) => {
            let is_model =
                block.text.contains("\"convention\"") && block.text.contains("\"links\"");
            if is_model {
                if let Err(e) = Robot::from_json(block.text.as_bytes(), &ModelLimits::default()) {
                    walk.failures
                        .push(format!("{at}: the model does not validate: {e:?}"));
                }
            } else if let Err(e) = serde_json::from_str::<serde_json::Value>(&block.text) {
                walk.failures
                    .push(format!("{at}: the JSON block does not parse: {e}"));
            }
        }
        (_, Some(Marker::File(_))) => {}
        (lang, _) => walk.failures.push(format!(
            "{at}: a ```{lang} block the docs test cannot run or check: mark it \
             `<!-- not run: reason -->` on the line before its fence, or show it as \
             `<!-- output -->` of the block before"
        )),
    }
}

/// Walks one page's blocks in order against its own server.
async fn walk_page(page: &str, text: &str) -> Walk {
    let app = spawn_app_with(|c| c.api_token = Some(TOKEN.into())).await;
    let dir = scratch_dir();
    let blocks = fenced_blocks(text);
    let mut walk = Walk::default();
    let mut last = Last::Nothing;
    for (i, block) in blocks.iter().enumerate() {
        let at = format!("{page}:{}", block.line);
        match &block.marker {
            Some(Marker::NotRun(reason)) => {
                if reason.is_empty() {
                    walk.failures
                        .push(format!("{at}: `not run` needs a reason"));
                }
                continue;
            }
            Some(Marker::Output) => {
                compare_documented(
                    &at,
                    block,
                    std::mem::replace(&mut last, Last::Nothing),
                    &mut walk,
                );
                continue;
            }
            Some(Marker::File(name)) => {
                std::fs::write(dir.path().join(name), &block.text).expect("file written");
            }
            _ => {}
        }
        let Some(runner) = Runner::of(&block.lang) else {
            check_data(page, block, &mut walk);
            continue;
        };
        let missing: Vec<_> = tools_needed(runner, &block.text)
            .into_iter()
            .filter(|t| !on_path(t))
            .collect();
        if !missing.is_empty() {
            skip_unless_ci(
                TEST,
                &format!("{at} needs {}", missing.join(", ")),
                ".ci/run installs them",
            );
            walk.skipped += 1;
            last = Last::Unavailable;
            continue;
        }
        walk.ran += 1;
        match run_block(runner, &block.text, dir.path(), &app).await {
            Ok(stdout) => {
                if stdout.contains("urn:kinserve:problem:") && !has_output(&blocks, i) {
                    walk.failures.push(format!(
                        "{at}: printed a problem the page does not show as its output:\n{stdout}"
                    ));
                }
                last = Last::Ran(Ran {
                    line: block.line,
                    stdout,
                });
            }
            Err(why) => {
                walk.failures.push(format!("{at}: {why}"));
                last = Last::Unavailable;
            }
        }
    }
    app.stop().await.expect("the page's server stops");
    walk
}

/// Compares a documented output with what the block before it printed.
fn compare_documented(at: &str, block: &Block, last: Last, walk: &mut Walk) {
    let ran = match last {
        Last::Ran(ran) => ran,
        Last::Unavailable => return,
        Last::Nothing => {
            walk.failures
                .push(format!("{at}: an output with no runnable block before it"));
            return;
        }
    };
    walk.compared += 1;
    if let Err(why) = compare_output(&block.text, &ran.stdout) {
        walk.failures.push(format!(
            "{at}: not what the block at line {} prints: {why}\n--- printed\n{}",
            ran.line, ran.stdout
        ));
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_block_of_the_docs_runs_as_shown_or_is_marked() {
    let pages = pages();
    assert!(pages.len() > 10, "README.md and docs/*.md are found");
    let walks =
        futures_util::future::join_all(pages.iter().map(|(page, text)| walk_page(page, text)))
            .await;
    let mut failures = Vec::new();
    let (mut ran, mut compared, mut skipped) = (0, 0, 0);
    for walk in walks {
        failures.extend(walk.failures);
        ran += walk.ran;
        compared += walk.compared;
        skipped += walk.skipped;
    }
    report(&format!(
        "docs examples: {ran} blocks ran, {compared} outputs compared, {skipped} skipped, over {} pages",
        pages.len()
    ));
    assert!(
        failures.is_empty(),
        "{} docs blocks fail:\n\n{}",
        failures.len(),
        failures.join("\n\n")
    );
    assert!(
        ran >= 30 && compared >= 10,
        "the docs run examples ({ran}) and show outputs ({compared})"
    );
}

/// Every page under docs/ is reachable from the index, docs/README.md.
#[test]
fn every_docs_page_is_linked_from_the_index() {
    let pages = pages();
    let index = &pages
        .iter()
        .find(|(p, _)| p == "docs/README.md")
        .expect("docs/README.md exists")
        .1;
    let unlinked: Vec<_> = pages
        .iter()
        .filter_map(|(p, _)| p.strip_prefix("docs/"))
        .filter(|name| *name != "README.md" && !index.contains(&format!("]({name}")))
        .collect();
    assert!(
        unlinked.is_empty(),
        "docs/README.md links no page {unlinked:?}: add a line for each"
    );
}
