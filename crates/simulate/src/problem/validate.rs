//! The checks of the entries that need no mesh — `dim`, `degree`, `final_time`, `steps`, the
//! name and `[output]` — and of the contact face Γ3 a 3D problem needs.

use super::file::{problem_error, ProblemFile};
use crate::contact_line::ProfileSegment;
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::io::vtk::VtuEncoding;
use contact_input::InputError;
use std::path::Path;

/// Checks `dim` (= D), `degree`, `final_time`, `steps` and `output.every`, in this order.
pub(super) fn check_sizes<const D: usize>(
    file: &ProblemFile,
    origin: &str,
) -> Result<(), InputError> {
    if file.dim != D {
        return Err(problem_error(
            origin,
            "dim",
            format!("expected {D}, got {}", file.dim),
        ));
    }
    if !(1..=2).contains(&file.degree) {
        return Err(problem_error(
            origin,
            "degree",
            format!("must be 1 or 2, got {}", file.degree),
        ));
    }
    if !(file.final_time.is_finite() && file.final_time > 0.0) {
        return Err(problem_error(
            origin,
            "final_time",
            format!(
                "must be a positive number, got {}",
                contact_input::number::short(file.final_time)
            ),
        ));
    }
    if file.steps == 0 {
        return Err(problem_error(origin, "steps", "must be at least 1"));
    }
    if file.output.every == 0 {
        return Err(problem_error(origin, "output.every", "must be at least 1"));
    }
    Ok(())
}

/// The times of the damage pictures (`output.pictures`, default T/2 and T), each in (0, T].
pub(super) fn picture_times(file: &ProblemFile, origin: &str) -> Result<Vec<f64>, InputError> {
    let pictures = file
        .output
        .pictures
        .clone()
        .unwrap_or_else(|| vec![0.5 * file.final_time, file.final_time]);
    if let Some(bad) = pictures
        .iter()
        .find(|&&t| !(t.is_finite() && t > 0.0 && t <= file.final_time))
    {
        return Err(problem_error(
            origin,
            "output.pictures",
            format!(
                "every time must lie in (0, final_time = {}], got {bad}",
                file.final_time
            ),
        ));
    }
    Ok(pictures)
}

/// The encoding of the VTU arrays (`output.vtu`, default binary).
pub(super) fn vtu_encoding(file: &ProblemFile, origin: &str) -> Result<VtuEncoding, InputError> {
    let vtu = match file.output.vtu.as_deref() {
        None | Some("binary") => VtuEncoding::Binary,
        Some("ascii") => VtuEncoding::Ascii,
        Some(other) => {
            return Err(problem_error(
                origin,
                "output.vtu",
                format!("must be \"binary\" or \"ascii\", got \"{other}\""),
            ))
        }
    };
    Ok(vtu)
}

/// A point of `output` (`key`): d finite coordinates.
fn output_point<const D: usize>(
    values: &[f64],
    key: &str,
    origin: &str,
) -> Result<[f64; D], InputError> {
    if values.len() != D {
        return Err(problem_error(
            origin,
            key,
            format!(
                "must have {D} coordinates (dim = {D}), got {}",
                values.len()
            ),
        ));
    }
    if let Some(bad) = values.iter().find(|x| !x.is_finite()) {
        return Err(problem_error(
            origin,
            key,
            format!("every coordinate must be finite, got {bad}"),
        ));
    }
    Ok(std::array::from_fn(|i| values[i]))
}

/// The profile line of `output.profile`, if any: two distinct points of d coordinates and a
/// positive width. Whether it meets Γ3 is checked on the mesh, before the first step.
pub(super) fn profile_segment<const D: usize>(
    file: &ProblemFile,
    origin: &str,
) -> Result<Option<ProfileSegment<D>>, InputError> {
    let Some(profile) = &file.output.profile else {
        return Ok(None);
    };
    let from = output_point::<D>(&profile.from, "output.profile.from", origin)?;
    let to = output_point::<D>(&profile.to, "output.profile.to", origin)?;
    if from == to {
        return Err(problem_error(
            origin,
            "output.profile.to",
            "must differ from `from`: the segment gives the direction of s",
        ));
    }
    if let Some(width) = profile.width.filter(|w| !(w.is_finite() && *w > 0.0)) {
        return Err(problem_error(
            origin,
            "output.profile.width",
            format!("must be a positive number, got {width}"),
        ));
    }
    Ok(Some(ProfileSegment {
        from,
        to,
        width: profile.width,
    }))
}

/// The point of `output.moment_about` (default the origin).
pub(super) fn moment_point<const D: usize>(
    file: &ProblemFile,
    origin: &str,
) -> Result<[f64; D], InputError> {
    match &file.output.moment_about {
        None => Ok([0.0; D]),
        Some(point) => output_point::<D>(point, "output.moment_about", origin),
    }
}

/// The problem name (`name`, default the stem of the file at `path`), which must name a folder.
pub(super) fn problem_name(
    file: &ProblemFile,
    path: &Path,
    origin: &str,
) -> Result<String, InputError> {
    let name = match &file.name {
        Some(name) => name.clone(),
        None => path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "problem".into()),
    };
    if name.is_empty() || name.contains(['/', '\\']) || name == "." || name == ".." {
        return Err(problem_error(
            origin,
            "name",
            format!("`{name}` cannot name a folder"),
        ));
    }
    Ok(name)
}

/// Refuses a 3D problem without a contact face Γ3: its damage pictures are drawn on Γ3, so
/// before the first step.
pub(super) fn check_contact_face<const D: usize>(
    file: &ProblemFile,
    mesh: &Mesh<D>,
    origin: &str,
) -> Result<(), InputError> {
    if D == 3 && !(0..mesh.num_facets()).any(|f| mesh.facet_part(f) == BoundaryPart::Contact) {
        let key = if file.mesh.gmsh.is_some() {
            "mesh.gmsh.contact"
        } else {
            "mesh.box.sides"
        };
        return Err(problem_error(
            origin,
            key,
            "a 3D problem needs a contact face Γ3 (its damage pictures are drawn on it), and no boundary facet is `contact`",
        ));
    }
    Ok(())
}
