//! Compares the errors of two baselines, e.g. the committed `reports/` before and after a
//! change of the harness:
//!
//! ```text
//! cargo run -p verify --example compare_baselines -- OLD_REPORTS NEW_REPORTS [TOLERANCE]
//! ```
//!
//! For every `<case>/l<order>/errors.csv` present in both folders, the runs of the same study
//! at the same level (cells and steps) are paired and every component of E(h, k) and the
//! velocity error is compared; prints the largest relative difference per case and order and
//! exits with status 1 if one exceeds TOLERANCE (default 1e-10). Levels present in only one
//! baseline are counted, not compared.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::ExitCode;
use verify::cli::BUILT_IN_CASES;

const COMPONENTS: [&str; 6] = [
    "displacement",
    "difference_quotient",
    "damage",
    "damage_gradient",
    "total",
    "velocity",
];

/// (study, cells, steps) → the components (None for `—`).
type Rows = BTreeMap<(String, String, String), Vec<Option<f64>>>;

fn read(path: &Path) -> Result<Rows, String> {
    let mut reader =
        csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let headers = reader
        .headers()
        .map_err(|e| format!("{}: {e}", path.display()))?
        .clone();
    let column = |name: &str| {
        headers
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| format!("{}: no column `{name}`", path.display()))
    };
    let keys = [column("study")?, column("cells")?, column("steps")?];
    let values: Vec<usize> = COMPONENTS
        .iter()
        .map(|name| column(name))
        .collect::<Result<_, _>>()?;
    let mut rows = Rows::new();
    for record in reader.records() {
        let record = record.map_err(|e| format!("{}: {e}", path.display()))?;
        let key = (
            record[keys[0]].to_string(),
            record[keys[1]].to_string(),
            record[keys[2]].to_string(),
        );
        let components = values
            .iter()
            .map(|&c| record[c].parse::<f64>().ok())
            .collect();
        rows.insert(key, components);
    }
    Ok(rows)
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: compare_baselines OLD_REPORTS NEW_REPORTS [TOLERANCE]");
        return ExitCode::FAILURE;
    }
    let tolerance: f64 = args.get(3).map_or(1e-10, |t| t.parse().expect("a number"));
    let mut worst_overall = 0.0f64;
    let mut failed = false;
    println!("| case | l | runs compared | only old | only new | max relative difference |");
    println!("|---|---|---|---|---|---|");
    for (case, _) in BUILT_IN_CASES {
        for order in [1, 2] {
            let relative = format!("{case}/l{order}/errors.csv");
            let (old, new) = (
                Path::new(&args[1]).join(&relative),
                Path::new(&args[2]).join(&relative),
            );
            if !old.exists() || !new.exists() {
                continue;
            }
            let (old, new) = match (read(&old), read(&new)) {
                (Ok(old), Ok(new)) => (old, new),
                (Err(e), _) | (_, Err(e)) => {
                    eprintln!("{e}");
                    return ExitCode::FAILURE;
                }
            };
            let mut worst = 0.0f64;
            let mut compared = 0;
            for (key, old_values) in &old {
                let Some(new_values) = new.get(key) else {
                    continue;
                };
                compared += 1;
                for (a, b) in old_values.iter().zip(new_values) {
                    match (a, b) {
                        (Some(a), Some(b)) => {
                            worst = worst.max((a - b).abs() / a.abs().max(f64::MIN_POSITIVE))
                        }
                        (None, None) => {}
                        _ => worst = f64::INFINITY,
                    }
                }
            }
            let only_old = old.keys().filter(|k| !new.contains_key(*k)).count();
            let only_new = new.keys().filter(|k| !old.contains_key(*k)).count();
            println!("| {case} | {order} | {compared} | {only_old} | {only_new} | {worst:.1e} |");
            worst_overall = worst_overall.max(worst);
            failed |= worst > tolerance;
        }
    }
    println!("\nlargest relative difference {worst_overall:.1e} (tolerance {tolerance:.0e})");
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
