//! The API's one error type: every 4xx answer is JSON naming the field at
//! fault, `{"error": {"status", "field", "message"}}`
//! (`schemas/api/error.schema.json`).

use axum::Json;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde::Serialize;

use crate::protocol::ProtocolError;

/// What an error repeats of a request is quoted short (`hdlod::input::quote`).
pub use hdlod::input::quote;

/// `text` cut to about 100 characters, without quotes.
fn clip(text: &str) -> String {
    match text.char_indices().nth(100) {
        None => text.to_owned(),
        Some((cut, _)) => format!("{}...", &text[..cut]),
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ApiError {
    #[serde(skip)]
    pub status: StatusCode,
    /// The request field (`camera.fov_y_deg`), query parameter or path part.
    pub field: Option<String>,
    pub message: String,
}

impl ApiError {
    /// `field` may be the client's text (an unknown parameter's name): it
    /// is cut to about 100 characters like every quote of the request. So
    /// is each long word of the message: messages made elsewhere (serde's
    /// "unknown field `...`") quote the request whole.
    pub fn new(status: StatusCode, field: Option<String>, message: impl Into<String>) -> Self {
        let message = message.into();
        let message = if message.split_whitespace().any(|w| w.len() > 100) {
            message.split(' ').map(clip).collect::<Vec<_>>().join(" ")
        } else {
            message
        };
        ApiError {
            status,
            field: field.map(|f| clip(&f)),
            message,
        }
    }

    pub fn bad(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, Some(field.into()), message)
    }

    pub fn not_found(field: &str, message: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, Some(field.into()), message)
    }

    /// The JSON value of the body, also sent over the WebSocket.
    pub fn body(&self) -> serde_json::Value {
        serde_json::json!({"error": {
            "status": self.status.as_u16(),
            "field": self.field,
            "message": self.message,
        }})
    }
}

impl From<ProtocolError> for ApiError {
    fn from(e: ProtocolError) -> Self {
        Self::bad(e.field, e.message)
    }
}

impl From<hdlod::Error> for ApiError {
    fn from(e: hdlod::Error) -> Self {
        match e {
            hdlod::Error::Argument { at, message } => Self::bad(at, message),
            other => Self::new(StatusCode::INTERNAL_SERVER_ERROR, None, other.to_string()),
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.status, Json(self.body())).into_response()
    }
}
