//! Hostile edits of the built-in case files (numbers replaced by 0, nan, 1e300, 10⁹, …, lines
//! deleted, duplicated or swapped, stray quotes and brackets, truncation; see
//! `contact_input::mutation`): reading and validating the edited file gives a case or an error,
//! never a panic. A case that validates is also built at its coarsest level, where
//! the memory guard of the studies applies first.

use contact_input::mutation::mutate;
use proptest::prelude::*;
use verify::case::{parse_case_file, Case};
use verify::cli::BUILT_IN_CASES;

/// Reads, validates and (if valid) builds the coarsest h-level of the edited case `text`.
fn read(text: &str) {
    let Ok(file) = parse_case_file(text, "fuzz.toml") else {
        return;
    };
    let dim = file.dim;
    let first_cells = file
        .studies
        .values()
        .filter_map(|set| set.h.as_ref())
        .find_map(|study| study.cells.first().copied());
    match dim {
        2 => build::<2>(file, first_cells),
        3 => build::<3>(file, first_cells),
        _ => {}
    }
}

fn build<const D: usize>(file: verify::case::CaseFile, first_cells: Option<usize>) {
    let Ok(case) = Case::<D>::new(file, "fuzz.toml") else {
        return;
    };
    let limit = 0.25 * contact_damage::algebra::memory::GIB;
    if let Some(cells) = first_cells {
        let estimate = contact_damage::algebra::memory::estimate_box(&[cells; D], 1);
        if contact_damage::algebra::memory::check(estimate, limit, "fuzz", "--memory-limit").is_ok()
        {
            let _ = case.problem(cells, 1, 2);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(192))]
    #[test]
    fn edited_case_files_never_panic(
        which in 0..BUILT_IN_CASES.len(),
        edits in proptest::collection::vec((0u8..6, 0.0f64..1.0, 0usize..64), 1..4),
    ) {
        let text = mutate(BUILT_IN_CASES[which].1, &edits);
        read(&text);
    }
}
