//! The finite element method of the paper's Section 5: simplicial meshes 𝒯^h and their
//! refinement and shape regularity, quadrature on the reference simplex, Lagrange elements of
//! degree l ∈ {1, 2} and the spaces X^h (the element kernels of the scheme's operators, which
//! need the laws, are in [`crate::scheme::assembly`]).

pub mod curved;
pub mod element;
pub mod facet_split;
pub mod mesh;
pub mod quadrature;
pub mod quality;
pub mod refine;
pub mod space;
