//! The input layer shared by the `verify` harness and the `simulate` command (both read TOML
//! files describing Problem P of Han, Shillor & Sofonea 2001 and write report files):
//! - [`expr`]: closed-form expressions in named variables, evaluated on `f64` or on `num-dual`
//!   numbers (derivatives by automatic differentiation), tree-walking or compiled;
//! - [`file`](mod@file): TOML text of an input file into its tables, expression and number entries;
//! - [`laws`]: the `[laws]` table, built and validated as the solver's model;
//! - [`sides`]: the sides of a box domain and their boundary parts Γ1, Γ2, Γ3;
//! - [`scheme`]: the `[scheme]` table (explicit or implicit normal compliance);
//! - [`output`]: atomic writing of output files (raw bytes, JSON, CSV), missing values;
//! - [`console`]: writing to standard output and error without panicking;
//! - [`threads`]: the `--threads` option;
//! - [`written`]: which files of a folder a program wrote, so that it replaces no other;
//! - [`regular`]: input files are read only when they are regular files;
//! - [`number`]: numbers in messages, printed short;
//! - [`mutation`]: hostile edits of input text for the parsers' robustness tests;
//! - [`error`]: the error type, naming file, key or line; the file kind ("case" or
//!   "problem file") is the caller's ([`FileKind`]).

pub mod console;
pub mod error;
pub mod expr;
pub mod file;
pub mod laws;
pub mod mutation;
pub mod number;
pub mod output;
pub mod regular;
pub mod scheme;
pub mod sides;
pub mod threads;
pub mod written;

pub use error::{FileKind, InputError};
