//! `simulate PROBLEM.toml [--out DIR] [--resume]`, or
//! `simulate --convergence K PROBLEM.toml --out DIR [--ratio R] [--at t1,t2]` (solution
//! verification, [`simulate::convergence`]): see the crate documentation.
//!
//! Exit codes: 0 done, 1 error, 130 interrupted by Ctrl-C (the step in progress was finished
//! and saved; `--resume` continues), 141 standard output or error is a closed pipe (e.g. `|
//! head`; the program ends quietly at the first line it cannot write). A second Ctrl-C ends the
//! program at once; every file on disk is then still whole (all of them are written atomically
//! or appended line by line). Every line goes through [`contact_input::console`]: a write that
//! fails is an error, never a panic.

use clap::Parser;
use contact_input::{errln, outln, InputError};
use simulate::run::RunOptions;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

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
    /// Worker threads, 1 ..= 4 × the available cores (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Refuse problems whose estimated memory exceeds this many GiB (default: the physical
    /// memory of the machine).
    #[arg(long, value_name = "GiB")]
    memory_limit: Option<f64>,
    /// Solution verification: run K ≥ 3 levels refined in h and k together and write the GCI
    /// of the quantities of interest (convergence.csv/json, report.md, tables.tex, SVGs) to --out.
    #[arg(long, value_name = "K", conflicts_with_all = ["resume", "until_step"])]
    convergence: Option<usize>,
    /// Refinement ratio of h and k between levels (with --convergence).
    #[arg(long, default_value_t = 2.0, requires = "convergence")]
    ratio: f64,
    /// Times of the contact force and zone (with --convergence; default T/2 and T).
    #[arg(long, value_delimiter = ',', requires = "convergence")]
    at: Option<Vec<f64>>,
}

/// The end of the program after `error`: status 1 after the message on standard error, or 141
/// quietly for a closed pipe ([`contact_input::console::exit_status`]).
fn fail(error: &InputError) -> ExitCode {
    ExitCode::from(contact_input::console::exit_status(
        "simulate",
        error,
        error.is_closed_pipe(),
        1,
    ))
}

/// The end of the program for a command line that clap did not run (`--help`, `--version`, a
/// usage error): its text written without panicking, and clap's status.
fn clap_exit(error: &clap::Error) -> ExitCode {
    match contact_input::console::write_clap_message(error, 1) {
        Ok(status) => ExitCode::from(status),
        Err(failed) => fail(&failed.into()),
    }
}

/// `--convergence`: runs the levels, prints the table and writes the files.
fn convergence(cli: &Cli, levels: usize) -> ExitCode {
    let Some(out) = cli.out.clone() else {
        return fail(&InputError::InvalidInput(
            "--convergence needs --out DIR (the levels and the reports go there)".to_string(),
        ));
    };
    let options = simulate::convergence::ConvergenceOptions {
        levels,
        ratio: cli.ratio,
        at: cli.at.clone(),
        out: out.clone(),
        overwrite: cli.overwrite,
        quiet: cli.quiet,
        memory_limit: cli
            .memory_limit
            .map(|gib| gib * contact_damage::algebra::memory::GIB),
    };
    let result = simulate::convergence::run_convergence(&cli.problem, &options).and_then(|study| {
        outln!("{}", simulate::convergence::report::table(&study))?;
        let written = simulate::convergence::report::write_files(&out, &study)?;
        for path in written {
            outln!("wrote {}", path.display())?;
        }
        Ok(())
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => fail(&error),
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error) => return clap_exit(&error),
    };
    if let Err(error) = contact_input::threads::set_threads(cli.threads) {
        return fail(&error);
    }
    if let Some(gib) = cli.memory_limit {
        if !(gib.is_finite() && gib > 0.0) {
            return fail(&InputError::InvalidInput(format!(
                "--memory-limit {gib}: must be a positive number of GiB"
            )));
        }
    }
    if let Some(levels) = cli.convergence {
        return convergence(&cli, levels);
    }
    let interrupt = Arc::new(AtomicBool::new(false));
    let flag = interrupt.clone();
    let handler = ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::SeqCst) {
            // standard error may be gone too: the status says it all
            let _ = errln!("simulate: second interrupt, stopping now");
            std::process::exit(130);
        }
        let _ = errln!(
            "simulate: interrupt, finishing the step in progress (Ctrl-C again to stop now)"
        );
    });
    if let Err(error) = handler {
        return fail(&InputError::InvalidInput(format!(
            "cannot install the Ctrl-C handler: {error}"
        )));
    }
    let options = RunOptions {
        out: cli.out,
        resume: cli.resume,
        overwrite: cli.overwrite,
        until_step: cli.until_step,
        quiet: cli.quiet,
        interrupt: Some(interrupt),
        memory_limit: cli
            .memory_limit
            .map(|gib| gib * contact_damage::algebra::memory::GIB),
    };
    let result = simulate::run_file(&cli.problem, &options).and_then(|outcome| {
        report(&outcome)?;
        Ok(outcome)
    });
    match result {
        Ok(outcome) if outcome.interrupted => ExitCode::from(130),
        Ok(_) => ExitCode::SUCCESS,
        Err(error) => fail(&error),
    }
}

/// The last line of a run: how it ended and where its output is.
fn report(outcome: &simulate::run::RunOutcome) -> Result<(), InputError> {
    match outcome {
        outcome if outcome.interrupted => {
            outln!(
                "interrupted after step {} ({:.1} s); output in {}; continue with --resume",
                outcome.last_step,
                outcome.seconds,
                outcome.output_dir.display()
            )?;
        }
        outcome if outcome.last_step <= outcome.started_from => {
            outln!(
                "nothing to do: the run in {} already reached step {}; output unchanged",
                outcome.output_dir.display(),
                outcome.started_from
            )?;
        }
        outcome => {
            outln!(
                "steps {}..{} in {:.1} s, max KKT {:.1e} (velocity) {:.1e} (damage); output in {}",
                outcome.started_from + 1,
                outcome.last_step,
                outcome.seconds,
                outcome.max_kkt.velocity,
                outcome.max_kkt.damage,
                outcome.output_dir.display()
            )?;
        }
    }
    Ok(())
}
