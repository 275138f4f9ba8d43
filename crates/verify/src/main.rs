use clap::Parser;
use std::process::ExitCode;
use verify::cli::{main_with, Cli};

fn main() -> ExitCode {
    match main_with(Cli::parse()) {
        Ok(outcome) => ExitCode::from(outcome.exit_status()),
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::from(2)
        }
    }
}
