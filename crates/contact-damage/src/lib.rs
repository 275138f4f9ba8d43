//! Finite elements for the quasistatic viscoelastic contact problem with friction and damage of
//! W. Han, M. Shillor, M. Sofonea, J. Comput. Appl. Math. 137 (2001) 377–398.

pub mod error;
pub mod obstacle;

pub use error::{Error, Result};
