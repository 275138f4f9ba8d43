//! `simulate PROBLEM.toml [--out DIR] [--resume]`, or
//! `simulate --convergence K PROBLEM.toml --out DIR [--ratio R] [--at t1,t2]` (solution
//! verification, [`simulate::convergence`]): see the crate documentation.
//!
//! Exit codes: 0 done, 1 error, 130 interrupted by Ctrl-C (the step in progress was finished
//! and saved; `--resume` continues). A second Ctrl-C ends the program at once; every file on
//! disk is then still whole (all of them are written atomically or appended line by line).

use clap::Parser;
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

/// `--convergence`: runs the levels, prints the table and writes the files.
fn convergence(cli: &Cli, levels: usize) -> ExitCode {
    let Some(out) = cli.out.clone() else {
        eprintln!("simulate: --convergence needs --out DIR (the levels and the reports go there)");
        return ExitCode::FAILURE;
    };
    let options = simulate::convergence::ConvergenceOptions {
        levels,
        ratio: cli.ratio,
        at: cli.at.clone(),
        out: out.clone(),
        overwrite: cli.overwrite,
        quiet: cli.quiet,
    };
    let result = simulate::convergence::run_convergence(&cli.problem, &options).and_then(|study| {
        println!("{}", simulate::convergence::report::table(&study));
        simulate::convergence::report::write_files(&out, &study)
    });
    match result {
        Ok(written) => {
            for path in written {
                println!("wrote {}", path.display());
            }
            ExitCode::SUCCESS
        }
        Err(error) => {
            eprintln!("simulate: {error}");
            ExitCode::FAILURE
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(error) = contact_input::threads::set_threads(cli.threads) {
        eprintln!("simulate: {error}");
        return ExitCode::FAILURE;
    }
    if let Some(gib) = cli.memory_limit {
        if !(gib.is_finite() && gib > 0.0) {
            eprintln!("simulate: --memory-limit {gib}: must be a positive number of GiB");
            return ExitCode::FAILURE;
        }
    }
    if let Some(levels) = cli.convergence {
        return convergence(&cli, levels);
    }
    let interrupt = Arc::new(AtomicBool::new(false));
    let flag = interrupt.clone();
    let handler = ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::SeqCst) {
            eprintln!("simulate: second interrupt, stopping now");
            std::process::exit(130);
        }
        eprintln!("simulate: interrupt, finishing the step in progress (Ctrl-C again to stop now)");
    });
    if let Err(error) = handler {
        eprintln!("simulate: cannot install the Ctrl-C handler: {error}");
        return ExitCode::FAILURE;
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
    match simulate::run_file(&cli.problem, &options) {
        Ok(outcome) if outcome.interrupted => {
            println!(
                "interrupted after step {} ({:.1} s); output in {}; continue with --resume",
                outcome.last_step,
                outcome.seconds,
                outcome.output_dir.display()
            );
            ExitCode::from(130)
        }
        Ok(outcome) if outcome.last_step <= outcome.started_from => {
            println!(
                "nothing to do: the run in {} already reached step {}; output unchanged",
                outcome.output_dir.display(),
                outcome.started_from
            );
            ExitCode::SUCCESS
        }
        Ok(outcome) => {
            println!(
                "steps {}..{} in {:.1} s, max KKT {:.1e} (velocity) {:.1e} (damage); output in {}",
                outcome.started_from + 1,
                outcome.last_step,
                outcome.seconds,
                outcome.max_kkt.velocity,
                outcome.max_kkt.damage,
                outcome.output_dir.display()
            );
            ExitCode::SUCCESS
        }
        Err(error) => {
            eprintln!("simulate: {error}");
            ExitCode::FAILURE
        }
    }
}
