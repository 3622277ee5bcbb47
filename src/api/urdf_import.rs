//! URDF import for both front doors: [`crate::service::Service::import_urdf`]
//! (the conversion and its check against the URDF's own FK, a few
//! milliseconds for an arm, more for a long chain) runs on the compute pool
//! under the caller's share, so a large document never stalls the request
//! threads. The model it returns is registered by the caller exactly as a
//! JSON / `RegisterRobot` model is ([`crate::service::Service::register`]).
//! Depends on the service and the model only.

use crate::compute::ClientId;
use crate::error::Error;
use crate::model::{RobotSpec, UrdfImport};
use crate::service::Service;

/// The robot model of `req`, or the import's refusal (422 / INVALID_ARGUMENT
/// on `urdf`, `base_link` or `tip_link`; 503 / RESOURCE_EXHAUSTED when the
/// client's share of the compute pool is taken).
pub async fn import(
    service: &Service,
    client: ClientId,
    req: UrdfImport,
) -> Result<RobotSpec, Error> {
    service.import_urdf(client, req).await
}
