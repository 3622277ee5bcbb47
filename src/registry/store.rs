//! Persistence of registered robots behind a small trait; the embedded default
//! is one JSON file per robot, written atomically. A store owns durability and
//! the check-and-write of conditional writes; it must not depend on the
//! registry's snapshot, the service or the front doors.

use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, UNIX_EPOCH};

use super::version::{Condition, Version, next_revision, revision_time};
use crate::error::{Error, Result};
use crate::model::{RobotSpec, parse_json};

/// A stored model and its version.
#[derive(Clone, Debug)]
pub struct Record {
    /// The model as registered.
    pub spec: RobotSpec,
    /// Its version.
    pub version: Version,
}

/// The outcome of a save.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Saved {
    /// The new version.
    pub version: Version,
    /// Whether the robot was created (it did not exist before).
    pub created: bool,
}

/// How a store is doing, for `/readyz` and the metrics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoreHealth {
    /// `file`, `memory` or `postgres`.
    pub kind: &'static str,
    /// Whether writes can be made now.
    pub up: bool,
    /// How long ago the snapshot was last known to equal the store (zero for
    /// the local stores, whose snapshot is the only writer's).
    pub snapshot_age: Duration,
}

impl StoreHealth {
    /// The health of a local store: always up, snapshot always current.
    pub fn local(kind: &'static str) -> StoreHealth {
        StoreHealth {
            kind,
            up: true,
            snapshot_age: Duration::ZERO,
        }
    }
}

/// Where registered robots live. Implementations must make `save` and `delete`
/// durable before returning `Ok` (the API answers only afterwards), and must
/// check the write's [`Condition`] and make the change as one atomic step.
///
/// `known` is the revision the caller's snapshot holds for the robot (`None`:
/// absent). A local store ([`Store::is_shared`] false) is its only writer: the
/// registry serialises its writes and it trusts `known`. A shared store (a
/// database several replicas write to) checks against its own data instead.
pub trait Store: Send + Sync + 'static {
    /// Every stored model, each with a label for logs (e.g. its file path).
    /// Entries that cannot be read come back as errors and are skipped by the
    /// caller. May block (call it off the async runtime).
    fn load_all(&self) -> Vec<(String, Result<Record>)>;
    /// Stores (creates or replaces) a model durably if `cond` holds
    /// ([`Error::PreconditionFailed`] otherwise). Blocking.
    fn save(&self, spec: &RobotSpec, cond: &Condition, known: Option<u64>) -> Result<Saved>;
    /// Removes a model durably if it exists ([`Error::NotFound`] otherwise) and
    /// `cond` holds; returns the revision of the removal. Blocking.
    fn delete(&self, name: &str, cond: &Condition, known: Option<u64>) -> Result<Version>;
    /// Whether other processes write to this store too (see the trait docs).
    fn is_shared(&self) -> bool {
        false
    }
    /// Sets the most robots the store may hold, for a shared store to check
    /// on create against its own data (a save over it fails with
    /// [`Error::Full`]). Local stores need not: the registry reserves a slot
    /// before every create.
    fn limit_registered(&mut self, _max: usize) {}
    /// How the store is doing.
    fn health(&self) -> StoreHealth;
}

fn not_found(name: &str) -> Error {
    Error::NotFound {
        name: name.to_string(),
        suggestions: Vec::new(),
    }
}

/// The version a local store gives a change of a robot last at `known`.
fn local_version(known: Option<u64>) -> Version {
    let revision = next_revision(known);
    Version {
        revision,
        updated: revision_time(revision),
    }
}

/// Keeps nothing: for tests and throw-away servers. Conditions are checked
/// against the caller's snapshot.
#[derive(Debug, Default)]
pub struct MemoryStore;

impl Store for MemoryStore {
    fn load_all(&self) -> Vec<(String, Result<Record>)> {
        Vec::new()
    }
    fn save(&self, spec: &RobotSpec, cond: &Condition, known: Option<u64>) -> Result<Saved> {
        cond.check(&spec.name, known)?;
        Ok(Saved {
            version: local_version(known),
            created: known.is_none(),
        })
    }
    fn delete(&self, name: &str, cond: &Condition, known: Option<u64>) -> Result<Version> {
        if known.is_none() {
            return Err(not_found(name));
        }
        cond.check(name, known)?;
        Ok(local_version(known))
    }
    fn health(&self) -> StoreHealth {
        StoreHealth::local("memory")
    }
}

/// One `<name>.json` per robot under `<data_dir>/robots/`. A save writes a hidden
/// temporary file, fsyncs it, renames it over the target and fsyncs the
/// directory, so a crash leaves either the old or the new file, never half of one.
///
/// A robot's revision is the file's modification time in nanoseconds, set
/// explicitly on every write (always above the previous one), so ETags
/// survive restarts on file systems that keep nanosecond times (ext4, xfs,
/// btrfs, tmpfs); elsewhere they change once at a restart, which only makes
/// an old `If-Match` fail safely.
#[derive(Debug)]
pub struct FileStore {
    dir: PathBuf,
}

/// A failed file operation, naming the file relative to the data directory
/// (`robots/<file>`) so that no host path reaches a response.
fn storage(what: &str, path: &Path, e: std::io::Error) -> Error {
    Error::Storage {
        detail: format!("{what} {}: {e}", shown(path)),
    }
}

/// `robots/<file name>` (or `robots/` for the directory itself).
fn shown(path: &Path) -> String {
    match path.file_name() {
        Some(n) if n != "robots" => format!("robots/{}", n.to_string_lossy()),
        _ => "robots/".to_string(),
    }
}

/// Whether `file` is a temporary file this server writes
/// (`.<robot name>.json.tmp-<32 hex digits>`); nothing else is ever removed.
fn is_own_temp_file(file: &str) -> bool {
    let Some(rest) = file.strip_prefix('.') else {
        return false;
    };
    let Some((name, suffix)) = rest.split_once(".json.tmp-") else {
        return false;
    };
    crate::model::validate_name(name).is_ok()
        && suffix.len() == 32
        && suffix
            .bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

impl FileStore {
    /// Opens (creating if needed) the store under `data_dir`, removing the
    /// temporary files of this server that a crash may have left. Fails, naming
    /// the directory and the reason, when `robots` is not a directory (a plain
    /// file, a dangling link) or cannot be listed.
    pub fn open(data_dir: &Path) -> Result<FileStore> {
        let dir = data_dir.join("robots");
        let refuse = |why: String| Error::Storage {
            detail: format!("data directory {}: {why}", dir.display()),
        };
        match fs::symlink_metadata(&dir) {
            Ok(m) if m.file_type().is_symlink() && !dir.exists() => {
                return Err(refuse("is a dangling symbolic link".into()));
            }
            Ok(_) if dir.exists() && !dir.is_dir() => {
                return Err(refuse("exists but is not a directory".into()));
            }
            _ => {}
        }
        fs::create_dir_all(&dir).map_err(|e| refuse(format!("cannot create it: {e}")))?;
        let entries = fs::read_dir(&dir).map_err(|e| refuse(format!("cannot list it: {e}")))?;
        for entry in entries.flatten() {
            let name = entry.file_name();
            if is_own_temp_file(&name.to_string_lossy()) {
                tracing::info!(file = %entry.path().display(), "removing temporary file left by an interrupted write");
                let _ = fs::remove_file(entry.path());
            }
        }
        Ok(FileStore { dir })
    }

    /// Directory holding the robot files.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn path_of(&self, name: &str) -> PathBuf {
        self.dir.join(format!("{name}.json"))
    }

    fn sync_dir(&self) -> Result<()> {
        File::open(&self.dir)
            .and_then(|d| d.sync_all())
            .map_err(|e| storage("cannot sync", &self.dir, e))
    }
}

impl Store for FileStore {
    fn load_all(&self) -> Vec<(String, Result<Record>)> {
        let entries = match fs::read_dir(&self.dir) {
            Ok(entries) => entries,
            Err(e) => {
                let listing = storage("cannot list", &self.dir, e);
                return vec![(self.dir.display().to_string(), Err(listing))];
            }
        };
        let mut paths: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.extension().is_some_and(|x| x == "json")
                    && !p
                        .file_name()
                        .is_some_and(|n| n.to_string_lossy().starts_with('.'))
            })
            .collect();
        paths.sort();
        paths
            .into_iter()
            .map(|p| (p.display().to_string(), read_record(&p)))
            .collect()
    }

    fn save(&self, spec: &RobotSpec, cond: &Condition, known: Option<u64>) -> Result<Saved> {
        cond.check(&spec.name, known)?;
        let version = local_version(known);
        self.write_file(spec, version)?;
        Ok(Saved {
            version,
            created: known.is_none(),
        })
    }

    fn delete(&self, name: &str, cond: &Condition, known: Option<u64>) -> Result<Version> {
        if known.is_none() {
            return Err(not_found(name));
        }
        cond.check(name, known)?;
        let path = self.path_of(name);
        match fs::remove_file(&path) {
            Ok(()) => self.sync_dir()?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(storage("cannot remove", &path, e)),
        }
        Ok(local_version(known))
    }

    fn health(&self) -> StoreHealth {
        StoreHealth::local("file")
    }
}

impl FileStore {
    /// Writes `spec` atomically with its modification time set to `version`.
    fn write_file(&self, spec: &RobotSpec, version: Version) -> Result<()> {
        let target = self.path_of(&spec.name);
        let tmp = self.dir.join(format!(
            ".{}.json.tmp-{}",
            spec.name,
            uuid::Uuid::new_v4().simple()
        ));
        let bytes = serde_json::to_vec_pretty(spec).map_err(|e| Error::Internal {
            detail: e.to_string(),
        })?;
        let result = (|| {
            let mut f = OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&tmp)
                .map_err(|e| storage("cannot create", &tmp, e))?;
            f.write_all(&bytes)
                .map_err(|e| storage("cannot write", &tmp, e))?;
            f.set_modified(version.updated)
                .map_err(|e| storage("cannot set the time of", &tmp, e))?;
            f.sync_all().map_err(|e| storage("cannot sync", &tmp, e))?;
            fs::rename(&tmp, &target).map_err(|e| storage("cannot rename into", &target, e))?;
            self.sync_dir()
        })();
        if result.is_err() {
            let _ = fs::remove_file(&tmp);
        }
        result
    }
}

/// A robot file and its version (from its modification time). The model's
/// name must match the file name.
fn read_record(p: &Path) -> Result<Record> {
    let bytes = crate::model::read_robot_file(p).map_err(|e| storage("cannot read", p, e))?;
    let spec: RobotSpec = parse_json(&bytes)?;
    let stem = p.file_stem().map(|s| s.to_string_lossy().into_owned());
    if stem.as_deref() != Some(spec.name.as_str()) {
        return Err(Error::invalid_field(
            "name",
            format!("'{}' does not match the file name", spec.name),
        ));
    }
    let modified = fs::metadata(p)
        .and_then(|m| m.modified())
        .map_err(|e| storage("cannot read the time of", p, e))?;
    let revision = modified
        .duration_since(UNIX_EPOCH)
        .map_or(1, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    Ok(Record {
        spec,
        version: Version {
            revision,
            updated: modified,
        },
    })
}
