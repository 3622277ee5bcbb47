//! The PostgreSQL store: registered robots in one table shared by every
//! replica (`--database-url`). Owns the connection settings (the password
//! never leaves them), the pool, the schema (module `schema`), conditional writes
//! (the row is locked, checked and changed in one transaction that also sends
//! the NOTIFY, committed before the write is acknowledged) and the link state
//! the sync task ([`sync`]) keeps. Must not depend on the registry's snapshot,
//! the service or the front doors: changes learnt from the database leave
//! through [`sync::Applier`].
//!
//! A create also checks the cap on registered robots against the database
//! itself (under an advisory lock, so creates on different replicas are
//! counted one after the other): replicas creating at the same moment cannot
//! overshoot it together.
//!
//! The [`Store`] methods block (they run on the blocking pool and drive the
//! async driver with the runtime handle), give up after [`WRITE_TIMEOUT`], and
//! fail at once while the sync task knows the database to be unreachable.

mod schema;
pub mod sync;

use std::future::Future;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime};

use deadpool_postgres::{Manager, ManagerConfig, Pool, RecyclingMethod, Runtime};
use tokio_postgres::Row;
use tokio_postgres::error::SqlState;

use super::Change;
use super::store::{Record, Saved, Store, StoreHealth};
use super::version::{Condition, Version};
use crate::error::{Error, Result};
use crate::model::RobotSpec;

/// The NOTIFY channel every write announces itself on.
pub const CHANNEL: &str = "kinserve_robots";
/// Longest a write may take before it is answered 503 (store unavailable).
pub const WRITE_TIMEOUT: Duration = Duration::from_millis(1500);
/// Longest a connection attempt may take.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(1);
/// How long start-up keeps trying to reach the database before giving up.
const STARTUP_TIMEOUT: Duration = Duration::from_secs(30);
/// Connections in the write pool.
const POOL_SIZE: usize = 8;
/// Key of the advisory lock a create holds while it counts and inserts
/// ("kinsrcap" in ASCII).
const CAP_LOCK_KEY: i64 = 0x6b69_6e73_7263_6170;

/// How to reach the database. `Debug` never shows the URL.
#[derive(Clone)]
pub struct PgSettings {
    /// `postgres://user:password@host:port/db` or the `key=value` form.
    pub url: String,
    /// A file whose first line is the password (replaces the URL's).
    pub password_file: Option<PathBuf>,
    /// The CA the database's certificate must chain to (`sslmode=verify-ca`,
    /// `verify-full`; replaces the URL's `sslrootcert`).
    pub ca_file: Option<PathBuf>,
    /// Interval of the full resync (besides the one after every reconnect).
    pub resync_interval: Duration,
}

impl std::fmt::Debug for PgSettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PgSettings")
            .field("url", &"<redacted>")
            .field("password_file", &self.password_file)
            .field("ca_file", &self.ca_file)
            .field("resync_interval", &self.resync_interval)
            .finish()
    }
}

impl PgSettings {
    /// The driver configuration: the URL, the password file, timeouts and
    /// keepalives (a dead link is noticed within seconds), and TLS as the
    /// URL's `sslmode` says (`crate::tls::postgres`). Errors never quote the URL.
    fn driver_config(&self) -> std::result::Result<Driver, String> {
        let split = crate::tls::postgres::split_url(&self.url)?;
        let ca_file = self.ca_file.as_ref().or(split.root_cert.as_ref());
        let tls = crate::tls::postgres::connector(split.mode, ca_file.map(PathBuf::as_path))?;
        let mut c: tokio_postgres::Config = split.url.parse().map_err(|_| {
            "--database-url is not a PostgreSQL connection string (postgres://user:password@host:port/db)".to_string()
        })?;
        if let Some(path) = &self.password_file {
            let text = std::fs::read_to_string(path).map_err(|e| {
                format!(
                    "cannot read the database password file {}: {e}",
                    path.display()
                )
            })?;
            c.password(text.lines().next().unwrap_or("").trim_end());
        }
        c.connect_timeout(CONNECT_TIMEOUT)
            .tcp_user_timeout(Duration::from_secs(5))
            .keepalives_idle(Duration::from_secs(10))
            .application_name("kinserve")
            .ssl_mode(split.mode.driver_mode());
        Ok(Driver { config: c, tls })
    }
}

/// A connection of [`Driver::connect`] (its driver half).
pub(crate) type Connection = tokio_postgres::Connection<
    tokio_postgres::Socket,
    <tokio_postgres_rustls::MakeRustlsConnect as tokio_postgres::tls::MakeTlsConnect<
        tokio_postgres::Socket,
    >>::Stream,
>;

/// How to connect: the driver's configuration and its TLS connector.
#[derive(Clone)]
pub(crate) struct Driver {
    config: tokio_postgres::Config,
    tls: tokio_postgres_rustls::MakeRustlsConnect,
}

impl Driver {
    /// Opens one connection.
    pub(crate) async fn connect(
        &self,
    ) -> std::result::Result<(tokio_postgres::Client, Connection), tokio_postgres::Error> {
        self.config.connect(self.tls.clone()).await
    }
}

/// Whether the database is reachable, and when the snapshot was last known
/// to equal it; shared by the store and its sync task.
#[derive(Debug)]
pub(crate) struct Link {
    up: AtomicBool,
    synced_at: Mutex<Instant>,
}

impl Link {
    fn new() -> Link {
        Link {
            up: AtomicBool::new(true),
            synced_at: Mutex::new(Instant::now()),
        }
    }

    pub(crate) fn is_up(&self) -> bool {
        self.up.load(Ordering::Acquire)
    }

    /// Sets the state; returns the previous one.
    pub(crate) fn set_up(&self, up: bool) -> bool {
        self.up.swap(up, Ordering::AcqRel)
    }

    pub(crate) fn mark_synced(&self) {
        *self.synced_at.lock().unwrap_or_else(|p| p.into_inner()) = Instant::now();
    }

    fn snapshot_age(&self) -> Duration {
        self.synced_at
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .elapsed()
    }
}

/// The PostgreSQL [`Store`].
pub struct PgStore {
    pool: Pool,
    driver: Driver,
    runtime: tokio::runtime::Handle,
    link: Arc<Link>,
    /// Most live robots in the database (`usize::MAX`: no check).
    max_registered: usize,
}

impl std::fmt::Debug for PgStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PgStore").field("link", &self.link).finish()
    }
}

fn unavailable(detail: impl Into<String>) -> Error {
    Error::StoreUnavailable {
        detail: detail.into(),
    }
}

/// A driver or pool error as the client sees it (the cause goes to the log only).
fn db_error(e: impl std::fmt::Display) -> Error {
    tracing::warn!(error = %e, "database request failed");
    unavailable("the database did not complete the request; nothing was acknowledged")
}

impl PgStore {
    /// Connects (retrying for up to 30 s while the database is not there yet),
    /// applies the embedded migrations under an advisory lock, and opens the
    /// write pool. Call inside the runtime.
    pub async fn connect(settings: &PgSettings) -> std::result::Result<PgStore, String> {
        let driver = settings.driver_config()?;
        let deadline = Instant::now() + STARTUP_TIMEOUT;
        let mut pause = Duration::from_millis(100);
        loop {
            match schema::migrate(&driver).await {
                Ok(()) => break,
                // A refused certificate stays refused: say so now, not in 30 s.
                Err(e) if crate::tls::postgres::certificate_error(&e).is_some() => {
                    let why = crate::tls::postgres::certificate_error(&e).unwrap_or_default();
                    return Err(format!(
                        "the database's TLS certificate is refused ({why}): check --database-ca-file \
                         (or sslrootcert) and, with sslmode=verify-full, the host name in --database-url"
                    ));
                }
                Err(e) if Instant::now() < deadline => {
                    tracing::warn!(error = %e, "cannot prepare the database yet; retrying");
                    tokio::time::sleep(pause).await;
                    pause = (pause * 2).min(Duration::from_secs(2));
                }
                Err(e) => {
                    return Err(format!(
                        "cannot prepare the database within {}s: {e}",
                        STARTUP_TIMEOUT.as_secs()
                    ));
                }
            }
        }
        let manager = Manager::from_config(
            driver.config.clone(),
            driver.tls.clone(),
            ManagerConfig {
                recycling_method: RecyclingMethod::Fast,
            },
        );
        let pool = Pool::builder(manager)
            .max_size(POOL_SIZE)
            .runtime(Runtime::Tokio1)
            .wait_timeout(Some(WRITE_TIMEOUT))
            .create_timeout(Some(CONNECT_TIMEOUT))
            .recycle_timeout(Some(CONNECT_TIMEOUT))
            .build()
            .map_err(|e| format!("cannot build the database pool: {e}"))?;
        Ok(PgStore {
            pool,
            driver,
            runtime: tokio::runtime::Handle::current(),
            link: Arc::new(Link::new()),
            max_registered: usize::MAX,
        })
    }

    /// The task that keeps this replica's snapshot in step (see [`sync`]).
    pub fn syncer(&self, resync_interval: Duration) -> sync::Syncer {
        sync::Syncer::new(self.driver.clone(), self.link.clone(), resync_interval)
    }

    /// Runs `fut` on the runtime from a blocking thread: at once
    /// [`Error::StoreUnavailable`] while the link is down, and after
    /// [`WRITE_TIMEOUT`] at the latest.
    fn block<T>(&self, fut: impl Future<Output = Result<T>>) -> Result<T> {
        if !self.link.is_up() {
            return Err(unavailable(
                "the database is unreachable; reconnecting in the background (reads and FK go on)",
            ));
        }
        self.runtime.block_on(async {
            tokio::time::timeout(WRITE_TIMEOUT, fut)
                .await
                .unwrap_or_else(|_| {
                    Err(unavailable(format!(
                        "the database did not answer within {} ms; the write may or may not have been committed: read the robot again",
                        WRITE_TIMEOUT.as_millis()
                    )))
                })
        })
    }

    async fn save_async(&self, spec: &RobotSpec, cond: &Condition) -> Result<Saved> {
        let model = serde_json::to_value(spec).map_err(|e| Error::Internal {
            detail: e.to_string(),
        })?;
        // A create that loses a race for a new name sees the row on its second try.
        for _ in 0..2 {
            if let Some(saved) = self.try_save(&spec.name, &model, cond).await? {
                return Ok(saved);
            }
        }
        Err(unavailable(
            "concurrent writes kept racing for this name; retry",
        ))
    }

    /// One transaction: lock the row, check `cond`, write, NOTIFY, commit.
    /// `None`: a concurrent transaction created the name first (retry).
    async fn try_save(
        &self,
        name: &str,
        model: &serde_json::Value,
        cond: &Condition,
    ) -> Result<Option<Saved>> {
        let mut client = self.pool.get().await.map_err(db_error)?;
        let tx = client.transaction().await.map_err(db_error)?;
        let current = locked_row(&tx, name).await?;
        cond.check(name, current.and_then(live_revision))?;
        if current.and_then(live_revision).is_none() {
            self.check_cap(&tx).await?;
        }
        let row = match current {
            Some(_) => tx.query_one(UPDATE, &[&name, model]).await,
            None => match tx.query_one(INSERT, &[&name, model]).await {
                Err(e) if e.code() == Some(&SqlState::UNIQUE_VIOLATION) => return Ok(None),
                r => r,
            },
        }
        .map_err(db_error)?;
        let version = version_of(&row)?;
        notify(&tx, name, version.revision).await?;
        tx.commit().await.map_err(db_error)?;
        Ok(Some(Saved {
            version,
            created: current.and_then(live_revision).is_none(),
        }))
    }

    /// Refuses a create once the database holds the cap of live robots. The
    /// advisory lock (held to the end of the transaction) orders the creates
    /// of every replica, so each counts the ones committed before it.
    async fn check_cap(&self, tx: &tokio_postgres::Transaction<'_>) -> Result<()> {
        if self.max_registered == usize::MAX {
            return Ok(());
        }
        tx.execute("SELECT pg_advisory_xact_lock($1)", &[&CAP_LOCK_KEY])
            .await
            .map_err(db_error)?;
        let live: i64 = tx
            .query_one(COUNT_LIVE, &[])
            .await
            .and_then(|r| r.try_get(0))
            .map_err(db_error)?;
        if usize::try_from(live).unwrap_or(usize::MAX) >= self.max_registered {
            return Err(Error::Full {
                detail: format!(
                    "the shared registry holds its maximum of {} registered robots (counted in the database, over every replica): delete one, or start the replicas with a higher --max-robots",
                    self.max_registered
                ),
            });
        }
        Ok(())
    }

    async fn delete_async(&self, name: &str, cond: &Condition) -> Result<Version> {
        let mut client = self.pool.get().await.map_err(db_error)?;
        let tx = client.transaction().await.map_err(db_error)?;
        let current = locked_row(&tx, name).await?.and_then(live_revision);
        if current.is_none() {
            return Err(Error::NotFound {
                name: name.to_string(),
                suggestions: Vec::new(),
            });
        }
        cond.check(name, current)?;
        let row = tx.query_one(TOMBSTONE, &[&name]).await.map_err(db_error)?;
        let version = version_of(&row)?;
        notify(&tx, name, version.revision).await?;
        tx.commit().await.map_err(db_error)?;
        Ok(version)
    }
}

const SELECT_FOR_UPDATE: &str =
    "SELECT revision, deleted FROM kinserve_robots WHERE name = $1 FOR UPDATE";
const UPDATE: &str = "UPDATE kinserve_robots SET model = $2, deleted = false, \
     revision = nextval('kinserve_robot_revision'), updated_at = now(), \
     created_at = CASE WHEN deleted THEN now() ELSE created_at END \
     WHERE name = $1 RETURNING revision, updated_at";
const INSERT: &str = "INSERT INTO kinserve_robots (name, model, revision) \
     VALUES ($1, $2, nextval('kinserve_robot_revision')) RETURNING revision, updated_at";
const COUNT_LIVE: &str = "SELECT count(*) FROM kinserve_robots WHERE NOT deleted";
const TOMBSTONE: &str = "UPDATE kinserve_robots SET model = NULL, deleted = true, \
     revision = nextval('kinserve_robot_revision'), updated_at = now() \
     WHERE name = $1 RETURNING revision, updated_at";
/// Every row, tombstones included, in the column order [`change_of`] reads.
pub(crate) const SELECT_ALL: &str =
    "SELECT name, model, revision, deleted, updated_at FROM kinserve_robots";
/// One row, in the column order [`change_of`] reads.
pub(crate) const SELECT_ONE: &str =
    "SELECT name, model, revision, deleted, updated_at FROM kinserve_robots WHERE name = $1";

/// The locked row of `name`: `(revision, deleted)`, `None` if there is none.
async fn locked_row(
    tx: &tokio_postgres::Transaction<'_>,
    name: &str,
) -> Result<Option<(i64, bool)>> {
    let row = tx
        .query_opt(SELECT_FOR_UPDATE, &[&name])
        .await
        .map_err(db_error)?;
    row.map(|r| {
        Ok((
            r.try_get(0).map_err(db_error)?,
            r.try_get(1).map_err(db_error)?,
        ))
    })
    .transpose()
}

/// The revision of a row that holds a robot (not a tombstone).
fn live_revision((revision, deleted): (i64, bool)) -> Option<u64> {
    (!deleted).then(|| to_revision(revision))
}

fn to_revision(r: i64) -> u64 {
    u64::try_from(r).unwrap_or(0)
}

fn version_of(row: &Row) -> Result<Version> {
    Ok(Version {
        revision: to_revision(row.try_get(0).map_err(db_error)?),
        updated: row.try_get(1).map_err(db_error)?,
    })
}

/// Announces a change; delivered to every listener when the transaction commits.
async fn notify(tx: &tokio_postgres::Transaction<'_>, name: &str, revision: u64) -> Result<()> {
    let payload = serde_json::json!({"name": name, "revision": revision}).to_string();
    tx.execute("SELECT pg_notify($1, $2)", &[&CHANNEL, &payload])
        .await
        .map_err(db_error)?;
    Ok(())
}

/// A row of [`SELECT_ALL`] / [`SELECT_ONE`] as a change.
pub(crate) fn change_of(row: &Row) -> Result<Change> {
    let name: String = row.try_get(0).map_err(db_error)?;
    let revision = to_revision(row.try_get(2).map_err(db_error)?);
    if row.try_get::<_, bool>(3).map_err(db_error)? {
        return Ok(Change::Deleted { name, revision });
    }
    let model: serde_json::Value = row.try_get(1).map_err(db_error)?;
    let updated: SystemTime = row.try_get(4).map_err(db_error)?;
    let spec: RobotSpec = serde_json::from_value(model).map_err(|e| {
        Error::malformed_field(
            "model",
            format!("stored model of '{name}' is not a robot: {e}"),
        )
    })?;
    if spec.name != name {
        return Err(Error::invalid_field(
            "name",
            format!("stored model '{}' is in the row of '{name}'", spec.name),
        ));
    }
    Ok(Change::Put(Box::new(Record {
        spec,
        version: Version { revision, updated },
    })))
}

impl Store for PgStore {
    fn load_all(&self) -> Vec<(String, Result<Record>)> {
        let rows = self.runtime.block_on(async {
            let client = self.pool.get().await.map_err(db_error)?;
            client.query(SELECT_ALL, &[]).await.map_err(db_error)
        });
        match rows {
            Err(e) => vec![("database".to_string(), Err(e))],
            Ok(rows) => rows
                .iter()
                .filter_map(|row| {
                    let label = row
                        .try_get::<_, String>(0)
                        .map_or_else(|_| "database row".into(), |n| format!("database row '{n}'"));
                    match change_of(row) {
                        Ok(Change::Put(r)) => Some((label, Ok(*r))),
                        Ok(Change::Deleted { .. }) => None,
                        Err(e) => Some((label, Err(e))),
                    }
                })
                .collect(),
        }
    }

    fn save(&self, spec: &RobotSpec, cond: &Condition, _known: Option<u64>) -> Result<Saved> {
        self.block(self.save_async(spec, cond))
    }

    fn delete(&self, name: &str, cond: &Condition, _known: Option<u64>) -> Result<Version> {
        self.block(self.delete_async(name, cond))
    }

    fn is_shared(&self) -> bool {
        true
    }

    fn limit_registered(&mut self, max: usize) {
        self.max_registered = max;
    }

    fn health(&self) -> StoreHealth {
        StoreHealth {
            kind: "postgres",
            up: self.link.is_up(),
            snapshot_age: self.link.snapshot_age(),
        }
    }
}
