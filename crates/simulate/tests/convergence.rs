//! `simulate --convergence`: a reduced rectangle_2d (8 × 4 cells, 50 steps, T = 1) on three
//! levels; the files agree with each other and with the levels' histories.

use std::path::Path;
use std::process::Command;

const EXAMPLE_2D: &str = include_str!("../examples/rectangle_2d.toml");

fn small_problem(dir: &Path) -> std::path::PathBuf {
    let text = EXAMPLE_2D
        .replace("cells = [40, 20]", "cells = [8, 4]")
        .replace("steps = 250", "steps = 50")
        .replace("final_time = 5.0", "final_time = 1.0")
        .replace("every = 10", "every = 50");
    assert!(text.contains("cells = [8, 4]") && text.contains("steps = 50"));
    let path = dir.join("small.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn simulate(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_simulate"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn three_levels_give_consistent_gci_files() {
    let scratch = tempfile::tempdir().unwrap();
    let problem = small_problem(scratch.path());
    let out = scratch.path().join("study");
    let output = simulate(&[
        "--convergence",
        "3",
        problem.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--at",
        "0.5,1",
        "-q",
    ]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(
        stdout.contains("h and k refined together by r = 2"),
        "{stdout}"
    );

    // the levels: cells and steps doubled, each with its history
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("convergence.json")).unwrap())
            .unwrap();
    let levels = json["levels"].as_array().unwrap();
    assert_eq!(levels.len(), 3);
    for (i, level) in levels.iter().enumerate() {
        assert_eq!(level["steps"], 50 << i);
        assert_eq!(level["cells"], serde_json::json!([8 << i, 4 << i]));
        assert!(level["max_kkt"]["velocity"].as_f64().unwrap() < 1e-8);
        assert!(level["max_kkt"]["damage"].as_f64().unwrap() < 1e-8);
    }

    // convergence.csv: one row per quantity, values equal to the histories at the step of t
    let csv = std::fs::read_to_string(out.join("convergence.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 2 * 2 + 4);
    let history = |level: usize| {
        let text = std::fs::read_to_string(out.join(format!("level_{level}/history.csv"))).unwrap();
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        let rows: Vec<Vec<String>> = lines
            .map(|l| l.split(',').map(String::from).collect())
            .collect();
        (header, rows)
    };
    for level in 0..3 {
        let (h_header, h_rows) = history(level);
        for row in &rows {
            let t: f64 = row[column("t")].parse().unwrap();
            let step = (t / (1.0 / (50 << level) as f64)).round() as usize;
            let c = h_header
                .iter()
                .position(|h| h == row[column("quantity")])
                .unwrap();
            let value: f64 = h_rows[step - 1][c].parse().unwrap();
            let reported: f64 = row[column(&format!("level_{level}"))].parse().unwrap();
            assert_eq!(value, reported, "{row:?}");
        }
    }
    // an order is given exactly for the monotone rows, and it matches the levels' values
    let mut monotone = 0;
    for row in &rows {
        let kind = row[column("convergence")];
        let order = row[column("order")];
        if kind == "monotone" {
            monotone += 1;
            let phi: Vec<f64> = (0..3)
                .map(|l| row[column(&format!("level_{l}"))].parse().unwrap())
                .collect();
            let ratio = (phi[1] - phi[0]) / (phi[2] - phi[1]);
            // constant ratio 2: p = ln(ε32/ε21)/ln 2 exactly
            let p: f64 = order.parse().unwrap();
            assert!((p - ratio.ln() / 2f64.ln()).abs() < 1e-9, "{row:?}");
            // Roache's GCI on the finest level (Celik et al. 2008, eq. (6), safety factor 1.25
            // for three grids): 1.25 |(φ1 − φ2)/φ1| / (r^p − 1) with φ1 the finest value
            // (level 2), and r^p = 2^p = ε32/ε21 = `ratio` for the constant ratio r = 2. The
            // tool computes 2^p from p; the two agree to rounding amplified by
            // r^p/(r^p − 1) (observed: at most 3.2e-16 relative, ratios 1.30 to 11.1).
            let gci: f64 = row[column("gci_fine")].parse().unwrap();
            let expected = 1.25 * ((phi[2] - phi[1]) / phi[2]).abs() / (ratio - 1.0);
            assert!(
                (gci - expected).abs() <= 1e-14 * expected,
                "GCI {gci} vs {expected} from the formula, {row:?}"
            );
        } else {
            assert_eq!(order, "—", "{row:?}");
            assert_eq!(row[column("gci_fine")], "—", "{row:?}");
        }
    }
    assert!(monotone >= 1, "{csv}");

    // report.md and tables.tex carry the same rows; every SVG it links exists
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let tex = std::fs::read_to_string(out.join("tables.tex")).unwrap();
    assert!(tex.contains("\\toprule") && tex.contains("\\bottomrule"));
    for row in &rows {
        let kind = row[column("convergence")];
        let name = row[column("quantity")].replace('_', "\\_");
        assert!(
            md.contains(&format!("| {name} | {} |", row[column("t")])),
            "{md}"
        );
        assert!(
            tex.contains(&format!("{name} & {}", row[column("t")])),
            "{tex}"
        );
        assert!(md.contains(kind) && tex.contains(kind));
    }
    for link in md.split("](").skip(1) {
        let file = link.split(')').next().unwrap();
        assert!(out.join(file).is_file(), "{file}");
        assert!(std::fs::read_to_string(out.join(file))
            .unwrap()
            .contains("<svg"));
    }
    for name in [
        "convergence.csv",
        "convergence.json",
        "report.md",
        "tables.tex",
    ] {
        assert!(out.join(name).is_file());
    }
}

#[test]
fn bad_requests_are_refused_with_a_clear_message() {
    let scratch = tempfile::tempdir().unwrap();
    let problem = small_problem(scratch.path());
    let out = scratch.path().join("study");
    let p = problem.to_str().unwrap();
    let o = out.to_str().unwrap();
    for (args, message) in [
        (
            vec!["--convergence", "2", p, "--out", o],
            "at least 3 levels",
        ),
        (vec!["--convergence", "3", p], "needs --out"),
        (
            vec!["--convergence", "3", p, "--out", o, "--at", "0.33"],
            "--at",
        ),
        (
            vec!["--convergence", "3", p, "--out", o, "--ratio", "1.3"],
            "--ratio",
        ),
    ] {
        let output = simulate(&args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{args:?}");
        assert!(stderr.contains(message), "{args:?}: {stderr}");
        assert!(!out.join("level_0").exists(), "{args:?}");
    }
    // a Gmsh mesh is refined uniformly, which halves h: another ratio is refused before
    // anything runs
    let gmsh = scratch.path().join("gmsh.toml");
    let text = std::fs::read_to_string(&problem).unwrap().replace(
        "box = { lower = [0.0, 0.0], upper = [2.0, 1.0], cells = [8, 4], sides = { x_min = \"clamped\", y_min = \"contact\" } }",
        "gmsh = { file = \"part.msh\", clamped = [\"left\"], contact = [\"bottom\"] }",
    );
    assert!(text.contains("gmsh ="));
    std::fs::write(&gmsh, text).unwrap();
    let output = simulate(&[
        "--convergence",
        "3",
        gmsh.to_str().unwrap(),
        "--out",
        o,
        "--ratio",
        "3",
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("use --ratio 2"), "{stderr}");
    assert!(!out.join("level_0").exists());
}

#[test]
fn the_size_of_every_level_is_checked_before_any_level_is_built() {
    let scratch = tempfile::tempdir().unwrap();
    let problem = small_problem(scratch.path());
    let out = scratch.path().join("study");
    let p = problem.to_str().unwrap();
    let o = out.to_str().unwrap();
    for (args, messages) in [
        // level 2 (32 × 16 cells) is above a limit of 1 MiB: refused before level 0 runs
        (
            vec![
                "--convergence",
                "3",
                p,
                "--out",
                o,
                "--memory-limit",
                "0.001",
            ],
            vec![
                "--convergence 3: level 2 (cells [32, 16])",
                "--memory-limit",
            ],
        ),
        // the finest level of 40 would have 8 × 2³⁹ cells per axis: refused at once
        (
            vec!["--convergence", "40", p, "--out", o],
            vec!["--convergence 40: at most 16 levels"],
        ),
        (
            vec!["--convergence", "18446744073709551615", p, "--out", o],
            vec!["at most 16 levels"],
        ),
        // 16 levels are allowed, but the finest (8 × 2¹⁵ by 4 × 2¹⁵ cells) needs far more
        // than the default limit
        (
            vec!["--convergence", "16", p, "--out", o],
            vec![
                "--convergence 16: level 15 (cells [262144, 131072])",
                "above the limit",
            ],
        ),
    ] {
        let output = simulate(&args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{args:?}: {stderr}");
        for message in messages {
            assert!(
                stderr.contains(message),
                "{args:?}: `{message}` not in {stderr}"
            );
        }
        assert!(!out.exists(), "{args:?}: {} was created", out.display());
    }
}

#[test]
fn a_report_of_the_user_in_out_is_never_replaced_without_overwrite() {
    let scratch = tempfile::tempdir().unwrap();
    let problem = small_problem(scratch.path());
    let out = scratch.path().join("study");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("report.md"), "my notes\n").unwrap();
    std::fs::write(out.join("notes.txt"), "kept\n").unwrap();
    let (p, o) = (problem.to_str().unwrap(), out.to_str().unwrap());
    let output = simulate(&["--convergence", "3", p, "--out", o, "-q"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("`report.md`") && stderr.contains("--overwrite"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("report.md")).unwrap(),
        "my notes\n"
    );
    assert!(!out.join("level_0").exists(), "a level ran");
    // --overwrite replaces the report names only
    let output = simulate(&["--convergence", "3", p, "--out", o, "-q", "--overwrite"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert_ne!(
        std::fs::read_to_string(out.join("report.md")).unwrap(),
        "my notes\n"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "kept\n"
    );
}
