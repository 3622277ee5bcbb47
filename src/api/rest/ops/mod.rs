//! The operations on one configuration on REST ([`crate::model::operations`]):
//! one module per operation, each declared by its line of the table
//! ([`crate::model::config_ops!`]), which also adds its route here
//! ([`routes`]). A module holds the operation's answer body, its handler
//! (whose `#[utoipa::path]` is its route and its OpenAPI operation) and its
//! [`RestOp`] impl; the handler calls [`answer`], shared by all.
//!
//! Depends on the adapter's extractors, problems and bodies and on the
//! service; nothing here depends on a particular operation.

use axum::Json;
use axum::extract::State;
use serde::Serialize;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::dto::JointsRequest;
use super::extract::{JsonBody, RobotName};
use super::problem::ApiError;
use crate::model::Robot;
use crate::model::operations::ConfigOp;

/// An operation on one configuration on REST (and in the CLI, which prints
/// the same body): its answer body.
pub trait RestOp: ConfigOp {
    /// The answer body (`ToSchema` for its handler's OpenAPI operation).
    type Output: Serialize;
    /// The body answering `answer` for `robot`.
    fn output(robot: &Robot, answer: Self::Answer) -> Self::Output;
}

/// The answer of `Op` for the robot in the path: validated once, computed
/// on this task (one configuration is cheap).
pub async fn answer<Op: RestOp>(
    State(state): State<AppState>,
    RobotName(name): RobotName,
    JsonBody(body): JsonBody<JointsRequest>,
) -> Result<Json<Op::Output>, ApiError> {
    let entry = state.service.robot(&name)?;
    let answer = state.service.config_op::<Op>(&entry.robot, &body.into())?;
    Ok(Json(Op::output(&entry.robot, answer)))
}

/// Declares one module per operation and [`routes`].
macro_rules! rest_ops {
    ($( $(#[$doc:meta])* $name:ident: $op:ident => [$($answer:tt)+]; )*) => {
        $( $(#[$doc])* pub mod $name; )*

        /// `routes` with the route of every operation on one configuration.
        pub(super) fn routes(routes: OpenApiRouter<AppState>) -> OpenApiRouter<AppState> {
            routes $( .routes(routes!($name::handler)) )*
        }
    };
}

crate::model::config_ops!(rest_ops);
