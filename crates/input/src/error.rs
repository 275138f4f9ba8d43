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

/// The laws under `[laws]` whose parameter errors the solver names by their key below it.
const LAW_KEYS: [&str; 4] = ["elasticity.", "viscosity.", "contact.", "damage_source"];

/// The initial data under `[loads]` whose errors the solver names by their key.
const INITIAL_KEYS: [&str; 2] = ["initial_damage", "initial_displacement"];

impl InputError {
    /// A solver error that names a key of the input file, located in the file `origin` of
    /// kind `kind`: a law that left its admissible range during a run (the solver names it,
    /// `elasticity.shear_modulus`) at its key under `[laws]`, initial data out of range
    /// (`initial_damage at node 0 [0.0, 0.0]`) at theirs under `[loads]`, constraints of Γ1
    /// that leave the body free to move rigidly at `displacement` (the `[[displacement]]`
    /// parts and the clamped sides or groups, which the message names; `domain.sides` in a
    /// case), parts of Γ1 that disagree on a shared node at `displacement`, data of a step
    /// not finite or out of the scale of double precision at the key they come from.
    /// Other errors are returned unchanged.
    pub fn located(self, kind: FileKind, origin: &str) -> InputError {
        match self {
            InputError::Solver(contact_damage::Error::InvalidParameter {
                name, reason, ..
            }) if LAW_KEYS.iter().any(|law| name.starts_with(law)) => {
                kind.error(origin, &format!("laws.{name}"), reason)
            }
            InputError::Solver(contact_damage::Error::InvalidParameter {
                name,
                value,
                reason,
            }) if INITIAL_KEYS.iter().any(|key| name.starts_with(key)) => {
                // the key, then where
                let (key, place) = name.split_once(' ').unwrap_or((name.as_str(), ""));
                kind.error(
                    origin,
                    &format!("loads.{key}"),
                    format!("{place}: {key} = {}: {reason}", crate::number::short(value)),
                )
            }
            InputError::Solver(contact_damage::Error::RigidMotion(message)) => {
                let key = match kind {
                    FileKind::Problem => "displacement",
                    FileKind::Case => "domain.sides",
                };
                kind.error(origin, key, message)
            }
            InputError::Solver(contact_damage::Error::ConflictingParts(message)) => {
                kind.error(origin, "displacement", message)
            }
            InputError::Solver(contact_damage::Error::StepData {
                quantity, message, ..
            }) => {
                use contact_damage::error::StepDatum;
                let (key, source) = match (kind, quantity) {
                    (FileKind::Problem, StepDatum::Load) => (
                        "loads",
                        "`loads.body_force`, `loads.traction` and `loads.traction_curve`",
                    ),
                    (FileKind::Problem, StepDatum::Contact) => (
                        "loads.gap",
                        "the gap, the displacement and `laws.contact.stiffness`",
                    ),
                    (FileKind::Problem, StepDatum::PrescribedVelocity) => {
                        ("displacement", "the rate of a `[[displacement]]` component")
                    }
                    (FileKind::Case, StepDatum::Load) => (
                        "exact",
                        "the manufactured loads, derived from `exact` and `laws`",
                    ),
                    (FileKind::Case, StepDatum::Contact) => (
                        "exact.gap",
                        "the gap, the displacement and `laws.contact.stiffness`",
                    ),
                    (FileKind::Case, StepDatum::PrescribedVelocity) => {
                        ("exact.u", "the rate of `exact.u` on a prescribed side")
                    }
                };
                kind.error(origin, key, format!("{message}; it comes from {source}"))
            }
            other => other,
        }
    }

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
    fn solver_errors_that_name_a_key_are_located_in_the_file() {
        let law = InputError::Solver(contact_damage::Error::parameter(
            "elasticity.shear_modulus",
            -1.0,
            "μ(β) must be ≥ 0",
        ));
        assert_eq!(
            law.located(FileKind::Case, "c.toml").to_string(),
            "case `c.toml`, key `laws.elasticity.shear_modulus`: μ(β) must be ≥ 0"
        );
        let initial = InputError::Solver(contact_damage::Error::parameter(
            "initial_damage at node 3 [0.5, 0.0]",
            1.5,
            "β0 must take values in [0, 1]",
        ));
        assert_eq!(
            initial.located(FileKind::Problem, "p.toml").to_string(),
            "problem file `p.toml`, key `loads.initial_damage`: at node 3 [0.5, 0.0]: \
             initial_damage = 1.5: β0 must take values in [0, 1]"
        );
        let rigid = InputError::Solver(contact_damage::Error::RigidMotion(
            "the body can move rigidly (translation along y)".into(),
        ));
        assert_eq!(
            rigid.located(FileKind::Problem, "p.toml").to_string(),
            "problem file `p.toml`, key `displacement`: the body can move rigidly (translation \
             along y)"
        );
        let other = InputError::Solver(contact_damage::Error::parameter("steps", 0.0, "≥ 1"));
        assert!(!other
            .located(FileKind::Problem, "p.toml")
            .to_string()
            .contains("p.toml"));
    }

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
