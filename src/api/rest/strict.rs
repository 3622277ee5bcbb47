//! HTTP message checks hyper leaves to the application.
//!
//! - An HTTP/1.1 request must carry exactly one `Host` header (RFC 9112
//!   §3.2): none or several is 400. HTTP/1.0 may omit it; HTTP/2 carries the
//!   authority in `:authority`, so `Host` is not required there.
//! - The only transfer coding understood is `chunked` (hyper reads the framing
//!   of any list that ends in `chunked`, and refuses others with 400): a list
//!   with any other coding, such as `gzip, chunked`, is 501 (RFC 9112 §6.1),
//!   never read as if it were plain chunked.
//!
//! Both answers close the connection, as the body (if any) is left unread.

use axum::extract::Request;
use axum::http::{Version, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::problem::ApiError;
use super::refuse_unread;
use crate::error::Error;

/// Refuses requests with a missing or repeated `Host` (HTTP/1.1) or a
/// transfer coding other than `chunked`.
pub async fn check_message(req: Request, next: Next) -> Response {
    if let Err(e) = host(&req).and_then(|()| transfer_coding(&req)) {
        metrics::counter!("kinserve_http_rejected_total", "reason" => "message").increment(1);
        return refuse_unread(true, ApiError(e).into_response());
    }
    next.run(req).await
}

fn host(req: &Request) -> Result<(), Error> {
    if req.version() != Version::HTTP_11 {
        return Ok(());
    }
    match req.headers().get_all(header::HOST).iter().count() {
        1 => Ok(()),
        0 => Err(Error::malformed_field(
            "host",
            "an HTTP/1.1 request must have a Host header",
        )),
        _ => Err(Error::malformed_field(
            "host",
            "send one Host header, not several",
        )),
    }
}

fn transfer_coding(req: &Request) -> Result<(), Error> {
    for value in req.headers().get_all(header::TRANSFER_ENCODING) {
        let text = value.to_str().unwrap_or("?");
        for coding in text.split(',').map(str::trim).filter(|c| !c.is_empty()) {
            if !coding.eq_ignore_ascii_case("chunked") {
                return Err(Error::NotImplemented {
                    detail: format!(
                        "Transfer-Encoding '{}' is not supported; only 'chunked' is",
                        coding.chars().take(100).collect::<String>()
                    ),
                });
            }
        }
    }
    Ok(())
}
