//! Error type of the library.
//!
//! Two kinds of failure reach the user: bad input (a job, data or system file that is wrong,
//! or an output folder another run holds; the CLI maps it to exit code 2 and prints the
//! one-line message) and numerical failure of a fit, which is reported through
//! [`crate::estimate::Termination`] rather than as an error. The variants say which input was
//! wrong, for callers that sort errors by kind (the Python package's exceptions); the message
//! and exit code do not depend on it.

use std::path::PathBuf;

/// Library error. Every variant's message names the file (and field, column or line) at fault.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A job, system or results file is missing, unreadable or malformed.
    #[error("{}: {msg}", path.display())]
    Input { path: PathBuf, msg: String },
    /// A data file (or array) is missing, unreadable or malformed ([`crate::data`]).
    #[error("{}: {msg}", path.display())]
    Data { path: PathBuf, msg: String },
    /// The output folder is in use by another run ([`crate::lock`]).
    #[error("{}: {msg}", path.display())]
    Locked { path: PathBuf, msg: String },
    /// A command-line or job setting is out of range or inconsistent.
    #[error("{0}")]
    Invalid(String),
    /// Writing an output file failed.
    #[error("{}: {msg}", path.display())]
    Output { path: PathBuf, msg: String },
}

impl Error {
    pub fn input(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Input { path: path.into(), msg: msg.into() }
    }
    pub fn data(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Data { path: path.into(), msg: msg.into() }
    }
    pub fn locked(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Locked { path: path.into(), msg: msg.into() }
    }
    pub fn output(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Output { path: path.into(), msg: msg.into() }
    }
    /// True when the error is the user's input (exit code 2), false for an I/O failure on output.
    pub fn is_bad_input(&self) -> bool {
        matches!(self, Error::Input { .. } | Error::Data { .. } | Error::Locked { .. } | Error::Invalid(_))
    }
}

pub type Result<T> = std::result::Result<T, Error>;
