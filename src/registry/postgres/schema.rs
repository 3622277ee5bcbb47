//! The database schema: embedded, numbered migrations applied at start-up in
//! one transaction under an advisory lock, so replicas starting together
//! apply each migration exactly once (the others wait, then find it done).
//! Owns the migration list only.

/// The migrations, in order; a number is never reused or changed once released.
const MIGRATIONS: &[(i32, &str)] = &[(1, include_str!("migrations/0001_robots.sql"))];

/// Key of the advisory lock taken while migrating ("kinserve" in ASCII).
const LOCK_KEY: i64 = 0x6b69_6e73_6572_7665;

/// Connects and brings the schema up to date. Errors are the driver's (they
/// never contain the password).
pub(super) async fn migrate(driver: &super::Driver) -> Result<(), tokio_postgres::Error> {
    let (mut client, connection) = driver.connect().await?;
    let task = tokio::spawn(connection);
    let result = apply(&mut client).await;
    drop(client);
    let _ = task.await;
    result
}

async fn apply(client: &mut tokio_postgres::Client) -> Result<(), tokio_postgres::Error> {
    let tx = client.transaction().await?;
    tx.execute("SELECT pg_advisory_xact_lock($1)", &[&LOCK_KEY])
        .await?;
    tx.batch_execute(
        "CREATE TABLE IF NOT EXISTS kinserve_schema_migrations (\
           version integer PRIMARY KEY, applied_at timestamptz NOT NULL DEFAULT now())",
    )
    .await?;
    let mut done = Vec::new();
    for row in tx
        .query("SELECT version FROM kinserve_schema_migrations", &[])
        .await?
    {
        done.push(row.try_get::<_, i32>(0)?);
    }
    for (version, sql) in MIGRATIONS {
        if done.contains(version) {
            continue;
        }
        tx.batch_execute(sql).await?;
        tx.execute(
            "INSERT INTO kinserve_schema_migrations (version) VALUES ($1)",
            &[version],
        )
        .await?;
        tracing::info!(version, "database migration applied");
    }
    tx.commit().await
}
