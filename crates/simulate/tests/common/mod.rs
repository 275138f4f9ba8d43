//! Helpers shared by the integration tests of `simulate` (each test file uses some of them).
#![allow(dead_code)]

use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// A fresh folder `name` under cargo's per-test temporary directory (names must differ
/// between the test files, which run at the same time).
pub fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The boundary facets of `part`.
pub fn facets_of<const D: usize>(mesh: &Mesh<D>, part: BoundaryPart) -> Vec<usize> {
    (0..mesh.num_facets())
        .filter(|&f| mesh.facet_part(f) == part)
        .collect()
}

/// The vertices of the facets of `part`.
pub fn vertices_of<const D: usize>(mesh: &Mesh<D>, part: BoundaryPart) -> BTreeSet<usize> {
    facets_of(mesh, part)
        .into_iter()
        .flat_map(|f| mesh.facet(f).to_vec())
        .collect()
}

/// Number of P1 contact nodes the scheme must find: the vertices of Γ3 less those on Γ1.
pub fn expected_contact_nodes<const D: usize>(mesh: &Mesh<D>) -> usize {
    vertices_of(mesh, BoundaryPart::Contact)
        .difference(&vertices_of(mesh, BoundaryPart::Dirichlet))
        .count()
}

/// Column `name` of the history at `step` (columns looked up by the header).
pub fn history_value(history: &str, step: usize, name: &str) -> f64 {
    let mut lines = history.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = header
        .iter()
        .position(|&c| c == name)
        .unwrap_or_else(|| panic!("no column {name}"));
    let row = lines
        .map(|line| line.split(',').collect::<Vec<_>>())
        .find(|fields| fields[0] == step.to_string())
        .unwrap_or_else(|| panic!("no row for step {step}"));
    row[column].parse().unwrap()
}

/// Runs `setup` quietly into `out` up to step `until`, asserts that every step converged with
/// KKT residuals below 1e-9, and returns the text of `history.csv`.
pub fn checked_run<const D: usize>(
    setup: &simulate::problem::ProblemSetup<D>,
    out: &Path,
    until: usize,
) -> String {
    let outcome = simulate::run::run(
        setup,
        &simulate::run::RunOptions {
            out: Some(out.to_path_buf()),
            quiet: true,
            until_step: Some(until),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(outcome.last_step, until);
    assert!(
        outcome.max_kkt.velocity < 1e-9 && outcome.max_kkt.damage < 1e-9,
        "KKT residuals {:?}",
        outcome.max_kkt
    );
    std::fs::read_to_string(out.join(simulate::history::HISTORY_FILE)).unwrap()
}
