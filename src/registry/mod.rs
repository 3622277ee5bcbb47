//! Named robot models: built-ins loaded from `robots/`, registered ones kept in
//! a [`Store`]. Reads take a lock-free snapshot; writers are serialised and
//! publish a new snapshot (copy-on-write) only after the store has made the
//! change durable. Owns the robot cap (`--max-robots`): a create reserves a
//! slot atomically before its store write and gives it back when the write
//! fails (or once the robot is published), and the name rules that span
//! robots: a registered name may not pass for a built-in's (module `names`,
//! which also answers the suggestions of a 404).

pub mod builtin;
pub mod names;
pub mod postgres;
mod store;
pub mod version;

use std::collections::HashMap;
use std::ops::Deref;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

use arc_swap::ArcSwap;

pub use store::{FileStore, MemoryStore, Record, Saved, Store, StoreHealth};
pub use version::{Condition, Version};

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
    /// The stored version (registered robots only).
    pub version: Option<Version>,
    /// Its entity tag, quotes included: the revision for registered robots,
    /// a content hash for built-ins.
    etag: String,
    /// Its `kinserve_poses_computed_total` counters, resolved on first use.
    poses: OnceLock<PoseCounters>,
    /// Its closed form (or why there is none), computed at most once per
    /// version: a new version is a new entry.
    closed_form: OnceLock<Arc<ClosedFormResult>>,
}

/// A robot's closed form, or why it has none.
pub type ClosedFormResult = std::result::Result<crate::model::ClosedForm, crate::model::ModelError>;

impl Entry {
    /// An entry for `robot` with no stored version (a built-in's ETag is a
    /// hash of its model).
    pub fn new(robot: Robot, origin: Origin) -> Entry {
        let etag = version::content_etag(&serde_json::to_vec(robot.spec()).unwrap_or_default());
        Entry {
            robot,
            origin,
            version: None,
            etag,
            poses: OnceLock::new(),
            closed_form: OnceLock::new(),
        }
    }

    /// A registered robot at `version`.
    pub fn registered(robot: Robot, version: Version) -> Entry {
        Entry {
            robot,
            origin: Origin::Registered,
            etag: version.etag(),
            version: Some(version),
            poses: OnceLock::new(),
            closed_form: OnceLock::new(),
        }
    }

    /// The entity tag, quotes included (`"17"`).
    pub fn etag(&self) -> &str {
        &self.etag
    }

    /// The stored revision (registered robots only).
    pub fn revision(&self) -> Option<u64> {
        self.version.map(|v| v.revision)
    }

    /// Its closed form, computed by the first caller (others wait for it).
    pub fn closed_form(&self) -> Arc<ClosedFormResult> {
        Arc::clone(
            self.closed_form
                .get_or_init(|| Arc::new(crate::model::ClosedForm::of(&self.robot))),
        )
    }

    /// Its closed form if it has been computed.
    pub fn closed_form_if_known(&self) -> Option<Arc<ClosedFormResult>> {
        self.closed_form.get().map(Arc::clone)
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

/// A change of a registered robot learnt from the store (another replica's
/// write, or a resync), applied to the snapshot only if newer than what it holds.
#[derive(Clone, Debug)]
pub enum Change {
    /// Created or replaced.
    Put(Box<Record>),
    /// Deleted at `revision`.
    Deleted {
        /// The robot name.
        name: String,
        /// The revision of the deletion.
        revision: u64,
    },
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

/// One published state of the registry: the robots by name, how many of them
/// are registered, and their name index (built on first use, so at most once
/// per registry change).
#[derive(Debug, Default)]
struct Snapshot {
    robots: Map,
    registered: usize,
    names: OnceLock<names::NameIndex>,
}

impl Snapshot {
    fn new(robots: Map) -> Snapshot {
        let registered = robots
            .values()
            .filter(|e| e.origin == Origin::Registered)
            .count();
        Snapshot {
            robots,
            registered,
            names: OnceLock::new(),
        }
    }

    fn names(&self) -> &names::NameIndex {
        self.names.get_or_init(|| {
            names::NameIndex::build(
                self.robots
                    .values()
                    .map(|e| (e.robot.name(), e.origin == Origin::Builtin)),
            )
        })
    }
}

impl Deref for Snapshot {
    type Target = Map;
    fn deref(&self) -> &Map {
        &self.robots
    }
}

/// A slot of the robot cap held by a create under way; given back on drop
/// (after the robot was published, or when its write failed).
struct Slot<'a>(&'a Mutex<usize>);

impl Drop for Slot<'_> {
    fn drop(&mut self) {
        let mut pending = self.0.lock().unwrap_or_else(|p| p.into_inner());
        *pending = pending.saturating_sub(1);
    }
}

/// Deleted names and the revision of their deletion, so that an older change
/// learnt later does not bring a robot back.
type Tombstones = HashMap<String, u64>;

/// The set of named robots.
pub struct Registry {
    map: ArcSwap<Snapshot>,
    /// Bumped after every new snapshot (see [`Registry::generation`]).
    generation: AtomicU64,
    /// Serialises snapshot updates (and the writes of a local store).
    writer: Mutex<Tombstones>,
    store: Box<dyn Store>,
    /// Most registered (not built-in) robots; a new one beyond is refused.
    max_registered: usize,
    /// Creates under way, each holding a slot of `max_registered`.
    pending: Mutex<usize>,
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
            map: ArcSwap::from_pointee(Snapshot::default()),
            generation: AtomicU64::new(0),
            writer: Mutex::new(Tombstones::new()),
            store,
            max_registered: usize::MAX,
            pending: Mutex::new(0),
        }
    }

    /// The same registry, refusing a new registered robot once `max` are held
    /// ([`Error::Full`]); replacing one is always allowed.
    pub fn with_max_registered(mut self, max: usize) -> Registry {
        self.max_registered = max;
        self.store.limit_registered(max);
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
        let _guard = self.lock();
        let mut map = self.map.load().robots.clone();
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
        self.swap_in(map);
        report
    }

    /// Loads every robot the store holds. Unreadable or invalid entries, and
    /// entries whose name clashes with a built-in, are reported and skipped
    /// (left in place). A store holding more than the cap (written by an
    /// older version, or with a higher `--max-robots`) is loaded whole, with
    /// a warning naming both counts; creates are then refused until deletes
    /// bring it under the cap. Blocking (store I/O).
    pub fn load_stored(&self, limits: &ModelLimits) -> LoadReport {
        let mut report = LoadReport::default();
        for (label, record) in self.store.load_all() {
            match record.and_then(|r| self.apply(Change::Put(Box::new(r)), limits)) {
                Ok(_) => report.loaded += 1,
                Err(e) => report.skipped.push((label, e)),
            }
        }
        let registered = self.map.load().registered;
        if registered > self.max_registered {
            tracing::warn!(
                registered,
                max_robots = self.max_registered,
                "the store holds {registered} registered robots, more than --max-robots {}: all are served, new ones are refused (507) until deletes bring the count under the cap",
                self.max_registered
            );
        }
        report
    }

    /// Applies a change learnt from the store if it is newer than what the
    /// snapshot holds for that name (`Ok(false)`: stale, ignored). A model
    /// that is invalid here (e.g. over this replica's limits), or whose name
    /// is a built-in's, is an error and changes nothing.
    pub fn apply(&self, change: Change, limits: &ModelLimits) -> Result<bool> {
        let (name, revision) = match &change {
            Change::Put(r) => (r.spec.name.as_str(), r.version.revision),
            Change::Deleted { name, revision } => (name.as_str(), *revision),
        };
        if self.known_revision(name).is_some_and(|k| k >= revision) {
            return Ok(false);
        }
        let (name, revision, entry) = match change {
            Change::Put(r) => {
                let r = *r;
                let robot = Robot::from_spec(r.spec, limits)?;
                let name = robot.name().to_string();
                let entry = Arc::new(Entry::registered(robot, r.version));
                (name, r.version.revision, Some(entry))
            }
            Change::Deleted { name, revision } => (name, revision, None),
        };
        let mut guard = self.lock();
        self.publish(&mut guard, &name, revision, entry)
    }

    /// Puts `entry` (or, for `None`, a tombstone) under `name` if `revision`
    /// is newer than the snapshot's; built-ins are never replaced.
    fn publish(
        &self,
        tombstones: &mut MutexGuard<'_, Tombstones>,
        name: &str,
        revision: u64,
        entry: Option<Arc<Entry>>,
    ) -> Result<bool> {
        let current = self.map.load_full();
        let known = match current.get(name) {
            Some(e) if e.origin == Origin::Builtin => {
                return Err(Error::ReadOnly {
                    name: name.to_string(),
                });
            }
            Some(e) => e.revision(),
            None => tombstones.get(name).copied(),
        };
        if known.is_some_and(|k| k >= revision) {
            return Ok(false);
        }
        let mut map = current.robots.clone();
        match entry {
            Some(e) => {
                tombstones.remove(name);
                map.insert(name.to_string(), e);
            }
            None => {
                tombstones.insert(name.to_string(), revision);
                map.remove(name);
            }
        }
        self.swap_in(map);
        Ok(true)
    }

    /// The revision the snapshot holds for `name` (a robot's or a deletion's).
    fn known_revision(&self, name: &str) -> Option<u64> {
        let tombstones = self.lock();
        match self.map.load().get(name) {
            Some(e) => e.revision(),
            None => tombstones.get(name).copied(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Tombstones> {
        self.writer.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// How the store is doing.
    pub fn store_health(&self) -> StoreHealth {
        self.store.health()
    }

    /// The robot called `name`, if any. Lock-free.
    pub fn get(&self, name: &str) -> Option<Arc<Entry>> {
        self.map.load().get(name).cloned()
    }

    /// A number that changes whenever the set of robots may have: read
    /// before [`Registry::get`], an entry got then is still the current one
    /// for its name while the number is the same (a stream's messages look
    /// their robot up once per change, see [`crate::service::RobotCache`]).
    pub fn generation(&self) -> u64 {
        self.generation.load(Ordering::Acquire)
    }

    /// Makes `map` the registry's robots, then moves the generation on.
    fn swap_in(&self, map: Map) {
        self.map.store(Arc::new(Snapshot::new(map)));
        self.generation.fetch_add(1, Ordering::Release);
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
        (map.len() - map.registered, map.registered)
    }

    /// Up to three existing names close to `name`, best first (see
    /// [`names::NameIndex::nearest`]): a bounded amount of work per call, the
    /// index being built once per registry change.
    pub fn nearest_names(&self, name: &str) -> Vec<String> {
        self.map.load().names().nearest(name)
    }

    /// Refuses a new robot whose name passes for a built-in's once case,
    /// `-`, `_` and spaces are ignored (`puma-560` beside `puma560`).
    fn check_lookalike(&self, name: &str) -> Result<()> {
        let snapshot = self.map.load();
        if snapshot.contains_key(name) {
            return Ok(());
        }
        match snapshot.names().builtin_lookalike(name) {
            Some(builtin) => Err(Error::invalid_field(
                "name",
                format!(
                    "looks like the built-in robot '{builtin}' (the same once case, '-', '_' and spaces are ignored): use '{builtin}' itself, or a name that differs in letters or digits"
                ),
            )),
            None => Ok(()),
        }
    }

    /// A slot of the robot cap for a create of `name` (`None`: the name is
    /// registered already, a replacement needs none). The count and the
    /// pending creates are read under one lock, and a slot is given back only
    /// after its robot was published, so concurrent creates never pass the cap.
    fn reserve_slot(&self, name: &str) -> Result<Option<Slot<'_>>> {
        let mut pending = self.pending.lock().unwrap_or_else(|p| p.into_inner());
        let snapshot = self.map.load();
        if snapshot.contains_key(name) {
            return Ok(None);
        }
        if snapshot.registered + *pending >= self.max_registered {
            return Err(Error::Full {
                detail: format!(
                    "the registry holds its maximum of {} registered robots: delete one, or start the server with a higher --max-robots",
                    self.max_registered
                ),
            });
        }
        *pending += 1;
        Ok(Some(Slot(&self.pending)))
    }

    /// Registers `robot` if `cond` holds, persisting it first; returns the
    /// new entry and whether it was created. [`PutMode::Create`] fails with
    /// [`Error::AlreadyExists`] when the name is taken (whatever `cond`).
    /// Blocking (store I/O).
    pub fn put(&self, robot: Robot, mode: PutMode, cond: Condition) -> Result<(Arc<Entry>, bool)> {
        let name = robot.name().to_string();
        let cond = match mode {
            PutMode::Create => Condition::Absent,
            PutMode::Upsert => cond,
        };
        self.check_lookalike(&name)?;
        // Held across the write and its publication; released on return.
        let _slot = self.reserve_slot(&name)?;
        let spec = robot.spec().clone();
        let result = self.write(
            &name,
            "put",
            |known| self.store.save(&spec, &cond, known),
            |saved| {
                let entry = Arc::new(Entry::registered(robot, saved.version));
                (
                    saved.version.revision,
                    Some(entry.clone()),
                    (entry, saved.created),
                )
            },
        );
        match (mode, result) {
            (PutMode::Create, Err(Error::PreconditionFailed { name, .. })) => {
                Err(Error::AlreadyExists { name })
            }
            (_, r) => r,
        }
    }

    /// Deletes a registered robot if `cond` holds, durably. Blocking (store I/O).
    pub fn delete(&self, name: &str, cond: Condition) -> Result<()> {
        self.write(
            name,
            "delete",
            |known| self.store.delete(name, &cond, known),
            |v| (v.revision, None, ()),
        )
    }

    /// One write of `name` to the store, then its publication in the snapshot.
    /// A local store's write runs under the writer lock with the snapshot's
    /// revision as `known`; a shared store arbitrates itself, and the lock is
    /// taken only to publish (a newer change learnt meanwhile wins).
    fn write<S, T>(
        &self,
        name: &str,
        op: &'static str,
        store_write: impl FnOnce(Option<u64>) -> Result<S>,
        outcome: impl FnOnce(S) -> (u64, Option<Arc<Entry>>, T),
    ) -> Result<T> {
        let builtin = |map: &Snapshot| {
            map.get(name)
                .is_some_and(|e| e.origin == Origin::Builtin)
                .then(|| Error::ReadOnly {
                    name: name.to_string(),
                })
        };
        if self.store.is_shared() {
            if let Some(e) = builtin(&self.map.load()) {
                return Err(e);
            }
            let (revision, entry, out) = outcome(timed_write(op, || store_write(None))?);
            let mut guard = self.lock();
            self.publish(&mut guard, name, revision, entry)?;
            return Ok(out);
        }
        let mut guard = self.lock();
        let current = self.map.load_full();
        if let Some(e) = builtin(&current) {
            return Err(e);
        }
        let known = current.get(name).and_then(|e| e.revision());
        let (revision, entry, out) = outcome(timed_write(op, || store_write(known))?);
        self.publish(&mut guard, name, revision, entry)?;
        Ok(out)
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
