//! The boundary parts of a domain: which part Γ1 (clamped), Γ2 (traction) or Γ3 (contact) each
//! side of a box belongs to (`domain.sides` of case files, `mesh.box.sides` of problem files),
//! and the physical groups of a Gmsh mesh that make up each part ([`GroupFile`]).

use std::collections::BTreeMap;

use contact_damage::fem::mesh::BoundaryPart;
use contact_damage::io::gmsh::GroupRef;
use serde::Deserialize;

/// A physical group of a Gmsh mesh, by name (`"contact"`) or by tag (`7`), as the lists of
/// groups of each boundary part are written in case and problem files.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(untagged)]
pub enum GroupFile {
    /// By `$PhysicalNames` name.
    Name(String),
    /// By physical tag.
    Tag(i32),
}

impl GroupFile {
    /// The group as the mesh reader takes it.
    pub fn to_ref(&self) -> GroupRef {
        match self {
            GroupFile::Name(name) => GroupRef::Name(name.clone()),
            GroupFile::Tag(tag) => GroupRef::Tag(*tag),
        }
    }
}

use crate::error::{FileKind, InputError};

/// Parses box sides (`x_min`, `x_max`, `y_min`, `y_max`, `z_min`, `z_max` → `clamped` (Γ1),
/// `traction` (Γ2) or `contact` (Γ3)); sides not listed are traction sides. Errors name
/// `origin` and the key `key_prefix.SIDE`.
pub fn parse_sides<const D: usize>(
    kind: FileKind,
    origin: &str,
    key_prefix: &str,
    sides_file: &BTreeMap<String, String>,
) -> Result<[[BoundaryPart; 2]; D], InputError> {
    let axes = ["x", "y", "z"];
    let mut sides = [[BoundaryPart::Neumann; 2]; D];
    for (key, part) in sides_file {
        let (axis, end) = match key.split_once('_') {
            Some((a, e)) => (axes.iter().position(|n| *n == a), e),
            None => (None, ""),
        };
        let side = match end {
            "min" => Some(0),
            "max" => Some(1),
            _ => None,
        };
        let (Some(axis), Some(side)) = (axis.filter(|&a| a < D), side) else {
            return Err(kind.error(
                origin,
                &format!("{key_prefix}.{key}"),
                "unknown side (use x_min, x_max, y_min, y_max[, z_min, z_max])",
            ));
        };
        sides[axis][side] = match part.as_str() {
            "clamped" => BoundaryPart::Dirichlet,
            "traction" => BoundaryPart::Neumann,
            "contact" => BoundaryPart::Contact,
            other => {
                return Err(kind.error(
                    origin,
                    &format!("{key_prefix}.{key}"),
                    format!("unknown part `{other}` (use clamped, traction or contact)"),
                ))
            }
        };
    }
    Ok(sides)
}
/// A prescribed side of a box: axis, end (0 = min, 1 = max) and the prescribed components.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PrescribedSide<const D: usize> {
    /// Axis of the side's normal.
    pub axis: usize,
    /// 0 for the side x_axis = lower, 1 for upper.
    pub end: usize,
    /// Prescribed components.
    pub components: [bool; D],
}

/// The side name (`x_min`, …) as (axis, end), if it names a side in dimension D.
pub fn side_index<const D: usize>(key: &str) -> Option<(usize, usize)> {
    let (axis, end) = key.split_once('_')?;
    let axis = ["x", "y", "z"].iter().position(|n| *n == axis)?;
    let end = match end {
        "min" => 0,
        "max" => 1,
        _ => return None,
    };
    (axis < D).then_some((axis, end))
}

/// A component name (`x`, `y`, `z`) as its index in dimension D.
pub fn component_index<const D: usize>(name: &str) -> Option<usize> {
    ["x", "y", "z"]
        .iter()
        .position(|n| *n == name)
        .filter(|&i| i < D)
}

/// Checks `[[displacement]]` (key prefix `key`) against the box sides and marks the prescribed
/// sides as Γ1: a side must be `clamped` or unlisted (`contact` overlaps Γ3, `traction` is Γ2:
/// errors), listed once, with at least one component, each once.
pub fn prescribed_sides<const D: usize>(
    kind: FileKind,
    origin: &str,
    key: &str,
    parts: &[(String, Vec<String>)],
    sides_file: &BTreeMap<String, String>,
    sides: &mut [[BoundaryPart; 2]; D],
) -> Result<Vec<PrescribedSide<D>>, InputError> {
    let mut result: Vec<PrescribedSide<D>> = Vec::new();
    for (i, (part, components)) in parts.iter().enumerate() {
        let key = format!("{key}[{i}]");
        let Some((axis, end)) = side_index::<D>(part) else {
            return Err(kind.error(
                origin,
                &format!("{key}.part"),
                format!("unknown side `{part}` (use x_min, x_max, y_min, y_max[, z_min, z_max])"),
            ));
        };
        match sides_file.get(part).map(String::as_str) {
            None | Some("clamped") => sides[axis][end] = BoundaryPart::Dirichlet,
            Some("contact") => {
                return Err(kind.error(
                    origin,
                    &format!("{key}.part"),
                    format!("side `{part}` is the contact boundary Γ3: a prescribed displacement may not overlap Γ3"),
                ))
            }
            Some(other) => {
                return Err(kind.error(
                    origin,
                    &format!("{key}.part"),
                    format!("side `{part}` is `{other}`: a prescribed displacement acts on a `clamped` (Γ1) or unlisted side"),
                ))
            }
        }
        if result.iter().any(|s| (s.axis, s.end) == (axis, end)) {
            return Err(kind.error(
                origin,
                &format!("{key}.part"),
                format!("side `{part}` is listed twice"),
            ));
        }
        let mut mask = [false; D];
        for (j, name) in components.iter().enumerate() {
            match component_index::<D>(name) {
                Some(c) if !mask[c] => mask[c] = true,
                _ => {
                    return Err(kind.error(
                        origin,
                        &format!("{key}.components[{j}]"),
                        format!("`{name}` is not a component (x, y[, z]) or is listed twice"),
                    ))
                }
            }
        }
        if !mask.contains(&true) {
            return Err(kind.error(
                origin,
                &format!("{key}.components"),
                "list at least one prescribed component",
            ));
        }
        result.push(PrescribedSide {
            axis,
            end,
            components: mask,
        });
    }
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sides(entries: &[(&str, &str)]) -> BTreeMap<String, String> {
        entries
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    #[test]
    fn listed_sides_get_their_part_and_the_others_are_traction_sides() {
        let parts = parse_sides::<2>(
            FileKind::Case,
            "c.toml",
            "domain.sides",
            &sides(&[("x_min", "clamped"), ("y_min", "contact")]),
        )
        .unwrap();
        assert_eq!(
            parts,
            [
                [BoundaryPart::Dirichlet, BoundaryPart::Neumann],
                [BoundaryPart::Contact, BoundaryPart::Neumann]
            ]
        );
    }

    #[test]
    fn an_unknown_side_or_part_names_the_key() {
        let error = parse_sides::<2>(
            FileKind::Problem,
            "p.toml",
            "mesh.box.sides",
            &sides(&[("z_min", "clamped")]),
        )
        .unwrap_err()
        .to_string();
        assert!(
            error.starts_with("problem file `p.toml`, key `mesh.box.sides.z_min`: unknown side"),
            "{error}"
        );
        let error = parse_sides::<3>(
            FileKind::Case,
            "c.toml",
            "domain.sides",
            &sides(&[("z_max", "glued")]),
        )
        .unwrap_err()
        .to_string();
        assert!(
            error.contains("key `domain.sides.z_max`: unknown part `glued`"),
            "{error}"
        );
    }
}
