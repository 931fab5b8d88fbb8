//! What every handler takes from the request besides the state: path
//! segments ([`Segments`]), query pairs ([`Pairs`]) and the WebSocket
//! upgrade ([`Upgrade`]). A rejection is the API's JSON error naming the
//! part at fault, never axum's plain text; [`json_errors`] catches what
//! no extractor sees (a body over the limit, anything a layer answers).

use axum::extract::ws::WebSocketUpgrade;
use axum::extract::{FromRequestParts, Path, Query, Request};
use axum::http::request::Parts;
use axum::http::{StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use serde::de::DeserializeOwned;

use super::error::{ApiError, quote};

/// The path's segments as `T` (a `String` or a tuple of them).
pub struct Segments<T>(pub T);

impl<S: Send + Sync, T: DeserializeOwned + Send> FromRequestParts<S> for Segments<T> {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        use axum::extract::path::ErrorKind;
        use axum::extract::rejection::PathRejection;
        match Path::<T>::from_request_parts(parts, state).await {
            Ok(Path(value)) => Ok(Segments(value)),
            Err(PathRejection::FailedToDeserializePathParams(e)) => Err(match e.kind() {
                ErrorKind::InvalidUtf8InPathParam { key } => {
                    ApiError::bad(key.as_str(), "is not UTF-8 text once percent-decoded")
                }
                _ => ApiError::bad("path", e.body_text()),
            }),
            Err(other) => Err(ApiError::new(
                other.status(),
                Some("path".into()),
                other.body_text(),
            )),
        }
    }
}

/// The query's `key=value` pairs in order. A key given twice is an error
/// naming it: which one would count is a guess (the JSON body's duplicate
/// keys are rejected the same way).
pub struct Pairs(pub Vec<(String, String)>);

impl Pairs {
    pub fn from_parts(parts: &Parts) -> Result<Pairs, ApiError> {
        let Query(pairs) = Query::<Vec<(String, String)>>::try_from_uri(&parts.uri)
            .map_err(|r| ApiError::bad("query", r.body_text()))?;
        for (i, (key, _)) in pairs.iter().enumerate() {
            if pairs[..i].iter().any(|(k, _)| k == key) {
                return Err(ApiError::bad(key.as_str(), "is given more than once"));
            }
        }
        Ok(Pairs(pairs))
    }
}

impl<S: Send + Sync> FromRequestParts<S> for Pairs {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, ApiError> {
        Pairs::from_parts(parts)
    }
}

/// The WebSocket handshake of the stream; a plain GET (no `Upgrade:
/// websocket`) is a 400 that says what the endpoint wants.
pub struct Upgrade(pub WebSocketUpgrade);

impl<S: Send + Sync> FromRequestParts<S> for Upgrade {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        WebSocketUpgrade::from_request_parts(parts, state)
            .await
            .map(Upgrade)
            .map_err(|r| {
                ApiError::new(
                    r.status(),
                    Some("upgrade".into()),
                    format!(
                        "this endpoint is a WebSocket; connect with a WebSocket client ({})",
                        r.body_text()
                    ),
                )
            })
    }
}

/// Every 4xx and 5xx answer that is not JSON yet becomes the API's error
/// body: the one fallback for what axum, tower-http or hyper's service
/// layer answer on their own (a body over the limit, a bad method).
pub async fn json_errors(request: Request, next: Next) -> Response {
    let response = next.run(request).await;
    let status = response.status();
    if !(status.is_client_error() || status.is_server_error()) {
        return response;
    }
    let json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(b"application/json"));
    if json {
        return response;
    }
    // What the layer said, if short; its text is ours, not the client's,
    // but it is quoted all the same.
    let text = axum::body::to_bytes(response.into_body(), 4096)
        .await
        .map(|b| String::from_utf8_lossy(&b).trim().to_owned())
        .unwrap_or_default();
    let message = if text.is_empty() {
        status.canonical_reason().unwrap_or("error").to_owned()
    } else {
        quote(&text)
    };
    ApiError::new(status, Some(field_of(status).into()), message).into_response()
}

/// The part of a request a status without an extractor's word blames.
fn field_of(status: StatusCode) -> &'static str {
    match status {
        StatusCode::METHOD_NOT_ALLOWED => "method",
        StatusCode::PAYLOAD_TOO_LARGE | StatusCode::UNSUPPORTED_MEDIA_TYPE => "body",
        StatusCode::URI_TOO_LONG | StatusCode::NOT_FOUND => "path",
        StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE => "headers",
        _ => "request",
    }
}
