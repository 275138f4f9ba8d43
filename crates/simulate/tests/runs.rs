//! End-to-end tests of `simulate`: the 2D example at a tiny size writes VTU/PVD files that an
//! XML parser reads back with the right sizes and fields, and a history whose integral columns
//! agree with each other; an interrupted (by `--until-step`, by the interrupt flag, by SIGINT
//! to the binary) and resumed run gives bitwise the same result as an uninterrupted one; a
//! changed problem is not resumed; bad problem files name the key.

use crate::common;

use base64::Engine;
use common::scratch;
use simulate::problem::ProblemSetup;
use simulate::run::{read_saved_state, RunOptions};
use std::path::{Path, PathBuf};

const EXAMPLE_2D: &str = include_str!("../examples/rectangle_2d.toml");
const EXAMPLE_3D: &str = include_str!("../examples/block_3d.toml");

/// The 2D example on an 8 × 4 mesh with 12 steps, saved every 4, written into `dir`.
fn tiny_example(dir: &Path) -> PathBuf {
    let text = EXAMPLE_2D
        .replace("cells = [40, 20]", "cells = [8, 4]")
        .replace("steps = 250", "steps = 12")
        .replace("final_time = 5.0", "final_time = 0.6")
        .replace("every = 10", "every = 4");
    assert_ne!(text, EXAMPLE_2D);
    let path = dir.join("tiny.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn quiet(out: &Path) -> RunOptions {
    RunOptions {
        out: Some(out.to_path_buf()),
        quiet: true,
        ..RunOptions::default()
    }
}

/// Values of the `DataArray` called `name` and its number of components: decimal text, or
/// (the default) the UInt64 byte count and the little-endian Float64 values, base64-encoded.
fn data_array(document: &roxmltree::Document, name: &str) -> (usize, Vec<f64>) {
    let node = document
        .descendants()
        .find(|n| n.has_tag_name("DataArray") && n.attribute("Name") == Some(name))
        .unwrap_or_else(|| panic!("no DataArray {name}"));
    let components = node
        .attribute("NumberOfComponents")
        .map_or(1, |c| c.parse().unwrap());
    let text = node.text().unwrap_or("");
    let values = match node.attribute("format") {
        Some("ascii") => text
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect(),
        Some("binary") => {
            assert_eq!(node.attribute("type"), Some("Float64"), "{name}");
            let bytes = base64::engine::general_purpose::STANDARD
                .decode(text.trim())
                .unwrap();
            let (header, data) = bytes.split_at(8);
            assert_eq!(
                u64::from_le_bytes(header.try_into().unwrap()) as usize,
                data.len(),
                "{name}: byte count"
            );
            data.chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
                .collect()
        }
        other => panic!("{name}: format {other:?}"),
    };
    (components, values)
}

fn piece_sizes(document: &roxmltree::Document) -> (usize, usize) {
    let piece = document
        .descendants()
        .find(|n| n.has_tag_name("Piece"))
        .unwrap();
    (
        piece.attribute("NumberOfPoints").unwrap().parse().unwrap(),
        piece.attribute("NumberOfCells").unwrap().parse().unwrap(),
    )
}

#[test]
fn output_is_read_back_with_fields_sizes_and_contact_status() {
    let dir = scratch("simulate-output");
    let problem = tiny_example(&dir);
    let out = dir.join("out");
    let outcome = simulate::run_file(&problem, &quiet(&out)).unwrap();
    assert_eq!(outcome.last_step, 12);
    assert_eq!(outcome.saved_steps, vec![4, 8, 12]);
    assert!(outcome.max_kkt.velocity <= 1e-10 && outcome.max_kkt.damage <= 1e-12);

    // 8 × 4 squares, two triangles each; P1 nodes on a 9 × 5 lattice; 9 nodes on y = 0, of
    // which the clamped corner is no contact node
    let (points, cells) = (45, 64);
    for pvd_name in ["solution.pvd", "contact.pvd"] {
        let text = std::fs::read_to_string(out.join(pvd_name)).unwrap();
        let pvd = roxmltree::Document::parse(&text).unwrap();
        let entries: Vec<(f64, String)> = pvd
            .descendants()
            .filter(|n| n.has_tag_name("DataSet"))
            .map(|n| {
                (
                    n.attribute("timestep").unwrap().parse().unwrap(),
                    n.attribute("file").unwrap().to_string(),
                )
            })
            .collect();
        assert_eq!(entries.len(), 3, "{pvd_name}");
        for (entry, step) in entries.iter().zip([4, 8, 12]) {
            assert!((entry.0 - step as f64 * 0.05).abs() < 1e-14);
            assert!(out.join(&entry.1).exists(), "{} is missing", entry.1);
        }
    }

    let mut touched = false;
    for step in [4, 8, 12] {
        let text = std::fs::read_to_string(out.join(format!("solution_{step:06}.vtu"))).unwrap();
        let vtu = roxmltree::Document::parse(&text).unwrap();
        assert_eq!(piece_sizes(&vtu), (points, cells));
        for (name, components, count) in [
            ("displacement", 3, points),
            ("velocity", 3, points),
            ("damage", 1, points),
            ("stress", 9, cells),
        ] {
            let (c, values) = data_array(&vtu, name);
            assert_eq!(
                (c, values.len()),
                (components, count * components),
                "{name}"
            );
            assert!(values.iter().all(|v| v.is_finite()), "{name}");
        }
        let (_, damage) = data_array(&vtu, "damage");
        assert!(damage.iter().all(|b| (0.0..=1.0).contains(b)));
        // the stress is symmetric (2D: embedded with zero third row and column)
        let (_, stress) = data_array(&vtu, "stress");
        for sigma in stress.chunks(9) {
            assert!((sigma[1] - sigma[3]).abs() <= 1e-12 * (1.0 + sigma[1].abs()));
            assert_eq!(&sigma[6..], &[0.0, 0.0, 0.0]);
        }

        let text = std::fs::read_to_string(out.join(format!("contact_{step:06}.vtu"))).unwrap();
        let boundary = roxmltree::Document::parse(&text).unwrap();
        assert_eq!(piece_sizes(&boundary), (9, 8));
        let (_, status) = data_array(&boundary, "status");
        let (_, contact_node) = data_array(&boundary, "contact_node");
        let (_, pressure) = data_array(&boundary, "normal_pressure");
        let (components, traction) = data_array(&boundary, "tangential_traction");
        assert_eq!((status.len(), pressure.len()), (9, 9));
        assert_eq!((components, traction.len()), (3, 27));
        assert!(status.iter().all(|s| [0.0, 1.0, 2.0].contains(s)));
        assert_eq!(contact_node.iter().filter(|&&c| c == 1.0).count(), 8);
        assert!(pressure.iter().all(|p| *p >= 0.0));
        // the friction traction is tangential (no y component on y = 0) and bounded by μ p_ν
        for (node, t) in traction.chunks(3).enumerate() {
            assert_eq!(t[1], 0.0);
            assert!(t[0].abs() <= 0.4 * pressure[node] * (1.0 + 1e-12) + 1e-15);
        }
        let in_contact = status
            .iter()
            .zip(&contact_node)
            .filter(|(s, c)| **c == 1.0 && **s > 0.0)
            .count();
        touched |= in_contact > 0;
    }
    assert!(touched, "no contact node is ever in contact");

    // one history row per step, the step column counting up, the columns consistent
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let rows: Vec<&str> = history.lines().collect();
    assert_eq!(rows.len(), 13);
    let header: Vec<&str> = rows[0].split(',').collect();
    let column = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no column {name}"))
    };
    let value = |row: &str, name: &str| -> f64 {
        row.split(',').nth(column(name)).unwrap().parse().unwrap()
    };
    // the reaction of the clamped side x = 0, one column per component
    assert_eq!(
        &header[header.len() - 2..],
        &["reaction_clamped_x", "reaction_clamped_y"]
    );
    let time_step = 0.05;
    // Γ3 is the bottom side (0, 2) × {0} minus its clamped end: the contact weights sum to 2
    let (mut friction_energy, mut viscous_energy, mut slipped) = (0.0, 0.0, 0.0f64);
    let mut max_slip_zone = 0.0f64;
    for (n, row) in rows[1..].iter().enumerate() {
        assert_eq!(row.split(',').count(), header.len());
        assert_eq!(value(row, "step"), (n + 1) as f64);
        let counts = value(row, "stick") + value(row, "slip") + value(row, "separated");
        assert_eq!(counts, 8.0, "stick + slip + separated = contact nodes");
        let (contact_zone, slip_zone) = (value(row, "contact_zone"), value(row, "slip_zone"));
        assert!((0.0..=2.0 + 1e-12).contains(&slip_zone));
        assert!((0.0..=2.0 + 1e-12).contains(&contact_zone));
        // p_ν > 0 at some node exactly where the interpolated penetration is positive somewhere
        let normal_force = value(row, "normal_force");
        assert_eq!(contact_zone == 0.0, normal_force == 0.0);
        if contact_zone > 0.0 {
            let (low, high) = (value(row, "zone_min"), value(row, "zone_max"));
            assert!(0.0 <= low && low < high && high <= 2.0 && contact_zone <= high - low + 1e-12);
        }
        // Γ3 is flat with outward normal (0, −1): the foundation pushes up with the normal
        // force, and the friction force is horizontal
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * (1.0 + b.abs());
        assert!(close(value(row, "force_y"), normal_force));
        assert!(close(
            value(row, "force_x").abs(),
            value(row, "tangential_force")
        ));
        assert_eq!(value(row, "force_z"), 0.0);
        max_slip_zone = max_slip_zone.max(slip_zone);
        // the running sums add k × the rates
        assert!(value(row, "friction_power") >= 0.0 && value(row, "viscous_power") >= 0.0);
        friction_energy += time_step * value(row, "friction_power");
        viscous_energy += time_step * value(row, "viscous_power");
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * (1.0 + b.abs());
        assert!(close(value(row, "friction_dissipation"), friction_energy));
        assert!(close(value(row, "viscous_dissipation"), viscous_energy));
        // slip accumulates
        let max_slip = value(row, "max_accumulated_slip");
        assert!(max_slip >= slipped);
        slipped = max_slip;
    }
    assert!(viscous_energy > 0.0, "the body never moved");
    assert!(max_slip_zone > 0.0 && slipped > 0.0, "nothing ever slipped");
}

#[test]
fn resumed_run_equals_uninterrupted_run_bitwise() {
    let dir = scratch("simulate-resume");
    let problem = tiny_example(&dir);
    let whole = dir.join("whole");
    let split = dir.join("split");
    simulate::run_file(&problem, &quiet(&whole)).unwrap();

    let first = simulate::run_file(
        &problem,
        &RunOptions {
            until_step: Some(5),
            ..quiet(&split)
        },
    )
    .unwrap();
    assert_eq!(first.last_step, 5);
    assert_eq!(read_saved_state(&split).unwrap().step, 5);
    // a crash after step 6 leaves a history row beyond the saved state: resuming drops it
    let mut history = std::fs::read_to_string(split.join("history.csv")).unwrap();
    let columns = simulate::history::HISTORY_HEADER.split(',').count();
    history.push_str(&format!("6,0.3{}\n", ",0".repeat(columns - 2)));
    std::fs::write(split.join("history.csv"), history).unwrap();
    let mut contact_history = std::fs::read_to_string(split.join("contact_history.csv")).unwrap();
    contact_history.push_str("6,0.3,0.25,1,0.5,0,0\n6,0.3,0.5,");
    std::fs::write(split.join("contact_history.csv"), contact_history).unwrap();

    let second = simulate::run_file(
        &problem,
        &RunOptions {
            resume: true,
            ..quiet(&split)
        },
    )
    .unwrap();
    assert_eq!((second.started_from, second.last_step), (5, 12));
    assert_eq!(second.saved_steps, vec![4, 5, 8, 12]);

    let (a, b) = (
        read_saved_state(&whole).unwrap(),
        read_saved_state(&split).unwrap(),
    );
    assert_eq!(a.step, b.step);
    assert_eq!(a.time.to_bits(), b.time.to_bits());
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.displacement), bits(&b.displacement));
    assert_eq!(bits(&a.velocity), bits(&b.velocity));
    assert_eq!(bits(&a.damage), bits(&b.damage));
    assert_eq!(bits(&a.accumulated_slip), bits(&b.accumulated_slip));
    for file in [
        "history.csv",
        "solution_000012.vtu",
        "contact_000012.vtu",
        "contact_history.csv",
        "contact_history.svg",
        "damage_000006.svg",
        "damage_000012.svg",
    ] {
        let (a, b) = (
            std::fs::read_to_string(whole.join(file)).unwrap(),
            std::fs::read_to_string(split.join(file)).unwrap(),
        );
        let first_difference = a.lines().zip(b.lines()).position(|(x, y)| x != y);
        assert_eq!(first_difference, None, "{file} differs at this line index");
        assert_eq!(a.len(), b.len(), "{file}");
    }
}

/// A run gives the same bits on one, two and three threads: the loads, the statistics and the
/// damage step sum in a fixed order of chunks, and the dense products of every velocity step
/// run on the calling thread. The 3D example at its own size (16 × 8 × 8 cells, 288
/// tangential contact unknowns), 6 steps: with faer's parallel matrix–vector products in the
/// condensed velocity step, the velocities differed in the last bits from the first step on
/// (at 8 × 4 × 4 cells faer does not split the products, so that size would not show it).
/// Three threads split the work unevenly; `simulate` accepts up to four per core, so the
/// count is valid on any machine.
#[test]
fn run_is_the_same_on_one_two_and_three_threads() {
    use std::process::Command;
    let dir = scratch("simulate-threads");
    let text = EXAMPLE_3D
        .replace("steps = 75", "steps = 6")
        .replace("final_time = 3.0", "final_time = 0.6");
    assert_ne!(text, EXAMPLE_3D);
    let problem = dir.join("block.toml");
    std::fs::write(&problem, text).unwrap();
    let run = |threads: &str| {
        let out = dir.join(format!("threads-{threads}"));
        let status = Command::new(env!("CARGO_BIN_EXE_simulate"))
            .arg(&problem)
            .args(["--quiet", "--threads", threads, "--out"])
            .arg(&out)
            .status()
            .unwrap();
        assert!(status.success(), "--threads {threads}: {status}");
        out
    };
    let one = run("1");
    let history = |out: &Path| std::fs::read_to_string(out.join("history.csv")).unwrap();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let reference = history(&one);
    assert_eq!(reference.lines().count(), 7);
    let reference_state = read_saved_state(&one).unwrap();
    assert_eq!(reference_state.step, 6);
    for threads in ["2", "3"] {
        let out = run(threads);
        let rows = history(&out);
        assert_eq!(
            rows.lines().count(),
            reference.lines().count(),
            "--threads {threads}: history.csv has another number of lines"
        );
        let first_difference = reference
            .lines()
            .zip(rows.lines())
            .position(|(x, y)| x != y);
        assert_eq!(
            first_difference, None,
            "--threads {threads}: history.csv differs at this line index"
        );
        let state = read_saved_state(&out).unwrap();
        assert_eq!(
            bits(&reference_state.displacement),
            bits(&state.displacement)
        );
        assert_eq!(bits(&reference_state.velocity), bits(&state.velocity));
        assert_eq!(bits(&reference_state.damage), bits(&state.damage));
    }
}

#[test]
fn resume_and_restart_refuse_mismatches() {
    let dir = scratch("simulate-refuse");
    let problem = tiny_example(&dir);
    let out = dir.join("out");
    // nothing to resume
    let error = simulate::run_file(
        &problem,
        &RunOptions {
            resume: true,
            ..quiet(&out)
        },
    )
    .unwrap_err()
    .to_string();
    assert!(error.contains("state.json"), "{error}");

    simulate::run_file(
        &problem,
        &RunOptions {
            until_step: Some(4),
            ..quiet(&out)
        },
    )
    .unwrap();
    // a fresh run does not overwrite a run silently
    let error = simulate::run_file(&problem, &quiet(&out))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("--resume") && error.contains("--overwrite"),
        "{error}"
    );
    // another number of steps is another problem
    let text = std::fs::read_to_string(&problem)
        .unwrap()
        .replace("steps = 12", "steps = 24");
    let other = dir.join("other.toml");
    std::fs::write(&other, text).unwrap();
    let error = simulate::run_file(
        &other,
        &RunOptions {
            resume: true,
            ..quiet(&out)
        },
    )
    .unwrap_err()
    .to_string();
    assert!(error.contains("steps is 12 there but 24"), "{error}");
    // --overwrite starts afresh
    let outcome = simulate::run_file(
        &other,
        &RunOptions {
            overwrite: true,
            until_step: Some(2),
            ..quiet(&out)
        },
    )
    .unwrap();
    assert_eq!(outcome.saved_steps, vec![2]);
    assert!(!out.join("solution_000004.vtu").exists());

    // changed loads, laws, constants or mesh: the saved state belongs to another problem
    for (from, to, key) in [
        ("pressure = 1.2", "pressure = 1.3", "`constants`"),
        ("friction = 0.4", "friction = 0.5", "`laws`"),
        ("gap = \"0.02*x\"", "gap = \"0.03*x\"", "`loads`"),
        ("upper = [2.0, 1.0]", "upper = [2.0, 1.1]", "`mesh`"),
    ] {
        let text = std::fs::read_to_string(&other).unwrap();
        assert!(text.contains(from), "{from}");
        let changed = dir.join("changed.toml");
        std::fs::write(&changed, text.replace(from, to)).unwrap();
        let error = simulate::run_file(
            &changed,
            &RunOptions {
                resume: true,
                ..quiet(&out)
            },
        )
        .unwrap_err()
        .to_string();
        assert!(
            error.contains(&format!("{key} changed since the saved run")),
            "{to}: {error}"
        );
    }
    // solver settings and output may change: resuming with a larger iteration limit works
    let text = std::fs::read_to_string(&other).unwrap() + "\n[solver]\nmax_newton = 80\n";
    let relaxed = dir.join("relaxed.toml");
    std::fs::write(&relaxed, text).unwrap();
    let outcome = simulate::run_file(
        &relaxed,
        &RunOptions {
            resume: true,
            until_step: Some(3),
            ..quiet(&out)
        },
    )
    .unwrap();
    assert_eq!((outcome.started_from, outcome.last_step), (2, 3));
}

#[test]
fn interrupt_flag_saves_the_step_in_progress_and_resume_continues_bitwise() {
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;
    let dir = scratch("simulate-interrupt");
    let problem = tiny_example(&dir);
    let whole = dir.join("whole");
    let split = dir.join("split");
    simulate::run_file(&problem, &quiet(&whole)).unwrap();
    // the flag is already set: the run stops after step 1, which is not a step of the
    // output cadence (every 4) but is saved all the same
    let outcome = simulate::run_file(
        &problem,
        &RunOptions {
            interrupt: Some(Arc::new(AtomicBool::new(true))),
            ..quiet(&split)
        },
    )
    .unwrap();
    assert!(outcome.interrupted);
    assert_eq!(
        (outcome.last_step, outcome.saved_steps.clone()),
        (1, vec![1])
    );
    assert_eq!(read_saved_state(&split).unwrap().step, 1);
    assert!(split.join("solution_000001.vtu").exists());
    let outcome = simulate::run_file(
        &problem,
        &RunOptions {
            resume: true,
            interrupt: Some(Arc::new(AtomicBool::new(false))),
            ..quiet(&split)
        },
    )
    .unwrap();
    assert!(!outcome.interrupted);
    assert_eq!(outcome.last_step, 12);
    let (a, b) = (
        read_saved_state(&whole).unwrap(),
        read_saved_state(&split).unwrap(),
    );
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.displacement), bits(&b.displacement));
    assert_eq!(bits(&a.damage), bits(&b.damage));
    assert_eq!(
        a.viscous_dissipation.to_bits(),
        b.viscous_dissipation.to_bits()
    );
    assert_eq!(
        std::fs::read_to_string(whole.join("history.csv")).unwrap(),
        std::fs::read_to_string(split.join("history.csv")).unwrap()
    );
}

/// SIGINT to the `simulate` binary: it finishes and saves the step in progress, exits with
/// 130, and `--resume` from there agrees bitwise with an uninterrupted run.
#[cfg(unix)]
#[test]
fn ctrl_c_saves_the_step_in_progress_and_exits_130() {
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};
    let dir = scratch("simulate-sigint");
    // long enough (20000 steps, ≈ 30 s) not to finish before the signal arrives
    let text = std::fs::read_to_string(tiny_example(&dir))
        .unwrap()
        .replace("steps = 12", "steps = 20000")
        .replace("final_time = 0.6", "final_time = 1000.0");
    let problem = dir.join("long.toml");
    std::fs::write(&problem, text).unwrap();
    let out = dir.join("out");
    let child = Command::new(env!("CARGO_BIN_EXE_simulate"))
        .arg(&problem)
        .arg("--out")
        .arg(&out)
        .arg("--quiet")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // wait for a few completed steps
    let started = Instant::now();
    loop {
        let rows = std::fs::read_to_string(out.join("history.csv"))
            .map(|h| h.lines().count())
            .unwrap_or(0);
        if rows > 3 {
            break;
        }
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "no step done in 120 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let pid = nix::unistd::Pid::from_raw(i32::try_from(child.id()).unwrap());
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).unwrap();
    let output = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert_eq!(output.status.code(), Some(130), "{stdout}");
    assert!(stdout.contains("continue with --resume"), "{stdout}");
    let saved = read_saved_state(&out).unwrap();
    assert!(saved.step > 3 && saved.step < 20000, "{}", saved.step);
    // every completed step is in the history, and the last one is the saved state
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    assert_eq!(history.lines().count(), saved.step + 1);
    assert!(out.join(format!("solution_{:06}.vtu", saved.step)).exists());

    let until = saved.step + 2;
    let resumed = simulate::run_file(
        &problem,
        &RunOptions {
            resume: true,
            until_step: Some(until),
            ..quiet(&out)
        },
    )
    .unwrap();
    assert_eq!(resumed.last_step, until);
    let whole = dir.join("whole");
    simulate::run_file(
        &problem,
        &RunOptions {
            until_step: Some(until),
            ..quiet(&whole)
        },
    )
    .unwrap();
    let (a, b) = (
        read_saved_state(&whole).unwrap(),
        read_saved_state(&out).unwrap(),
    );
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.displacement), bits(&b.displacement));
    assert_eq!(bits(&a.velocity), bits(&b.velocity));
    assert_eq!(bits(&a.damage), bits(&b.damage));
}

/// The error of building the 2D example with `from` replaced by `to`.
fn error_of(from: &str, to: &str) -> String {
    let text = EXAMPLE_2D.replace(from, to);
    assert_ne!(text, EXAMPLE_2D, "`{from}` is not in the example");
    let path = Path::new("bad.toml");
    let file = match simulate::problem::parse_problem_file(&text, "bad.toml") {
        Ok(file) => file,
        Err(error) => return error.to_string(),
    };
    match ProblemSetup::<2>::new(file, path) {
        Ok(_) => panic!("`{to}` was accepted"),
        Err(error) => error.to_string(),
    }
}

/// `output.vtu = "ascii"` writes the same arrays as the default binary encoding, bitwise.
#[test]
fn text_and_binary_vtu_files_hold_the_same_arrays() {
    let dir = scratch("vtu-encodings");
    let binary_problem = tiny_example(&dir);
    let text = std::fs::read_to_string(&binary_problem)
        .unwrap()
        .replace("every = 4", "every = 4\nvtu = \"ascii\"");
    let ascii_problem = dir.join("tiny_ascii.toml");
    std::fs::write(&ascii_problem, text).unwrap();
    let (binary_out, ascii_out) = (dir.join("binary"), dir.join("ascii"));
    simulate::run_file(&binary_problem, &quiet(&binary_out)).unwrap();
    simulate::run_file(&ascii_problem, &quiet(&ascii_out)).unwrap();
    for (file, names) in [
        (
            "solution_000012.vtu",
            &["displacement", "velocity", "damage", "stress"][..],
        ),
        (
            "contact_000012.vtu",
            &["status", "normal_pressure", "tangential_traction"][..],
        ),
    ] {
        let read = |out: &Path| std::fs::read_to_string(out.join(file)).unwrap();
        let (binary_text, ascii_text) = (read(&binary_out), read(&ascii_out));
        assert!(
            binary_text.contains("format=\"binary\"") && !binary_text.contains("format=\"ascii\"")
        );
        assert!(
            ascii_text.contains("format=\"ascii\"") && !ascii_text.contains("format=\"binary\"")
        );
        let binary = roxmltree::Document::parse(&binary_text).unwrap();
        let ascii = roxmltree::Document::parse(&ascii_text).unwrap();
        assert_eq!(piece_sizes(&binary), piece_sizes(&ascii));
        for name in names.iter().chain(&["Points"]) {
            let bits = |document| {
                let (components, values) = data_array(document, name);
                (
                    components,
                    values.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                )
            };
            assert_eq!(bits(&binary), bits(&ascii), "{file}: {name}");
        }
    }
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn bad_problem_files_name_the_key() {
    for (from, to, expected) in [
        ("[output]", "[outptu]", "unknown field `outptu`"),
        ("every = 10", "every = 0", "key `output.every`"),
        (
            "every = 10",
            "every = 10\nvtu = \"hdf5\"",
            "key `output.vtu`: must be \"binary\" or \"ascii\", got \"hdf5\"",
        ),
        (
            "every = 10",
            "every = 10\npictures = [2.5, 6.0]",
            "key `output.pictures`: every time must lie in (0, final_time = 5], got 6",
        ),
        ("gap = \"0.02*x\"", "gap = \"0.02*w\"", "key `loads.gap`"),
        (
            "gap = \"0.02*x\"",
            "gap = \"0.02*x\"\nbody_force = [\"1\"]",
            "key `loads.body_force`: need 2 components",
        ),
        (
            "\"-pressure*max",
            "\"-pressur*max",
            "key `loads.traction[1]`",
        ),
        (
            "x_min = \"clamped\"",
            "x_low = \"clamped\"",
            "key `mesh.box.sides.x_low`",
        ),
        ("cells = [40, 20]", "cells = [40]", "key `mesh.box.cells`"),
        (
            "box = {",
            "gmsh = { file = \"a.msh\" }\nbox = {",
            "key `mesh`",
        ),
        (
            "stiffness = 4.0",
            "stiffness = -4.0",
            "key `laws.contact.stiffness`",
        ),
        (
            "viscosity = { kind = \"linear\", shear = 3.0, bulk = 1.5 }",
            "viscosity = { kind = \"potential\", potential = \"tr_eps^2\" }",
            "key `laws.viscosity.potential`: `tr_eps^2`",
        ),
        (
            "elasticity = { kind = \"damaged_hooke\", shear_modulus = 1.0, lame_lambda = 1.0 }",
            "elasticity = { kind = \"moduli\", shear_modulus = \"beta - 1\", lame_lambda = \"0\" }",
            "key `laws.elasticity.shear_modulus`: `beta - 1`",
        ),
        ("dim = 2", "dim = 3", "key `dim`"),
        ("steps = 250", "steps = 0", "key `steps`"),
        ("degree = 1", "degree = 3", "key `degree`"),
        (
            "[output]",
            "[solver]\nvelocity_tolerance = 1e-4\n[output]",
            "key `solver.velocity_tolerance`: must lie in (0, 1e-6]",
        ),
        (
            "[output]",
            "[solver]\ndamage_max_iterations = 0\n[output]",
            "key `solver.damage_max_iterations`: must be at least 1",
        ),
        (
            "[output]",
            "[solver]\ndamage_method = \"pdas\"\n[output]",
            "key `solver.damage_method`: must be \"multigrid\" or \"active-set\", got \"pdas\"",
        ),
        (
            "[output]",
            "[solver]\ntangent = \"bfgs\"\n[output]",
            "key `solver.tangent`: must be \"frozen\" or \"newton\", got \"bfgs\"",
        ),
        (
            "[output]",
            "[solver]\nfriction_tolerance = -1e-12\n[output]",
            "key `solver.friction_tolerance`",
        ),
        (
            "[output]",
            "[solver]\ntolerance = 1e-9\n[output]",
            "unknown field `tolerance`",
        ),
    ] {
        let error = error_of(from, to);
        // worded for a problem file, also by the tables shared with case files ([laws], sides)
        assert!(
            error.starts_with("problem file `bad.toml`, key `"),
            "{error}"
        );
        assert!(error.contains(expected), "`{to}`: {error}");
    }
    // an unknown key is located by line
    let error = error_of("[output]", "[outptu]");
    assert!(error.contains("line "), "{error}");
}

#[test]
fn potential_and_moduli_laws_load_and_run_like_the_linear_laws_they_equal() {
    // 𝒜: η|ε|² + ζ/2 tr² = η|ε_D|² + (η/2 + ζ/2) tr² in 2D with (η, ζ) = (3, 1.5);
    // G: μ(β) = β, λ(β) = β is damaged_hooke with μ = λ = 1
    let dir = scratch("simulate-user-laws");
    let linear = EXAMPLE_2D
        .replace("cells = [40, 20]", "cells = [8, 4]")
        .replace("steps = 250", "steps = 2")
        .replace("final_time = 5.0", "final_time = 0.1")
        .replace("every = 10", "every = 1");
    let user = linear
        .replace(
            r#"viscosity = { kind = "linear", shear = 3.0, bulk = 1.5 }"#,
            r#"viscosity = { kind = "potential", potential = "3*dev_norm^2 + (3/2 + 1.5/2)*tr_eps^2" }"#,
        )
        .replace(
            r#"elasticity = { kind = "damaged_hooke", shear_modulus = 1.0, lame_lambda = 1.0 }"#,
            r#"elasticity = { kind = "moduli", shear_modulus = "beta", lame_lambda = "beta" }"#,
        );
    assert!(user.contains("kind = \"potential\"") && user.contains("kind = \"moduli\""));
    let mut states = Vec::new();
    for (name, text) in [("linear", &linear), ("user", &user)] {
        let problem = dir.join(format!("{name}.toml"));
        std::fs::write(&problem, text).unwrap();
        let out = dir.join(name);
        let outcome = simulate::run_file(&problem, &quiet(&out)).unwrap();
        assert_eq!(outcome.last_step, 2, "{name}");
        states.push(read_saved_state(&out).unwrap());
    }
    let close = |a: &[f64], b: &[f64]| {
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-8 * scale)
    };
    assert!(close(&states[0].displacement, &states[1].displacement));
    assert!(close(&states[0].velocity, &states[1].velocity));
    assert!(close(&states[0].damage, &states[1].damage));
}

#[test]
fn gmsh_problem_runs_on_a_committed_mesh() {
    let dir = scratch("simulate-gmsh");
    let mesh =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../contact-damage/tests/meshes/square.msh");
    std::fs::copy(mesh, dir.join("square.msh")).unwrap();
    let text = EXAMPLE_2D
        .replace(
            "box = { lower = [0.0, 0.0], upper = [2.0, 1.0], cells = [40, 20], sides = { x_min = \"clamped\", y_min = \"contact\" } }",
            "gmsh = { file = \"square.msh\", clamped = [\"clamped\"], traction = [\"traction\"], contact = [\"contact\"] }",
        )
        .replace("steps = 250", "steps = 4")
        .replace("final_time = 5.0", "final_time = 0.4");
    let problem = dir.join("gmsh.toml");
    std::fs::write(&problem, text).unwrap();
    let outcome = simulate::run_file(&problem, &quiet(&dir.join("out"))).unwrap();
    assert_eq!(outcome.saved_steps, vec![4]);
    // a missing group is reported with the key
    let text = std::fs::read_to_string(&problem)
        .unwrap()
        .replace("contact = [\"contact\"]", "contact = [\"foundation\"]");
    std::fs::write(&problem, text).unwrap();
    let error = simulate::run_file(&problem, &quiet(&dir.join("out2")))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("key `mesh.gmsh`") && error.contains("foundation"),
        "{error}"
    );
}

#[test]
fn pictures_show_damage_on_every_cell_and_the_contact_history_with_legends() {
    let dir = scratch("simulate-pictures");
    let problem = tiny_example(&dir);
    let out = dir.join("out");
    simulate::run_file(&problem, &quiet(&out)).unwrap();
    let read = |name: &str| std::fs::read_to_string(out.join(name)).unwrap();

    // default picture times T/2 = 0.3 and T = 0.6: steps 6 and 12 of k = 0.05
    for (name, time) in [
        ("damage_000006.svg", "0.3000"),
        ("damage_000012.svg", "0.6000"),
    ] {
        let svg = read(name);
        assert!(svg.contains("<svg"), "{name}");
        // one filled triangle per cell of the 8 × 4 mesh, and a colour bar of 50 bands
        assert_eq!(svg.matches("<polygon").count(), 64, "{name}");
        assert!(svg.matches("<rect").count() >= 50, "{name}");
        assert!(svg.contains(&format!("t = {time}")), "{name}");
        assert!(svg.contains("damage β on Ω"), "{name}");
    }
    assert!(!out.join("damage_000004.svg").exists());

    // 8 contact nodes on y = 0 (the clamped corner is none) at the steps 4, 8 and 12 that
    // `output.every = 4` records (of 12)
    let csv = read("contact_history.csv");
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("step,t,s,status,normal_pressure,slip_rate,accumulated_slip")
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 3 * 8);
    for (index, row) in rows.iter().enumerate() {
        assert_eq!(row[0], (4 * (index / 8 + 1)) as f64);
        assert!(
            (row[2] - (index % 8 + 1) as f64 * 0.25).abs() < 1e-12,
            "{row:?}"
        );
        assert!(
            [0.0, 1.0, 2.0].contains(&row[3]) && row[4] >= 0.0,
            "{row:?}"
        );
    }
    // the bump presses the body onto the foundation: some node is in contact at some step
    assert!(rows.iter().any(|row| row[3] > 0.0 && row[4] > 0.0));
    // a sticking node does not slide; the slip accumulates k |v_τ| node by node, at least the
    // k |v_τ| of the recorded step since the record before
    for (index, row) in rows.iter().enumerate() {
        if row[3] == 1.0 {
            assert!(row[5] < 1e-9, "stick with |v_τ| = {}", row[5]);
        }
        let before = if index >= 8 { rows[index - 8][6] } else { 0.0 };
        assert!(
            row[6] >= before + 0.05 * row[5] - 1e-14 * (1.0 + row[6]),
            "{row:?}"
        );
    }
    assert!(rows.iter().any(|row| row[3] == 2.0 && row[5] > 0.0));

    let svg = read("contact_history.svg");
    assert!(svg.contains("<svg") && svg.contains("<rect") && svg.contains("<polyline"));
    for label in [
        "separated",
        "stick",
        "slip",
        "contact status on Γ3 over time",
        "normal pressure p_ν on Γ3",
        "accumulated slip Σ k |v_τ| on Γ3",
        // the picture times 0.3 and 0.6 drawn at the nearest recorded steps, 4 and 12
        "t = 0.2000",
        "t = 0.6000",
        "x on Γ3",
    ] {
        assert!(svg.contains(label), "{label} is missing");
    }
}

#[test]
fn solver_settings_are_read_from_the_problem_file() {
    let text = EXAMPLE_2D.replace(
        "[output]",
        "[solver]\nvelocity_tolerance = 1e-11\nmax_newton = 7\nfriction_tolerance = 1e-13\nfriction_max_newton = 30\nfriction_max_gradient = 500\ndamage_tolerance = 1e-13\ndamage_max_iterations = 40\ndamage_method = \"active-set\"\ntangent = \"newton\"\n[output]",
    );
    let file = simulate::problem::parse_problem_file(&text, "solver.toml").unwrap();
    let setup = ProblemSetup::<2>::new(file, Path::new("solver.toml")).unwrap();
    let settings = &setup.problem.settings;
    assert_eq!(settings.velocity.tolerance, 1e-11);
    assert_eq!(settings.velocity.max_newton, 7);
    assert_eq!(settings.velocity.friction.tolerance, 1e-13);
    assert_eq!(settings.velocity.friction.max_newton, 30);
    assert_eq!(settings.velocity.friction.max_gradient, 500);
    assert_eq!(settings.damage.tolerance, 1e-13);
    assert_eq!(settings.damage.max_iterations, 40);
    assert_eq!(
        settings.damage.method,
        contact_damage::solvers::box_qp::BoxQpMethod::ActiveSet
    );
    assert_eq!(
        settings.velocity.tangent,
        contact_damage::scheme::velocity::TangentUpdate::Newton
    );
    // missing entries keep the defaults
    let file = simulate::problem::parse_problem_file(EXAMPLE_2D, "example.toml").unwrap();
    let setup = ProblemSetup::<2>::new(file, Path::new("example.toml")).unwrap();
    let defaults = contact_damage::scheme::SchemeSettings::default();
    assert_eq!(
        setup.problem.settings.velocity.tolerance,
        defaults.velocity.tolerance
    );
    assert_eq!(
        setup.problem.settings.damage.max_iterations,
        defaults.damage.max_iterations
    );
    assert_eq!(
        setup.problem.settings.velocity.tangent,
        contact_damage::scheme::velocity::TangentUpdate::Frozen
    );
}

#[test]
fn implicit_contact_scheme_is_selected_by_the_problem_file() {
    let dir = scratch("simulate-implicit-contact");
    let text = EXAMPLE_2D
        .replace("cells = [40, 20]", "cells = [8, 4]")
        .replace("steps = 250", "steps = 4")
        .replace("final_time = 5.0", "final_time = 0.4")
        .replace("every = 10", "every = 1");
    let implicit = text.replacen("[laws]", "[scheme]\ncontact = \"implicit\"\n\n[laws]", 1);
    assert!(implicit.contains("contact = \"implicit\""));
    let mut states = Vec::new();
    for (name, text) in [("explicit", &text), ("implicit", &implicit)] {
        let problem = dir.join(format!("{name}.toml"));
        std::fs::write(&problem, text).unwrap();
        let out = dir.join(name);
        let outcome = simulate::run_file(&problem, &quiet(&out)).unwrap();
        assert_eq!(outcome.last_step, 4, "{name}");
        states.push(read_saved_state(&out).unwrap());
    }
    // the two schemes differ in the contact pressure, so in the displacement
    assert_ne!(states[0].displacement, states[1].displacement);
    // an unknown treatment is refused with the file and the line
    let problem = dir.join("bogus.toml");
    std::fs::write(
        &problem,
        implicit.replace("contact = \"implicit\"", "contact = \"sometimes\""),
    )
    .unwrap();
    let message = simulate::run_file(&problem, &quiet(&dir.join("bogus")))
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("bogus.toml") && message.contains("sometimes"),
        "{message}"
    );
}

#[test]
fn resume_validates_the_saved_values_and_the_scheme() {
    let dir = scratch("simulate-resume-values");
    let problem = tiny_example(&dir);
    let out = dir.join("out");
    let until = |step| RunOptions {
        until_step: Some(step),
        ..quiet(&out)
    };
    let resume = RunOptions {
        resume: true,
        ..quiet(&out)
    };
    simulate::run_file(&problem, &until(4)).unwrap();
    let state_path = out.join("state.json");
    let original = std::fs::read_to_string(&state_path).unwrap();
    let mut state: serde_json::Value = serde_json::from_str(&original).unwrap();
    // a damage value outside [0, 1] is refused with the file, the field and the entry
    state["damage"][3] = serde_json::json!(5.0);
    std::fs::write(&state_path, state.to_string()).unwrap();
    let error = simulate::run_file(&problem, &resume)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("state.json") && error.contains("`damage` [3] = 5"),
        "{error}"
    );
    // so is a velocity of the wrong length
    let mut state: serde_json::Value = serde_json::from_str(&original).unwrap();
    state["velocity"].as_array_mut().unwrap().pop();
    std::fs::write(&state_path, state.to_string()).unwrap();
    let error = simulate::run_file(&problem, &resume)
        .unwrap_err()
        .to_string();
    assert!(error.contains("`velocity` has"), "{error}");
    // the untouched state resumes; the implicit scheme does not resume an explicit run, nor
    // the explicit scheme an implicit one
    std::fs::write(&state_path, &original).unwrap();
    let text = std::fs::read_to_string(&problem).unwrap();
    let implicit = dir.join("implicit.toml");
    std::fs::write(
        &implicit,
        text.replacen("[laws]", "[scheme]\ncontact = \"implicit\"\n\n[laws]", 1),
    )
    .unwrap();
    let error = simulate::run_file(&implicit, &resume)
        .unwrap_err()
        .to_string();
    assert!(error.contains("`scheme` changed"), "{error}");
    simulate::run_file(
        &implicit,
        &RunOptions {
            overwrite: true,
            ..until(4)
        },
    )
    .unwrap();
    let error = simulate::run_file(&problem, &resume)
        .unwrap_err()
        .to_string();
    assert!(error.contains("`scheme` changed"), "{error}");
    simulate::run_file(&implicit, &resume).unwrap();
}

/// `[scheme] damage = false`: a pure contact problem. The damage laws may be left out, no damage
/// step is solved (β stays 1, no damage iterations), and no damage pictures are drawn; the same
/// file with evolving damage is refused, naming the missing law.
#[test]
fn frozen_damage_runs_without_damage_laws_or_pictures() {
    let dir = scratch("simulate-frozen-damage");
    let text = std::fs::read_to_string(tiny_example(&dir)).unwrap();
    let without_laws: String = text
        .lines()
        .filter(|line| !line.starts_with("damage_source") && !line.starts_with("damage_diffusion"))
        .map(|line| format!("{line}\n"))
        .collect();
    assert_ne!(without_laws, text);
    let refused = dir.join("refused.toml");
    std::fs::write(&refused, &without_laws).unwrap();
    let error = simulate::run_file(&refused, &quiet(&dir.join("refused")))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("key `laws.damage_source`") && error.contains("damage = false"),
        "{error}"
    );
    let frozen = dir.join("frozen.toml");
    std::fs::write(
        &frozen,
        format!("{without_laws}\n[scheme]\ndamage = false\n"),
    )
    .unwrap();
    let out = dir.join("out");
    simulate::run_file(&frozen, &quiet(&out)).unwrap();
    let state = read_saved_state(&out).unwrap();
    assert!(state.damage.iter().all(|&beta| beta == 1.0));
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let header: Vec<&str> = history.lines().next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    for row in history.lines().skip(1) {
        let fields: Vec<&str> = row.split(',').collect();
        assert_eq!(fields[column("mean_damage")], "1");
        assert_eq!(fields[column("damage_iterations")], "0");
    }
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|entry| entry.unwrap().file_name().into_string().unwrap())
        .collect();
    assert!(
        !names.iter().any(|name| name.starts_with("damage_")),
        "{names:?}"
    );
    assert!(names.iter().any(|name| name == "contact_history.svg"));
}

/// The contact zone of a 3D P2 run is the disc the pressure covers: in the quarter-block
/// indenter example (P2, h = 1/12, a zone of radius about 2.5 h), `contact_zone` is the area
/// of a quarter disc of radius `zone_max` to 5 % (both are cut from the same linear
/// interpolant, whose polygonal edge lies within O(h²) of a circle). Taking the penetration of
/// the vertices of the quadratic faces, which carry no contact weight, gave 57 % of it.
#[test]
fn p2_contact_zone_in_3d_is_the_quarter_disc_of_its_radius() {
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/indenter_3d.toml");
    let setup = simulate::problem::ProblemSetup::<3>::from_path(&example).unwrap();
    let out = common::scratch("indenter-zone");
    let history = common::checked_run(&setup, &out, 1);
    let area = common::history_value(&history, 1, "contact_zone");
    let radius = common::history_value(&history, 1, "zone_max");
    let disc = std::f64::consts::PI * radius * radius / 4.0;
    assert!(radius > 0.1, "zone radius {radius}");
    assert!(
        (area / disc - 1.0).abs() < 0.05,
        "zone {area}, quarter disc {disc}"
    );
}

/// A resumed run keeps `output.every`, which decides the rows of `contact_history.csv`: another
/// value is refused naming the file and the key (it used to fail on a row of the contact
/// history); the same value resumes.
#[test]
fn resume_refuses_another_output_every_naming_the_key() {
    let dir = scratch("simulate-resume-every");
    let problem = tiny_example(&dir);
    let out = dir.join("out");
    simulate::run_file(
        &problem,
        &RunOptions {
            until_step: Some(3),
            ..quiet(&out)
        },
    )
    .unwrap();
    let changed = dir.join("every3.toml");
    let text = std::fs::read_to_string(&problem).unwrap();
    assert!(text.contains("every = 4"));
    std::fs::write(&changed, text.replace("every = 4", "every = 3")).unwrap();
    let resume = RunOptions {
        resume: true,
        ..quiet(&out)
    };
    let error = simulate::run_file(&changed, &resume)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("every3.toml")
            && error.contains("key `output.every`")
            && error.contains("every 4 steps"),
        "{error}"
    );
    simulate::run_file(&problem, &resume).unwrap();
}

/// A radius of the indenter's contact disc as the profile line: the quarter-block indenter
/// (P2, symmetry planes x = 0 and y = 0) with `output.profile` along the diagonal from the
/// centre of the disc, across the grid lines. The recorded nodes run from the centre outwards,
/// the pressure is largest near the centre and vanishes beyond the zone, whose extent
/// `zone_max` is now measured along the diagonal. The moment about the centre of the disc is
/// moment_x = ∫ y p = −moment_y (the quarter is symmetric in x and y), with moment_z = 0; its
/// lever arm moment_x / F_z, the centroid of the pressure on the quarter disc of radius a, lies
/// between the two limits of the block: a thin elastic layer, where p follows the penetration
/// (1 − r²/a², centroid 16a/15π ≈ 0.340 a), and a half-space (Hertz, p0 √(1 − r²/a²),
/// centroid 3a/8); the block, as thick as its width and four times the radius, sits between
/// them. 5 % of margin on either side for a, which spans about 2.5 cells.
#[test]
fn radial_profile_and_moment_of_the_indenter_follow_the_contact_disc() {
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/indenter_3d.toml");
    let dir = scratch("indenter-profile");
    let text = std::fs::read_to_string(&example).unwrap().replace(
        "profile = { from = [0, 0, 0], to = [1, 0, 0] }",
        "profile = { from = [0, 0, 0], to = [1, 1, 0] }\nmoment_about = [0, 0, 0]",
    );
    assert!(text.contains("to = [1, 1, 0]"));
    let problem = dir.join("indenter_profile.toml");
    std::fs::write(&problem, text).unwrap();
    let setup = ProblemSetup::<3>::from_path(&problem).unwrap();
    let out = dir.join("out");
    let history = common::checked_run(&setup, &out, 1);
    let value = |name: &str| common::history_value(&history, 1, name);
    let radius = value("zone_max");
    let normal_force = value("force_z");
    assert!(
        radius > 0.1 && normal_force > 0.0,
        "{radius} {normal_force}"
    );
    // a zone symmetric about the diagonal: its extent along it starts at the centre
    assert!(value("zone_min").abs() < 1e-12, "{}", value("zone_min"));
    let (moment_x, moment_y) = (value("moment_x"), value("moment_y"));
    let lever = moment_x / normal_force / radius;
    let (layer, half_space) = (16.0 / (15.0 * std::f64::consts::PI), 3.0 / 8.0);
    assert!(
        lever > 0.95 * layer && lever < 1.05 * half_space,
        "lever arm {lever} a, outside [{layer}, {half_space}] a"
    );
    assert!(
        (moment_x + moment_y).abs() < 1e-9 * moment_x.abs(),
        "{moment_x} {moment_y}"
    );
    assert!(value("moment_z").abs() < 1e-12 * moment_x.abs());

    let rows = std::fs::read_to_string(out.join("contact_history.csv")).unwrap();
    let profile: Vec<(f64, f64)> = rows
        .lines()
        .skip(1)
        .map(|row| {
            let fields: Vec<f64> = row.split(',').map(|f| f.parse().unwrap()).collect();
            (fields[2], fields[4])
        })
        .collect();
    // the contact nodes of the diagonal from the centre to the corner, in order of s: the
    // midpoints of the 12 diagonal edges (the vertices of a quadratic face carry no contact
    // weight, hence no contact unknowns)
    assert!(profile.windows(2).all(|w| w[0].0 <= w[1].0));
    let diagonal = 2.0f64.sqrt();
    let spacing = diagonal / 24.0;
    assert!(profile.len() >= 12, "{profile:?}");
    assert!(profile[0].0 <= spacing + 1e-12);
    assert!(profile[profile.len() - 1].0 >= diagonal - spacing - 1e-12);
    let peak = profile.iter().map(|p| p.1).fold(0.0, f64::max);
    assert!(peak > 0.0 && profile[0].1 == peak, "{profile:?}");
    for &(s, pressure) in &profile {
        if s > radius + spacing {
            assert_eq!(
                pressure, 0.0,
                "pressure {pressure} at s = {s} beyond the zone"
            );
        }
    }
    let picture = std::fs::read_to_string(out.join("contact_history.svg")).unwrap();
    assert!(picture.contains("from (0, 0, 0) towards (1, 1, 0)"));
}

/// A profile segment that no contact node lies near, a degenerate one and a point with the
/// wrong number of coordinates are refused naming the key, before any output is written.
#[test]
fn profile_and_moment_point_are_checked_before_the_first_step() {
    let dir = scratch("simulate-profile-errors");
    let problem = tiny_example(&dir);
    let text = std::fs::read_to_string(&problem).unwrap();
    for (output, key, message) in [
        (
            "profile = { from = [0, 0.5], to = [2, 0.5] }",
            "output.profile",
            "no contact node of Γ3 lies within",
        ),
        (
            "profile = { from = [1, 0], to = [1, 0] }",
            "output.profile.to",
            "must differ from `from`",
        ),
        (
            "profile = { from = [0, 0], to = [2, 0], width = -1 }",
            "output.profile.width",
            "positive",
        ),
        (
            "moment_about = [1, 0, 0]",
            "output.moment_about",
            "must have 2 coordinates",
        ),
    ] {
        let bad = dir.join("bad.toml");
        std::fs::write(
            &bad,
            text.replace("every = 4", &format!("every = 4\n{output}")),
        )
        .unwrap();
        let out = dir.join("out");
        let error = simulate::run_file(&bad, &quiet(&out))
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("bad.toml")
                && error.contains(&format!("key `{key}`"))
                && error.contains(message),
            "{output}: {error}"
        );
        assert!(!out.join("history.csv").exists(), "{output}");
    }
}

/// A resumed run keeps the profile line and the moment point of the run it continues: another
/// value of either is refused naming the key; the same values resume.
#[test]
fn resume_refuses_another_profile_or_moment_point_naming_the_key() {
    let dir = scratch("simulate-resume-profile");
    let tiny = tiny_example(&dir);
    let text = std::fs::read_to_string(&tiny).unwrap();
    let with = |output: &str, name: &str| {
        let path = dir.join(name);
        std::fs::write(
            &path,
            text.replace("every = 4", &format!("every = 4\n{output}")),
        )
        .unwrap();
        path
    };
    let problem = with(
        "profile = { from = [0, 0], to = [2, 0] }\nmoment_about = [1, 0]",
        "profile.toml",
    );
    let out = dir.join("out");
    simulate::run_file(
        &problem,
        &RunOptions {
            until_step: Some(3),
            ..quiet(&out)
        },
    )
    .unwrap();
    let resume = RunOptions {
        resume: true,
        ..quiet(&out)
    };
    for (output, key) in [
        ("moment_about = [1, 0]", "output.profile"),
        (
            "profile = { from = [0, 0], to = [2, 0] }\nmoment_about = [0, 0]",
            "output.moment_about",
        ),
    ] {
        let changed = with(output, "changed.toml");
        let error = simulate::run_file(&changed, &resume)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("changed.toml") && error.contains(&format!("key `{key}`")),
            "{output}: {error}"
        );
    }
    simulate::run_file(&problem, &resume).unwrap();
}

/// A body held by a roller only (u_x = 0 on x = 0, nothing else on Γ1) can slide along y: the
/// run is refused before anything is factorized or written, naming the file, the key
/// `displacement`, the free motion and the part.
#[test]
fn a_body_on_a_roller_only_is_refused_naming_the_file_and_the_key() {
    let dir = scratch("simulate-rigid");
    let tiny = tiny_example(&dir);
    let text = std::fs::read_to_string(&tiny).unwrap();
    assert!(text.contains("x_min = \"clamped\", "));
    let roller = text.replace("x_min = \"clamped\", ", "")
        + "\n[[displacement]]\npart = \"x_min\"\nx = \"0\"\n";
    let problem = dir.join("roller.toml");
    std::fs::write(&problem, roller).unwrap();
    let out = dir.join("out");
    let error = simulate::run_file(&problem, &quiet(&out))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("roller.toml")
            && error.contains("key `displacement`")
            && error.contains("can move rigidly")
            && error.contains("translation along y")
            && error.contains("`x_min`"),
        "{error}"
    );
    assert!(!out.join("history.csv").exists());
}
