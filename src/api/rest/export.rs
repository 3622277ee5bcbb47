//! `GET /v1/robots/{name}/closed-form` and `GET /v1/robots/{name}/urdf`: a
//! robot's DH table as closed-form FK in the course's notation and as URDF.
//!
//! Thin: the service computes both (`kinserve_model::ClosedForm`,
//! `kinserve_model::to_urdf`); this module only answers over HTTP and holds
//! the OpenAPI examples (the planar arm's real answers, checked by the API tests).

use axum::Json;
use axum::extract::State;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};

use super::AppState;
use super::extract::{Client, RobotName};
use super::problem::{ApiError, Problem};
use crate::error::Error;
use crate::model::ClosedForm;

/// The closed form of `planar_2dof` as served (the OpenAPI example).
pub const PLANAR_CLOSED_FORM_EXAMPLE: &str = include_str!("examples/planar_2dof.closed-form.json");
/// The URDF of `planar_2dof` as served (the OpenAPI example).
pub const PLANAR_URDF_EXAMPLE: &str = include_str!("examples/planar_2dof.urdf");

fn planar_closed_form() -> serde_json::Value {
    serde_json::from_str(PLANAR_CLOSED_FORM_EXAMPLE).unwrap_or_default()
}

/// Closed-form FK of the robot's DH table, as the course notes write it.
///
/// `transform` is ⁰Tₙ = A₁⋯Aₙ of the DH rows only (FK is `base · ⁰Tₙ · tool`;
/// `base` and `tool` are given as numbers); `link_transforms[i]` is the matrix
/// of DH row i + 1. Each matrix comes as `text` (4×4 expression strings),
/// `latex` and presentation `mathml`. Grammar of `text`: numbers, `+ - * /`,
/// parentheses and identifiers: `cI`/`sI` = cos/sin(Σ θ_j, j ∈ I) with θ_j the
/// joint value plus the row's θ offset (`c1`, `c23`; `c9_10` when the table has
/// 10 or more rows); a prismatic row's variable `dI` (joint value plus d
/// offset); every other identifier (`aI`, `dI`, `cos_alphaI`, …) is a
/// constant with its value in `symbols` (lengths in `length_unit`). In the
/// modified convention row i holds `a{i-1}` (Craig). Angle sums are collapsed
/// over runs of parallel revolute axes; constant angles that are multiples of
/// 90° are folded to 0/±1.
#[utoipa::path(get, path = "/v1/robots/{name}/closed-form", tag = "robots",
    params(("name" = String, Path, description = "Robot name")),
    responses(
        (status = 200, description = "Closed-form FK (example: planar_2dof, x = a1*c1 + a2*c12)", body = ClosedForm,
            example = json!(planar_closed_form())),
        (status = 400, description = "Malformed robot name", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "The closed form is past the work limit (4,000,000 counted operations, ~50–100 ms of CPU) or 20,000 terms; computed once per robot version and kept", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn closed_form(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    Client(client): Client,
) -> Result<Response, ApiError> {
    let cf = state.service.closed_form(client, &name).await?;
    match cf.as_ref() {
        Ok(cf) => Ok(Json(cf).into_response()),
        Err(e) => Err(Error::from(e.clone()).into()),
    }
}

/// The robot as a URDF document (`application/xml`): root link `world`, the
/// base as the fixed joint `base_joint`, one joint per DH row (`revolute` with
/// limits, `continuous` without, `prismatic`, `fixed`) with the θ/d offsets in
/// the joint origins, the tool as the fixed joint `tool_joint` to the link
/// `tool`; metres and radians; cylinder visuals; `effort`/`velocity` are
/// placeholders (a DH table has no dynamics).
#[utoipa::path(get, path = "/v1/robots/{name}/urdf", tag = "robots",
    params(("name" = String, Path, description = "Robot name")),
    responses(
        (status = 200, description = "URDF (example: planar_2dof)", body = String, content_type = "application/xml",
            example = json!(PLANAR_URDF_EXAMPLE)),
        (status = 400, description = "Malformed robot name", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No robot of that name", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn urdf(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    Client(client): Client,
) -> Result<Response, ApiError> {
    let xml = state.service.urdf(client, &name).await?;
    Ok((
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/xml"),
        )],
        xml,
    )
        .into_response())
}
