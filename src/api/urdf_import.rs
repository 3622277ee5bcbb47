//! URDF import for both front doors: runs [`crate::model::import_urdf`] (the
//! conversion and its check against the URDF's own FK, a few milliseconds for
//! an arm, more for a long chain) on the blocking pool, so a large document
//! never stalls the request threads. The model it returns is registered by
//! the caller exactly as a JSON / `RegisterRobot` model is
//! ([`crate::service::Service::register`]). Depends on the model only.

use crate::error::Error;
use crate::model::{RobotSpec, UrdfImport, import_urdf};

/// The robot model of `req`, or the import's refusal (422 / INVALID_ARGUMENT
/// on `urdf`, `base_link` or `tip_link`).
pub async fn import(req: UrdfImport) -> Result<RobotSpec, Error> {
    match tokio::task::spawn_blocking(move || import_urdf(&req)).await {
        Ok(done) => Ok(done?),
        Err(e) => match e.try_into_panic() {
            Ok(payload) => Err(super::panic_to_error(payload.as_ref(), "URDF import")),
            Err(e) => Err(Error::Internal {
                detail: e.to_string(),
            }),
        },
    }
}
