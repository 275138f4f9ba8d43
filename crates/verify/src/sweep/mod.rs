//! Studies beyond one process: a manifest of every run ([`plan`]), running one run or a share
//! of them ([`run`], [`shard`]) into a results folder of one checked file per run ([`cache`]), and merging
//! the results into the studies and their reports ([`merge`]).
//!
//! A single-process `verify` is the same three steps in one process (plan, run what the results
//! folder `<out>/runs/` does not hold yet, merge), so its reports and those of `verify merge`
//! come from the same code.

pub mod cache;
pub mod merge;
pub mod plan;
pub mod run;
pub mod shard;
