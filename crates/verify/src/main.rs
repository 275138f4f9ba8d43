//! `verify`: see [`verify::cli`]. Exit status 0 (PASS), 1 (FAIL, or runs without a result), 3
//! (DRIFTING), 2 (an error), 141 (standard output or error is a closed pipe, e.g. `| head`: the
//! program ends quietly at the first line it cannot write). Every line goes through
//! [`contact_input::console`]: a write that fails is an error, never a panic.

use clap::Parser;
use std::process::ExitCode;
use verify::cli::{main_with, Cli};

/// The end of the program after `error`: status 2 after the message on standard error, or 141
/// quietly for a closed pipe ([`contact_input::console::exit_status`]).
fn fail(error: &verify::InputError) -> ExitCode {
    ExitCode::from(contact_input::console::exit_status(
        "error",
        error,
        error.is_closed_pipe(),
        2,
    ))
}

/// The end of the program for a command line that clap did not run (`--help`, `--version`, a
/// usage error): its text written without panicking, and clap's status.
fn clap_exit(error: &clap::Error) -> ExitCode {
    match contact_input::console::write_clap_message(error, 2) {
        Ok(status) => ExitCode::from(status),
        Err(failed) => fail(&failed.into()),
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error) => return clap_exit(&error),
    };
    match main_with(cli) {
        Ok(outcome) => ExitCode::from(outcome.exit_status()),
        Err(error) => fail(&error),
    }
}
