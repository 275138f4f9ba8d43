//! Hostile input to the `simulate` binary: a fresh run never deletes or overwrites a
//! file of the user, `--overwrite` and `--resume` remove stale temporaries of our writers and
//! nothing else, `--threads` out of range and a 3D problem without a contact face are refused
//! before any work, with a message naming the option or key.

use crate::common;
use crate::process;

use common::scratch;
use process::{closed_pipe, full_disk, output_within_a_minute};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const EXAMPLE_3D: &str = include_str!("../examples/block_3d.toml");

/// The 2D example on an 8 × 4 mesh with 8 steps, saved every 4, as `dir/small.toml`.
fn small_problem(dir: &Path) -> PathBuf {
    let path = dir.join("small.toml");
    std::fs::write(&path, crate::catalogue::small_example()).unwrap();
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

/// Name → contents of every file in `dir`.
fn contents(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|entry| {
            let entry = entry.unwrap();
            (
                entry.file_name().into_string().unwrap(),
                std::fs::read(entry.path()).unwrap(),
            )
        })
        .collect()
}

/// The user's own files, whose names only look like those a run writes.
const USER_FILES: [(&str, &str); 5] = [
    ("solution_final.vtu", "mine: final solution\n"),
    ("damage_map.svg", "mine: damage map\n"),
    ("notes.tmp", "mine: notes\n"),
    (
        ".solution_final.vtu.12.0.tmp",
        "mine: looks like a temporary\n",
    ),
    (".mine.tmp", "mine: hidden\n"),
];

fn write_user_files(dir: &Path) {
    for (name, text) in USER_FILES {
        std::fs::write(dir.join(name), text).unwrap();
    }
}

fn assert_user_files_kept(dir: &Path) {
    for (name, text) in USER_FILES {
        assert_eq!(
            std::fs::read_to_string(dir.join(name)).unwrap(),
            text,
            "{name} was changed"
        );
    }
}

/// Stale temporaries as `kill -9` leaves them (both atomic writers' patterns).
const STALE: [&str; 4] = [
    ".solution_000008.vtu.999999.0.tmp",
    ".solution.pvd.999999.1.tmp",
    ".history.csv.tmp.999999.3",
    ".state.json.tmp.999999.4",
];

#[test]
fn fresh_run_refuses_a_folder_holding_files_of_the_names_it_writes() {
    let dir = scratch("hostile-data-loss");
    let problem = small_problem(&dir);
    // a folder of the user's files, two of them named as files the run writes
    let out = dir.join("d");
    std::fs::create_dir_all(&out).unwrap();
    write_user_files(&out); // solution_final.vtu among them
    std::fs::write(out.join("history.csv"), "x\n").unwrap();
    let before = contents(&out);

    let output = simulate(&problem, &out, &[]);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(1), "{message}");
    assert!(
        message.contains(&out.display().to_string())
            && message.contains("`history.csv`")
            && message.contains("--overwrite")
            && message.contains("--out"),
        "{message}"
    );
    assert_eq!(contents(&out), before, "the folder was changed");

    // a folder holding only a per-step file of an earlier run is refused too
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("damage_000004.svg"), "x\n").unwrap();
    let output = simulate(&problem, &other, &[]);
    assert_eq!(output.status.code(), Some(1));
    assert!(
        stderr(&output).contains("`damage_000004.svg`"),
        "{}",
        stderr(&output)
    );
    assert_eq!(
        std::fs::read_to_string(other.join("damage_000004.svg")).unwrap(),
        "x\n"
    );

    // files that only look like ours do not stop a fresh run, and are kept
    let alike = dir.join("alike");
    std::fs::create_dir_all(&alike).unwrap();
    write_user_files(&alike);
    let output = simulate(&problem, &alike, &[]);
    assert!(output.status.success(), "{}", stderr(&output));
    assert_user_files_kept(&alike);
    assert!(alike.join("solution_000008.vtu").exists());

    // with --overwrite the run proceeds: our names are replaced, the user's others kept
    let output = simulate(&problem, &out, &["--overwrite"]);
    assert!(output.status.success(), "{}", stderr(&output));
    assert!(std::fs::read_to_string(out.join("history.csv"))
        .unwrap()
        .starts_with("step,"));
    assert_user_files_kept(&out);
}

#[test]
fn overwrite_and_resume_remove_stale_temporaries_and_nothing_else() {
    let dir = scratch("hostile-temporaries");
    let problem = small_problem(&dir);
    let out = dir.join("out");
    let output = simulate(&problem, &out, &["--until-step", "4"]);
    assert!(output.status.success(), "{}", stderr(&output));
    write_user_files(&out);

    for flags in [&["--resume", "--until-step", "6"][..], &["--overwrite"][..]] {
        for name in STALE {
            std::fs::write(out.join(name), "half a file").unwrap();
        }
        let output = simulate(&problem, &out, flags);
        assert!(output.status.success(), "{flags:?}: {}", stderr(&output));
        for name in STALE {
            assert!(!out.join(name).exists(), "{flags:?}: {name} is still there");
        }
        assert_user_files_kept(&out);
    }
    // --overwrite started afresh: the steps of the resumed run are gone or rewritten
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    assert_eq!(history.lines().count(), 1 + 8);

    // a stale temporary alone also stops a fresh run (it is ours; --overwrite removes it)
    let fresh = dir.join("fresh");
    std::fs::create_dir_all(&fresh).unwrap();
    std::fs::write(fresh.join(STALE[0]), "half a file").unwrap();
    let output = simulate(&problem, &fresh, &[]);
    assert_eq!(output.status.code(), Some(1));
    assert!(stderr(&output).contains(STALE[0]), "{}", stderr(&output));
    assert!(fresh.join(STALE[0]).exists());
}

#[test]
fn threads_out_of_range_are_refused_before_any_work() {
    let dir = scratch("hostile-threads");
    let problem = small_problem(&dir);
    let out = dir.join("out");
    for threads in ["10000", "0"] {
        let output = simulate(&problem, &out, &["--threads", threads]);
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(1), "{message}");
        assert!(
            message.contains(&format!("--threads {threads}")) && message.contains("1 ..= "),
            "{message}"
        );
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

#[test]
fn out_that_is_a_file_is_refused_with_its_name() {
    let dir = scratch("hostile-out-file");
    let problem = small_problem(&dir);
    let out = dir.join("results.txt");
    std::fs::write(&out, "mine\n").unwrap();
    let output = simulate(&problem, &out, &[]);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(1), "{message}");
    assert!(
        message.contains(&out.display().to_string()) && message.contains("not a folder"),
        "{message}"
    );
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "mine\n");
}

/// A contact stiffness or a viscosity that makes k exceed the stability limit of the explicit
/// terms of (5.1): unchecked, such runs go to the end with displacements of 1e9…1e91 and exit
/// code 0. They are refused before anything is written, naming the step, the limit and the
/// remedies; with the implicit normal compliance the stiff foundation runs.
#[test]
fn step_above_the_stability_limit_is_refused_before_anything_is_written() {
    let dir = scratch("simulate-step-limit");
    let problem = small_problem(&dir);
    let text = std::fs::read_to_string(&problem).unwrap();
    for (name, from, to) in [
        ("stiff", "stiffness = 4.0", "stiffness = 1e6"),
        (
            "soft",
            "shear = 3.0, bulk = 1.5",
            "shear = 1e-12, bulk = 0.0",
        ),
    ] {
        let changed = dir.join(format!("{name}.toml"));
        assert!(text.contains(from));
        std::fs::write(&changed, text.replace(from, to)).unwrap();
        let out = dir.join(format!("out-{name}"));
        let output = simulate(&changed, &out, &[]);
        assert_eq!(output.status.code(), Some(1), "{name}");
        let message = stderr(&output);
        for part in [
            "time step k",
            "exceeds the stability limit",
            "raise `steps` to at least",
        ] {
            assert!(
                message.contains(part),
                "{name}: `{part}` missing in {message}"
            );
        }
        assert!(
            !out.exists(),
            "{name}: the refused run wrote {}",
            out.display()
        );
    }
    // the stiff foundation with p_ν taken implicitly: only the elastic limit applies, and it holds
    let stiff = dir.join("stiff.toml");
    let message = stderr(&simulate(&stiff, &dir.join("x"), &[]));
    assert!(
        message.contains("[scheme] contact = \"implicit\""),
        "{message}"
    );
    let implicit = dir.join("implicit.toml");
    std::fs::write(
        &implicit,
        format!(
            "{}\n[scheme]\ncontact = \"implicit\"\n",
            std::fs::read_to_string(&stiff).unwrap()
        ),
    )
    .unwrap();
    let output = simulate(&implicit, &dir.join("out-implicit"), &[]);
    assert!(output.status.success(), "{}", stderr(&output));
}

/// A load expression undefined at a time between the checks at load (t = 0, T/2, T) stops the
/// run with the file, the key and the time, not with a degree of freedom of the solver.
#[test]
fn a_load_undefined_at_one_time_names_its_key_and_the_time() {
    let dir = scratch("hostile-load-nan");
    let problem = small_problem(&dir);
    let text = std::fs::read_to_string(&problem).unwrap();
    for (key, from, to) in [
        (
            "loads.gap",
            "gap = \"0.02*x\"",
            "gap = \"0.02*x + 0/(t - 0.1)\"",
        ),
        (
            "loads.traction",
            "\"-pressure*max(0, ny)",
            "\"-pressure*(1 + 0/(t - 0.1))*max(0, ny)",
        ),
        (
            "displacement[0].x",
            "[output]",
            "[[displacement]]\npart = \"x_min\"\nx = \"0.001*t + 0/(t - 0.1)\"\ny = \"0\"\n\n[output]",
        ),
    ] {
        assert!(text.contains(from), "{from}");
        let changed = dir.join("changed.toml");
        std::fs::write(&changed, text.replace(from, to)).unwrap();
        let output = simulate(&changed, &dir.join(format!("out-{key}")), &[]);
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(1), "{message}");
        for part in [
            changed.display().to_string(),
            format!("key `{key}`"),
            "t = 0.1".into(),
        ] {
            assert!(message.contains(&part), "`{part}` missing in {message}");
        }
    }
}

/// A moduli law that passes the sampled check at load (β = k/100) but is negative between two
/// samples stops the run where the damage reaches that band, naming the key, the point, the
/// damage and the time, instead of running on with μ < 0.
#[test]
fn a_moduli_law_negative_between_its_samples_stops_the_run_naming_it() {
    let dir = scratch("hostile-moduli-range");
    let problem = small_problem(&dir);
    let text = std::fs::read_to_string(&problem).unwrap();
    let from = "elasticity = { kind = \"damaged_hooke\", shear_modulus = 1.0, lame_lambda = 1.0 }";
    assert!(text.contains(from));
    // μ(β) < 0 for 0.703 < β < 0.705 only: μ(0.70) = 0.6, μ(0.71) = 1.4
    let to = "elasticity = { kind = \"moduli\", shear_modulus = \"1 + 0.002/(beta - 0.705)\", \
              lame_lambda = \"1\" }";
    let changed = dir.join("changed.toml");
    let text = text
        .replace(from, to)
        .replace("[loads]", "[loads]\ninitial_damage = \"0.704\"");
    std::fs::write(&changed, &text).unwrap();
    let output = simulate(&changed, &dir.join("out"), &[]);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(1), "{message}");
    for part in [
        &format!("problem file `{}`", changed.display()),
        "key `laws.elasticity.shear_modulus`",
        "μ(0.704)",
        "quadrature point [",
        "t = 0",
    ] {
        assert!(message.contains(part), "`{part}` missing in {message}");
    }
}

/// Initial data out of range (β0 outside [0, 1], u0 ≠ u_D(x, 0) on Γ1) are refused with the
/// file, the key under `[loads]` and the node, not as a bare solver parameter.
#[test]
fn initial_data_out_of_range_name_the_file_and_the_key() {
    let dir = scratch("hostile-initial-data");
    let problem = small_problem(&dir);
    let text = std::fs::read_to_string(&problem).unwrap();
    for (key, line) in [
        ("loads.initial_damage", "initial_damage = \"1.5\""),
        ("loads.initial_damage", "initial_damage = \"1 + 0/(x - 1)\""),
        (
            "loads.initial_displacement",
            "initial_displacement = [\"0.1\", \"0\"]",
        ),
    ] {
        let changed = dir.join("changed.toml");
        std::fs::write(
            &changed,
            text.replace("[loads]", &format!("[loads]\n{line}")),
        )
        .unwrap();
        let output = simulate(&changed, &dir.join("out"), &[]);
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(1), "{message}");
        for part in [
            format!("problem file `{}`", changed.display()),
            format!("key `{key}`"),
            "at node".into(),
        ] {
            assert!(message.contains(&part), "`{part}` missing in {message}");
        }
    }
}

/// Huge numbers in messages are printed in scientific notation, not with 300 digits.
#[test]
fn a_huge_final_time_is_refused_in_a_short_message() {
    let dir = scratch("hostile-huge-time");
    let problem = small_problem(&dir);
    let text = std::fs::read_to_string(&problem).unwrap();
    std::fs::write(
        &problem,
        text.replace("final_time = 0.4", "final_time = 1e300"),
    )
    .unwrap();
    let output = simulate(&problem, &dir.join("out"), &[]);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(1), "{message}");
    assert!(message.contains("1e300"), "{message}");
    assert!(!message.contains("0000000000"), "{message}");
}

/// Resuming a run that already reached its last step says so instead of "steps 9..8".
#[test]
fn resuming_a_finished_run_says_there_is_nothing_to_do() {
    let dir = scratch("hostile-resume-finished");
    let problem = small_problem(&dir);
    let out = dir.join("out");
    assert!(simulate(&problem, &out, &[]).status.success());
    let before = contents(&out);
    let output = simulate(&problem, &out, &["--resume"]);
    let printed = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{}", stderr(&output));
    assert!(
        printed.contains("nothing to do") && printed.contains("step 8"),
        "{printed}"
    );
    assert!(!printed.contains("steps 9..8"), "{printed}");
    assert_eq!(contents(&out), before);
}

/// A box of 10¹⁸ cells or a limit below the estimate is refused before the mesh is built, with
/// the estimate and the limit: no abort, no capacity-overflow panic.
#[test]
fn problems_too_large_for_the_memory_are_refused_before_allocating() {
    let dir = scratch("hostile-memory");
    let problem = small_problem(&dir);
    let text = std::fs::read_to_string(&problem).unwrap();
    let huge = dir.join("huge.toml");
    std::fs::write(
        &huge,
        text.replace("cells = [8, 4]", "cells = [1000000000, 1000000000]"),
    )
    .unwrap();
    for (file, flags) in [
        (&huge, vec![]),
        (&problem, vec!["--memory-limit", "0.000001"]),
    ] {
        let out = dir.join("out");
        let output = simulate(file, &out, &flags);
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(1), "{message}");
        assert!(
            message.contains("needs an estimated") && message.contains("--memory-limit"),
            "{message}"
        );
        assert!(!out.exists());
    }
}

/// Runs `simulate args` with standard output `stdout`.
fn simulate_into(args: &[&std::ffi::OsStr], stdout: std::process::Stdio) -> Output {
    Command::new(env!("CARGO_BIN_EXE_simulate"))
        .args(args)
        .stdout(stdout)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap()
        .wait_with_output()
        .unwrap()
}

#[test]
fn a_full_standard_output_is_an_error_naming_it_not_a_panic() {
    let dir = scratch("hostile-dev-full");
    let problem = small_problem(&dir);
    let out = dir.join("out");
    let help = simulate_into(&["--help".as_ref()], full_disk());
    let run = simulate_into(
        &[problem.as_os_str(), "--out".as_ref(), out.as_os_str()],
        full_disk(),
    );
    for (what, output) in [("--help", help), ("a run", run)] {
        let message = stderr(&output);
        assert!(!message.contains("panicked"), "{what}: {message}");
        assert_eq!(output.status.code(), Some(1), "{what}: {message}");
        assert!(
            message.contains("standard output") && message.contains("No space left on device"),
            "{what}: {message}"
        );
    }
}

#[test]
fn a_closed_standard_output_ends_quietly_with_status_141() {
    let dir = scratch("hostile-closed-pipe");
    let problem = small_problem(&dir);
    let out = dir.join("out");
    let help = simulate_into(&["--help".as_ref()], closed_pipe());
    let run = simulate_into(
        &[problem.as_os_str(), "--out".as_ref(), out.as_os_str()],
        closed_pipe(),
    );
    for (what, output) in [("--help", help), ("a run", run)] {
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(141), "{what}: {message}");
        assert!(message.is_empty(), "{what}: {message}");
    }
}

/// Runs `simulate args`, failing the test if it has not ended after a minute.
fn simulate_within_a_minute(args: &[&std::ffi::OsStr]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_simulate"));
    command.args(args);
    output_within_a_minute(command)
}

#[test]
fn pipes_devices_and_directories_are_refused_by_name_before_they_are_read() {
    let dir = scratch("hostile-special-files");
    let pipe = dir.join("pipe.toml");
    let made = Command::new("mkfifo").arg(&pipe).status().unwrap();
    assert!(made.success());
    let out = dir.join("out");
    // the problem file itself: a named pipe, a directory
    for (path, kind) in [(&pipe, "named pipe"), (&dir, "directory")] {
        let output =
            simulate_within_a_minute(&[path.as_os_str(), "--out".as_ref(), out.as_os_str()]);
        assert!(!output.status.success());
        let message = stderr(&output);
        assert!(
            message.contains("problem file")
                && message.contains(kind)
                && !message.contains("panicked"),
            "{message}"
        );
    }
    // the Gmsh mesh of a problem file: a named pipe, a device, another kind of file
    let mesh_pipe = dir.join("mesh.msh");
    assert!(Command::new("mkfifo")
        .arg(&mesh_pipe)
        .status()
        .unwrap()
        .success());
    let foreign = dir.join("notes.msh");
    std::fs::write(
        &foreign,
        "secret: the first line of a file that is no mesh\n",
    )
    .unwrap();
    for mesh in [
        mesh_pipe.as_path(),
        Path::new("/dev/zero"),
        foreign.as_path(),
    ] {
        let problem = dir.join("gmsh.toml");
        let text: String = std::fs::read_to_string(small_problem(&dir))
            .unwrap()
            .lines()
            .map(|line| {
                if line.starts_with("box = ") {
                    format!(
                        "gmsh = {{ file = \"{}\", clamped = [\"left\"], contact = [\"bottom\"] }}\n",
                        mesh.display()
                    )
                } else {
                    format!("{line}\n")
                }
            })
            .collect();
        assert!(text.contains("gmsh = "));
        std::fs::write(&problem, text).unwrap();
        let output =
            simulate_within_a_minute(&[problem.as_os_str(), "--out".as_ref(), out.as_os_str()]);
        assert!(!output.status.success());
        let message = stderr(&output);
        assert!(
            message.contains(&mesh.display().to_string()) && !message.contains("panicked"),
            "{message}"
        );
        assert!(
            !message.contains("secret"),
            "the message quotes the file: {message}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
