//! The end-to-end tests and the CI rate assertions of the workspace (package `verify`), built
//! as one test binary: the solver's generic code is instantiated and linked once for all of
//! them, and their tests share one process (none of them touches process-wide state).

mod common;
mod guide;
mod process;

mod baselines;
mod case_fuzz;
mod cases;
mod catalogue;
mod cli;
mod docs;
mod negative_controls;
mod rates;
mod regularity;
mod sweep;
