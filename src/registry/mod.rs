//! Named robot models: built-ins loaded from `robots/`, registered ones kept in
//! a [`Store`]. Reads take a lock-free snapshot; writers are serialised and
//! publish a new snapshot (copy-on-write) only after the store has made the
//! change durable.

pub mod builtin;
mod store;

use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex, OnceLock};

use arc_swap::ArcSwap;

pub use store::{FileStore, MemoryStore, Store};

use crate::error::{Error, Result};
use crate::model::{ModelLimits, Robot};
use crate::telemetry::{PoseCounters, Protocol, robot_label};

/// Where a robot came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// Loaded from the robots directory at start-up; read-only.
    Builtin,
    /// Registered through the API; persisted in the store.
    Registered,
}

/// A robot in the registry.
#[derive(Debug)]
pub struct Entry {
    /// The validated model.
    pub robot: Robot,
    /// Built-in or registered.
    pub origin: Origin,
    /// Its `kinserve_poses_computed_total` counters, resolved on first use.
    poses: OnceLock<PoseCounters>,
}

impl Entry {
    /// An entry for `robot`.
    pub fn new(robot: Robot, origin: Origin) -> Entry {
        Entry {
            robot,
            origin,
            poses: OnceLock::new(),
        }
    }

    /// Counts `n` poses computed for this robot over `protocol`.
    pub fn count_poses(&self, protocol: Protocol, n: u64) {
        self.poses
            .get_or_init(|| {
                let label = robot_label(self.robot.name(), self.origin == Origin::Builtin);
                PoseCounters::new(&label)
            })
            .add(protocol, n);
    }
}

/// How a registration treats an existing robot of the same name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PutMode {
    /// Fail with [`Error::AlreadyExists`] if the name is taken.
    Create,
    /// Replace a registered robot of that name, or create it.
    Upsert,
}

type Map = HashMap<String, Arc<Entry>>;

/// The set of named robots.
pub struct Registry {
    map: ArcSwap<Map>,
    writer: Mutex<()>,
    store: Box<dyn Store>,
    /// Most registered (not built-in) robots; a new one beyond is refused.
    max_registered: usize,
}

impl std::fmt::Debug for Registry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Registry")
            .field("robots", &self.map.load().len())
            .finish()
    }
}

/// Outcome of loading robots at start-up.
#[derive(Debug, Default)]
pub struct LoadReport {
    /// Robots loaded.
    pub loaded: usize,
    /// Files skipped, each with why.
    pub skipped: Vec<(String, Error)>,
}

impl Registry {
    /// An empty registry over `store` (nothing loaded yet).
    pub fn new(store: Box<dyn Store>) -> Registry {
        Registry {
            map: ArcSwap::from_pointee(Map::new()),
            writer: Mutex::new(()),
            store,
            max_registered: usize::MAX,
        }
    }

    /// The same registry, refusing a new registered robot once `max` are held
    /// ([`Error::Full`]); replacing one is always allowed.
    pub fn with_max_registered(mut self, max: usize) -> Registry {
        self.max_registered = max;
        self
    }

    /// Loads the built-in robots, read-only: the ones embedded in the binary,
    /// then every `*.json` in `dir` (when given), which adds robots or
    /// replaces embedded ones of the same name. Invalid files are reported
    /// and skipped.
    pub fn load_builtins(&self, dir: Option<&Path>, limits: &ModelLimits) -> LoadReport {
        let mut report = LoadReport::default();
        let files = builtin::embedded(limits).chain(
            dir.map(|d| builtin::from_dir(d, limits))
                .into_iter()
                .flatten(),
        );
        let _guard = self.writer.lock().unwrap_or_else(|p| p.into_inner());
        let mut map = Map::clone(&self.map.load());
        for (label, result) in files {
            match result {
                Ok(robot) => {
                    map.insert(
                        robot.name().to_string(),
                        Arc::new(Entry::new(robot, Origin::Builtin)),
                    );
                }
                Err(e) => report.skipped.push((label, e)),
            }
        }
        report.loaded = map.values().filter(|e| e.origin == Origin::Builtin).count();
        self.map.store(Arc::new(map));
        report
    }

    /// Loads every robot the store holds. Unreadable or invalid entries, and
    /// entries whose name clashes with a built-in, are reported and skipped (left in place).
    pub fn load_stored(&self, limits: &ModelLimits) -> LoadReport {
        let mut report = LoadReport::default();
        let _guard = self.writer.lock().unwrap_or_else(|p| p.into_inner());
        let mut map = Map::clone(&self.map.load());
        for (label, spec) in self.store.load_all() {
            match spec.and_then(|s| Ok(Robot::from_spec(s, limits)?)) {
                Ok(robot) => {
                    if map
                        .get(robot.name())
                        .is_some_and(|e| e.origin == Origin::Builtin)
                    {
                        let name = robot.name().to_string();
                        report.skipped.push((label, Error::ReadOnly { name }));
                        continue;
                    }
                    map.insert(
                        robot.name().to_string(),
                        Arc::new(Entry::new(robot, Origin::Registered)),
                    );
                    report.loaded += 1;
                }
                Err(e) => report.skipped.push((label, e)),
            }
        }
        self.map.store(Arc::new(map));
        report
    }

    /// The robot called `name`, if any. Lock-free.
    pub fn get(&self, name: &str) -> Option<Arc<Entry>> {
        self.map.load().get(name).cloned()
    }

    /// Every robot, sorted by name.
    pub fn list(&self) -> Vec<Arc<Entry>> {
        let map = self.map.load();
        let mut all: Vec<_> = map.values().cloned().collect();
        all.sort_by(|a, b| a.robot.name().cmp(b.robot.name()));
        all
    }

    /// Number of robots of each origin `(builtin, registered)`.
    pub fn counts(&self) -> (usize, usize) {
        let map = self.map.load();
        let builtin = map.values().filter(|e| e.origin == Origin::Builtin).count();
        (builtin, map.len() - builtin)
    }

    /// Registers `robot`, persisting it first. Returns `true` if it was created,
    /// `false` if it replaced a registered robot. Blocking (store I/O).
    pub fn put(&self, robot: Robot, mode: PutMode) -> Result<bool> {
        let _guard = self.writer.lock().unwrap_or_else(|p| p.into_inner());
        let current = self.map.load_full();
        let name = robot.name().to_string();
        let created = match current.get(&name) {
            Some(e) if e.origin == Origin::Builtin => return Err(Error::ReadOnly { name }),
            Some(_) if mode == PutMode::Create => return Err(Error::AlreadyExists { name }),
            Some(_) => false,
            None => true,
        };
        if created {
            let registered = current
                .values()
                .filter(|e| e.origin == Origin::Registered)
                .count();
            if registered >= self.max_registered {
                return Err(Error::Full {
                    detail: format!(
                        "the registry holds its maximum of {} registered robots: delete one, or start the server with a higher --max-robots",
                        self.max_registered
                    ),
                });
            }
        }
        timed_write("put", || self.store.save(robot.spec()))?;
        let mut map = Map::clone(&current);
        map.insert(name, Arc::new(Entry::new(robot, Origin::Registered)));
        self.map.store(Arc::new(map));
        Ok(created)
    }

    /// Deletes a registered robot, durably. Blocking (store I/O).
    pub fn delete(&self, name: &str) -> Result<()> {
        let _guard = self.writer.lock().unwrap_or_else(|p| p.into_inner());
        let current = self.map.load_full();
        match current.get(name) {
            None => {
                return Err(Error::NotFound {
                    name: name.to_string(),
                    suggestions: Vec::new(),
                });
            }
            Some(e) if e.origin == Origin::Builtin => {
                return Err(Error::ReadOnly {
                    name: name.to_string(),
                });
            }
            Some(_) => {}
        }
        timed_write("delete", || self.store.delete(name))?;
        let mut map = Map::clone(&current);
        map.remove(name);
        self.map.store(Arc::new(map));
        Ok(())
    }
}

/// Runs a durable store write, recording its latency in
/// `kinserve_store_write_duration_seconds{op}`.
fn timed_write<T>(op: &'static str, write: impl FnOnce() -> Result<T>) -> Result<T> {
    let start = std::time::Instant::now();
    let r = write();
    metrics::histogram!("kinserve_store_write_duration_seconds", "op" => op)
        .record(start.elapsed().as_secs_f64());
    r
}
