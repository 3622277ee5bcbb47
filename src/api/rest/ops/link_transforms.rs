//! `link_transforms` on REST: `POST /v1/robots/{name}/link-transforms` and
//! its answer body (also `kinserve link-transforms`' output). The computation
//! is [`crate::model::operations::LinkTransforms`]; the WebSocket, gRPC and
//! CLI parts come from its line of [`crate::model::config_ops!`].

use axum::Json;
use axum::extract::State;
use serde::Serialize;
use utoipa::ToSchema;

use super::RestOp;
use crate::api::rest::AppState;
use crate::api::rest::dto::JointsRequest;
use crate::api::rest::extract::{JsonBody, RobotName};
use crate::api::rest::problem::{ApiError, Problem};
use crate::model::operations::{LinkTransform, LinkTransforms};
use crate::model::{LengthUnit, Robot};

/// `POST /v1/robots/{name}/link-transforms` response and `kinserve link-transforms` output.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({"robot": "planar_2dof", "length_unit": "m", "link_transforms": [
    {"matrix": [[0.8775825618903728, -0.479425538604203, 0.0, 0.3510330247561491], [0.479425538604203, 0.8775825618903728, 0.0, 0.1917702154416812], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
     "inverse": [[0.8775825618903728, 0.479425538604203, 0.0, -0.4], [-0.479425538604203, 0.8775825618903728, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]},
    {"matrix": [[0.9950041652780258, -0.09983341664682815, 0.0, 0.29850124958340776], [0.09983341664682815, 0.9950041652780258, 0.0, 0.029950024994048446], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
     "inverse": [[0.9950041652780258, 0.09983341664682815, 0.0, -0.3], [-0.09983341664682815, 0.9950041652780258, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]}]}))]
pub struct LinkTransformsOutput {
    /// Robot name.
    pub robot: String,
    /// Length unit of the translations.
    pub length_unit: LengthUnit,
    /// One per DH row in table order (fixed rows included; base and tool are
    /// not rows): `base · A₁ ⋯ Aₙ · tool` is the tool pose.
    pub link_transforms: Vec<LinkTransform>,
}

impl RestOp for LinkTransforms {
    type Output = LinkTransformsOutput;
    fn output(robot: &Robot, link_transforms: Vec<LinkTransform>) -> LinkTransformsOutput {
        LinkTransformsOutput {
            robot: robot.name().to_string(),
            length_unit: robot.length_unit(),
            link_transforms,
        }
    }
}

/// Each DH row's link matrix `ⁱ⁻¹Aᵢ` (the course notes' factors of the arm
/// matrix) and its closed-form inverse at one configuration, in table order;
/// `base · A₁ ⋯ Aₙ · tool` is the tool pose.
#[utoipa::path(post, path = "/v1/robots/{name}/link-transforms", tag = "fk",
    operation_id = "link_transforms", request_body = JointsRequest,
    params(("name" = String, Path, description = "Robot name")),
    responses((status = 200, body = LinkTransformsOutput),
        (status = 400, body = Problem, content_type = "application/problem+json"),
        (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 413, body = Problem, content_type = "application/problem+json"),
        (status = 415, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Overloaded or timed out (Retry-After)", body = Problem, content_type = "application/problem+json")))]
pub async fn handler(
    state: State<AppState>,
    name: RobotName,
    body: JsonBody<JointsRequest>,
) -> Result<Json<LinkTransformsOutput>, ApiError> {
    super::answer::<LinkTransforms>(state, name, body).await
}
