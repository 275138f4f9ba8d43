//! Manufactured-solution convergence verification for the `contact-damage` solver
//! (Han, Shillor & Sofonea 2001, error estimate of Theorem 5.2).
//!
//! Building blocks of the verification harness:
//! - [`expr`]: closed-form expressions in `x, y, z, t` (or any named variables) from the case
//!   files, evaluated generically on `num-dual` numbers so that source terms can be derived by
//!   automatic differentiation;
//! - [`plot`]: log–log convergence plots written as SVG;
//! - [`output`]: atomic writing of report files (raw bytes, JSON, CSV).

pub mod error;
pub mod expr;
pub mod output;
pub mod plot;

pub use error::VerifyError;
