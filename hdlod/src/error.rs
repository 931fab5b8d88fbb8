//! The library's one error type. Every variant names the file and, where
//! there is one, the object, task or field at fault, so that a user can fix
//! the input without reading our code.

use std::path::PathBuf;

pub type Result<T, E = Error> = std::result::Result<T, E>;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read, written or renamed.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The content of a file is wrong: `at` names the object, task or field
    /// (for example `tasks[3].finish` or `object "C-12"`).
    #[error("{}: {at}: {message}", file.display())]
    Invalid {
        file: PathBuf,
        at: String,
        message: String,
    },
    /// A file wrong as a whole, with no one field at fault: an unknown
    /// format, or a mesh that fails its checks.
    #[error("{}: {message}", file.display())]
    File { file: PathBuf, message: String },
    /// Input that does not come from a file (an API argument, a parameter).
    #[error("{at}: {message}")]
    Argument { at: String, message: String },
    /// A value wrong in itself (a date, a keyframe list, a mesh), checked
    /// where nobody knows yet where it came from: the caller places it in
    /// its file or argument, quoting the message.
    #[error("{message}")]
    Value { message: String },
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    pub fn invalid(
        file: impl Into<PathBuf>,
        at: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Error::Invalid {
            file: file.into(),
            at: at.into(),
            message: message.into(),
        }
    }

    pub fn file(file: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::File {
            file: file.into(),
            message: message.into(),
        }
    }

    pub fn argument(at: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Argument {
            at: at.into(),
            message: message.into(),
        }
    }

    pub fn value(message: impl Into<String>) -> Self {
        Error::Value {
            message: message.into(),
        }
    }
}
