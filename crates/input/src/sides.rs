//! The sides of a box domain (`domain.sides` of case files, `mesh.box.sides` of problem files):
//! which boundary part Γ1 (clamped), Γ2 (traction) or Γ3 (contact) each side belongs to.

use std::collections::BTreeMap;

use contact_damage::mesh::BoundaryPart;

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
