//! Figures for BENCHMARKS.md, not a test (ignored; `scripts/bench-replicas.sh`
//! runs it in release): two `kinserve` processes on one private PostgreSQL;
//! 1,000 replacements through A, each timed from A's answer until B serves
//! the new ETag (B polled over a kept-alive connection), and A's write
//! latency; then the same writes against a file-store server for comparison.

use std::time::{Duration, Instant};

use crate::etags::{etag_of, planar_version, put_with};
use crate::helpers::*;

const CHANGES: usize = 1000;

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

fn summary(what: &str, mut v: Vec<Duration>) -> String {
    v.sort();
    format!(
        "{what}: n={} p50={:.2} ms p90={:.2} ms p99={:.2} ms max={:.2} ms",
        v.len(),
        percentile(&v, 0.5).as_secs_f64() * 1e3,
        percentile(&v, 0.9).as_secs_f64() * 1e3,
        percentile(&v, 0.99).as_secs_f64() * 1e3,
        v.last().unwrap().as_secs_f64() * 1e3
    )
}

/// `CHANGES` replacements of one robot through `base`; returns each write's latency
/// and, when `peer` is given, the delay until `peer` serves the new ETag.
async fn replace_many(base: &str, peer: Option<&str>) -> (Vec<Duration>, Vec<Duration>) {
    let client = reqwest::Client::new();
    let (mut writes, mut delays) = (Vec::new(), Vec::new());
    for i in 0..CHANGES {
        let body = planar_version("bench", 0.1 + (i % 500) as f64 / 1000.0);
        let start = Instant::now();
        let r = put_with(&client, base, "bench", &body, &[]).await;
        let acked = Instant::now();
        assert!(r.status().is_success(), "{}", r.status());
        writes.push(acked - start);
        let Some(peer) = peer else { continue };
        let etag = etag_of(&r);
        loop {
            let g = client
                .get(format!("{peer}/v1/robots/bench"))
                .send()
                .await
                .unwrap();
            if g.status() == 200 && etag_of(&g) == etag {
                break;
            }
            assert!(
                acked.elapsed() < Duration::from_secs(10),
                "change {i} never arrived"
            );
        }
        delays.push(acked.elapsed());
    }
    (writes, delays)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "benchmark: scripts/bench-replicas.sh"]
async fn replicas_bench_propagation_and_write_latency() {
    let Some(pg) = crate::replicas::postgres("replicas_bench").await else {
        return;
    };
    let (da, db) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let url = pg.url();
    let env = [("KINSERVE_DATABASE_URL", url.as_str())];
    let a = start_server(da.path(), &env, None).await;
    let b = start_server(db.path(), &env, None).await;
    let (writes, delays) = replace_many(&a.http, Some(&b.http)).await;
    println!(
        "{}",
        summary("propagation A -> B (from A's answer)", delays)
    );
    println!(
        "{}",
        summary("write latency, PostgreSQL store (PUT replace)", writes)
    );
    let (writes, _) = replace_many(&a.http, None).await;
    println!(
        "{}",
        summary("write latency, PostgreSQL store, nobody polling", writes)
    );
    drop((a, b));
    let df = tempfile::tempdir().unwrap();
    let f = start_server(df.path(), &[], None).await;
    let (writes, _) = replace_many(&f.http, None).await;
    println!(
        "{}",
        summary("write latency, file store (PUT replace, fsync)", writes)
    );
}
