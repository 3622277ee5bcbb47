//! TLS to PostgreSQL: libpq's `sslmode` (and `sslrootcert`) read from the
//! connection string, which the driver (tokio-postgres) does not know past
//! `require`, and the rustls connector that does what the mode says.
//!
//! | `sslmode` | TLS | server certificate |
//! |---|---|---|
//! | `disable` | never | — |
//! | `prefer` (default) | if the server offers it | not checked |
//! | `require` | always | not checked; with a CA file, the chain is (as libpq does) |
//! | `verify-ca` | always | chain to the CA file |
//! | `verify-full` | always | chain to the CA file, and the host name |
//!
//! The CA file is `--database-ca-file`, else the string's `sslrootcert`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rustls::ClientConfig;
use rustls::client::danger::ServerCertVerifier;
use tokio_postgres::config::SslMode as DriverMode;
use tokio_postgres_rustls::MakeRustlsConnect;

use super::pem;
use super::verify::{ChainOnly, Unverified};

/// libpq's `sslmode` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SslMode {
    /// Plain TCP.
    Disable,
    /// TLS if the server offers it, unauthenticated.
    Prefer,
    /// TLS, unauthenticated (unless a CA file is given).
    Require,
    /// TLS, the chain checked.
    VerifyCa,
    /// TLS, the chain and the host name checked.
    VerifyFull,
}

impl SslMode {
    fn parse(s: &str) -> Result<SslMode, String> {
        Ok(match s {
            "disable" => SslMode::Disable,
            "prefer" | "allow" => SslMode::Prefer,
            "require" => SslMode::Require,
            "verify-ca" => SslMode::VerifyCa,
            "verify-full" => SslMode::VerifyFull,
            other => {
                return Err(format!(
                    "sslmode '{other}' in --database-url is not one of disable, prefer, require, verify-ca, verify-full"
                ));
            }
        })
    }

    /// The driver's own setting (it only knows whether to ask for TLS).
    pub fn driver_mode(self) -> DriverMode {
        match self {
            SslMode::Disable => DriverMode::Disable,
            SslMode::Prefer => DriverMode::Prefer,
            SslMode::Require | SslMode::VerifyCa | SslMode::VerifyFull => DriverMode::Require,
        }
    }
}

/// A connection string with its TLS parameters taken out.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SplitUrl {
    /// The rest, for the driver.
    pub url: String,
    /// `sslmode` (default `prefer`, as libpq's).
    pub mode: SslMode,
    /// `sslrootcert`, if given.
    pub root_cert: Option<PathBuf>,
}

/// Takes `sslmode` and `sslrootcert` out of a connection string, in either
/// form (`postgres://…?sslmode=…` or `key=value …`).
///
/// ```
/// use kinserve::tls::postgres::{split_url, SslMode};
/// let s = split_url("postgres://kin@db:5432/kin?sslmode=verify-full&application_name=x").unwrap();
/// assert_eq!(s.mode, SslMode::VerifyFull);
/// assert_eq!(s.url, "postgres://kin@db:5432/kin?application_name=x");
/// let s = split_url("host=db sslmode='verify-ca' sslrootcert=/ca.pem user=kin").unwrap();
/// assert_eq!((s.mode, s.url.as_str()), (SslMode::VerifyCa, "host=db user=kin"));
/// assert_eq!(s.root_cert.unwrap().to_str(), Some("/ca.pem"));
/// ```
pub fn split_url(url: &str) -> Result<SplitUrl, String> {
    let (rest, params) = if url.starts_with("postgres://") || url.starts_with("postgresql://") {
        split_query(url)
    } else {
        split_key_values(url)
    };
    let mut mode = SslMode::Prefer;
    let mut root_cert = None;
    for (key, value) in params {
        match key.as_str() {
            "sslmode" => mode = SslMode::parse(&value)?,
            _ => root_cert = Some(PathBuf::from(value)),
        }
    }
    Ok(SplitUrl {
        url: rest,
        mode,
        root_cert,
    })
}

const TAKEN: [&str; 2] = ["sslmode", "sslrootcert"];

/// URL form: the query's TLS parameters out (values percent-decoded).
fn split_query(url: &str) -> (String, Vec<(String, String)>) {
    let Some((base, query)) = url.split_once('?') else {
        return (url.to_string(), vec![]);
    };
    let (mut kept, mut taken) = (vec![], vec![]);
    for pair in query.split('&') {
        let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
        if TAKEN.contains(&k) {
            taken.push((k.to_string(), percent_decode(v)));
        } else if !pair.is_empty() {
            kept.push(pair);
        }
    }
    let url = match kept.is_empty() {
        true => base.to_string(),
        false => format!("{base}?{}", kept.join("&")),
    };
    (url, taken)
}

fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = bytes
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (bytes[i], hex) {
            (b'%', Some(b)) => {
                out.push(b);
                i += 3;
            }
            (b, _) => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// `key=value` form: the TLS pairs out (values may be single-quoted, with
/// `\'` and `\\` escapes, as libpq allows); the other pairs kept verbatim.
fn split_key_values(s: &str) -> (String, Vec<(String, String)>) {
    let (mut kept, mut taken) = (vec![], vec![]);
    let mut rest = s.trim_start();
    while !rest.is_empty() {
        let (pair, key, value, next) = next_pair(rest);
        if TAKEN.contains(&key.as_str()) {
            taken.push((key, value));
        } else {
            kept.push(pair);
        }
        rest = next.trim_start();
    }
    (kept.join(" "), taken)
}

/// The first `key=value` pair of `s`: its text, key, unquoted value, and what follows.
fn next_pair(s: &str) -> (&str, String, String, &str) {
    let eq = s.find('=').unwrap_or(s.len());
    let key = s[..eq].trim().to_string();
    let after = s[eq.min(s.len())..].strip_prefix('=').unwrap_or("");
    let after = after.trim_start();
    let start_of_value = s.len() - after.len();
    let mut value = String::new();
    let mut chars = after.char_indices();
    let end;
    if after.starts_with('\'') {
        chars.next();
        loop {
            match chars.next() {
                Some((_, '\\')) => value.extend(chars.next().map(|(_, c)| c)),
                Some((i, '\'')) => break end = start_of_value + i + 1,
                Some((_, c)) => value.push(c),
                None => break end = s.len(),
            }
        }
    } else {
        let len = after.find(char::is_whitespace).unwrap_or(after.len());
        value.push_str(&after[..len]);
        end = start_of_value + len;
    }
    (&s[..end], key, value, &s[end..])
}

/// The rustls connector for `mode`, trusting `ca_file` where the mode
/// checks the server's certificate. Errors name the file or the missing option.
pub fn connector(mode: SslMode, ca_file: Option<&Path>) -> Result<MakeRustlsConnect, String> {
    let roots = match ca_file {
        Some(path) => Some(pem::roots_file(path, "database CA file")?),
        None => None,
    };
    let verifier: Arc<dyn ServerCertVerifier> = match (mode, roots) {
        (SslMode::VerifyCa | SslMode::VerifyFull, None) => {
            return Err(
                "sslmode=verify-ca and verify-full need the CA that signs the database's certificate: \
                 --database-ca-file (or sslrootcert= in --database-url)"
                    .into(),
            );
        }
        (SslMode::VerifyFull, Some(roots)) => {
            rustls::client::WebPkiServerVerifier::builder_with_provider(roots, super::provider())
                .build()
                .map_err(|e| e.to_string())?
        }
        (SslMode::VerifyCa | SslMode::Require, Some(roots)) => Arc::new(ChainOnly::new(roots)?),
        (SslMode::Disable | SslMode::Prefer | SslMode::Require, _) => Arc::new(Unverified::new()),
    };
    let config = ClientConfig::builder_with_provider(super::provider())
        .with_safe_default_protocol_versions()
        .map_err(|e| e.to_string())?
        .dangerous()
        .with_custom_certificate_verifier(verifier)
        .with_no_client_auth();
    Ok(MakeRustlsConnect::new(config))
}

/// The refused server certificate among `e` and its causes, if that is
/// what failed (`invalid peer certificate: UnknownIssuer`, ...): a lasting
/// error, worth saying so at once rather than retrying.
pub fn certificate_error(e: &(dyn std::error::Error + 'static)) -> Option<String> {
    let mut cause = Some(e);
    while let Some(e) = cause {
        if let Some(tls @ rustls::Error::InvalidCertificate(_)) = e.downcast_ref::<rustls::Error>()
        {
            return Some(tls.to_string());
        }
        if let Some(found) = e
            .downcast_ref::<std::io::Error>()
            .and_then(|io| io.get_ref())
            .and_then(|inner| certificate_error(inner))
        {
            return Some(found);
        }
        cause = e.source();
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tls_parameters_leave_both_forms_and_the_rest_stays() {
        let s = split_url("postgresql://u:p%40w@h/db?sslrootcert=%2Ftmp%2Fca.pem&sslmode=require")
            .unwrap();
        assert_eq!(s.url, "postgresql://u:p%40w@h/db");
        assert_eq!(s.mode, SslMode::Require);
        assert_eq!(s.root_cert, Some(PathBuf::from("/tmp/ca.pem")));
        let s = split_url("postgres://h/db").unwrap();
        assert_eq!(
            (s.url.as_str(), s.mode),
            ("postgres://h/db", SslMode::Prefer)
        );
        let s = split_url("host=h password='a b\\'c' sslmode=disable port=5432").unwrap();
        assert_eq!(s.url, "host=h password='a b\\'c' port=5432");
        assert_eq!(s.mode, SslMode::Disable);
        assert!(split_url("host=h sslmode=bogus").is_err());
    }

    #[test]
    fn verifying_modes_need_a_ca() {
        let err = connector(SslMode::VerifyFull, None).err().unwrap();
        assert!(err.contains("--database-ca-file"), "{err}");
        assert!(connector(SslMode::Require, None).is_ok());
        let err = connector(SslMode::VerifyCa, Some(Path::new("/nonexistent/ca.pem")))
            .err()
            .unwrap();
        assert!(err.contains("/nonexistent/ca.pem"), "{err}");
    }
}
