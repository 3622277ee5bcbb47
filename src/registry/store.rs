//! Persistence of registered robots behind a small trait; the embedded default
//! is one JSON file per robot, written atomically.

use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::model::{RobotSpec, parse_json};

/// Where registered robots live. Implementations must make `save` and `delete`
/// durable before returning `Ok` (the API answers only afterwards).
pub trait Store: Send + Sync + 'static {
    /// Every stored model, each with a label for logs (e.g. its file path).
    /// Entries that cannot be read come back as errors and are skipped by the caller.
    fn load_all(&self) -> Vec<(String, Result<RobotSpec>)>;
    /// Stores (creates or replaces) a model durably.
    fn save(&self, spec: &RobotSpec) -> Result<()>;
    /// Removes a model durably; removing a missing one is not an error.
    fn delete(&self, name: &str) -> Result<()>;
}

/// Keeps nothing: for tests and throw-away servers.
#[derive(Debug, Default)]
pub struct MemoryStore;

impl Store for MemoryStore {
    fn load_all(&self) -> Vec<(String, Result<RobotSpec>)> {
        Vec::new()
    }
    fn save(&self, _spec: &RobotSpec) -> Result<()> {
        Ok(())
    }
    fn delete(&self, _name: &str) -> Result<()> {
        Ok(())
    }
}

/// One `<name>.json` per robot under `<data_dir>/robots/`. A save writes a hidden
/// temporary file, fsyncs it, renames it over the target and fsyncs the
/// directory, so a crash leaves either the old or the new file, never half of one.
#[derive(Debug)]
pub struct FileStore {
    dir: PathBuf,
}

fn storage(what: &str, path: &Path, e: std::io::Error) -> Error {
    Error::Storage {
        detail: format!("{what} {}: {e}", path.display()),
    }
}

impl FileStore {
    /// Opens (creating if needed) the store under `data_dir`, removing temporary
    /// files a crash may have left.
    pub fn open(data_dir: &Path) -> Result<FileStore> {
        let dir = data_dir.join("robots");
        fs::create_dir_all(&dir).map_err(|e| storage("cannot create", &dir, e))?;
        if let Ok(entries) = fs::read_dir(&dir) {
            for entry in entries.flatten() {
                let name = entry.file_name();
                let name = name.to_string_lossy();
                if name.starts_with('.') && name.contains(".tmp") {
                    tracing::info!(file = %entry.path().display(), "removing temporary file left by an interrupted write");
                    let _ = fs::remove_file(entry.path());
                }
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
    fn load_all(&self) -> Vec<(String, Result<RobotSpec>)> {
        let Ok(entries) = fs::read_dir(&self.dir) else {
            return Vec::new();
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
            .map(|p| {
                let label = p.display().to_string();
                let spec = fs::read(&p)
                    .map_err(|e| storage("cannot read", &p, e))
                    .and_then(|b| Ok(parse_json::<RobotSpec>(&b)?))
                    .and_then(|s| {
                        let stem = p.file_stem().map(|s| s.to_string_lossy().into_owned());
                        if stem.as_deref() == Some(s.name.as_str()) {
                            Ok(s)
                        } else {
                            Err(Error::invalid_field(
                                "name",
                                format!("'{}' does not match the file name", s.name),
                            ))
                        }
                    });
                (label, spec)
            })
            .collect()
    }

    fn save(&self, spec: &RobotSpec) -> Result<()> {
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
            f.sync_all().map_err(|e| storage("cannot sync", &tmp, e))?;
            fs::rename(&tmp, &target).map_err(|e| storage("cannot rename into", &target, e))?;
            self.sync_dir()
        })();
        if result.is_err() {
            let _ = fs::remove_file(&tmp);
        }
        result
    }

    fn delete(&self, name: &str) -> Result<()> {
        let path = self.path_of(name);
        match fs::remove_file(&path) {
            Ok(()) => self.sync_dir(),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(e) => Err(storage("cannot remove", &path, e)),
        }
    }
}
