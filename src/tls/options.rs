//! The TLS options of `kinserve serve` (flattened into the server's
//! configuration; each has a `KINSERVE_*` env twin), and their checks.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, ValueEnum};

/// Whether a client must present a certificate (with `--tls-client-ca`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum ClientAuth {
    /// Every client presents a certificate the client CA signed; others are
    /// refused during the handshake.
    #[default]
    Require,
    /// A client may present one (checked against the client CA; a bad one
    /// is refused) or none.
    Optional,
}

/// TLS on both listeners, and the database's CA.
#[derive(Clone, Debug, Args)]
pub struct TlsOptions {
    /// Serve TLS on both listeners (REST: ALPN h2 and http/1.1; gRPC: h2)
    /// with this certificate chain (PEM, leaf first). Needs --tls-key.
    /// Re-read when the file changes and on SIGHUP.
    #[arg(long, env = "KINSERVE_TLS_CERT")]
    pub tls_cert: Option<PathBuf>,
    /// The private key of --tls-cert (PEM: PKCS#8, PKCS#1 or SEC1).
    #[arg(long, env = "KINSERVE_TLS_KEY")]
    pub tls_key: Option<PathBuf>,
    /// CA certificates (PEM) that sign client certificates: clients must
    /// present one (see --tls-client-auth). Needs --tls-cert.
    #[arg(long, env = "KINSERVE_TLS_CLIENT_CA")]
    pub tls_client_ca: Option<PathBuf>,
    /// With --tls-client-ca: `require` a client certificate, or accept
    /// clients without one (`optional`; one presented must still be valid).
    #[arg(long, env = "KINSERVE_TLS_CLIENT_AUTH", value_enum, default_value_t = ClientAuth::Require)]
    pub tls_client_auth: ClientAuth,
    /// How often the certificate, key and client CA files are checked for
    /// changes (0: only on SIGHUP). A change that does not load keeps the
    /// previous certificate and logs a warning.
    #[arg(long, env = "KINSERVE_TLS_RELOAD_INTERVAL", default_value = "5s", value_parser = kinserve_api::parse_duration)]
    pub tls_reload_interval: Duration,
    /// CA certificates (PEM) the database's certificate must chain to, for
    /// `sslmode=verify-ca` and `verify-full` in --database-url (with
    /// `sslmode=require` it makes the chain checked too, as libpq does).
    #[arg(long, env = "KINSERVE_DATABASE_CA_FILE")]
    pub database_ca_file: Option<PathBuf>,
}

impl TlsOptions {
    /// Whether the listeners serve TLS.
    pub fn enabled(&self) -> bool {
        self.tls_cert.is_some()
    }

    /// The combinations clap cannot check: a client CA without a
    /// certificate, `optional` without a client CA.
    pub fn check(&self) -> Result<(), String> {
        if self.tls_cert.is_some() != self.tls_key.is_some() {
            return Err("--tls-cert and --tls-key go together".into());
        }
        if self.tls_client_ca.is_some() && self.tls_cert.is_none() {
            return Err("--tls-client-ca needs --tls-cert and --tls-key".into());
        }
        if self.tls_client_auth == ClientAuth::Optional && self.tls_client_ca.is_none() {
            return Err("--tls-client-auth optional needs --tls-client-ca".into());
        }
        Ok(())
    }
}
