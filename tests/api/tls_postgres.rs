//! TLS to PostgreSQL: a private cluster with `ssl = on` and a certificate of
//! a test CA (made here). `sslmode=verify-full` connects (and the
//! connections are TLS, as `pg_stat_ssl` shows); a wrong CA is refused at
//! once with an error that says so; `verify-ca` accepts a certificate for
//! another host name, which `verify-full` refuses; `disable` stays plain.

use std::time::Duration;

use kinserve::App;
use kinserve::config::ServeConfig;

use crate::helpers::tls::*;
use crate::helpers::*;

async fn tls_postgres(test: &'static str, server: Pem) -> Option<Postgres> {
    tokio::task::spawn_blocking(move || Postgres::start_with_tls(test, &server))
        .await
        .unwrap()
}

/// The server's result of building against the database with `mode` and `ca`.
async fn build(pg: &Postgres, mode: &str, ca: &std::path::Path) -> std::io::Result<App> {
    let dir = tempfile::tempdir().unwrap();
    let mut c = ServeConfig::for_tests(dir.path().to_path_buf());
    c.database_url = Some(format!("{}?sslmode={mode}", pg.url()));
    c.tls.database_ca_file = Some(ca.to_path_buf());
    App::build(c).await
}

/// How many of kinserve's connections are (and are not) TLS.
fn kinserve_connections(pg: &Postgres) -> (u32, u32) {
    let out = pg.psql(
        "SELECT count(*) FILTER (WHERE s.ssl), count(*) FILTER (WHERE NOT s.ssl) \
         FROM pg_stat_ssl s JOIN pg_stat_activity a USING (pid) \
         WHERE a.application_name = 'kinserve'",
    );
    let (tls, plain) = out.split_once('|').unwrap();
    (tls.parse().unwrap(), plain.parse().unwrap())
}

#[tokio::test]
async fn verify_full_connects_over_tls_and_a_wrong_ca_is_refused_at_once() {
    let ca = TestCa::new("database CA");
    let Some(pg) = tls_postgres("tls_postgres::verify_full", ca.server("postgres")).await else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let ca_file = dir.path().join("db-ca.pem");
    std::fs::write(&ca_file, ca.pem()).unwrap();
    // verify-full against the right CA (the URL's host is 127.0.0.1, in the certificate).
    let url = format!("{}?sslmode=verify-full", pg.url());
    let app = spawn_app_with(|c| {
        c.database_url = Some(url);
        c.tls.database_ca_file = Some(ca_file.clone());
    })
    .await;
    let put = app
        .client
        .put(format!("{}/v1/robots/over-tls", app.http))
        .json(&planar_model("over-tls"))
        .send()
        .await
        .unwrap();
    assert_eq!(put.status(), 201);
    assert_eq!(
        pg.psql("SELECT count(*) FROM kinserve_robots WHERE name = 'over-tls'"),
        "1"
    );
    let (tls, plain) = kinserve_connections(&pg);
    assert!(tls >= 1 && plain == 0, "TLS {tls}, plain {plain}");
    drop(app);
    // Another CA: refused at once (not after the 30 s start-up retries).
    let wrong = dir.path().join("wrong-ca.pem");
    std::fs::write(&wrong, TestCa::new("wrong CA").pem()).unwrap();
    let started = std::time::Instant::now();
    let err = build(&pg, "verify-full", &wrong)
        .await
        .err()
        .expect("refused");
    let msg = err.to_string();
    assert!(msg.contains("TLS certificate is refused"), "{msg}");
    assert!(
        msg.contains("UnknownIssuer") || msg.contains("issuer"),
        "{msg}"
    );
    assert!(
        started.elapsed() < Duration::from_secs(10),
        "{:?}",
        started.elapsed()
    );
    let err = build(&pg, "verify-ca", &wrong)
        .await
        .err()
        .expect("refused");
    assert!(
        err.to_string().contains("TLS certificate is refused"),
        "{err}"
    );
}

#[tokio::test]
async fn verify_ca_ignores_the_host_name_which_verify_full_checks() {
    let ca = TestCa::new("database CA");
    // A certificate of the right CA, but for another host.
    let Some(pg) = tls_postgres(
        "tls_postgres::verify_ca",
        ca.server_for(&["db.example"], "db.example"),
    )
    .await
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let ca_file = dir.path().join("db-ca.pem");
    std::fs::write(&ca_file, ca.pem()).unwrap();
    let err = build(&pg, "verify-full", &ca_file)
        .await
        .err()
        .expect("refused");
    assert!(
        err.to_string().contains("TLS certificate is refused"),
        "{err}"
    );
    let app = build(&pg, "verify-ca", &ca_file)
        .await
        .expect("verify-ca connects");
    drop(app);
    // disable: plain, even though the server offers TLS.
    let plain_app = spawn_app_with(|c| {
        c.database_url = Some(format!("{}?sslmode=disable", pg.url()));
    })
    .await;
    let (tls, plain) = kinserve_connections(&pg);
    assert!(plain >= 1 && tls == 0, "TLS {tls}, plain {plain}");
    drop(plain_app);
}
