//! The sync task: keeps this replica's snapshot equal to the database. One
//! connection LISTENs on [`CHANNEL`]; each notification names a robot, whose
//! row is read and handed to the [`Applier`] (which ignores it unless its
//! revision is newer than the snapshot's). After every (re)connect and every
//! resync interval all rows are read again, so a missed notification cannot
//! leave the replica stale for long. A heartbeat notices a dead link within
//! seconds; the link state turns down (writes are refused at once), and the
//! task reconnects with backoff. Owns no snapshot: it only reads the database.

use std::sync::Arc;
use std::time::Duration;

use futures_util::StreamExt;
use tokio::sync::mpsc;
use tokio_postgres::{AsyncMessage, Client};
use tokio_util::sync::CancellationToken;

use super::{CHANNEL, Link, SELECT_ALL, SELECT_ONE, change_of};
use crate::registry::Change;

/// Receives the changes read from the database and where they came from
/// (`notify` or `resync`).
pub type Applier = Arc<dyn Fn(Vec<Change>, &'static str) + Send + Sync>;

/// Interval of the heartbeat on the listening connection.
const HEARTBEAT: Duration = Duration::from_secs(1);
/// Longest a heartbeat or a sync query may take before the link counts as dead.
const QUERY_TIMEOUT: Duration = Duration::from_secs(2);
/// First and longest pause between reconnection attempts.
const BACKOFF: (Duration, Duration) = (Duration::from_millis(100), Duration::from_secs(2));

/// The sync task of one replica (see the module docs).
pub struct Syncer {
    driver: super::Driver,
    link: Arc<Link>,
    resync_interval: Duration,
}

/// A [`Syncer`] running with its applier.
struct Running {
    syncer: Syncer,
    apply: Applier,
}

impl std::fmt::Debug for Syncer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Syncer")
            .field("resync_interval", &self.resync_interval)
            .finish()
    }
}

impl Syncer {
    pub(super) fn new(driver: super::Driver, link: Arc<Link>, resync_interval: Duration) -> Syncer {
        Syncer {
            driver,
            link,
            resync_interval: resync_interval.max(Duration::from_millis(100)),
        }
    }

    /// Runs until `shutdown`, handing every change read to `apply`: listen,
    /// resync, follow notifications; on any failure mark the link down and
    /// reconnect with backoff.
    pub async fn run(self, apply: Applier, shutdown: CancellationToken) {
        Running {
            syncer: self,
            apply,
        }
        .run(shutdown)
        .await
    }
}

impl Running {
    async fn run(self, shutdown: CancellationToken) {
        let mut pause = BACKOFF.0;
        loop {
            let error = match self.session(&shutdown, &mut pause).await {
                Ok(()) => return,
                Err(e) => e,
            };
            metrics::counter!("kinserve_store_reconnects_total").increment(1);
            if self.syncer.link.set_up(false) {
                tracing::warn!(error = %error, "lost the database: writes are refused until it is back; reads and FK go on from the snapshot");
            } else {
                tracing::debug!(error = %error, "database still unreachable");
            }
            tokio::select! {
                _ = shutdown.cancelled() => return,
                _ = tokio::time::sleep(pause) => {}
            }
            pause = (pause * 2).min(BACKOFF.1);
        }
    }

    /// One connection's life: `Ok` on shutdown, `Err` when the link fails.
    async fn session(
        &self,
        shutdown: &CancellationToken,
        pause: &mut Duration,
    ) -> Result<(), String> {
        let (client, mut notes) = listen(&self.syncer.driver).await?;
        self.resync(&client).await?;
        *pause = BACKOFF.0;
        if !self.syncer.link.set_up(true) {
            tracing::info!("database reachable: writes accepted, snapshot resynced");
        }
        let mut heartbeat = tokio::time::interval(HEARTBEAT);
        let mut resync = tokio::time::interval(self.syncer.resync_interval);
        resync.reset();
        loop {
            tokio::select! {
                _ = shutdown.cancelled() => return Ok(()),
                note = notes.recv() => match note {
                    Some(payload) => self.follow(&client, &payload).await?,
                    None => return Err("the listening connection closed".into()),
                },
                _ = heartbeat.tick() => {
                    timed(client.simple_query("SELECT 1")).await?;
                    self.syncer.link.mark_synced();
                }
                _ = resync.tick() => self.resync(&client).await?,
            }
        }
    }

    /// Reads every row and applies it.
    async fn resync(&self, client: &Client) -> Result<(), String> {
        let rows = timed(client.query(SELECT_ALL, &[])).await?;
        let changes = rows.iter().filter_map(read).collect();
        (self.apply)(changes, "resync");
        self.syncer.link.mark_synced();
        Ok(())
    }

    /// Reads the row a notification names and applies it.
    async fn follow(&self, client: &Client, payload: &str) -> Result<(), String> {
        let Some(name) = serde_json::from_str::<serde_json::Value>(payload)
            .ok()
            .and_then(|v| v.get("name")?.as_str().map(str::to_string))
        else {
            tracing::warn!(payload, "ignoring a notification that names no robot");
            return Ok(());
        };
        let row = timed(client.query_opt(SELECT_ONE, &[&name])).await?;
        if let Some(change) = row.as_ref().and_then(read) {
            (self.apply)(vec![change], "notify");
        }
        self.syncer.link.mark_synced();
        Ok(())
    }
}

/// A row as a change; unreadable rows are logged and skipped.
fn read(row: &tokio_postgres::Row) -> Option<Change> {
    change_of(row)
        .map_err(|e| tracing::error!(error = %e, "skipping an unreadable robot row"))
        .ok()
}

/// A query with [`QUERY_TIMEOUT`]; errors as text (never the password).
async fn timed<T>(
    query: impl std::future::Future<Output = Result<T, tokio_postgres::Error>>,
) -> Result<T, String> {
    match tokio::time::timeout(QUERY_TIMEOUT, query).await {
        Ok(r) => r.map_err(|e| e.to_string()),
        Err(_) => Err(format!("no answer within {} s", QUERY_TIMEOUT.as_secs())),
    }
}

/// Opens the listening connection: its driver runs in a task that forwards
/// notification payloads; the channel closes when the connection ends.
async fn listen(
    driver: &super::Driver,
) -> Result<(Client, mpsc::UnboundedReceiver<String>), String> {
    let (client, mut connection) = driver.connect().await.map_err(|e| e.to_string())?;
    let (tx, rx) = mpsc::unbounded_channel();
    tokio::spawn(async move {
        let mut messages = futures_util::stream::poll_fn(move |cx| connection.poll_message(cx));
        while let Some(message) = messages.next().await {
            match message {
                Ok(AsyncMessage::Notification(n)) => {
                    if tx.send(n.payload().to_string()).is_err() {
                        return;
                    }
                }
                Ok(_) => {}
                Err(e) => {
                    tracing::debug!(error = %e, "listening connection ended");
                    return;
                }
            }
        }
    });
    timed(client.batch_execute(&format!("LISTEN {CHANNEL}"))).await?;
    Ok((client, rx))
}
