//! The bodies of `POST /v1/robots` and `PUT /v1/robots/{name}`: a robot model
//! (`application/json`), a URDF document (`application/xml` or `text/xml`,
//! the robot's name, the chain's ends and the convention as query
//! parameters), or a URDF import as JSON ([`URDF_IMPORT_JSON`], the same
//! fields in the body). Either way the handler gets one [`RobotSpec`] and
//! registers it as it registers a model; a URDF's conversion is
//! [`crate::api::urdf_import`]'s.
//!
//! Owns the body extractor of the two routes, their query parameters and the
//! JSON import body. Depends on the body reading in `extract` and the model.

use axum::extract::{FromRequest, Request};
use axum::response::Response;
use serde::Deserialize;
use utoipa::{IntoParams, ToSchema};

use super::AppState;
use super::extract::{content_type, is_json, parse_object, read_bytes, refusal};
use crate::error::Error;
use crate::model::{ConventionSpec, RobotSpec, UrdfImport};

/// The media type of a URDF import sent as JSON ([`UrdfImportBody`]).
pub const URDF_IMPORT_JSON: &str = "application/vnd.kinserve.urdf-import+json";

/// What a registration body holds.
pub enum RobotBody {
    /// A robot model (`application/json`).
    Model(Box<RobotSpec>),
    /// A URDF document (`application/xml`, `text/xml`), read as UTF-8.
    Urdf(String),
    /// A URDF import as JSON ([`URDF_IMPORT_JSON`]).
    Import(UrdfImportBody),
}

impl FromRequest<AppState> for RobotBody {
    type Rejection = Response;

    async fn from_request(req: Request, state: &AppState) -> Result<Self, Self::Rejection> {
        let unread = super::has_body(req.headers());
        read(req, state).await.map_err(|e| refusal(unread, e))
    }
}

/// The body as its content type says (415 for any other type).
async fn read(req: Request, state: &AppState) -> Result<RobotBody, Error> {
    let ct = content_type(&req);
    let mime = ct.split(';').next().unwrap_or("").trim();
    if mime.eq_ignore_ascii_case(URDF_IMPORT_JSON) {
        let bytes = read_bytes(req, state).await?;
        Ok(RobotBody::Import(parse_object(&bytes)?))
    } else if is_json(ct) {
        let bytes = read_bytes(req, state).await?;
        Ok(RobotBody::Model(Box::new(parse_object(&bytes)?)))
    } else if mime.eq_ignore_ascii_case("application/xml") || mime.eq_ignore_ascii_case("text/xml")
    {
        utf8_charset(ct)?;
        let bytes = read_bytes(req, state).await?;
        let doc = String::from_utf8(bytes.to_vec()).map_err(|e| {
            Error::malformed_field(
                "urdf",
                format!(
                    "the document is not UTF-8 (byte {}): send it as UTF-8",
                    e.utf8_error().valid_up_to()
                ),
            )
        })?;
        Ok(RobotBody::Urdf(doc))
    } else {
        Err(Error::UnsupportedMediaType {
            detail: format!(
                "expected Content-Type application/json (a robot model), application/xml or \
                 text/xml (a URDF document) or {URDF_IMPORT_JSON}, got '{}'",
                ct.chars().take(100).collect::<String>()
            ),
        })
    }
}

/// Refuses an XML body declared in another charset than UTF-8 (415).
fn utf8_charset(content_type: &str) -> Result<(), Error> {
    let charset = content_type
        .split(';')
        .skip(1)
        .filter_map(|p| p.split_once('='))
        .find(|(k, _)| k.trim().eq_ignore_ascii_case("charset"))
        .map(|(_, v)| v.trim().trim_matches('"'));
    match charset {
        Some(c) if !c.eq_ignore_ascii_case("utf-8") && !c.eq_ignore_ascii_case("utf8") => {
            Err(Error::UnsupportedMediaType {
                detail: format!(
                    "charset '{}' is not supported; send the URDF as UTF-8",
                    c.chars().take(40).collect::<String>()
                ),
            })
        }
        _ => Ok(()),
    }
}

/// A URDF import as JSON (`Content-Type: application/vnd.kinserve.urdf-import+json`).
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"name": "imported-arm", "urdf": "<robot name=\"two\">…</robot>", "tip_link": "tool", "convention": "standard"}))]
pub struct UrdfImportBody {
    /// The robot's name in kinserve (the rules of a model's `name`).
    pub name: String,
    /// The URDF document (XML).
    pub urdf: String,
    /// The chain's first link (absent or empty: the URDF's root, when it has one).
    #[serde(default)]
    pub base_link: Option<String>,
    /// The chain's last link (absent or empty: the only leaf below the base;
    /// otherwise the error lists the candidates).
    #[serde(default)]
    pub tip_link: Option<String>,
    /// The DH convention of the table (default `standard`).
    #[serde(default)]
    pub convention: Option<ConventionSpec>,
}

/// Query of `POST /v1/robots` with a URDF body (`application/xml`, `text/xml`).
#[derive(Clone, Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct CreateParams {
    /// URDF body only: the robot's name in kinserve (required with a URDF body).
    pub name: Option<String>,
    /// URDF body only: the chain's first link (default: the URDF's root, when it has one).
    pub base_link: Option<String>,
    /// URDF body only: the chain's last link (default: the only leaf below
    /// the base; otherwise the error lists the candidates).
    pub tip_link: Option<String>,
    /// URDF body only: the DH convention of the table, `standard` (default) or `modified`.
    #[param(value_type = Option<ConventionSpec>)]
    pub convention: Option<String>,
}

/// Query of `PUT /v1/robots/{name}` with a URDF body (the name is the path's).
#[derive(Clone, Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ReplaceParams {
    /// URDF body only: the chain's first link (default: the URDF's root, when it has one).
    pub base_link: Option<String>,
    /// URDF body only: the chain's last link (default: the only leaf below
    /// the base; otherwise the error lists the candidates).
    pub tip_link: Option<String>,
    /// URDF body only: the DH convention of the table, `standard` (default) or `modified`.
    #[param(value_type = Option<ConventionSpec>)]
    pub convention: Option<String>,
}

impl From<ReplaceParams> for CreateParams {
    fn from(p: ReplaceParams) -> Self {
        CreateParams {
            name: None,
            base_link: p.base_link,
            tip_link: p.tip_link,
            convention: p.convention,
        }
    }
}

/// An empty link name means the default.
fn link(name: Option<String>) -> Option<String> {
    name.filter(|n| !n.is_empty())
}

/// The model a registration body stands for: the model itself, or the
/// URDF's imported (on the compute pool, under the caller's share). `path` is PUT's name: a name in
/// the body must match it.
pub async fn robot_spec(
    (service, client): (&crate::service::Service, crate::compute::ClientId),
    body: RobotBody,
    params: CreateParams,
    path: Option<&str>,
) -> Result<RobotSpec, Error> {
    let spec = match body {
        RobotBody::Model(spec) => {
            no_import_params(&params, "a robot model")?;
            *spec
        }
        RobotBody::Import(b) => {
            no_import_params(&params, "a JSON import (the fields go in the body)")?;
            same_name(&b.name, path)?;
            let req = UrdfImport {
                name: b.name,
                urdf: b.urdf,
                base_link: link(b.base_link),
                tip_link: link(b.tip_link),
                convention: b.convention.unwrap_or(ConventionSpec::Standard),
            };
            crate::api::urdf_import::import(service, client, req).await?
        }
        RobotBody::Urdf(urdf) => {
            let name = match (path, params.name) {
                (Some(p), _) => p.to_string(),
                (None, Some(n)) => n,
                (None, None) => {
                    return Err(Error::invalid_field(
                        "name",
                        "a URDF body needs the robot's name: POST /v1/robots?name=my-arm",
                    ));
                }
            };
            let req = UrdfImport {
                name,
                urdf,
                base_link: link(params.base_link),
                tip_link: link(params.tip_link),
                convention: convention(params.convention.as_deref())?,
            };
            crate::api::urdf_import::import(service, client, req).await?
        }
    };
    same_name(&spec.name, path)?;
    Ok(spec)
}

/// The `convention` query parameter (absent: standard).
fn convention(value: Option<&str>) -> Result<ConventionSpec, Error> {
    match value {
        None | Some("standard") => Ok(ConventionSpec::Standard),
        Some("modified") => Ok(ConventionSpec::Modified),
        Some(_) => Err(Error::invalid_field(
            "convention",
            "must be standard (the default) or modified",
        )),
    }
}

/// Refuses the URDF query parameters with a body that is not a URDF document.
fn no_import_params(params: &CreateParams, what: &str) -> Result<(), Error> {
    let given = [
        ("name", params.name.is_some()),
        ("base_link", params.base_link.is_some()),
        ("tip_link", params.tip_link.is_some()),
        ("convention", params.convention.is_some()),
    ];
    match given.iter().find(|(_, set)| *set) {
        Some((field, _)) => Err(Error::malformed_field(
            *field,
            format!(
                "the query parameter {field} goes with a URDF body (Content-Type application/xml); \
                 this body is {what}: drop the parameter"
            ),
        )),
        None => Ok(()),
    }
}

/// A body's name must be PUT's path name.
fn same_name(name: &str, path: Option<&str>) -> Result<(), Error> {
    match path {
        Some(p) if p != name => Err(Error::invalid_field(
            "name",
            format!(
                "'{}' does not match the name in the path",
                name.chars().take(64).collect::<String>()
            ),
        )),
        _ => Ok(()),
    }
}
