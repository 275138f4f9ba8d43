//! The end-to-end tests of `simulate`, built as one test binary: the generic solver code
//! is instantiated and linked once for all of them, and their tests share one process (none of
//! them touches process-wide state).

mod common;
#[path = "../../../tests/guide/mod.rs"]
mod guide;
#[path = "../../../tests/process/mod.rs"]
mod process;

mod catalogue;
mod convergence;
mod docs;
mod gmsh_example;
mod gmsh_example_3d;
mod hostile;
mod loads;
mod problem_fuzz;
mod runs;
mod validation;
