//! The memory a study needs, checked before the first solve.
//!
//! The levels of an h- or diagonal study run in parallel, so a study may hold all of its levels
//! at once; a k-study holds its levels and the reference run on one mesh. The estimate of a
//! study is the sum of the estimates of its runs ([`contact_damage::memory`]), and the largest
//! study selected must fit under the limit (`--memory-limit`, default the physical memory).

use crate::case::Case;
use crate::VerifyError;
use contact_damage::memory::{check, estimate_box, MemoryEstimate};

/// Refuses the studies `names` of order `degree` of `case` (each cut to its first `levels`
/// levels) if the largest needs more than `limit` bytes.
pub fn check_studies<const D: usize>(
    case: &Case<D>,
    degree: usize,
    names: &[String],
    levels: Option<usize>,
    limit: f64,
) -> Result<(), VerifyError> {
    let Some(set) = case.file.studies.get(&format!("order{degree}")) else {
        return Ok(());
    };
    let cut = |count: usize| levels.map_or(count, |levels| levels.min(count));
    let sum = |meshes: &[usize]| {
        meshes
            .iter()
            .map(|&cells| estimate_box(&[cells; D], degree))
            .fold(
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
                Some(study) => ("h", study.cells[..cut(study.cells.len())].to_vec()),
                None => continue,
            },
            "diagonal" => match &set.diagonal {
                Some(study) => ("diagonal", study.cells[..cut(study.cells.len())].to_vec()),
                None => continue,
            },
            "k" => match &set.k {
                Some(study) => ("k", vec![study.cells; cut(study.steps.len()) + 1]),
                None => continue,
            },
            _ => continue,
        };
        check(
            sum(&meshes),
            limit,
            &format!(
                "the {label} study of order {degree} of case `{}` (levels run at once: {meshes:?} cells per side)",
                case.origin
            ),
            "--memory-limit",
        )?;
    }
    Ok(())
}
