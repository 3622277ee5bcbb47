//! Raw connections for attacks (HTTP/1.1 by hand, h2c with the `h2` crate)
//! and the server process's memory (`/proc/PID/status`).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// `VmRSS` and `VmHWM` of process `pid`, in MiB. Panics when
/// `/proc/PID/status` cannot be read or lacks a field: a bound on memory must
/// not pass on a reading of 0.
pub(crate) fn rss_mib(pid: u32) -> (u64, u64) {
    let path = format!("/proc/{pid}/status");
    let status = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|kb| kb.parse::<u64>().ok())
            .unwrap_or_else(|| panic!("{path} has no {name} in kB:\n{status}"))
            / 1024
    };
    (field("VmRSS:"), field("VmHWM:"))
}

/// Samples a process's RSS every 50 ms; `finish` gives the highest seen (MiB).
pub(crate) struct RssWatch {
    stop: Arc<AtomicBool>,
    max: Arc<AtomicU64>,
    task: tokio::task::JoinHandle<()>,
    pid: u32,
}

impl RssWatch {
    pub(crate) fn start(pid: u32) -> RssWatch {
        let stop = Arc::new(AtomicBool::new(false));
        let max = Arc::new(AtomicU64::new(0));
        let (s, m) = (stop.clone(), max.clone());
        let task = tokio::spawn(async move {
            while !s.load(Ordering::Acquire) {
                m.fetch_max(rss_mib(pid).0, Ordering::AcqRel);
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        });
        RssWatch {
            stop,
            max,
            task,
            pid,
        }
    }

    /// Highest VmRSS seen, and the process's VmHWM (the kernel's peak, which
    /// no sampling can miss), in MiB. Fails when a sample could not be read.
    pub(crate) async fn finish(self) -> (u64, u64) {
        self.stop.store(true, Ordering::Release);
        self.task
            .await
            .expect("sampling /proc/PID/status failed (see the panic above)");
        let (now, hwm) = rss_mib(self.pid);
        (self.max.load(Ordering::Acquire).max(now), hwm)
    }
}

/// The status code of a response head read off `s` (`None`: closed or not
/// HTTP before a head arrived, or nothing within `within`).
pub(crate) async fn read_status(s: &mut TcpStream, within: Duration) -> Option<u16> {
    let head = read_head(s, within).await?;
    head.split(' ').nth(1).and_then(|c| c.parse().ok())
}

/// The response head (up to the blank line) read off `s`.
pub(crate) async fn read_head(s: &mut TcpStream, within: Duration) -> Option<String> {
    let mut buf = Vec::new();
    let mut byte = [0u8; 1];
    tokio::time::timeout(within, async {
        while !buf.ends_with(b"\r\n\r\n") {
            match s.read(&mut byte).await {
                Ok(1) => buf.push(byte[0]),
                _ => return None,
            }
        }
        Some(String::from_utf8_lossy(&buf).into_owned())
    })
    .await
    .ok()
    .flatten()
}

/// Reads (and discards) until the server ends the connection (EOF or reset);
/// the bytes read, or `None` if it was still open after `within`.
pub(crate) async fn read_to_close(s: &mut TcpStream, within: Duration) -> Option<usize> {
    let mut buf = vec![0u8; 64 << 10];
    let mut total = 0usize;
    tokio::time::timeout(within, async {
        loop {
            match s.read(&mut buf).await {
                Ok(0) | Err(_) => return total,
                Ok(n) => total += n,
            }
        }
    })
    .await
    .ok()
}

/// One raw HTTP/1.1 exchange on a new connection: sends `request` whole and
/// returns the response status and head.
pub(crate) async fn raw_exchange(addr: &str, request: &[u8]) -> (u16, String) {
    let mut s = TcpStream::connect(addr).await.unwrap();
    s.write_all(request).await.unwrap();
    let head = read_head(&mut s, EVENTUALLY_RAW)
        .await
        .unwrap_or_else(|| panic!("no answer to {:?}", String::from_utf8_lossy(request)));
    let status = head.split(' ').nth(1).and_then(|c| c.parse().ok()).unwrap();
    (status, head)
}

const EVENTUALLY_RAW: Duration = Duration::from_secs(10);
