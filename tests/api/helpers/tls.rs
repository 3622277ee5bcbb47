//! Test certificates made by the tests (rcgen; nothing is checked in): a CA,
//! server certificates for `localhost` and 127.0.0.1 and client
//! certificates it signs; TLS clients over them: raw HTTP/1.1, HTTP/2 (the
//! `h2` crate), WebSockets and tonic.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use kinserve::api::grpc::pb::kinematics_service_client::KinematicsServiceClient;
use rcgen::{
    BasicConstraints, CertificateParams, CertifiedIssuer, DnType, ExtendedKeyUsagePurpose, IsCa,
    KeyPair, KeyUsagePurpose,
};
use rustls::ClientConfig;
use rustls_pki_types::pem::PemObject;
use rustls_pki_types::{CertificateDer, PrivateKeyDer, ServerName};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_rustls::client::TlsStream;
use tonic::transport::{Channel, Endpoint};

/// A test CA, able to sign server and client certificates.
pub(crate) struct TestCa {
    issuer: CertifiedIssuer<'static, KeyPair>,
}

/// A certificate and its key, PEM.
#[derive(Clone)]
pub(crate) struct Pem {
    pub cert: String,
    pub key: String,
}

impl TestCa {
    /// A new CA named `name`.
    pub(crate) fn new(name: &str) -> TestCa {
        let mut params = CertificateParams::new(vec![]).unwrap();
        params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
        params.distinguished_name.push(DnType::CommonName, name);
        params.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
        let issuer = CertifiedIssuer::self_signed(params, KeyPair::generate().unwrap()).unwrap();
        TestCa { issuer }
    }

    /// The CA certificate, PEM.
    pub(crate) fn pem(&self) -> String {
        self.issuer.pem()
    }

    fn leaf(&self, names: &[&str], cn: &str, usage: ExtendedKeyUsagePurpose) -> Pem {
        let names: Vec<String> = names.iter().map(|n| n.to_string()).collect();
        let mut params = CertificateParams::new(names).unwrap();
        params.distinguished_name.push(DnType::CommonName, cn);
        params
            .distinguished_name
            .push(DnType::OrganizationName, "kinserve tests");
        params.extended_key_usages = vec![usage];
        let key = KeyPair::generate().unwrap();
        let cert = params.signed_by(&key, &self.issuer).unwrap();
        Pem {
            cert: cert.pem(),
            key: key.serialize_pem(),
        }
    }

    /// A server certificate for `localhost` and 127.0.0.1, with common name `cn`.
    pub(crate) fn server(&self, cn: &str) -> Pem {
        self.leaf(
            &["localhost", "127.0.0.1"],
            cn,
            ExtendedKeyUsagePurpose::ServerAuth,
        )
    }

    /// A server certificate for `names` only.
    pub(crate) fn server_for(&self, names: &[&str], cn: &str) -> Pem {
        self.leaf(names, cn, ExtendedKeyUsagePurpose::ServerAuth)
    }

    /// A client certificate with common name `cn`.
    pub(crate) fn client(&self, cn: &str) -> Pem {
        self.leaf(&[], cn, ExtendedKeyUsagePurpose::ClientAuth)
    }
}

/// Writes `pem` as `<stem>.crt` and `<stem>.key` in `dir` (replacing them
/// atomically, as a rotation would); returns both paths.
pub(crate) fn write_pem(dir: &Path, stem: &str, pem: &Pem) -> (PathBuf, PathBuf) {
    let (cert, key) = (
        dir.join(format!("{stem}.crt")),
        dir.join(format!("{stem}.key")),
    );
    for (path, text) in [(&key, &pem.key), (&cert, &pem.cert)] {
        let tmp = path.with_extension("tmp");
        std::fs::write(&tmp, text).unwrap();
        std::fs::rename(&tmp, path).unwrap();
    }
    (cert, key)
}

/// A client configuration trusting `ca_pem`, presenting `client` if given,
/// offering the ALPN protocols `alpn`.
pub(crate) fn client_config(
    ca_pem: &str,
    client: Option<&Pem>,
    alpn: &[&str],
) -> Arc<ClientConfig> {
    let mut roots = rustls::RootCertStore::empty();
    for cert in CertificateDer::pem_slice_iter(ca_pem.as_bytes()) {
        roots.add(cert.unwrap()).unwrap();
    }
    let builder = ClientConfig::builder_with_provider(kinserve::tls::provider())
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_root_certificates(roots);
    let mut config = match client {
        None => builder.with_no_client_auth(),
        Some(p) => builder
            .with_client_auth_cert(
                CertificateDer::pem_slice_iter(p.cert.as_bytes())
                    .map(Result::unwrap)
                    .collect(),
                PrivateKeyDer::from_pem_slice(p.key.as_bytes()).unwrap(),
            )
            .unwrap(),
    };
    config.alpn_protocols = alpn.iter().map(|p| p.as_bytes().to_vec()).collect();
    Arc::new(config)
}

/// `127.0.0.1:PORT` of a `scheme://127.0.0.1:PORT` base URL.
pub(crate) fn host_port(base: &str) -> String {
    base.split("://").nth(1).unwrap_or(base).to_string()
}

/// A TLS connection to `addr` (`127.0.0.1:PORT`) as `localhost`.
pub(crate) async fn tls_connect(
    addr: &str,
    config: Arc<ClientConfig>,
) -> std::io::Result<TlsStream<TcpStream>> {
    let tcp = TcpStream::connect(addr).await?;
    let name = ServerName::try_from("localhost").unwrap();
    tokio_rustls::TlsConnector::from(config)
        .connect(name, tcp)
        .await
}

/// The subject common name of the certificate `tls` was shown.
pub(crate) fn server_cn(tls: &TlsStream<TcpStream>) -> String {
    let der = &tls.get_ref().1.peer_certificates().unwrap()[0];
    kinserve::tls::ClientCert::from_der(der)
        .subject()
        .to_string()
}

/// `GET path` over HTTP/1.1 on a TLS connection (`Connection: close`):
/// the status and the body.
pub(crate) async fn h1_get(mut tls: TlsStream<TcpStream>, path: &str) -> (u16, String) {
    let req = format!("GET {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n");
    tls.write_all(req.as_bytes()).await.unwrap();
    let mut raw = Vec::new();
    // A close without close_notify is an error to rustls; what arrived counts.
    let _ = tls.read_to_end(&mut raw).await;
    let text = String::from_utf8_lossy(&raw).into_owned();
    let status = text
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let body = text
        .split_once("\r\n\r\n")
        .map_or("", |(_, b)| b)
        .to_string();
    (status, body)
}

/// `POST path` with a JSON body over HTTP/1.1 on a TLS connection, with
/// `token` as the bearer token if given: the status.
pub(crate) async fn h1_send(
    mut tls: TlsStream<TcpStream>,
    method: &str,
    path: &str,
    body: &str,
    token: Option<&str>,
) -> u16 {
    let auth = token.map_or(String::new(), |t| format!("Authorization: Bearer {t}\r\n"));
    let req = format!(
        "{method} {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n{auth}Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    );
    tls.write_all(req.as_bytes()).await.unwrap();
    let mut raw = Vec::new();
    let _ = tls.read_to_end(&mut raw).await;
    String::from_utf8_lossy(&raw)
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0)
}

/// A tonic channel to the gRPC listener at `addr` over TLS with `config`.
pub(crate) async fn grpc_tls_channel(
    addr: &str,
    config: Arc<ClientConfig>,
) -> Result<Channel, tonic::transport::Error> {
    let addr = addr.to_string();
    Endpoint::from_shared("http://localhost".to_string())
        .unwrap()
        .connect_with_connector(tower::service_fn(move |_uri| {
            let (addr, config) = (addr.clone(), config.clone());
            async move {
                let tls = tls_connect(&addr, config).await?;
                Ok::<_, std::io::Error>(hyper_util::rt::TokioIo::new(tls))
            }
        }))
        .await
}

/// A gRPC client over TLS.
pub(crate) async fn grpc_tls_client(
    addr: &str,
    config: Arc<ClientConfig>,
) -> KinematicsServiceClient<Channel> {
    KinematicsServiceClient::new(
        grpc_tls_channel(addr, config)
            .await
            .expect("grpc over TLS connects"),
    )
}
