//! The solver's [`Data`] from `[loads]` and `[[displacement]]`: the expressions parsed, checked
//! for finite values at sample points, and compiled into the fields the solver evaluates.

use super::fields::{
    eval_vector, parse_vector, point_values, BatchLoad, CompiledField, LoadCurve, FIELD_VARIABLES,
    STATIC_VARIABLES, TRACTION_VARIABLES,
};
use super::file::{problem_error, ProblemFile};
use crate::watch::LoadWatch;
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::scheme::{Data, PointScalarField, PrescribedDisplacement};
use contact_input::expr::Expr;
use contact_input::file::parse_expr;
use contact_input::sides::component_index;
use contact_input::{FileKind, InputError};
use std::collections::BTreeMap;
use std::sync::Arc;

/// The expressions of `[loads]`, parsed; missing entries are zero (β0 = 1).
pub(super) struct LoadExpressions<const D: usize> {
    /// f0 in x, y, z, t.
    body_force: Option<[Expr; D]>,
    /// f2 in x, y, z, t, nx, ny, nz.
    traction: Option<[Expr; D]>,
    /// u0 in x, y, z.
    initial_displacement: [Expr; D],
    /// g in x, y, z, t.
    gap: Expr,
    /// The factor of f2 over time.
    curve: Option<LoadCurve>,
    /// β0 in x, y, z.
    initial_damage: Expr,
}

impl<const D: usize> LoadExpressions<D> {
    /// Parses the entries of `[loads]` of `file` (`body_force`, `traction`,
    /// `initial_displacement`, `gap`, `traction_curve`, `initial_damage`, in this order).
    pub(super) fn parse(file: &ProblemFile, origin: &str) -> Result<Self, InputError> {
        let constants = &file.constants;
        let loads = &file.loads;
        let body_force = loads
            .body_force
            .as_ref()
            .map(|s| parse_vector::<D>(origin, "loads.body_force", s, &FIELD_VARIABLES, constants))
            .transpose()?;
        let traction = loads
            .traction
            .as_ref()
            .map(|s| parse_vector::<D>(origin, "loads.traction", s, &TRACTION_VARIABLES, constants))
            .transpose()?;
        let zero = vec!["0".to_string(); D];
        let initial_displacement = parse_vector::<D>(
            origin,
            "loads.initial_displacement",
            loads.initial_displacement.as_ref().unwrap_or(&zero),
            &STATIC_VARIABLES,
            constants,
        )?;
        let gap = parse_expr(
            FileKind::Problem,
            origin,
            "loads.gap",
            loads.gap.as_deref().unwrap_or("0"),
            &FIELD_VARIABLES,
            constants,
        )?;
        let curve = loads
            .traction_curve
            .as_ref()
            .map(|points| LoadCurve::new(origin, "loads.traction_curve", points))
            .transpose()?;
        let initial_damage = parse_expr(
            FileKind::Problem,
            origin,
            "loads.initial_damage",
            loads.initial_damage.as_deref().unwrap_or("1"),
            &STATIC_VARIABLES,
            constants,
        )?;
        Ok(Self {
            body_force,
            traction,
            initial_displacement,
            gap,
            curve,
            initial_damage,
        })
    }

    /// Checks f0 for finite values at the mesh vertices at `times`.
    pub(super) fn check_body_force(
        &self,
        mesh: &Mesh<D>,
        times: &[f64],
        origin: &str,
    ) -> Result<(), InputError> {
        if let Some(force) = &self.body_force {
            for x in mesh.vertices() {
                for &t in times {
                    let value = eval_vector(force, &point_values(x, &[t]));
                    if value.iter().any(|v| !v.is_finite()) {
                        return Err(problem_error(
                            origin,
                            "loads.body_force",
                            format!("f0 = {value:?} is not finite at x = {x:?}, t = {t}"),
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// Checks g for finite values at the vertices of Γ3 at `times`.
    pub(super) fn check_gap(
        &self,
        mesh: &Mesh<D>,
        times: &[f64],
        origin: &str,
    ) -> Result<(), InputError> {
        for f in (0..mesh.num_facets()).filter(|&f| mesh.facet_part(f) == BoundaryPart::Contact) {
            for &vertex in mesh.facet(f) {
                let x = mesh.vertex(vertex);
                for &t in times {
                    let value = self.gap.eval_f64(&point_values(&x, &[t]));
                    if !value.is_finite() {
                        return Err(problem_error(
                            origin,
                            "loads.gap",
                            format!("g = {value} is not finite at x = {x:?}, t = {t}"),
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// Checks f2 for finite values at the vertices of Γ2 (with the facet's outward normal) at
    /// `times`.
    pub(super) fn check_traction(
        &self,
        mesh: &Mesh<D>,
        times: &[f64],
        origin: &str,
    ) -> Result<(), InputError> {
        if let Some(traction) = &self.traction {
            for f in (0..mesh.num_facets()).filter(|&f| mesh.facet_part(f) == BoundaryPart::Neumann)
            {
                let normal = mesh.facet_normal(f);
                for &vertex in mesh.facet(f) {
                    let x = mesh.vertex(vertex);
                    for &t in times {
                        let mut extra = [t, 0.0, 0.0, 0.0];
                        extra[1..1 + D].copy_from_slice(&normal);
                        let value = eval_vector(traction, &point_values(&x, &extra));
                        if value.iter().any(|v| !v.is_finite()) {
                            return Err(problem_error(
                                origin,
                                "loads.traction",
                                format!("f2 = {value:?} is not finite at x = {x:?}, t = {t}"),
                            ));
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// The solver's data: the loads compiled once (they run at every quadrature point of every
    /// step), their non-finite values recorded by `load_watch`, with the prescribed
    /// displacements `dirichlet`.
    pub(super) fn into_data(
        self,
        dirichlet: Vec<PrescribedDisplacement<D>>,
        load_watch: &LoadWatch,
    ) -> Data<D> {
        let Self {
            body_force,
            traction,
            initial_displacement,
            gap,
            curve,
            initial_damage,
        } = self;
        let body_force = body_force.map(|force| {
            Arc::new(BatchLoad::new(
                &force,
                "loads.body_force",
                "f0",
                load_watch,
                None,
            )) as contact_damage::scheme::VectorField<D>
        });
        let symbol = if curve.is_some() {
            "f2 × traction_curve(t)"
        } else {
            "f2"
        };
        let traction = traction.map(|traction| {
            Arc::new(BatchLoad::new(
                &traction,
                "loads.traction",
                symbol,
                load_watch,
                curve,
            )) as contact_damage::scheme::BoundaryVectorField<D>
        });
        let gap = CompiledField::new(&[gap]);
        let gap_watch = load_watch.clone();
        Data {
            body_force,
            body_stress: None,
            traction,
            contact_traction: None,
            damage_supply: None,
            damage_flux: None,
            gap: Arc::new(move |x, t| {
                let value = gap.eval(x, &[t]);
                gap_watch.check("loads.gap", "g", value, x, t)[0]
            }),
            dirichlet,
            initial_displacement: Arc::new(move |x| {
                eval_vector(&initial_displacement, &point_values(x, &[]))
            }),
            initial_damage: Arc::new(move |x| initial_damage.eval_f64(&point_values(x, &[]))),
            jump_planes: Vec::new(),
        }
    }
}

/// The `[[displacement]]` parts as the solver's prescribed displacements on their facets: each
/// component parsed in x, y, z, t and checked finite at the part's vertices at `times`; a
/// non-finite value at another time is recorded by `load_watch` under its key.
pub(super) fn prescribed_displacements<const D: usize>(
    file: &ProblemFile,
    origin: &str,
    constants: &BTreeMap<String, f64>,
    mesh: &Mesh<D>,
    part_facets: Vec<Vec<usize>>,
    times: &[f64],
    load_watch: &LoadWatch,
) -> Result<Vec<PrescribedDisplacement<D>>, InputError> {
    let mut parts = Vec::new();
    for (i, (part, facets)) in file.displacement.iter().zip(part_facets).enumerate() {
        let mut components: [Option<PointScalarField<D>>; D] = std::array::from_fn(|_| None);
        let given = [("x", &part.x), ("y", &part.y), ("z", &part.z)];
        if given.iter().all(|(_, e)| e.is_none()) {
            return Err(problem_error(
                origin,
                &format!("displacement[{i}]"),
                "give at least one component (x, y, z) of the prescribed displacement",
            ));
        }
        for (name, source) in given {
            let Some(source) = source else { continue };
            let key = format!("displacement[{i}].{name}");
            let Some(c) = component_index::<D>(name) else {
                return Err(problem_error(
                    origin,
                    &key,
                    format!("a {D}D problem has no component `{name}`"),
                ));
            };
            let expr = parse_expr(
                FileKind::Problem,
                origin,
                &key,
                source,
                &FIELD_VARIABLES,
                constants,
            )?;
            for &f in &facets {
                for &vertex in mesh.facet(f) {
                    let x = mesh.vertex(vertex);
                    for &t in times {
                        let value = expr.eval_f64(&point_values(&x, &[t]));
                        if !value.is_finite() {
                            return Err(problem_error(
                                origin,
                                &key,
                                format!("u_D = {value} is not finite at x = {x:?}, t = {t}"),
                            ));
                        }
                    }
                }
            }
            let compiled = CompiledField::new(&[expr]);
            let watch = load_watch.clone();
            components[c] = Some(Arc::new(move |x: &[f64; D], t: f64| {
                let value = compiled.eval(x, &[t]);
                watch.check(&key, "u_D", value, x, t)[0]
            }) as PointScalarField<D>);
        }
        parts.push(PrescribedDisplacement {
            name: part.part.clone(),
            facets,
            components,
            traction: None,
        });
    }
    Ok(parts)
}
