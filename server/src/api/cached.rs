//! A JSON answer made once and sent with an ETag: a client that has it
//! gets `304 Not Modified`. `Cache-Control: no-cache` makes clients
//! revalidate each time, since a reload may change the answer under the
//! same URL.

use axum::body::{Body, Bytes};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;

/// A JSON body made once, and its ETag.
pub struct Cached {
    body: Bytes,
    etag: HeaderValue,
}

impl Cached {
    pub fn of(value: &impl Serialize) -> Cached {
        let body = serde_json::to_vec(value).expect("plain data serialises");
        let etag = format!("\"{}\"", blake3::hash(&body).to_hex());
        Cached {
            body: body.into(),
            etag: HeaderValue::from_str(&etag).expect("hex in quotes"),
        }
    }

    /// The body, or 304 when the request already has it. Clients revalidate
    /// each time (`no-cache`): a reload may change it under the same URL.
    pub fn answer(&self, headers: &HeaderMap) -> Response {
        let cache = HeaderValue::from_static("no-cache");
        let matches = headers
            .get(header::IF_NONE_MATCH)
            .and_then(|v| v.to_str().ok())
            .is_some_and(|v| {
                v.split(',')
                    .any(|t| t.trim().as_bytes() == self.etag.as_bytes() || t.trim() == "*")
            });
        if matches {
            return (
                StatusCode::NOT_MODIFIED,
                [
                    (header::ETAG, self.etag.clone()),
                    (header::CACHE_CONTROL, cache),
                ],
            )
                .into_response();
        }
        (
            [
                (
                    header::CONTENT_TYPE,
                    HeaderValue::from_static("application/json"),
                ),
                (header::ETAG, self.etag.clone()),
                (header::CACHE_CONTROL, cache),
            ],
            Body::from(self.body.clone()),
        )
            .into_response()
    }
}
