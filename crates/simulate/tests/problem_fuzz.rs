//! Hostile edits of the example problem files (see `contact_input::mutation`): reading,
//! validating and setting up the edited problem gives a setup or an error, never a panic.
//! The memory guard runs first, as in `simulate::run_file`, with a limit of 0.25 GiB so that
//! an edited cell count cannot make the test allocate much.

use contact_input::mutation::mutate;
use proptest::prelude::*;
use simulate::problem::{parse_problem_file, ProblemSetup};
use simulate::run::{check_memory, RunOptions};
use std::path::Path;

const EXAMPLES: [&str; 3] = [
    include_str!("../examples/rectangle_2d.toml"),
    include_str!("../examples/block_3d.toml"),
    include_str!("../examples/plate_with_hole_2d.toml"),
];

fn set_up(text: &str) {
    let Ok(file) = parse_problem_file(text, "fuzz.toml") else {
        return;
    };
    let options = RunOptions {
        memory_limit: Some(0.25 * contact_damage::algebra::memory::GIB),
        ..RunOptions::default()
    };
    if let Some(box_file) = &file.mesh.box_mesh {
        let estimate = contact_damage::algebra::memory::estimate_box(&box_file.cells, file.degree);
        if check_memory("fuzz.toml", estimate, &options).is_err() {
            return;
        }
    }
    // relative Gmsh paths are resolved against the examples folder
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/fuzz.toml");
    let _ = match file.dim {
        2 => ProblemSetup::<2>::new(file, &path).map(|_| ()),
        3 => ProblemSetup::<3>::new(file, &path).map(|_| ()),
        _ => Ok(()),
    };
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(192))]
    #[test]
    fn edited_problem_files_never_panic(
        which in 0..EXAMPLES.len(),
        edits in proptest::collection::vec((0u8..6, 0.0f64..1.0, 0usize..64), 1..4),
    ) {
        let text = mutate(EXAMPLES[which], &edits);
        set_up(&text);
    }
}
