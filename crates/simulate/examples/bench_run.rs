//! Wall time of a whole `simulate` run of the benchmark problem, set-up and output included:
//!
//! ```text
//! cargo run --release -p simulate --example bench_run -- [N] [REPEATS]
//! ```
//!
//! The problem is `examples/rectangle_2d.toml` on the unit square with N × N cells (default
//! 128), T = 1 and 128 steps, saved every 10 steps as in the example (13 snapshots), run on one
//! thread, REPEATS times (default 3) into a fresh folder under the system's temporary
//! directory, which is removed afterwards. Prints each wall time, the fastest and the median.
//! A benchmark, not a test: nothing is asserted.

use simulate::run::RunOptions;
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let cells: usize = args.first().map_or(Ok(128), |a| a.parse())?;
    let repeats: usize = args.get(1).map_or(Ok(3), |a| a.parse())?;
    if cells == 0 || repeats == 0 {
        return Err("N and REPEATS must be positive".into());
    }
    contact_input::threads::set_threads(Some(1))?;
    let mut text = include_str!("rectangle_2d.toml").to_string();
    for (from, to) in [
        (
            "upper = [2.0, 1.0], cells = [40, 20]".to_string(),
            format!("upper = [1.0, 1.0], cells = [{cells}, {cells}]"),
        ),
        (
            "final_time = 5.0".to_string(),
            "final_time = 1.0".to_string(),
        ),
        ("steps = 250".to_string(), "steps = 128".to_string()),
    ] {
        if !text.contains(&from) {
            return Err(format!("rectangle_2d.toml no longer contains `{from}`").into());
        }
        text = text.replace(&from, &to);
    }
    let dir = std::env::temp_dir().join(format!("bench-run-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let problem = dir.join(format!("rectangle_{cells}.toml"));
    let times = std::fs::write(&problem, text)
        .map_err(Into::into)
        .and_then(|()| time_runs(&problem, &dir.join("out"), repeats));
    // the folder goes whether the runs succeeded or not
    std::fs::remove_dir_all(&dir)?;
    let mut times = times?;
    times.sort_by(f64::total_cmp);
    println!(
        "rectangle_2d on (0,1)², {cells}×{cells} cells, 128 steps, one thread: fastest {:.2} s, median {:.2} s",
        times[0],
        times[times.len() / 2]
    );
    Ok(())
}

/// Wall seconds of `repeats` runs of `problem` into `out`, each printed.
fn time_runs(
    problem: &Path,
    out: &Path,
    repeats: usize,
) -> Result<Vec<f64>, Box<dyn std::error::Error>> {
    let mut times = Vec::new();
    for repeat in 0..repeats {
        let options = RunOptions {
            out: Some(out.to_path_buf()),
            overwrite: true,
            quiet: true,
            ..RunOptions::default()
        };
        let started = Instant::now();
        let outcome = simulate::run_file(problem, &options)?;
        let seconds = started.elapsed().as_secs_f64();
        println!(
            "run {}: {seconds:.2} s ({} steps, {} snapshots)",
            repeat + 1,
            outcome.last_step,
            outcome.saved_steps.len()
        );
        times.push(seconds);
    }
    Ok(times)
}
