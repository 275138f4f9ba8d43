//! Manufactured-solution convergence verification for the `contact-damage` solver
//! (Han, Shillor & Sofonea 2001, error estimate of Theorem 5.2).
//!
//! Building blocks of the verification harness:
//! - [`expr`]: closed-form expressions in `x, y, z, t` (or any named variables) from the case
//!   files, evaluated generically on `num-dual` numbers so that source terms can be derived by
//!   automatic differentiation;
//! - [`plot`]: log–log convergence plots written as SVG;
//! - [`output`]: atomic writing of report files (raw bytes, JSON, CSV);
//! - [`case`]: manufactured cases as TOML data, validated;
//! - [`manufactured`]: source terms f0, f2, f3, q derived by automatic differentiation;
//! - [`errors`]: the components of E(h, k) of Theorem 5.2;
//! - [`study`]: h-, k- and diagonal studies with rates and verdicts;
//! - [`report`]: CSV, JSON and SVG reports;
//! - [`cli`]: the `verify` command line.

pub mod case;
pub mod cli;
pub mod error;
pub mod errors;
pub mod expr;
pub mod manufactured;
pub mod output;
pub mod plot;
pub mod report;
pub mod study;

pub use error::VerifyError;
