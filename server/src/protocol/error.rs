//! The cut protocol's one error: the request field (`camera.fov_y_deg`),
//! query parameter or flag at fault, and what is wrong with it. The API
//! answers it as a 400 (`ApiError`), the CLI prints `FIELD: MESSAGE`.

use std::fmt;

#[derive(Debug, Clone, PartialEq)]
pub struct ProtocolError {
    pub field: String,
    pub message: String,
}

impl ProtocolError {
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        ProtocolError {
            field: field.into(),
            message: message.into(),
        }
    }

    /// A JSON body that does not parse or has the wrong shape: the field is
    /// the path serde stopped at, plus the missing or unknown field's name.
    pub fn from_json(e: serde_path_to_error::Error<serde_json::Error>) -> Self {
        let path = e.path().to_string();
        let message = e.inner().to_string();
        // serde's path stops at the container of a missing field, but at
        // an unknown field itself.
        let named = message
            .strip_prefix("missing field `")
            .and_then(|rest| rest.split('`').next());
        let field = match (path.as_str(), named) {
            (".", Some(name)) => name.to_owned(),
            (_, Some(name)) => format!("{path}.{name}"),
            (".", None) => "body".to_owned(),
            _ => path,
        };
        Self::new(field, message)
    }
}

impl fmt::Display for ProtocolError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.field, self.message)
    }
}

impl std::error::Error for ProtocolError {}

/// The library checks a view's arguments and names the field at fault; it
/// reads no file while a request is prepared, so any other error is the
/// request's too.
impl From<hdlod::Error> for ProtocolError {
    fn from(e: hdlod::Error) -> Self {
        match e {
            hdlod::Error::Argument { at, message } => Self::new(at, message),
            other => Self::new("request", other.to_string()),
        }
    }
}
