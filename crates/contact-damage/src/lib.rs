//! Finite elements for the quasistatic viscoelastic contact problem with normal compliance,
//! Coulomb friction and damage of W. Han, M. Shillor, M. Sofonea, *Variational and numerical
//! analysis of a quasistatic viscoelastic problem with normal compliance, friction and damage*,
//! J. Comput. Appl. Math. 137 (2001) 377–398.
//!
//! The crate implements the fully discrete scheme P_V^hk (5.1)–(5.5): continuous P1 or P2
//! elements on triangles and tetrahedra, backward Euler in time, the velocity step (5.1) solved
//! exactly as a Tresca-type variational inequality, and the damage step (5.2) solved exactly as
//! a box-constrained quadratic program.
//!
//! Modules, one concept each: [`mesh`], [`quadrature`], [`element`], [`space`], [`assembly`],
//! [`linalg`], [`laws`], [`contact`], [`friction`], [`velocity`], [`obstacle`], [`damage`],
//! [`scheme`].

pub mod assembly;
pub mod contact;
pub mod damage;
pub mod element;
pub mod error;
pub mod friction;
pub mod gmsh;
pub mod laws;
pub mod linalg;
pub mod mesh;
pub mod obstacle;
pub mod quadrature;
pub mod scheme;
pub mod space;
pub mod velocity;
pub mod vtk;

pub use error::{Error, Result};
