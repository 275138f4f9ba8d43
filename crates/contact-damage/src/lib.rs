//! Finite elements for the quasistatic viscoelastic contact problem with friction and damage of
//! W. Han, M. Shillor, M. Sofonea, J. Comput. Appl. Math. 137 (2001) 377–398.

pub mod error;
pub mod friction;

pub use error::{Error, Result};
pub mod element;
pub mod mesh;
pub mod quadrature;
