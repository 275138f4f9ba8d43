//! Error type of the input layer and of the programs built on it (`verify`, `simulate`). Every
//! error names what went wrong: the file path, the file and key (with line and column for TOML
//! syntax), the expression (with its column), or the underlying solver error.

use std::fmt;
use std::path::PathBuf;

use crate::expr::ExprError;

/// What kind of input file an error is about, as the user knows it: the wording comes from the
/// program that reads the file (`verify` reads case files, `simulate` problem files).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileKind {
    /// A manufactured case of `verify`: errors read "case `FILE`, key `KEY`: ...".
    Case,
    /// A problem file of `simulate`: errors read "problem file `FILE`, key `KEY`: ...".
    Problem,
}

impl FileKind {
    /// The error "`self` `origin`, key `key`: `message`".
    pub fn error(self, origin: &str, key: &str, message: impl Into<String>) -> InputError {
        InputError::File {
            kind: self,
            file: origin.to_string(),
            key: key.to_string(),
            message: message.into(),
        }
    }
}

impl fmt::Display for FileKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FileKind::Case => "case",
            FileKind::Problem => "problem file",
        })
    }
}

/// The error type of the input layer.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
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
    /// An input file (case or problem file, see [`FileKind`]) is invalid: names the file, the
    /// key (or the line and column of a TOML error) and the problem.
    #[error("{kind} `{file}`, key `{key}`: {message}")]
    File {
        kind: FileKind,
        file: String,
        key: String,
        message: String,
    },
    /// Invalid input other than an expression or a file entry (command-line options, saved
    /// state).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// Standard output or standard error could not be written.
    #[error(transparent)]
    Console(#[from] crate::console::ConsoleError),
    /// The solver crate reported an error.
    #[error(transparent)]
    Solver(#[from] contact_damage::Error),
}

impl InputError {
    /// Whether this is a write into a closed pipe (see [`crate::console`]).
    pub fn is_closed_pipe(&self) -> bool {
        matches!(self, InputError::Console(error) if error.is_closed_pipe())
    }

    /// Shorthand for [`InputError::Io`].
    pub fn io(action: &'static str, path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        InputError::Io {
            action,
            path: path.into(),
            source,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_file_kind_words_the_message() {
        let case = FileKind::Case.error("a.toml", "laws.contact", "bad");
        assert_eq!(case.to_string(), "case `a.toml`, key `laws.contact`: bad");
        let problem = FileKind::Problem.error("b.toml", "steps", "must be at least 1");
        assert_eq!(
            problem.to_string(),
            "problem file `b.toml`, key `steps`: must be at least 1"
        );
    }
}
