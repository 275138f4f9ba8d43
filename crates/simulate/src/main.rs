//! `simulate PROBLEM.toml [--out DIR] [--resume]`: see the crate documentation.

use clap::Parser;
use simulate::run::RunOptions;
use std::path::PathBuf;
use std::process::ExitCode;
use verify::VerifyError;

/// Runs Problem P (contact, friction, damage) from a TOML problem file and writes VTU/PVD
/// files, history.csv and state.json.
#[derive(Debug, Parser)]
#[command(name = "simulate", version)]
struct Cli {
    /// The problem file (TOML).
    problem: PathBuf,
    /// Output folder (default: `output.dir` of the problem, or results/<name>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Continue from the last saved step (state.json in the output folder).
    #[arg(long, conflicts_with = "overwrite")]
    resume: bool,
    /// Start afresh even if the output folder holds a run.
    #[arg(long)]
    overwrite: bool,
    /// Stop after this step (saved, so that --resume continues from it).
    #[arg(long)]
    until_step: Option<usize>,
    /// No progress lines.
    #[arg(long, short)]
    quiet: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let options = RunOptions {
        out: cli.out,
        resume: cli.resume,
        overwrite: cli.overwrite,
        until_step: cli.until_step,
        quiet: cli.quiet,
    };
    match simulate::run_file(&cli.problem, &options) {
        Ok(outcome) => {
            println!(
                "steps {}..{} in {:.1} s, max KKT {:.1e} (velocity) {:.1e} (damage); output in {}",
                outcome.started_from + 1,
                outcome.last_step,
                outcome.seconds,
                outcome.max_kkt[0],
                outcome.max_kkt[1],
                outcome.output_dir.display()
            );
            ExitCode::SUCCESS
        }
        Err(VerifyError::Case { file, key, message }) => {
            eprintln!("simulate: problem file `{file}`, key `{key}`: {message}");
            ExitCode::FAILURE
        }
        Err(error) => {
            eprintln!("simulate: {error}");
            ExitCode::FAILURE
        }
    }
}
