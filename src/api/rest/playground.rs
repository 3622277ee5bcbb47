//! The web playground: static files embedded in the binary, served at `/` and
//! `/playground/{file}` (no CDN, no build step).

use axum::extract::Path;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};

use super::problem::ApiError;
use crate::error::Error;

/// `(file name, content type, contents)` of every playground file.
const FILES: &[(&str, &str, &str)] = &[
    (
        "index.html",
        "text/html; charset=utf-8",
        include_str!("playground/index.html"),
    ),
    (
        "style.css",
        "text/css; charset=utf-8",
        include_str!("playground/style.css"),
    ),
    (
        "app.js",
        "text/javascript; charset=utf-8",
        include_str!("playground/app.js"),
    ),
    (
        "api.js",
        "text/javascript; charset=utf-8",
        include_str!("playground/api.js"),
    ),
    (
        "view3d.js",
        "text/javascript; charset=utf-8",
        include_str!("playground/view3d.js"),
    ),
    (
        "closedform.js",
        "text/javascript; charset=utf-8",
        include_str!("playground/closedform.js"),
    ),
    (
        "ghosts.js",
        "text/javascript; charset=utf-8",
        include_str!("playground/ghosts.js"),
    ),
    (
        "path.js",
        "text/javascript; charset=utf-8",
        include_str!("playground/path.js"),
    ),
    (
        "jsonlines.js",
        "text/javascript; charset=utf-8",
        include_str!("playground/jsonlines.js"),
    ),
];

fn serve(name: &str) -> Response {
    match FILES.iter().find(|(n, _, _)| *n == name) {
        Some((_, content_type, body)) => (
            [
                (header::CONTENT_TYPE, HeaderValue::from_static(content_type)),
                (header::CACHE_CONTROL, HeaderValue::from_static("no-cache")),
                (
                    header::CONTENT_SECURITY_POLICY,
                    HeaderValue::from_static(
                        "default-src 'self'; img-src 'self' data:; connect-src 'self' ws: wss:",
                    ),
                ),
                (
                    header::X_CONTENT_TYPE_OPTIONS,
                    HeaderValue::from_static("nosniff"),
                ),
            ],
            *body,
        )
            .into_response(),
        None => ApiError(Error::NoRoute {
            path: format!("/playground/{}", name.chars().take(100).collect::<String>()),
        })
        .into_response(),
    }
}

/// `GET /`: the playground page.
pub async fn index() -> Response {
    serve("index.html")
}

/// `GET /playground/{file}`: its scripts and styles.
pub async fn file(Path(name): Path<String>) -> Response {
    serve(&name)
}
