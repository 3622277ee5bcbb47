//! The REST routes, each declared once. A handler's `#[utoipa::path]`
//! attribute is both its route in the router and its operation in the OpenAPI
//! document (utoipa-axum's `routes!`), and the [`Group`] a route is declared
//! in sets how it is admitted: the registry's token check, the body limit, the
//! batch slot ([`Admission`]). Metric labels are the matched route templates,
//! so they need no list of their own either.
//!
//! Owns the route table and nothing else: handlers live in their modules, the
//! middleware and the OpenAPI completion in the parent module. Depends on the
//! handler modules and the parent's middleware, nothing outside the adapter.

use axum::Router;
use axum::middleware;
use axum::routing::get;
use utoipa::openapi::OpenApi;
use utoipa::{Modify, OpenApi as _};
use utoipa_axum::router::{OpenApiRouter, UtoipaMethodRouterExt};
use utoipa_axum::routes;

use super::openapi::Complete;
use super::{Admission, ApiDoc, AppState, export, handlers, ik, jacobian, ops, playground, ws};

/// The groups routes are declared in; each group is admitted its own way.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Group {
    /// The registry: the bearer token on writes, then admitted as [`Admission::Single`].
    Registry,
    /// Computations on one request and the exports: [`Admission::Single`].
    Single,
    /// Batches: [`Admission::Batch`] (the batch body limit, one batch slot).
    Batch,
    /// Probes and metrics: never refused for load, no body read ahead.
    Open,
}

/// Every documented route in its group (plus `extra`, admitted as single
/// requests), each group passed through `admit`, merged under the parts of
/// the document no route declares ([`ApiDoc`]).
fn declared(
    extra: Router<AppState>,
    admit: impl Fn(Group, OpenApiRouter<AppState>) -> OpenApiRouter<AppState>,
) -> OpenApiRouter<AppState> {
    let registry = OpenApiRouter::default()
        .routes(routes!(handlers::list_robots, handlers::create_robot))
        .routes(routes!(
            handlers::get_robot,
            handlers::put_robot,
            handlers::delete_robot
        ));
    let single = OpenApiRouter::from(extra)
        .routes(routes!(handlers::fk))
        .routes(routes!(jacobian::jacobian))
        .routes(routes!(ik::ik))
        // GET: the HTTP/1.1 upgrade; CONNECT: WebSockets over HTTP/2 (RFC 8441),
        // not an operation of its own (OpenAPI has no CONNECT).
        .routes(routes!(ws::stream).map(|r| r.connect(ws::stream)))
        .routes(routes!(export::closed_form))
        .routes(routes!(export::urdf));
    // The operations on one configuration, one route each (from the table).
    let single = ops::routes(single);
    let batch = OpenApiRouter::default()
        .routes(routes!(handlers::fk_batch))
        .routes(routes!(jacobian::jacobian_batch))
        .routes(routes!(ik::ik_batch))
        .routes(routes!(ik::ik_path));
    let open = OpenApiRouter::default()
        .routes(routes!(handlers::healthz))
        .routes(routes!(handlers::readyz))
        .routes(routes!(super::metrics_text));
    OpenApiRouter::with_openapi(ApiDoc::openapi())
        .merge(admit(Group::Registry, registry))
        .merge(admit(Group::Single, single))
        .merge(admit(Group::Batch, batch))
        .merge(admit(Group::Open, open))
}

/// The routes the server answers, admitted as their groups say, with the
/// pages no document lists (the playground), and the OpenAPI document they
/// make (served at `/openapi.json`).
pub(super) fn api(state: &AppState, extra: Router<AppState>) -> (Router<AppState>, OpenApi) {
    let (router, mut doc) =
        declared(extra, |group, routes| admitted(group, routes, state)).split_for_parts();
    Complete.modify(&mut doc);
    let router = router
        .route("/", get(playground::index))
        .route("/playground/{file}", get(playground::file));
    (router, doc)
}

/// The OpenAPI document of the REST API, as `/openapi.json` serves it,
/// without a server.
pub fn document() -> OpenApi {
    let mut doc = declared(Router::new(), |_, routes| routes).into_openapi();
    Complete.modify(&mut doc);
    doc
}

/// `routes` with the admission of `group`.
fn admitted(
    group: Group,
    routes: OpenApiRouter<AppState>,
    state: &AppState,
) -> OpenApiRouter<AppState> {
    let admit = |admission: Admission| {
        middleware::from_fn_with_state((state.clone(), admission), super::admit)
    };
    match group {
        // The token is checked before the body is read (`admit` reads it).
        Group::Registry => routes.route_layer(admit(Admission::Single)).route_layer(
            middleware::from_fn_with_state(state.clone(), super::require_token),
        ),
        Group::Single => routes.route_layer(admit(Admission::Single)),
        Group::Batch => routes.route_layer(admit(Admission::Batch)),
        Group::Open => routes,
    }
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;

    use super::*;

    /// The paths declared in each group.
    fn paths_by_group() -> Vec<(Group, String)> {
        let seen = RefCell::new(Vec::new());
        declared(Router::new(), |group, routes| {
            let paths = routes.get_openapi().paths.paths.keys().cloned();
            seen.borrow_mut().extend(paths.map(|p| (group, p)));
            routes
        });
        seen.into_inner()
    }

    #[test]
    fn batch_routes_are_declared_in_the_batch_group_and_only_they() {
        let all = paths_by_group();
        assert_eq!(all.len(), 16, "{all:?}");
        for (group, path) in &all {
            // A Cartesian path is a batch of steps: it takes a batch slot too.
            assert_eq!(
                *group == Group::Batch,
                path.ends_with("/batch") || path.ends_with("/ik/path"),
                "{path} is declared in {group:?}"
            );
        }
    }

    #[test]
    fn the_document_holds_every_declared_path_completed() {
        let doc = document();
        let declared: Vec<String> = paths_by_group().into_iter().map(|(_, p)| p).collect();
        let documented: Vec<&String> = doc.paths.paths.keys().collect();
        assert_eq!(documented.len(), declared.len());
        assert!(declared.iter().all(|p| doc.paths.paths.contains_key(p)));
        // `Complete` ran on the routes' operations: a response declared
        // without a description has the one from the error mapping.
        let too_large = doc
            .paths
            .paths
            .get("/v1/robots/{name}/fk/batch")
            .and_then(|item| item.post.as_ref())
            .and_then(|op| op.responses.responses.get("413"));
        let Some(utoipa::openapi::RefOr::T(too_large)) = too_large else {
            panic!("fk/batch documents its 413");
        };
        assert_eq!(
            too_large.description,
            crate::api::rest::openapi::describe("413")
        );
    }
}
