//! The continuous model, Problem P of §2–3: the constitutive laws 𝒜, G, φ, p_ν, p_τ, the load
//! fields, the contact boundary Γ3 and the Dirichlet data on Γ1 (with the check that they stop
//! every rigid motion), in the discrete form the scheme consumes.

pub mod contact;
pub mod dirichlet;
pub mod fields;
pub mod laws;
pub mod problem;
pub mod rigid;
