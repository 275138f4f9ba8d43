//! Solution verification of a simulation: `simulate --convergence K`.

pub mod gci;
