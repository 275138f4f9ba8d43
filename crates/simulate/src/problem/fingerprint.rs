//! What a saved state must match to be resumed with a problem (`ProblemSetup::fingerprint`):
//! the constants, laws, loads, scheme and prescribed displacements of the file as canonical JSON,
//! and the SHA-256 of the built mesh.

use super::file::ProblemFile;
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_input::scheme::SchemeFile;
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;

/// SHA-256 (hex) of the vertex coordinates, cells and boundary facets with their parts.
pub fn mesh_fingerprint<const D: usize>(mesh: &Mesh<D>) -> String {
    let mut hasher = Sha256::new();
    hasher.update((D as u64).to_le_bytes());
    hasher.update((mesh.num_vertices() as u64).to_le_bytes());
    for vertex in mesh.vertices() {
        for coordinate in vertex {
            hasher.update(coordinate.to_bits().to_le_bytes());
        }
    }
    hasher.update((mesh.num_cells() as u64).to_le_bytes());
    for c in 0..mesh.num_cells() {
        for &v in mesh.cell(c) {
            hasher.update((v as u64).to_le_bytes());
        }
    }
    hasher.update((mesh.num_facets() as u64).to_le_bytes());
    for f in 0..mesh.num_facets() {
        for &v in mesh.facet(f) {
            hasher.update((v as u64).to_le_bytes());
        }
        hasher.update([match mesh.facet_part(f) {
            BoundaryPart::Dirichlet => 1u8,
            BoundaryPart::Neumann => 2,
            BoundaryPart::Contact => 3,
        }]);
    }
    hasher
        .finalize()
        .iter()
        .map(|byte| format!("{byte:02x}"))
        .collect()
}

/// The fingerprint of the problem of `file` on `mesh`: `constants`, `laws`, `loads` and `mesh`
/// always, `scheme` and `displacement` when they are not the default.
pub(super) fn fingerprint<const D: usize>(
    file: &ProblemFile,
    mesh: &Mesh<D>,
) -> BTreeMap<String, String> {
    let canonical = |value: Result<String, serde_json::Error>| {
        value.unwrap_or_else(|e| unreachable!("plain data serializes to JSON: {e}"))
    };
    let mut fingerprint = BTreeMap::from([
        (
            "constants".to_string(),
            canonical(serde_json::to_string(&file.constants)),
        ),
        (
            "laws".to_string(),
            canonical(serde_json::to_string(&file.laws)),
        ),
        (
            "loads".to_string(),
            canonical(serde_json::to_string(&file.loads)),
        ),
        ("mesh".to_string(), mesh_fingerprint(mesh)),
    ]);
    if file.scheme != SchemeFile::default() {
        // a resumed run continues the same scheme (absent for the paper's default, so
        // that the states of earlier versions still resume)
        fingerprint.insert(
            "scheme".to_string(),
            canonical(serde_json::to_string(&file.scheme)),
        );
    }
    if !file.displacement.is_empty() {
        // a resumed run keeps the same prescribed displacements
        fingerprint.insert(
            "displacement".to_string(),
            canonical(serde_json::to_string(&file.displacement)),
        );
    }
    fingerprint
}
