//! The built-in robots: the files of `robots/`, embedded in the binary at
//! build time (see `build.rs`), optionally overridden or extended by a
//! directory given at start-up. Depends on the model crate only.

use std::path::Path;

use crate::error::{Error, Result};
use crate::model::{ModelLimits, Robot, load_robot_file_with};

include!(concat!(env!("OUT_DIR"), "/builtin_robots.rs"));

/// One built-in robot file: where it came from (for messages) and its validation result.
pub type BuiltinFile = (String, Result<Robot>);

/// Every embedded robot file, validated with `limits`, in file-name order.
pub fn embedded(limits: &ModelLimits) -> impl Iterator<Item = BuiltinFile> + '_ {
    EMBEDDED.iter().map(|(name, bytes)| {
        let robot = Robot::from_json(bytes, limits).map_err(Error::from);
        (format!("built-in {name}"), robot)
    })
}

/// Every `*.json` in `dir`, validated with `limits`, in file-name order. A
/// directory that cannot be listed is one error naming it.
pub fn from_dir(dir: &Path, limits: &ModelLimits) -> Vec<BuiltinFile> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) => {
            let detail = format!("cannot list robots directory {}: {e}", dir.display());
            return vec![(
                dir.display().to_string(),
                Err(Error::Malformed {
                    detail,
                    violations: Vec::new(),
                }),
            )];
        }
    };
    let mut paths: Vec<_> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    paths.sort();
    paths
        .into_iter()
        .map(|p| {
            let robot = load_robot_file_with(&p, limits).map_err(Error::from);
            (p.display().to_string(), robot)
        })
        .collect()
}

/// The built-in robot called `name`: from `dir` when given and it has
/// `{name}.json`, else the embedded file of that name. `None` if neither has it.
pub fn find(name: &str, dir: Option<&Path>, limits: &ModelLimits) -> Option<BuiltinFile> {
    let file = format!("{name}.json");
    if let Some(dir) = dir {
        let path = dir.join(&file);
        if path.is_file() {
            let robot = load_robot_file_with(&path, limits).map_err(Error::from);
            return Some((path.display().to_string(), robot));
        }
    }
    let (_, bytes) = EMBEDDED.iter().find(|(n, _)| *n == file)?;
    let robot = Robot::from_json(bytes, limits).map_err(Error::from);
    Some((format!("built-in {file}"), robot))
}

/// Names of the embedded robots (file names without `.json`), sorted.
pub fn embedded_names() -> impl Iterator<Item = &'static str> {
    EMBEDDED.iter().filter_map(|(n, _)| n.strip_suffix(".json"))
}
