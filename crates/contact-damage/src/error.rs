//! Errors of the solver crate. Every error names what went wrong: a parameter, a mesh
//! entity, or a solver with its iteration history.

use std::fmt;

/// Residual history of an iterative solver, printed compactly in error messages.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct History(pub Vec<f64>);

impl fmt::Display for History {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[")?;
        for (i, r) in self.0.iter().enumerate() {
            if i > 0 {
                write!(f, ", ")?;
            }
            write!(f, "{r:.3e}")?;
        }
        write!(f, "]")
    }
}

/// The error type of the solver crate.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A model or solver parameter violates an assumption of the theory.
    #[error("invalid parameter `{name}` = {}: {reason}", shown(*value))]
    InvalidParameter {
        name: String,
        value: f64,
        reason: String,
    },
    /// The mesh is not admissible (names the offending cell, facet or vertex).
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// Invalid input other than a scalar parameter or a mesh (sizes, options).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// The constraints of Γ1 leave a piece of the body free to move rigidly (names the motion,
    /// the piece and the parts that constrain it).
    #[error("{0}")]
    RigidMotion(String),
    /// Two parts of Γ1 prescribe different values of a component on a node they share (names
    /// both parts, the node, the component and the time).
    #[error("{0}")]
    ConflictingParts(String),
    /// An iterative solver stopped before reaching its tolerance.
    #[error(
        "{solver} did not converge in {iterations} iterations: residual {residual:.3e} > tolerance {tolerance:.1e}; residual history {history}"
    )]
    NoConvergence {
        solver: &'static str,
        iterations: usize,
        residual: f64,
        tolerance: f64,
        history: History,
    },
    /// A factorization or solve failed (e.g. the matrix is not positive definite).
    #[error("linear algebra failure in {context}: {message}")]
    LinearAlgebra { context: String, message: String },
    /// A NaN or infinity appeared in data or in a computed field.
    #[error("non-finite value: {0}")]
    NonFinite(String),
    /// A datum of a velocity step is not finite, or finite but so large that the solvers'
    /// squared norms and energies would overflow ([`crate::algebra::linalg::MAGNITUDE_LIMIT`]);
    /// `quantity` says which datum, so that a program can name the input it comes from.
    #[error("{message}")]
    StepData {
        quantity: StepDatum,
        /// Finite but beyond the limit (otherwise not finite).
        out_of_scale: bool,
        message: String,
    },
}

/// A datum of a velocity step, as named by [`Error::StepData`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepDatum {
    /// The load vector (body forces, tractions, the force of prescribed velocities).
    Load,
    /// The normal pressure p_ν or the friction bound of a contact node (from the gap, the
    /// displacement and the contact law).
    Contact,
    /// A prescribed velocity on Γ1 (the time derivative of a prescribed displacement).
    PrescribedVelocity,
}

/// `value` as Rust prints it, in exponent notation when that is shorter to read (|value| ≥ 1e6
/// or below 1e-4).
fn shown(value: f64) -> String {
    if value == 0.0 || !value.is_finite() || (1e-4..1e6).contains(&value.abs()) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

/// Result alias of the solver crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Shorthand for [`Error::InvalidParameter`].
    pub fn parameter(name: impl Into<String>, value: f64, reason: impl Into<String>) -> Self {
        Error::InvalidParameter {
            name: name.into(),
            value,
            reason: reason.into(),
        }
    }
}
