//! The integration tests of the solver crate, built as one test binary: the generic solver code
//! is instantiated and linked once for all of them, and their tests share one process (none of
//! them touches process-wide state).

mod common;

mod bulk_data;
mod curved;
mod damage_iterations;
mod implicit_contact;
mod invalid_input;
mod patch;
mod prescribed;
mod solver_kkt;
mod step_limit;
mod symmetry;
mod time_rate;
mod velocity_nonlinear;
