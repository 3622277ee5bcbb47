//! The client certificate of a connection, as the access and audit logs name
//! it (its subject, e.g. `CN=planner, O=Example`), and how a request's code
//! learns it: the connection's task runs each request inside [`scope`], and
//! the logs read [`current`].
//!
//! Only certificates the client CA verified during the handshake get here.
//! The subject names a client; it authorizes nothing (registry writes still
//! need the API token when one is configured, see docs/tls.md).

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};

use rustls_pki_types::CertificateDer;

/// Most characters of a subject kept for the logs.
const MAX_SUBJECT_CHARS: usize = 256;

/// A verified client certificate, by its subject.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ClientCert(Arc<str>);

impl ClientCert {
    /// The subject of the end-entity certificate `der` (RFC 4514 style,
    /// control characters replaced by `?`, at most 256 characters).
    ///
    /// ```
    /// # use kinserve::tls::ClientCert;
    /// let key = rcgen::KeyPair::generate().unwrap();
    /// let mut params = rcgen::CertificateParams::new(vec![]).unwrap();
    /// params.distinguished_name.push(rcgen::DnType::CommonName, "planner");
    /// let cert = params.self_signed(&key).unwrap();
    /// assert_eq!(ClientCert::from_der(cert.der()).subject(), "CN=planner");
    /// ```
    pub fn from_der(der: &CertificateDer<'_>) -> ClientCert {
        let subject = match x509_parser::parse_x509_certificate(der.as_ref()) {
            Ok((_, cert)) => cert.subject().to_string(),
            Err(_) => "(unparsable certificate)".to_string(),
        };
        let clean: String = subject
            .chars()
            .map(|c| if c.is_control() { '?' } else { c })
            .take(MAX_SUBJECT_CHARS)
            .collect();
        ClientCert(clean.into())
    }

    /// The subject, as logged.
    pub fn subject(&self) -> &str {
        &self.0
    }
}

tokio::task_local! {
    static CLIENT_CERT: Option<ClientCert>;
}

/// Runs `fut` (one request) with `cert` as its connection's client certificate.
pub fn scope<F: Future>(cert: Option<ClientCert>, fut: F) -> impl Future<Output = F::Output> {
    CLIENT_CERT.scope(cert, fut)
}

/// The client certificate of the request being served, if its connection
/// presented one (`None` outside [`scope`]).
pub fn current() -> Option<ClientCert> {
    CLIENT_CERT.try_with(Clone::clone).ok().flatten()
}

/// The subject of [`current`], for a log field (absent when `None`).
pub fn current_subject() -> Option<Arc<str>> {
    current().map(|c| c.0)
}

/// A tower layer that runs each request inside [`scope`], with the
/// certificate `of` finds in the request's extensions (for the gRPC server,
/// whose connection info tonic puts there).
#[derive(Clone, Copy)]
pub struct ScopeLayer {
    of: fn(&http::Extensions) -> Option<ClientCert>,
}

impl ScopeLayer {
    /// A layer reading the certificate with `of`.
    pub fn new(of: fn(&http::Extensions) -> Option<ClientCert>) -> ScopeLayer {
        ScopeLayer { of }
    }
}

impl<S> tower::Layer<S> for ScopeLayer {
    type Service = Scoped<S>;
    fn layer(&self, inner: S) -> Scoped<S> {
        Scoped { inner, of: self.of }
    }
}

/// The service of [`ScopeLayer`].
#[derive(Clone)]
pub struct Scoped<S> {
    inner: S,
    of: fn(&http::Extensions) -> Option<ClientCert>,
}

impl<S, B> tower::Service<http::Request<B>> for Scoped<S>
where
    S: tower::Service<http::Request<B>>,
    S::Future: Send + 'static,
{
    type Response = S::Response;
    type Error = S::Error;
    type Future = Pin<Box<dyn Future<Output = Result<S::Response, S::Error>> + Send>>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), S::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, req: http::Request<B>) -> Self::Future {
        let cert = (self.of)(req.extensions());
        Box::pin(scope(cert, self.inner.call(req)))
    }
}
