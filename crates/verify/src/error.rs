//! Error type of the verification crate. Every error names what went wrong: the file path,
//! the expression (with its column), or the underlying solver error.

use std::path::PathBuf;

use crate::expr::ExprError;

/// The error type of the verification crate.
#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    /// A file-system operation failed on `path` (`action` says which: "creating directory",
    /// "writing", ...).
    #[error("{action} `{path}`: {source}", path = path.display())]
    Io {
        action: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A value could not be serialized (to JSON or CSV) for the report file `path`.
    #[error("serializing report `{path}`: {message}", path = path.display())]
    Serialize { path: PathBuf, message: String },
    /// A plot could not be produced for `path` (no plottable data, or a drawing failure).
    #[error("plotting `{path}`: {message}", path = path.display())]
    Plot { path: PathBuf, message: String },
    /// An expression (e.g. the manufactured displacement component `name` of a case file)
    /// failed to parse.
    #[error("expression `{name}`: {source}")]
    Expression {
        name: String,
        #[source]
        source: ExprError,
    },
    /// A case file is invalid: names the file, the key and the problem.
    #[error("case `{file}`, key `{key}`: {message}")]
    Case {
        file: String,
        key: String,
        message: String,
    },
    /// Invalid input of the harness other than an expression (case-file values, options).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// The solver crate reported an error.
    #[error(transparent)]
    Solver(#[from] contact_damage::Error),
}

impl VerifyError {
    /// Shorthand for [`VerifyError::Io`].
    pub fn io(action: &'static str, path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        VerifyError::Io {
            action,
            path: path.into(),
            source,
        }
    }
}
