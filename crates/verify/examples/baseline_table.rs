//! Prints the tables of `docs/results/verification.md` from the committed verification baseline:
//! `cargo run -p verify --example baseline_table [-- reports]`.
//!
//! For every `reports/<case>/l<order>/summary.json` (cases in the order of the built-in list):
//! one row per study with the least-squares rate of each component of E(h, k), the largest KKT
//! residual and the verdict; then one row per case and order with the Newton iterations of the
//! velocity step (5.1) per step (mean over all steps of all runs, max), the largest velocity KKT
//! residual and the summed wall time of the runs.

use serde_json::Value;
use std::path::{Path, PathBuf};
use verify::cli::BUILT_IN_CASES;

const COMPONENTS: [&str; 5] = [
    "displacement",
    "difference_quotient",
    "damage",
    "damage_gradient",
    "total",
];

fn read(path: &Path) -> Result<Value, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

fn number(value: &Value) -> Option<f64> {
    value.as_f64().filter(|v| v.is_finite())
}

fn main() -> Result<(), String> {
    let root = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "reports".to_string()),
    );
    let mut found = Vec::new();
    for (case, _) in BUILT_IN_CASES {
        for order in [1, 2] {
            let path = root
                .join(case)
                .join(format!("l{order}"))
                .join("summary.json");
            if path.exists() {
                found.push((case, order, read(&path)?));
            }
        }
    }
    if found.is_empty() {
        return Err(format!("no summary.json under {}", root.display()));
    }
    println!("| case | d | l | study | levels (cells/steps) | expected | ‖u‖_V | ‖δu‖_V | ‖β‖_L² | (kΣ‖∇β‖²)^½ | E(h,k) | max KKT | verdict |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (case, order, summary) in &found {
        let dim = summary["dim"].as_u64().unwrap_or(0);
        for study in summary["studies"].as_array().into_iter().flatten() {
            let runs = study["runs"].as_array().cloned().unwrap_or_default();
            let levels: Vec<String> = runs
                .iter()
                .map(|r| format!("{}/{}", r["cells"], r["steps"]))
                .collect();
            let kkt = runs
                .iter()
                .filter_map(|r| number(&r["stats"]["max_velocity_kkt"]))
                .chain(
                    runs.iter()
                        .filter_map(|r| number(&r["stats"]["max_damage_kkt"])),
                )
                .fold(0.0f64, f64::max);
            let rate = |component: &str| {
                study["rates"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .find(|r| r["component"] == component)
                    .and_then(|r| number(&r["least_squares"]))
                    .map_or("—".to_string(), |v| format!("{v:.2}"))
            };
            let rates: Vec<String> = COMPONENTS
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    if i == COMPONENTS.len() - 1 {
                        format!("**{}**", rate(c))
                    } else {
                        rate(c)
                    }
                })
                .collect();
            println!(
                "| {case} | {dim} | {order} | {} | {} | {} | {} | {kkt:.0e} | {} |",
                study["kind"].as_str().unwrap_or("?"),
                levels.join(", "),
                number(&study["expected_rate"]).map_or("—".into(), |v| format!("{v:.2}")),
                rates.join(" | "),
                study["verdict"].as_str().unwrap_or("?").to_uppercase()
            );
        }
    }
    println!();
    println!("| case | l | Newton iterations of (5.1) per step, mean / max | max velocity KKT | Σ run wall time (s) |");
    println!("|---|---|---|---|---|");
    for (case, order, summary) in &found {
        let runs: Vec<&Value> = summary["studies"]
            .as_array()
            .into_iter()
            .flatten()
            .flat_map(|s| s["runs"].as_array().into_iter().flatten())
            .collect();
        let steps: f64 = runs.iter().filter_map(|r| number(&r["steps"])).sum();
        let newton: f64 = runs
            .iter()
            .filter_map(|r| number(&r["stats"]["newton_iterations"]))
            .sum();
        let most = runs
            .iter()
            .filter_map(|r| r["stats"]["max_newton_iterations"].as_u64())
            .max()
            .unwrap_or(0);
        let kkt = runs
            .iter()
            .filter_map(|r| number(&r["stats"]["max_velocity_kkt"]))
            .fold(0.0f64, f64::max);
        let wall: f64 = runs
            .iter()
            .filter_map(|r| number(&r["stats"]["wall_seconds"]))
            .sum();
        println!(
            "| {case} | {order} | {:.2} / {most} | {kkt:.1e} | {wall:.1} |",
            newton / steps.max(1.0)
        );
    }
    Ok(())
}
