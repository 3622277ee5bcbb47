//! A well-behaved client on its own loopback address (127.0.0.2) that asks
//! for one FK every 50 ms and `/healthz` every 200 ms while an attack from
//! 127.0.0.1 runs, checking every pose, and the server's CPU and memory read
//! from `/proc`. For the CPU-and-fairness tests.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use crate::helpers::*;

/// The well-behaved client's address (the attackers use 127.0.0.1).
pub(crate) const WITNESS_ADDR: [u8; 4] = [127, 0, 0, 2];

/// Loose bound telling served from stalled (not a performance figure).
pub(crate) const SERVED_WITHIN: Duration = Duration::from_secs(1);

/// A reqwest client whose connections come from `addr`.
pub(crate) fn client_from(addr: [u8; 4]) -> reqwest::Client {
    reqwest::Client::builder()
        .local_address(std::net::IpAddr::from(addr))
        .timeout(Duration::from_secs(30))
        .build()
        .unwrap()
}

/// What the well-behaved client saw: latencies (ms) and what went wrong.
#[derive(Debug, Default)]
pub(crate) struct WitnessReport {
    pub fk_ms: Vec<f64>,
    pub health_ms: Vec<f64>,
    pub failures: Vec<String>,
}

/// The running well-behaved client.
pub(crate) struct Witness {
    stop: Arc<AtomicBool>,
    task: tokio::task::JoinHandle<WitnessReport>,
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

/// Times one request; a failure (status, wrong pose, too slow) is noted.
async fn timed(
    what: &str,
    request: reqwest::RequestBuilder,
    check: impl FnOnce(&Value) -> bool,
    times: &mut Vec<f64>,
    failures: &mut Vec<String>,
) {
    let start = Instant::now();
    let outcome = match request.send().await {
        Ok(resp) if resp.status() == 200 => {
            let body = resp.text().await.unwrap_or_default();
            let v: Value = serde_json::from_str(&body).unwrap_or(Value::String(body));
            if check(&v) {
                Ok(())
            } else {
                Err(format!("{what}: wrong answer {v}"))
            }
        }
        Ok(resp) => Err(format!("{what}: status {}", resp.status())),
        Err(e) => Err(format!("{what}: {e}")),
    };
    let took = start.elapsed();
    times.push(took.as_secs_f64() * 1e3);
    if let Err(e) = outcome {
        failures.push(e);
    } else if took > SERVED_WITHIN {
        failures.push(format!("{what}: took {took:?}"));
    }
}

impl Witness {
    /// Starts asking `http` (the server's REST base URL).
    pub(crate) fn start(http: &str) -> Witness {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let http = http.to_owned();
        let task = tokio::spawn(async move {
            let want = reference_matrices();
            let client = client_from(WITNESS_ADDR);
            let mut r = WitnessReport::default();
            let mut i = 0usize;
            while !flag.load(Ordering::Acquire) || i < CHECK_CONFIGS.len() {
                let k = i % CHECK_CONFIGS.len();
                let q = CHECK_CONFIGS[k];
                let fk = client
                    .post(format!("{http}/v1/robots/puma560/fk"))
                    .json(&json!({"joints": q, "angle_unit": "deg"}));
                let same = |v: &Value| same_matrix(&matrix16(&v["pose"]), &want[k]);
                timed("FK", fk, same, &mut r.fk_ms, &mut r.failures).await;
                if i.is_multiple_of(4) {
                    let health = client.get(format!("{http}/healthz"));
                    let ok = |v: &Value| v.as_str().is_some_and(|s| s.contains("ok"));
                    timed("healthz", health, ok, &mut r.health_ms, &mut r.failures).await;
                }
                i += 1;
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
            r
        });
        Witness { stop, task }
    }

    /// Stops the client, prints its p50/p99 under `attack`, and asserts that
    /// every answer was correct and none slower than [`SERVED_WITHIN`].
    pub(crate) async fn finish(self, attack: &str) -> WitnessReport {
        self.stop.store(true, Ordering::Release);
        let r = self.task.await.expect("witness task");
        let mut fk = r.fk_ms.clone();
        let mut health = r.health_ms.clone();
        fk.sort_by(f64::total_cmp);
        health.sort_by(f64::total_cmp);
        println!(
            "{attack}: well-behaved client FK p50 {:.1} ms p99 {:.1} ms ({} requests); /healthz p50 {:.1} ms p99 {:.1} ms ({})",
            percentile(&fk, 0.5),
            percentile(&fk, 0.99),
            fk.len(),
            percentile(&health, 0.5),
            percentile(&health, 0.99),
            health.len()
        );
        assert!(
            r.failures.is_empty(),
            "{attack}: the well-behaved client saw failures: {:#?}",
            r.failures
        );
        r
    }
}

/// CPU seconds the process `pid` has used (user + system, from `/proc/PID/stat`).
pub(crate) fn cpu_seconds(pid: u32) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).expect("/proc/PID/stat");
    // Fields after the command (which is in parentheses and may hold spaces).
    let rest = &stat[stat.rfind(')').expect("stat format") + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = fields[11].parse::<f64>().unwrap() + fields[12].parse::<f64>().unwrap();
    // USER_HZ is 100 on Linux.
    ticks / 100.0
}

/// Asserts the server is back to idle within 2 s of the attackers leaving:
/// after 2 s, it uses under a quarter of a core over the next second (the
/// well-behaved client's few requests cost far less).
pub(crate) async fn assert_idle_after_attack(server: &Server, attack: &str) {
    tokio::time::sleep(Duration::from_secs(2)).await;
    let before = cpu_seconds(server.pid());
    tokio::time::sleep(Duration::from_secs(1)).await;
    let used = cpu_seconds(server.pid()) - before;
    println!("{attack}: server CPU 2–3 s after the attackers left: {used:.2} s per s");
    assert!(
        used < 0.25,
        "{attack}: the server still uses {used:.2} CPU-seconds per second 2 s after the attackers left"
    );
}

/// Asserts the server's peak resident memory stayed within 300 MiB.
pub(crate) fn assert_memory_bounded(server: &Server, attack: &str) {
    let (now, peak) = server.memory_mib();
    println!("{attack}: server RSS {now:.0} MiB, peak {peak:.0} MiB");
    assert!(peak <= 300.0, "{attack}: peak RSS {peak:.0} MiB > 300 MiB");
}
