//! End-to-end tests of `simulate`: the 2D example at a tiny size writes VTU/PVD files that an
//! XML parser reads back with the right sizes and fields; an interrupted and resumed run gives
//! bitwise the same result as an uninterrupted one; bad problem files name the key.

use simulate::problem::ProblemSetup;
use simulate::run::{read_saved_state, RunOptions};
use std::path::{Path, PathBuf};

const EXAMPLE_2D: &str = include_str!("../examples/rectangle_2d.toml");

/// A fresh folder under cargo's per-test temporary directory.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("simulate-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

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

/// Values of the `DataArray` called `name` and its number of components.
fn data_array(document: &roxmltree::Document, name: &str) -> (usize, Vec<f64>) {
    let node = document
        .descendants()
        .find(|n| n.has_tag_name("DataArray") && n.attribute("Name") == Some(name))
        .unwrap_or_else(|| panic!("no DataArray {name}"));
    let components = node
        .attribute("NumberOfComponents")
        .map_or(1, |c| c.parse().unwrap());
    let values = node
        .text()
        .unwrap_or("")
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
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
    let dir = scratch("output");
    let problem = tiny_example(&dir);
    let out = dir.join("out");
    let outcome = simulate::run_file(&problem, &quiet(&out)).unwrap();
    assert_eq!(outcome.last_step, 12);
    assert_eq!(outcome.saved_steps, vec![4, 8, 12]);
    assert!(outcome.max_kkt[0] <= 1e-10 && outcome.max_kkt[1] <= 1e-12);

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

    // one history row per step, the step column counting up
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let rows: Vec<&str> = history.lines().collect();
    assert_eq!(rows.len(), 13);
    assert!(rows[0].starts_with("step,t,normal_force,stick,slip,separated,mean_damage"));
    for (n, row) in rows[1..].iter().enumerate() {
        let fields: Vec<&str> = row.split(',').collect();
        assert_eq!(fields[0], (n + 1).to_string());
        let counts: usize = fields[3..6]
            .iter()
            .map(|c| c.parse::<usize>().unwrap())
            .sum();
        assert_eq!(counts, 8, "stick + slip + separated = contact nodes");
    }
}

#[test]
fn resumed_run_equals_uninterrupted_run_bitwise() {
    let dir = scratch("resume");
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
    history.push_str("6,0.3,0,0,0,8,1,0,0e0,0e0,1,1,1\n");
    std::fs::write(split.join("history.csv"), history).unwrap();
    let mut contact_history = std::fs::read_to_string(split.join("contact_history.csv")).unwrap();
    contact_history.push_str("6,0.3,0.25,1,0.5\n6,0.3,0.5,");
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

#[test]
fn resume_and_restart_refuse_mismatches() {
    let dir = scratch("refuse");
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
}

/// The error of building the 2D example with `from` replaced by `to`.
fn error_of(from: &str, to: &str) -> String {
    let text = EXAMPLE_2D.replace(from, to);
    assert_ne!(text, EXAMPLE_2D, "`{from}` is not in the example");
    let path = Path::new("bad.toml");
    let file = match verify::case::parse_toml(&text, "bad.toml") {
        Ok(file) => file,
        Err(error) => return error.to_string(),
    };
    match ProblemSetup::<2>::new(file, path) {
        Ok(_) => panic!("`{to}` was accepted"),
        Err(error) => error.to_string(),
    }
}

#[test]
fn bad_problem_files_name_the_key() {
    for (from, to, expected) in [
        ("[output]", "[outptu]", "unknown field `outptu`"),
        ("every = 10", "every = 0", "key `output.every`"),
        (
            "every = 10",
            "every = 10\npictures = [2.5, 6.0]",
            "key `output.pictures`: every time must lie in (0, final_time = 5], got 6",
        ),
        ("gap = \"0.02*x\"", "gap = \"0.02*t\"", "key `loads.gap`"),
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
        ("stiffness = 4.0", "stiffness = -4.0", "key `laws`"),
        ("dim = 2", "dim = 3", "key `dim`"),
        ("steps = 250", "steps = 0", "key `steps`"),
        ("degree = 1", "degree = 3", "key `degree`"),
    ] {
        let error = error_of(from, to);
        assert!(error.contains("bad.toml"), "{error}");
        assert!(error.contains(expected), "`{to}`: {error}");
    }
    // an unknown key is located by line
    let error = error_of("[output]", "[outptu]");
    assert!(error.contains("line "), "{error}");
}

#[test]
fn gmsh_problem_runs_on_a_committed_mesh() {
    let dir = scratch("gmsh");
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
    let dir = scratch("pictures");
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

    // 8 contact nodes on y = 0 (the clamped corner is none) in each of the 12 steps
    let csv = read("contact_history.csv");
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("step,t,s,status,normal_pressure"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 12 * 8);
    for (index, row) in rows.iter().enumerate() {
        assert_eq!(row[0], (index / 8 + 1) as f64);
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

    let svg = read("contact_history.svg");
    assert!(svg.contains("<svg") && svg.contains("<rect") && svg.contains("<polyline"));
    for label in [
        "separated",
        "stick",
        "slip",
        "contact status on Γ3 over time",
        "normal pressure p_ν on Γ3",
        "t = 0.3000",
        "t = 0.6000",
        "x on Γ3",
    ] {
        assert!(svg.contains(label), "{label} is missing");
    }
}
