//! Manufactured-solution convergence verification for the `contact-damage` solver
//! (Han, Shillor & Sofonea 2001, error estimate of Theorem 5.2).
//!
//! Building blocks of the verification harness:
//! - [`expr`], [`output`], [`InputError`]: the expression language, the atomic writers and the
//!   error type of the shared input layer (crate `contact-input`, re-exported here);
//! - [`plot`]: log–log convergence plots written as SVG;
//! - [`domain`]: the domain of a case, a box or a Gmsh mesh refined uniformly;
//! - [`case`]: manufactured cases as TOML data, validated (the `[laws]` and `[scheme]` tables
//!   and the box sides are read by `contact-input`, as in `simulate`'s problem files);
//! - [`manufactured`]: source terms f0, f2, f3, q derived by automatic differentiation;
//! - [`error_norms`]: the components of E(h, k) of Theorem 5.2;
//! - [`study`]: h-, k- and diagonal studies with rates and verdicts;
//! - [`regularity`]: regularity sweeps, the observed rates against the smoothness of the solution
//!   (the admissible exponents of their profiles in [`exponents`]);
//! - [`baseline`]: the committed baseline of the built-in cases and what moved in it;
//! - [`report`]: CSV, JSON and SVG reports, `report.md` and `tables.tex` ([`tables`]), from
//!   the rows of the CSV files ([`rows`]);
//! - [`sweep`]: plan / run one / merge / resume: manifests, the results cache, job arrays;
//! - [`cli`]: the `verify` command line.

pub mod baseline;
pub mod budget;
pub mod case;
pub mod cli;
pub mod domain;
pub mod error_norms;
pub mod exponents;
pub mod jump_planes;
pub mod manufactured;
pub mod plot;
pub mod regularity;
pub mod report;
pub mod rows;
pub mod smoothness;
pub mod study;
pub mod sweep;
pub mod tables;

/// The error type of the harness is that of the input layer ([`InputError`]; case-file errors
/// are [`FileKind::Case`](contact_input::FileKind::Case)).
pub use contact_input::{expr, output, InputError};
