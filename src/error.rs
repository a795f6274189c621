//! The crate's error type. Every message names the file, field or value at fault and what was
//! expected; the CLI maps input errors to exit code 2.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A value given by the user is out of range or unknown.
    #[error("{0}")]
    Input(String),
    /// A file could not be read or is not what was expected.
    #[error("{}: {msg}", path.display())]
    File { path: PathBuf, msg: String },
    /// The user stopped a run (Ctrl-C in Python); what finished is kept.
    #[error("{0}")]
    Stopped(String),
}

impl Error {
    pub fn file(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::File {
            path: path.into(),
            msg: msg.into(),
        }
    }
}

pub type Result<T> = std::result::Result<T, Error>;
