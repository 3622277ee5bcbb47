//! The gRPC adapter (tonic): `kinematics.v1.KinematicsService`, health and
//! reflection, split by role: `server` sets up the listener and its layers,
//! `methods` answers each call, `fk_stream` runs the bidirectional FK stream
//! and `stream` answers its messages;
//! `status` maps [`Error`] to gRPC statuses. The generated types and the
//! conversions to and from the model's requests live in `kinserve-api`
//! (re-exported here as [`pb`]).
//!
//! Depends on the service, the budgets and `kinserve-api`; nothing here is REST.

mod buffered;
mod fk_stream;
mod grpc_metrics;
mod methods;
mod oversize;
mod server;
pub mod status;
mod stream;
mod streams;

use std::sync::Arc;
use std::time::Duration;

use tokio_util::sync::CancellationToken;
use tonic::{Request, Status};

use crate::api::budget::StreamBudget;
use crate::compute::{ClientId, FairBudget, FairPermit};
use crate::error::Error;
use crate::service::Service;

pub use kinserve_api::pb;
pub use server::{DEFAULT_STREAM_WINDOW, Lifecycle, connection_window, serve};

/// What the gRPC adapter is configured with (start-up builds it from the
/// command line; the adapter never sees the command line itself).
#[derive(Clone, Debug)]
pub struct GrpcSettings {
    /// Largest message a client may send, in bytes.
    pub max_message_bytes: usize,
    /// Largest URDF document `ImportUrdf` converts, in bytes: REST's body
    /// limit (`--max-body-bytes`), so both front doors bound the conversion's
    /// work alike (it is linear in the document's joints).
    pub max_document_bytes: usize,
    /// Longest time a unary call may take.
    pub request_timeout: Duration,
    /// A stream that makes no progress in either direction (no message from
    /// the client, no reply taken by it) for this long is closed.
    pub stream_idle_timeout: Duration,
    /// A stream whose client has sent no message this long after it opened
    /// is closed (at most the idle timeout).
    pub stream_first_message_timeout: Duration,
    /// One access-log line per call (target `kinserve::access`).
    pub access_log: bool,
    /// Whether the last `x-forwarded-for` metadata address names the client
    /// (the peer is the operator's proxy).
    pub trust_forwarded_for: bool,
    /// HTTP/2 receive window of each call, in bytes (`--grpc-stream-window`);
    /// the connection window follows from it ([`connection_window`]).
    pub stream_window: u32,
}

/// The gRPC service over the shared [`Service`].
#[derive(Clone)]
pub struct GrpcService {
    service: Arc<Service>,
    settings: Arc<GrpcSettings>,
    permits: FairBudget,
    streams: StreamBudget,
    shutdown: CancellationToken,
}

/// The `authorization` metadata value of a request, if readable.
/// Two or more values are malformed: which one counts would be a guess.
fn authorization<T>(req: &Request<T>) -> Result<Option<&str>, Error> {
    let mut all = req.metadata().get_all("authorization").iter();
    let first = all.next();
    if all.next().is_some() {
        return Err(Error::malformed_field(
            "authorization",
            "send one authorization metadata value, not several",
        ));
    }
    Ok(first.and_then(|v| v.to_str().ok()))
}

impl GrpcService {
    /// The call's client and one of its request permits, or
    /// `RESOURCE_EXHAUSTED` at once when none is free.
    fn admit<T>(&self, req: &Request<T>) -> Result<(ClientId, FairPermit), Status> {
        let client = self.client(req);
        let permit = self.permits.try_acquire(client).map_err(|e| {
            metrics::counter!("kinserve_grpc_rejected_total", "reason" => "overloaded")
                .increment(1);
            Status::from(e)
        })?;
        Ok((client, permit))
    }

    /// The call's client: the connection's peer, or the last
    /// `x-forwarded-for` address behind a trusted proxy.
    fn client<T>(&self, req: &Request<T>) -> ClientId {
        let peer = req
            .extensions()
            .get::<streams::GrpcConnInfo>()
            .and_then(|c| c.peer);
        let forwarded = req
            .metadata()
            .get_all("x-forwarded-for")
            .iter()
            .next_back()
            .and_then(|v| v.to_str().ok());
        ClientId::resolve(peer, forwarded, self.settings.trust_forwarded_for)
    }
}
