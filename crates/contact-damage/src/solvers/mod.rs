//! The exact solvers of the two variational inequalities of the scheme: the condensed
//! Tresca-friction problem of the velocity step (5.1) ([`friction`]) and the box-constrained
//! quadratic program of the damage step (5.2) ([`box_qp`], with its coarse corrections).

pub mod box_qp;
pub(crate) mod box_qp_coarse;
pub mod friction;
