//! `ImportUrdfRequest` → the model's [`UrdfImport`], with REST's field paths
//! (`convention`; the document's own errors name `urdf`, `base_link` and
//! `tip_link` when the import runs). `replace` and `etag` are the caller's:
//! they say how the imported model is stored, as in `RegisterRobotRequest`.
//! Depends on the model and [`crate::pb`] only.

use kinserve_model::{ConventionSpec, ModelError, Result, UrdfImport};

use crate::pb;

/// The convention of an import: unspecified means standard (REST's default).
pub fn import_convention_from_pb(value: i32) -> Result<ConventionSpec> {
    match pb::Convention::try_from(value) {
        Ok(pb::Convention::Unspecified | pb::Convention::Standard) => Ok(ConventionSpec::Standard),
        Ok(pb::Convention::Modified) => Ok(ConventionSpec::Modified),
        Err(_) => Err(ModelError::invalid_field(
            "convention",
            "must be CONVENTION_STANDARD (the default) or CONVENTION_MODIFIED",
        )),
    }
}

/// An empty link name means "the default" (the root, the only leaf).
fn link(name: String) -> Option<String> {
    (!name.is_empty()).then_some(name)
}

impl TryFrom<pb::ImportUrdfRequest> for UrdfImport {
    type Error = ModelError;

    /// ```
    /// use kinserve_api::pb;
    /// use kinserve_model::{ConventionSpec, UrdfImport};
    /// let msg = pb::ImportUrdfRequest { name: "arm".into(), urdf: "<robot/>".into(),
    ///     tip_link: "tool0".into(), ..Default::default() };
    /// let req = UrdfImport::try_from(msg).unwrap();
    /// assert_eq!((req.base_link, req.tip_link.as_deref()), (None, Some("tool0")));
    /// assert_eq!(req.convention, ConventionSpec::Standard);
    /// ```
    fn try_from(r: pb::ImportUrdfRequest) -> Result<UrdfImport> {
        Ok(UrdfImport {
            convention: import_convention_from_pb(r.convention)?,
            name: r.name,
            urdf: r.urdf,
            base_link: link(r.base_link),
            tip_link: link(r.tip_link),
        })
    }
}
