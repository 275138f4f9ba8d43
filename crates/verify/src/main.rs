use clap::Parser;
use std::process::ExitCode;
use verify::cli::{main_with, Cli};

fn main() -> ExitCode {
    match main_with(Cli::parse()) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(1),
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::from(2)
        }
    }
}
