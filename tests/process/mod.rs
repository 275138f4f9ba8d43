//! Standard streams, time limits and the judgement of a refusal for the end-to-end tests that
//! run the programs (shared by `tests/cli.rs`, `tests/catalogue.rs` and
//! `crates/simulate/tests/hostile.rs`, `catalogue.rs`).
#![allow(dead_code)]

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// `/dev/full`, opened for writing: every write fails with ENOSPC.
pub fn full_disk() -> Stdio {
    std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .unwrap()
        .into()
}

/// The write end of a pipe whose read end is already closed: every write fails with EPIPE.
/// (The read end belongs to a `true` process, which has exited when this returns.)
pub fn closed_pipe() -> Stdio {
    let mut reader = Command::new("true").stdin(Stdio::piped()).spawn().unwrap();
    let writer = reader.stdin.take().unwrap();
    assert!(reader.wait().unwrap().success());
    writer.into()
}

/// Runs `command` with its output captured; a run that has not ended after a minute is killed
/// and fails the test (what a blocked read of a named pipe would do).
pub fn output_within_a_minute(mut command: Command) -> Output {
    let mut child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            child.kill().unwrap();
            panic!("{command:?} did not end within a minute");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

/// What is wrong with `output` as the refusal of a bad input, if anything: it must end with
/// exit status `status`, name `expected` (the file and the key) on standard error, and neither
/// panic nor report a solver that did not converge.
pub fn refusal_fault(output: &Output, status: i32, expected: &str) -> Option<String> {
    let message = String::from_utf8_lossy(&output.stderr);
    let fault = if output.status.code() != Some(status) {
        format!("exit status {:?}", output.status.code())
    } else if !message.contains(expected) {
        format!("no `{expected}`")
    } else if message.contains("panicked") || message.contains("did not converge") {
        "a panic or a stagnating solver".to_string()
    } else {
        return None;
    };
    Some(format!("{fault}\n  {message}"))
}
