//! TLS, with rustls and its `ring` provider only (no OpenSSL): the listeners'
//! certificates and their reload ([`server`]), the TLS handshake of an
//! accepted connection and the stream it gives ([`stream`]), the client
//! certificate of a connection as the logs name it ([`peer`]), the options
//! ([`options`]), the PostgreSQL client's TLS (`sslmode`, [`postgres`]) and
//! the probe's client ([`probe`]).
//!
//! TLS 1.2 and 1.3 only, with rustls' default cipher suites. Must not depend
//! on the front doors, the service, the registry or the configuration: they
//! depend on this module, and start-up hands it the options as values.

pub mod options;
pub mod peer;
pub mod postgres;
pub mod probe;
pub mod server;
pub mod stream;

mod pem;
mod verify;

use std::sync::Arc;

use rustls::crypto::CryptoProvider;

pub use options::{ClientAuth, TlsOptions};
pub use peer::ClientCert;
pub use server::{Listener, TlsServer};
pub use stream::MaybeTls;

/// The one crypto provider every TLS configuration is built with (ring),
/// named explicitly so that no process-wide default is needed.
pub fn provider() -> Arc<CryptoProvider> {
    Arc::new(rustls::crypto::ring::default_provider())
}
