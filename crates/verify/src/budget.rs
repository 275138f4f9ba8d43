//! The memory a study needs, checked before the first solve.
//!
//! The levels of an h- or diagonal study run in parallel, so a study may hold all of its levels
//! at once; a k-study holds its levels and the reference run on one mesh. The estimate of a
//! study is the sum of the estimates of its runs ([`contact_damage::algebra::memory`]), and the largest
//! study selected must fit under the limit (`--memory-limit`, default the physical memory).

use crate::case::Case;
use crate::domain::Domain;
use crate::InputError;
use contact_damage::algebra::memory::{check, estimate, estimate_box, MemoryEstimate};

/// Refuses the studies `names` of order `degree` of `case` (each cut to its first `levels`
/// levels) if the largest needs more than `limit` bytes.
pub fn check_memory<const D: usize>(
    case: &Case<D>,
    degree: usize,
    names: &[String],
    levels: Option<usize>,
    limit: f64,
) -> Result<(), InputError> {
    let Some(set) = case.file.studies.get(&format!("order{degree}")) else {
        return Ok(());
    };
    let cut = |count: usize| levels.map_or(count, |levels| levels.min(count));
    // a level is the cells per side of a box, or the refinements of a mesh (each multiplies
    // the vertices by about 2^D)
    let run = |level: usize| match &case.domain {
        Domain::Box { .. } => estimate_box(&[level; D], degree),
        Domain::Mesh { mesh, .. } => estimate(
            D,
            degree,
            mesh.num_vertices() as f64 * 2f64.powi((D * level) as i32),
        ),
    };
    let sum = |meshes: &[usize]| {
        meshes.iter().map(|&level| run(level)).fold(
            MemoryEstimate {
                unknowns: 0.0,
                bytes: 0.0,
            },
            |total, run| MemoryEstimate {
                unknowns: total.unknowns + run.unknowns,
                bytes: total.bytes + run.bytes,
            },
        )
    };
    for name in names {
        let (label, meshes) = match name.as_str() {
            "h" => match &set.h {
                Some(study) => ("h", study.levels()[..cut(study.levels().len())].to_vec()),
                None => continue,
            },
            "diagonal" => match &set.diagonal {
                Some(study) => (
                    "diagonal",
                    study.levels()[..cut(study.levels().len())].to_vec(),
                ),
                None => continue,
            },
            "k" => match &set.k {
                Some(study) => ("k", vec![study.level(); cut(study.steps.len()) + 1]),
                None => continue,
            },
            _ => continue,
        };
        check(
            sum(&meshes),
            limit,
            &format!(
                "the {label} study of order {degree} of case `{}` (levels run at once: {meshes:?} cells per side or refinements)",
                case.origin
            ),
            "--memory-limit",
        )?;
    }
    Ok(())
}
