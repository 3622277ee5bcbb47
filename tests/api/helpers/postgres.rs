//! A private PostgreSQL for a test: `initdb` in a temporary directory (as the
//! `postgres` user when the tests run as root: the server refuses root), a
//! free port on 127.0.0.1, password authentication over TCP, stopped (and
//! removed) when dropped. Where PostgreSQL is not installed the tests that
//! need it print SKIPPED, except under CI, where they fail
//! (`kinserve_testkit::skip_unless_ci`).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use super::process::free_port;

/// The password of the test clusters' `kinserve` user.
pub(crate) const PG_PASSWORD: &str = "kin-test-pw-4d1f";

/// A running private PostgreSQL cluster.
pub(crate) struct Postgres {
    bin: PathBuf,
    dir: tempfile::TempDir,
    /// Its TCP port on 127.0.0.1.
    pub port: u16,
    as_postgres: bool,
}

/// The directory of `pg_ctl` and `initdb`: on the PATH, else the newest
/// `/usr/lib/postgresql/<version>/bin` (Debian's layout).
fn pg_bin() -> Option<PathBuf> {
    if let Ok(out) = Command::new("sh")
        .args(["-c", "command -v pg_ctl"])
        .output()
        && out.status.success()
    {
        let path = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
        let real = std::fs::canonicalize(&path).unwrap_or(path);
        return real.parent().map(Path::to_path_buf);
    }
    let mut versions: Vec<(u32, PathBuf)> = std::fs::read_dir("/usr/lib/postgresql")
        .ok()?
        .flatten()
        .filter_map(|e| {
            let v = e.file_name().to_string_lossy().parse().ok()?;
            let bin = e.path().join("bin");
            bin.join("pg_ctl").is_file().then_some((v, bin))
        })
        .collect();
    versions.sort();
    versions.pop().map(|(_, bin)| bin)
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

fn check(what: &str, out: std::io::Result<Output>) {
    let out = out.unwrap_or_else(|e| panic!("{what}: {e}"));
    assert!(
        out.status.success(),
        "{what} failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

impl Postgres {
    /// Starts a fresh cluster; `None` (after printing SKIPPED) when PostgreSQL
    /// is not installed outside CI (under CI: a failure). Blocking (a second or two).
    pub(crate) fn start(test: &str) -> Option<Postgres> {
        Postgres::start_with(test, |_| {})
    }

    /// Starts a fresh cluster with `ssl = on` and `server` (a certificate
    /// and its key, PEM) as its certificate; plain connections still work.
    pub(crate) fn start_with_tls(test: &str, server: &super::tls::Pem) -> Option<Postgres> {
        Postgres::start_with(test, |pg| {
            let data = pg.data();
            std::fs::write(data.join("server.crt"), &server.cert).unwrap();
            std::fs::write(data.join("server.key"), &server.key).unwrap();
            let conf = data.join("postgresql.conf");
            let mut text = std::fs::read_to_string(&conf).unwrap();
            text.push_str(
                "\nssl = on\nssl_cert_file = 'server.crt'\nssl_key_file = 'server.key'\n",
            );
            std::fs::write(&conf, text).unwrap();
            // The server refuses a key others can read.
            let key = data.join("server.key");
            check("chmod", Command::new("chmod").arg("600").arg(&key).output());
            if pg.as_postgres {
                check(
                    "chown",
                    Command::new("chown")
                        .arg("postgres:postgres")
                        .arg(&key)
                        .arg(data.join("server.crt"))
                        .output(),
                );
            }
        })
    }

    /// Starts a fresh cluster, running `prepare` between initdb and the start.
    fn start_with(test: &str, prepare: impl FnOnce(&Postgres)) -> Option<Postgres> {
        let Some(bin) = pg_bin() else {
            kinserve_testkit::skip_unless_ci(
                test,
                "PostgreSQL is not installed",
                "apt-get install postgresql; .ci/run installs it",
            );
            return None;
        };
        let dir = tempfile::tempdir().unwrap();
        let as_postgres = is_root();
        if as_postgres {
            check(
                "chown",
                Command::new("chown")
                    .args(["-R", "postgres:postgres"])
                    .arg(dir.path())
                    .output(),
            );
        }
        let pg = Postgres {
            bin,
            dir,
            port: free_port(),
            as_postgres,
        };
        let pwfile = pg.dir.path().join("pw");
        std::fs::write(&pwfile, PG_PASSWORD).unwrap();
        let data = pg.data();
        check(
            "initdb",
            pg.command("initdb")
                .args(["-U", "kinserve", "-A", "scram-sha-256", "-E", "UTF8"])
                .arg(format!("--pwfile={}", pwfile.display()))
                .arg("-D")
                .arg(&data)
                .output(),
        );
        prepare(&pg);
        pg.start_server();
        Some(pg)
    }

    fn data(&self) -> PathBuf {
        self.dir.path().join("data")
    }

    fn command(&self, program: &str) -> Command {
        let path = self.bin.join(program);
        if self.as_postgres {
            let mut c = Command::new("runuser");
            c.args(["-u", "postgres", "--"]).arg(path);
            c
        } else {
            Command::new(path)
        }
    }

    /// Starts (again) the server on the same port and data.
    pub(crate) fn start_server(&self) {
        let options = format!(
            "-p {} -c listen_addresses=127.0.0.1 -c unix_socket_directories={}",
            self.port,
            self.dir.path().display()
        );
        check(
            "pg_ctl start",
            self.command("pg_ctl")
                .arg("-D")
                .arg(self.data())
                .args(["-o", &options, "-w", "-t", "60", "-l"])
                .arg(self.dir.path().join("log"))
                .arg("start")
                .output(),
        );
    }

    /// Stops the server at once (`-m fast`: open connections are cut).
    pub(crate) fn stop_server(&self) {
        check(
            "pg_ctl stop",
            self.command("pg_ctl")
                .arg("-D")
                .arg(self.data())
                .args(["-m", "fast", "-w", "stop"])
                .output(),
        );
    }

    /// The connection URL with the password.
    pub(crate) fn url(&self) -> String {
        format!(
            "postgres://kinserve:{PG_PASSWORD}@127.0.0.1:{}/postgres",
            self.port
        )
    }

    /// The connection URL without a password (for the password file).
    pub(crate) fn url_without_password(&self) -> String {
        format!("postgres://kinserve@127.0.0.1:{}/postgres", self.port)
    }

    /// Runs SQL with psql; returns its unaligned, tuples-only output.
    pub(crate) fn psql(&self, sql: &str) -> String {
        let out = Command::new(self.bin.join("psql"))
            .arg(self.url())
            .args(["-v", "ON_ERROR_STOP=1", "-At", "-c", sql])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "psql {sql}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).trim().to_string()
    }
}

impl Drop for Postgres {
    fn drop(&mut self) {
        let _ = self
            .command("pg_ctl")
            .arg("-D")
            .arg(self.data())
            .args(["-m", "immediate", "-w", "stop"])
            .output();
    }
}
