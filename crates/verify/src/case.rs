//! Manufactured cases as data: the TOML case file, its validation, and its translation into the
//! solver's [`Problem`] with source terms derived by
//! [`crate::manufactured`].
//!
//! A bad case file gets an error naming the file, the key and the problem.

use crate::domain::{check_levels, read_mesh, sample_points, Domain};
use crate::expr::Expr;
use crate::manufactured::data::{
    BodyForce, BodyStress, ContactLoad, ContactTraction, DamageFlux, DamageSupply, ExactPrograms,
    ManufacturedData, Traction,
};
use crate::manufactured::{value, ExactSolution, Laws};
use crate::InputError;
use contact_damage::algebra::linalg::MAGNITUDE_LIMIT;
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::scheme::{
    BoundSetPrediction, Data, JumpPlane, PointScalarField, PrescribedDisplacement, Problem,
    SchemeSettings,
};
use contact_input::file::{parse_expr, parse_toml, positive};
use contact_input::sides::{prescribed_sides, PrescribedSide};
use contact_input::FileKind;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

pub use crate::domain::DomainFile;
pub use contact_input::laws::{
    ContactFile, DamageSourceFile, ElasticityFile, ExpressionDamageSource, ExpressionModuli,
    ExpressionPotential, LawsFile, ViscosityFile, MODULI_VARIABLES, POTENTIAL_VARIABLES,
    SOURCE_VARIABLES,
};
pub use contact_input::scheme::{ContactTreatmentFile, SchemeFile};
pub use contact_input::sides::parse_sides;
pub use contact_input::sides::GroupFile;

/// The variables of the exact-field expressions.
pub const FIELD_VARIABLES: [&str; 4] = ["x", "y", "z", "t"];

/// The case file, as written in TOML.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaseFile {
    /// Short name (used for the report folder).
    pub name: String,
    /// What the case exercises.
    #[serde(default)]
    pub description: String,
    /// Space dimension d ∈ {2, 3}.
    pub dim: usize,
    /// Final time T.
    pub final_time: f64,
    /// The box and its boundary parts, or a Gmsh mesh with its physical groups.
    pub domain: DomainFile,
    /// Named constants usable in every expression.
    #[serde(default)]
    pub constants: BTreeMap<String, f64>,
    /// Constitutive laws.
    pub laws: LawsFile,
    /// Exact fields and auxiliary fields.
    pub exact: ExactFile,
    /// Studies per polynomial degree: keys `order1`, `order2`.
    #[serde(default)]
    pub studies: BTreeMap<String, StudySet>,
    /// `[scheme]`: variants of the scheme (default: the paper's (5.1)–(5.5)).
    #[serde(default)]
    pub scheme: SchemeFile,
    /// `[[displacement]]`: sides of Γ1 whose listed components are prescribed, u_D = u (the
    /// exact field); the other components of the side are free with the exact traction σν.
    #[serde(default)]
    pub displacement: Vec<CaseDisplacementFile>,
    /// How the manufactured loads enter (5.1): `"divergence"` (default) or `"stress"`
    /// ([`LoadForm`]).
    #[serde(default)]
    pub loads: LoadForm,
    /// `[regularity]`: the exponents of limited-smoothness profiles that `verify --regularity`
    /// may sweep ([`crate::regularity`]).
    #[serde(default)]
    pub regularity: Option<RegularityFile>,
}

/// How the manufactured data enter the load of (5.1), ⟨f, w⟩ (docs/model.md §5). Both forms are
/// the same functional for the exact σ; they differ in what the quadrature integrates.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LoadForm {
    /// ∫_Ω f0·w + ∫_Γ2 f2·w + ∫_Γ3 f3·w with f0 = −Div σ, f2 = σν, f3 = σν + p_ν ν + p_τ ξ̂: the
    /// data of the model's own form. The quadrature integrates second derivatives of u.
    #[default]
    Divergence,
    /// ∫_Ω σ : ε(w) + ∫_Γ3 (p_ν ν + p_τ ξ̂)·w (Green's formula; w = 0 on the fixed components of
    /// Γ1): the quadrature integrates first derivatives of u only. For fields of limited
    /// smoothness (a profile d₊^p across a front inside elements, [`crate::regularity`]),
    /// f0 ∝ d^{p−2} is integrated with an error of order h^{p−1}, which would hide the rate
    /// of the scheme; σ ∝ d^{p−1} is integrated with an error of the order of the
    /// interpolation error h^{p−1/2}.
    Stress,
}

/// `[regularity]` of a case file: the constants that are exponents p of profiles `(d)₊^p` of
/// the displacement across a front (`pospow(x - x_front, p)`: d is the distance to a plane
/// that crosses the body), so that `verify --regularity p=…` knows what a value of p implies
/// (the rules of [`crate::regularity::Profile`]).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegularityFile {
    /// Names of constants of `[constants]`.
    pub exponents: Vec<String>,
}

/// One `[[displacement]]` of a case file: a box side of Γ1 with prescribed components.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaseDisplacementFile {
    /// The side (`x_min`, …); it must be `clamped` or unlisted in `domain.sides`.
    pub part: String,
    /// The prescribed components (`"x"`, `"y"`, `"z"`); the others are free.
    pub components: Vec<String>,
}

/// `[exact]`: the manufactured fields.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExactFile {
    /// u components.
    pub u: Vec<String>,
    /// β.
    pub beta: String,
    /// ξ components (stick traction field, |ξ_τ| ≤ 1); default 0.
    #[serde(default)]
    pub stick_traction: Option<Vec<String>>,
    /// η (damage bound multiplier); default 0.
    #[serde(default)]
    pub damage_multiplier: Option<String>,
    /// g(x); default 0.
    #[serde(default)]
    pub gap: Option<String>,
    /// Planes across which the data jump (each an affine function of x whose zero set is the
    /// plane): the solver integrates the boundary facets they cross piecewise; default none.
    #[serde(default)]
    pub jump_planes: Vec<String>,
}

/// Studies for one polynomial degree.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudySet {
    /// h-study: the time error is kept negligible by the step counts given per level.
    pub h: Option<LevelStudy>,
    /// k-study on one mesh against a reference run with a much finer step.
    pub k: Option<TimeStudy>,
    /// Diagonal study k ∝ h^r.
    pub diagonal: Option<LevelStudy>,
}

/// A study over mesh levels, each with its number of time steps. A box domain gives its
/// levels by `cells`, a mesh domain by `refinements` (exactly one of them, checked by
/// [`Case::new`]).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LevelStudy {
    /// Cells per side of each level (box domains).
    #[serde(default)]
    pub cells: Vec<usize>,
    /// Uniform refinements of the mesh of each level (mesh domains).
    #[serde(default)]
    pub refinements: Vec<usize>,
    /// Time steps N of each level.
    pub steps: Vec<usize>,
}

/// A study over time steps on one mesh.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeStudy {
    /// Cells per side (box domains).
    #[serde(default)]
    pub cells: usize,
    /// Uniform refinements of the mesh (mesh domains).
    #[serde(default)]
    pub refinements: Option<usize>,
    /// Time steps N of each level.
    pub steps: Vec<usize>,
    /// Steps of the reference run (a common multiple of `steps`).
    pub reference_steps: usize,
}

impl LevelStudy {
    /// The level parameter of each run: `refinements` if given, else `cells`.
    pub fn levels(&self) -> &[usize] {
        if self.refinements.is_empty() {
            &self.cells
        } else {
            &self.refinements
        }
    }
}

impl TimeStudy {
    /// The level parameter of the runs: `refinements` if given, else `cells`.
    pub fn level(&self) -> usize {
        self.refinements.unwrap_or(self.cells)
    }
}

/// A validated case in dimension D.
#[derive(Clone)]
pub struct Case<const D: usize> {
    /// The file as read.
    pub file: CaseFile,
    /// Where it came from (a path or `built-in:NAME`).
    pub origin: String,
    /// The box or the Gmsh mesh.
    pub domain: Domain<D>,
    /// Laws (shared with the solver).
    pub laws: Laws<D>,
    /// Exact fields.
    pub exact: ExactSolution<D>,
    /// The exact fields and their derivatives compiled once ([`ExactPrograms`]).
    pub programs: Arc<ExactPrograms<D>>,
    /// Sides of Γ1 with prescribed components u_D = u.
    pub prescribed: Vec<PrescribedSide<D>>,
    /// The planes of `exact.jump_planes`.
    pub jump_planes: Vec<JumpPlane<D>>,
}

/// Checks the study definitions before anything runs: keys `order1`/`order2`; level studies with
/// `cells` (a box domain) or `refinements` (a mesh domain), not the other, and `steps` of one
/// length ≥ 2, the levels strictly increasing (else h does not change and the rates are
/// undefined; cells ≥ 1, refinements ≥ 0) and steps ≥ 1, nondecreasing; k-studies with
/// `cells` ≥ 1 or `refinements` as the domain needs, ≥ 2 step counts ≥ 1, strictly increasing,
/// and a reference that is a multiple of each and finer than all.
fn check_study_definitions(
    origin: &str,
    studies: &BTreeMap<String, StudySet>,
    mesh_domain: bool,
) -> Result<(), InputError> {
    let (wanted, other) = if mesh_domain {
        ("refinements", "cells")
    } else {
        ("cells", "refinements")
    };
    let needs = |key: &str| {
        if mesh_domain {
            format!("a mesh domain (`domain.mesh`) gives its levels by `refinements`, not `cells`; {key}")
        } else {
            format!("a box domain gives its levels by `cells`; `refinements` is for a Gmsh mesh (`domain.mesh`); {key}")
        }
    };
    for (order, set) in studies {
        if order != "order1" && order != "order2" {
            return Err(case_error(
                origin,
                &format!("studies.{order}"),
                "unknown study set (use order1 or order2)",
            ));
        }
        for (name, study) in [("h", &set.h), ("diagonal", &set.diagonal)] {
            let Some(study) = study else { continue };
            let key = format!("studies.{order}.{name}");
            let (levels, unwanted) = if mesh_domain {
                (&study.refinements, &study.cells)
            } else {
                (&study.cells, &study.refinements)
            };
            if !unwanted.is_empty() {
                return Err(case_error(
                    origin,
                    &format!("{key}.{other}"),
                    needs(&format!("give `{wanted}`")),
                ));
            }
            if levels.len() != study.steps.len() || levels.len() < 2 {
                return Err(case_error(
                    origin,
                    &key,
                    format!(
                        "`{wanted}` and `steps` need the same length ≥ 2, got {} and {}",
                        levels.len(),
                        study.steps.len()
                    ),
                ));
            }
            let smallest = usize::from(!mesh_domain);
            if levels.iter().any(|&l| l < smallest) || levels.windows(2).any(|w| w[0] >= w[1]) {
                return Err(case_error(
                    origin,
                    &format!("{key}.{wanted}"),
                    format!(
                        "must be ≥ {smallest} and increase strictly (each level a finer mesh), got {levels:?}"
                    ),
                ));
            }
            if study.steps.contains(&0) || study.steps.windows(2).any(|w| w[0] > w[1]) {
                return Err(case_error(
                    origin,
                    &format!("{key}.steps"),
                    format!("must be ≥ 1 and never decrease, got {:?}", study.steps),
                ));
            }
        }
        if let Some(study) = &set.k {
            let key = format!("studies.{order}.k");
            if mesh_domain {
                if study.cells != 0 {
                    return Err(case_error(
                        origin,
                        &format!("{key}.cells"),
                        needs("give `refinements`"),
                    ));
                }
                if study.refinements.is_none() {
                    return Err(case_error(
                        origin,
                        &format!("{key}.refinements"),
                        "missing (the refinements of the mesh of every run)",
                    ));
                }
            } else {
                if study.refinements.is_some() {
                    return Err(case_error(
                        origin,
                        &format!("{key}.refinements"),
                        needs("give `cells`"),
                    ));
                }
                if study.cells == 0 {
                    return Err(case_error(origin, &format!("{key}.cells"), "must be ≥ 1"));
                }
            }
            if study.steps.len() < 2
                || study.steps.contains(&0)
                || study.steps.windows(2).any(|w| w[0] >= w[1])
            {
                return Err(case_error(
                    origin,
                    &format!("{key}.steps"),
                    format!(
                        "need ≥ 2 step counts ≥ 1, increasing strictly, got {:?}",
                        study.steps
                    ),
                ));
            }
            let finest = study.steps.iter().copied().max().unwrap_or(0);
            if study.reference_steps <= finest
                || study.steps.iter().any(|&s| study.reference_steps % s != 0)
            {
                return Err(case_error(
                    origin,
                    &format!("{key}.reference_steps"),
                    format!(
                        "must exceed every step count and be a multiple of each (the reference is compared at their times), got {} for {:?}",
                        study.reference_steps, study.steps
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// The domain of the case and the sides with prescribed components (box domains only).
fn build_domain<const D: usize>(
    file: &CaseFile,
    origin: &str,
) -> Result<(Domain<D>, Vec<PrescribedSide<D>>), InputError> {
    let domain = &file.domain;
    if domain.is_mesh() {
        for (key, given) in [
            ("domain.lower", !domain.lower.is_empty()),
            ("domain.upper", !domain.upper.is_empty()),
            ("domain.sides", !domain.sides.is_empty()),
        ] {
            if given {
                return Err(case_error(
                    origin,
                    key,
                    "a domain is a box (`lower`, `upper`, `sides`) or a Gmsh mesh (`mesh` with `clamped`, `traction`, `contact`), not both",
                ));
            }
        }
        if !file.displacement.is_empty() {
            return Err(case_error(
                origin,
                "displacement",
                "prescribed components are given on box sides; a mesh domain (`domain.mesh`) has clamped groups only",
            ));
        }
        let domain = read_mesh::<D>(domain, origin)?;
        if let Domain::Mesh { mesh, .. } = &domain {
            for (order, set) in &file.studies {
                for (name, study) in [("h", &set.h), ("diagonal", &set.diagonal)] {
                    if let Some(study) = study {
                        let key = format!("studies.{order}.{name}.refinements");
                        check_levels(mesh, &study.refinements, origin, &key)?;
                    }
                }
                if let Some(study) = &set.k {
                    let key = format!("studies.{order}.k.refinements");
                    check_levels(mesh, &[study.level()], origin, &key)?;
                }
            }
        }
        return Ok((domain, Vec::new()));
    }
    for (key, given) in [
        ("domain.clamped", !domain.clamped.is_empty()),
        ("domain.traction", !domain.traction.is_empty()),
        ("domain.contact", !domain.contact.is_empty()),
    ] {
        if given {
            return Err(case_error(
                origin,
                key,
                "physical groups belong to a Gmsh mesh: give `domain.mesh` (or use `sides` for a box)",
            ));
        }
    }
    if domain.lower.len() != D || domain.upper.len() != D {
        return Err(case_error(
            origin,
            "domain.lower/upper",
            format!("need {D} coordinates each (or a Gmsh mesh: `domain.mesh`)"),
        ));
    }
    for axis in 0..D {
        let (low, high) = (domain.lower[axis], domain.upper[axis]);
        if !(low.is_finite() && high.is_finite() && low < high) {
            return Err(case_error(
                origin,
                "domain.lower/upper",
                format!(
                    "need finite coordinates with lower < upper, got lower = {:?}, upper = {:?}",
                    domain.lower, domain.upper
                ),
            ));
        }
    }
    let mut sides = parse_sides::<D>(FileKind::Case, origin, "domain.sides", &domain.sides)?;
    let parts: Vec<(String, Vec<String>)> = file
        .displacement
        .iter()
        .map(|d| (d.part.clone(), d.components.clone()))
        .collect();
    let prescribed = prescribed_sides::<D>(
        FileKind::Case,
        origin,
        "displacement",
        &parts,
        &domain.sides,
        &mut sides,
    )?;
    if !sides
        .iter()
        .flatten()
        .any(|&part| part == BoundaryPart::Dirichlet)
    {
        return Err(case_error(
            origin,
            "domain.sides",
            "no side is `clamped` and no `[[displacement]]` prescribes one: the velocity step (5.1) needs meas(Γ1) > 0 (Korn's inequality), else the body can move rigidly",
        ));
    }
    Ok((
        Domain::Box {
            lower: std::array::from_fn(|i| domain.lower[i]),
            upper: std::array::from_fn(|i| domain.upper[i]),
            sides,
        },
        prescribed,
    ))
}

fn case_error(origin: &str, key: &str, message: impl Into<String>) -> InputError {
    FileKind::Case.error(origin, key, message)
}

/// Reads and parses a case file (TOML syntax errors carry line and column).
pub fn read_case_file(path: &Path) -> Result<CaseFile, InputError> {
    contact_input::regular::check_regular_file(path, "case file")?;
    let text =
        std::fs::read_to_string(path).map_err(|e| InputError::io("reading case file", path, e))?;
    parse_case_file(&text, &path.display().to_string())
}

/// Parses case-file text; `origin` names it in errors.
pub fn parse_case_file(text: &str, origin: &str) -> Result<CaseFile, InputError> {
    parse_toml(text, FileKind::Case, origin)
}

impl<const D: usize> Case<D> {
    /// Validates the case file and builds the laws and exact fields. Checks, at sampled points,
    /// that u = 0 on Γ1, β ∈ [0, 1], |ξ_τ| ≤ 1 on Γ3, η ∈ ∂ψ_K(β) and that g is finite on Γ3
    /// (a gap may move and be negative).
    pub fn new(file: CaseFile, origin: &str) -> Result<Self, InputError> {
        if file.dim != D {
            return Err(case_error(
                origin,
                "dim",
                format!("expected {D}, got {}", file.dim),
            ));
        }
        positive(FileKind::Case, origin, "final_time", file.final_time)?;
        check_study_definitions(origin, &file.studies, file.domain.is_mesh())?;
        if let Some(regularity) = &file.regularity {
            crate::exponents::check_exponents(origin, &regularity.exponents, &file.constants)?;
        }
        let (domain, prescribed) = build_domain::<D>(&file, origin)?;
        let constants = &file.constants;
        if !file.scheme.damage {
            return Err(case_error(
                origin,
                "scheme.damage",
                "a manufactured case verifies the damage model (5.2): `damage = false` is for simulate problem files",
            ));
        }
        let laws = file.laws.build::<D>(
            FileKind::Case,
            origin,
            constants,
            file.scheme.damage_evolution(),
        )?;

        let exact_file = &file.exact;
        if exact_file.u.len() != D {
            return Err(case_error(
                origin,
                "exact.u",
                format!("need {D} components, got {}", exact_file.u.len()),
            ));
        }
        let vector = |key: &str, sources: &[String]| -> Result<[Expr; D], InputError> {
            let parsed: Vec<Expr> = sources
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    parse_expr(
                        FileKind::Case,
                        origin,
                        &format!("{key}[{i}]"),
                        s,
                        &FIELD_VARIABLES,
                        constants,
                    )
                })
                .collect::<Result<_, _>>()?;
            parsed
                .try_into()
                .map_err(|_| case_error(origin, key, format!("need {D} components")))
        };
        let zero = || vec!["0".to_string(); D];
        let exact = ExactSolution {
            displacement: vector("exact.u", &exact_file.u)?,
            damage: parse_expr(
                FileKind::Case,
                origin,
                "exact.beta",
                &exact_file.beta,
                &FIELD_VARIABLES,
                constants,
            )?,
            stick_traction: vector(
                "exact.stick_traction",
                exact_file.stick_traction.as_ref().unwrap_or(&zero()),
            )?,
            damage_multiplier: parse_expr(
                FileKind::Case,
                origin,
                "exact.damage_multiplier",
                exact_file.damage_multiplier.as_deref().unwrap_or("0"),
                &FIELD_VARIABLES,
                constants,
            )?,
            gap: parse_expr(
                FileKind::Case,
                origin,
                "exact.gap",
                exact_file.gap.as_deref().unwrap_or("0"),
                &FIELD_VARIABLES,
                constants,
            )?,
        };
        let jump_planes = crate::jump_planes::jump_planes(
            origin,
            &exact_file.jump_planes,
            constants,
            file.final_time,
        )?;
        let case = Self {
            origin: origin.to_string(),
            domain,
            prescribed,
            jump_planes,
            laws,
            programs: Arc::new(ExactPrograms::new(&exact)),
            exact,
            file,
        };
        case.check_samples()?;
        case.check_smooth()?;
        Ok(case)
    }

    /// The manufactured u and β are smooth on the domain (no pole between sample points, see
    /// [`crate::smoothness`]: on the edges of a lattice of a box, or of the mesh refined once)
    /// and u does not vanish identically (the displacement and velocity errors would then
    /// measure round-off, and their rates would be 0/0).
    fn check_smooth(&self) -> Result<(), InputError> {
        let times = [0.0, 0.5 * self.file.final_time, self.file.final_time];
        let (segments, points) = match &self.domain {
            Domain::Box { lower, upper, .. } => {
                let per_axis: usize = if D == 2 { 25 } else { 11 };
                let segments = crate::smoothness::lattice_segments(*lower, *upper, per_axis);
                let points: Vec<[f64; D]> = (0..7usize.pow(D as u32))
                    .map(|index| {
                        std::array::from_fn(|i| {
                            let step = index / 7usize.pow(i as u32) % 7;
                            lower[i] + (upper[i] - lower[i]) * (step as f64 + 0.5) / 7.0
                        })
                    })
                    .collect();
                (segments, points)
            }
            Domain::Mesh { mesh, .. } => {
                let fine = contact_damage::fem::mesh::refine_times(mesh, 1)?;
                let mut segments = Vec::new();
                for c in 0..fine.num_cells() {
                    let cell = fine.cell(c);
                    for (i, &a) in cell.iter().enumerate() {
                        for &b in &cell[i + 1..] {
                            if a < b {
                                segments.push((fine.vertex(a), fine.vertex(b)));
                            }
                        }
                    }
                }
                (segments, fine.vertices().to_vec())
            }
        };
        let fields = self
            .exact
            .displacement
            .iter()
            .enumerate()
            .map(|(i, u)| (format!("exact.u[{i}]"), u))
            .chain(std::iter::once((
                "exact.beta".to_string(),
                &self.exact.damage,
            )));
        for (key, field) in fields {
            crate::smoothness::check_resolved(field, &segments, &times)
                .map_err(|message| case_error(&self.origin, &key, message))?;
        }
        let vanishes = points.iter().all(|x| {
            times.iter().all(|&t| {
                self.exact
                    .displacement
                    .iter()
                    .all(|u| value(u, x, t) == 0.0)
            })
        });
        if vanishes {
            return Err(case_error(
                &self.origin,
                "exact.u",
                "the manufactured displacement vanishes at every sample point: the displacement and velocity errors would measure round-off only and their rates would be undefined; choose a nonzero u",
            ));
        }
        Ok(())
    }

    /// Checks the fields at sample points (a lattice of the box including its boundary, or the
    /// vertices of the mesh refined once and points of every boundary facet) at several times.
    fn check_samples(&self) -> Result<(), InputError> {
        match &self.domain {
            Domain::Box {
                lower,
                upper,
                sides,
            } => {
                let per_axis: usize = if D == 2 { 25 } else { 11 };
                let total = per_axis.pow(D as u32);
                for index in 0..total {
                    let mut rest = index;
                    let lattice: [usize; D] = std::array::from_fn(|_| {
                        let i = rest % per_axis;
                        rest /= per_axis;
                        i
                    });
                    let x: [f64; D] = std::array::from_fn(|i| {
                        lower[i] + (upper[i] - lower[i]) * lattice[i] as f64 / (per_axis - 1) as f64
                    });
                    // which sides is x on?
                    let mut parts = Vec::new();
                    for axis in 0..D {
                        for (side, coordinate) in [lower[axis], upper[axis]].into_iter().enumerate()
                        {
                            if (x[axis] - coordinate).abs() < 1e-14 {
                                // a prescribed side takes u_D = u: nothing to check there
                                let free = self
                                    .prescribed
                                    .iter()
                                    .any(|p| (p.axis, p.end) == (axis, side));
                                let mut n = [0.0; D];
                                n[axis] = if side == 0 { -1.0 } else { 1.0 };
                                let part = if free {
                                    BoundaryPart::Neumann
                                } else {
                                    sides[axis][side]
                                };
                                parts.push((part, n));
                            }
                        }
                    }
                    self.check_point(&x, &parts)?;
                }
            }
            Domain::Mesh { mesh, .. } => {
                let samples = sample_points(mesh)?;
                for x in &samples.interior {
                    self.check_point(x, &[])?;
                }
                for (x, part, normal) in &samples.boundary {
                    self.check_point(x, &[(*part, *normal)])?;
                }
            }
        }
        Ok(())
    }

    /// The checks of [`Case::check_samples`] at one point x, on the boundary parts (with their
    /// outward normals) that x lies on.
    fn check_point(
        &self,
        x: &[f64; D],
        parts: &[(BoundaryPart, [f64; D])],
    ) -> Result<(), InputError> {
        let origin = &self.origin;
        let x = *x;
        let times: Vec<f64> = (0..=4)
            .map(|i| self.file.final_time * i as f64 / 4.0)
            .collect();
        for &t in &times {
            let at = || format!("at x = {x:?}, t = {}", contact_input::number::short(t));
            let beta = value(&self.exact.damage, &x, t);
            if !(-1e-14..=1.0 + 1e-14).contains(&beta) || !beta.is_finite() {
                return Err(case_error(
                    origin,
                    "exact.beta",
                    format!("β = {beta} is outside [0, 1] {}", at()),
                ));
            }
            let eta = value(&self.exact.damage_multiplier, &x, t);
            let eta_ok = if beta >= 1.0 - 1e-14 {
                eta >= 0.0
            } else if beta <= 1e-14 {
                eta <= 0.0
            } else {
                eta.abs() <= 1e-12
            };
            if !eta_ok || !eta.is_finite() {
                return Err(case_error(
                    origin,
                    "exact.damage_multiplier",
                    format!("η = {eta} is not in ∂ψ_[0,1](β) for β = {beta} {}", at()),
                ));
            }
            for (part, normal) in parts {
                match part {
                    BoundaryPart::Dirichlet => {
                        for (i, component) in self.exact.displacement.iter().enumerate() {
                            let u = value(component, &x, t);
                            if u.abs() > 1e-12 {
                                return Err(case_error(
                                    origin,
                                    &format!("exact.u[{i}]"),
                                    format!("u = {u} ≠ 0 on Γ1 (clamped side) {}", at()),
                                ));
                            }
                        }
                    }
                    BoundaryPart::Contact => {
                        let gap = value(&self.exact.gap, &x, t);
                        if !gap.is_finite() {
                            return Err(case_error(
                                origin,
                                "exact.gap",
                                format!("g = {gap} is not finite on Γ3 {}", at()),
                            ));
                        }
                        if gap.abs() > MAGNITUDE_LIMIT {
                            return Err(case_error(
                                origin,
                                "exact.gap",
                                format!(
                                    "g = {gap:e} on Γ3 {} is beyond {MAGNITUDE_LIMIT:e} in magnitude, out of the scale of double precision (change the case's units)",
                                    at()
                                ),
                            ));
                        }
                        let xi: Vec<f64> = self
                            .exact
                            .stick_traction
                            .iter()
                            .map(|e| value(e, &x, t))
                            .collect();
                        let normal_part: f64 = xi.iter().zip(normal).map(|(a, b)| a * b).sum();
                        let tangential = (xi.iter().map(|v| v * v).sum::<f64>()
                            - normal_part * normal_part)
                            .max(0.0)
                            .sqrt();
                        // ξ ∈ ∂|·|(0), the closed unit ball: |ξ_τ| = 1 is the traction of a
                        // stick point at the friction bound (next to a stick–slip front)
                        if tangential > 1.0 + 1e-12 {
                            return Err(case_error(
                                origin,
                                "exact.stick_traction",
                                format!("|ξ_τ| = {tangential} > 1 on Γ3 {}", at()),
                            ));
                        }
                    }
                    BoundaryPart::Neumann => {}
                }
            }
        }
        Ok(())
    }

    /// The mesh of a study level: the box with `level` intervals per side, or the Gmsh mesh
    /// refined `level` times.
    pub fn mesh(&self, level: usize) -> Result<Mesh<D>, InputError> {
        Ok(self.domain.mesh(level)?)
    }

    /// The solver problem with the manufactured data (docs/model.md §5) for one run on the mesh of
    /// level `level` ([`Case::mesh`]).
    pub fn problem(
        &self,
        level: usize,
        degree: usize,
        steps: usize,
    ) -> Result<Problem<D>, InputError> {
        let laws = self.laws.clone();
        let exact = Arc::new(self.exact.clone());
        // A copy of the programs with empty caches: each run caches its own points.
        let programs = Arc::new(ExactPrograms::clone(&self.programs));
        let data = ManufacturedData::new(programs, laws.clone());
        // in stress form σ enters as ∫ σ : ε(w): no f0, and no traction σν on Γ2 or on the
        // free components of prescribed sides (Green's formula holds them)
        let divergence = self.file.loads == LoadForm::Divergence;
        let (eu, eb, eg) = (exact.clone(), exact.clone(), exact.clone());
        let mesh = self.mesh(level)?;
        let dirichlet = self
            .prescribed
            .iter()
            .map(|side| {
                let coordinate = match &self.domain {
                    Domain::Box { lower, upper, .. } => [lower, upper][side.end][side.axis],
                    // refused by `Case::new`: prescribed sides need a box
                    Domain::Mesh { .. } => f64::NAN,
                };
                let components = std::array::from_fn(|i| {
                    side.components[i].then(|| {
                        let e = exact.clone();
                        Arc::new(move |x: &[f64; D], t: f64| value(&e.displacement[i], x, t))
                            as PointScalarField<D>
                    })
                });
                let (et, lt) = (exact.clone(), laws.clone());
                PrescribedDisplacement {
                    name: format!(
                        "{}_{}",
                        ["x", "y", "z"][side.axis],
                        ["min", "max"][side.end]
                    ),
                    facets: mesh.boundary_facets_where(|x| x[side.axis] == coordinate),
                    components,
                    traction: divergence.then(|| {
                        Arc::new(move |x: &[f64; D], t: f64, n: &[f64; D]| {
                            et.traction(&lt, x, t, n)
                        }) as _
                    }),
                }
            })
            .collect();
        Ok(Problem {
            mesh: Arc::new(mesh),
            degree,
            model: laws.clone(),
            data: Data {
                body_force: divergence.then(|| Arc::new(BodyForce(data.clone())) as _),
                body_stress: (!divergence).then(|| Arc::new(BodyStress(data.clone())) as _),
                traction: divergence.then(|| Arc::new(Traction(data.clone())) as _),
                contact_traction: Some(if divergence {
                    Arc::new(ContactTraction(data.clone())) as _
                } else {
                    Arc::new(ContactLoad(data.clone())) as _
                }),
                damage_supply: Some(Arc::new(DamageSupply(data.clone()))),
                damage_flux: Some(Arc::new(DamageFlux(data))),
                gap: Arc::new(move |x, t| value(&eg.gap, x, t)),
                dirichlet,
                initial_displacement: Arc::new(move |x| {
                    std::array::from_fn(|i| value(&eu.displacement[i], x, 0.0))
                }),
                initial_damage: Arc::new(move |x| value(&eb.damage, x, 0.0)),
                jump_planes: self.jump_planes.clone(),
            },
            final_time: self.file.final_time,
            steps,
            settings: SchemeSettings {
                contact: self.file.scheme.contact_treatment(),
                damage_bound_sets: BoundSetPrediction::Followed,
                ..SchemeSettings::default()
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use contact_damage::model::laws::{
        LinearViscosity, PotentialViscosity, SaturatingViscosity, Tensor, Viscosity,
    };

    const SLIP2D: &str = include_str!("../../../verification/slip2d.toml");
    const SLIP3D: &str = include_str!("../../../verification/slip3d.toml");
    const LINEAR_VISCOSITY: &str = r#"viscosity = { kind = "linear", shear = 1.0, bulk = 0.5 }"#;
    const HOOKE: &str =
        r#"elasticity = { kind = "damaged_hooke", shear_modulus = 1.0, lame_lambda = 1.0 }"#;
    const SATURATING: &str = r#"viscosity = { kind = "saturating", shear = 1.0, bulk = 0.5, extra_shear = 0.5, rate_scale = 0.2 }"#;

    /// The saturating law (η, ζ, η₁, ε₀) = (1, 0.5, 0.5, 0.2) as a potential in dimension d:
    /// η|ε|² + ζ/2 tr² = η|ε_D|² + (η/d + ζ/2) tr², since |ε|² = |ε_D|² + tr²/d.
    fn saturating_potential(dim: usize) -> String {
        format!(
            "1.0*dev_norm^2 + (1.0/{dim} + 0.5/2)*tr_eps^2 + 0.5*0.04*(sqrt(1 + dev_norm^2/0.04) - 1)"
        )
    }

    fn potential_line(potential: &str) -> String {
        format!(r#"viscosity = {{ kind = "potential", potential = "{potential}" }}"#)
    }

    fn case<const D: usize>(
        text: &str,
        replacements: &[(&str, &str)],
    ) -> Result<Case<D>, InputError> {
        let mut text = text.to_string();
        for (from, to) in replacements {
            assert!(text.contains(from), "test setup: `{from}` not in the case");
            text = text.replacen(from, to, 1);
        }
        Case::new(parse_case_file(&text, "my_case.toml")?, "my_case.toml")
    }

    /// The error of the 2D case slip2d with the viscosity and elasticity lines replaced.
    fn rejection(viscosity: &str, elasticity: &str) -> String {
        match case::<2>(
            SLIP2D,
            &[(LINEAR_VISCOSITY, viscosity), (HOOKE, elasticity)],
        ) {
            Ok(_) => panic!("`{viscosity}`, `{elasticity}` was accepted"),
            Err(error) => {
                let message = error.to_string();
                assert!(message.contains("case `my_case.toml`"), "{message}");
                message
            }
        }
    }

    fn assert_close(what: &str, ours: &[f64], theirs: &[f64], tolerance: f64) {
        let difference: f64 = ours
            .iter()
            .zip(theirs)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        let size: f64 = theirs.iter().map(|b| b * b).sum::<f64>().sqrt();
        assert!(
            difference <= tolerance * size,
            "{what}: {ours:?} vs {theirs:?} (relative difference {:e})",
            difference / size
        );
    }

    fn same_source_terms<const D: usize>(text: &str, replacements: [(&str, &str); 2]) {
        let reference = case::<D>(text, &replacements[..1]).unwrap();
        let ours = case::<D>(text, &replacements[1..]).unwrap();
        let mut x = [0.0; D];
        for (k, t) in [0.1, 0.45, 0.9].into_iter().enumerate() {
            for (i, xi) in x.iter_mut().enumerate() {
                *xi = 0.15 + 0.3 * ((k + 2 * i) % 3) as f64;
            }
            let at = format!("D = {D}, x = {x:?}, t = {t}");
            assert_close(
                &format!("f0 {at}"),
                &ours.exact.body_force(&ours.laws, &x, t),
                &reference.exact.body_force(&reference.laws, &x, t),
                1e-10,
            );
            let mut normal = [0.0; D];
            normal[D - 1] = 1.0;
            assert_close(
                &format!("f2 {at}"),
                &ours.exact.traction(&ours.laws, &x, t, &normal),
                &reference.exact.traction(&reference.laws, &x, t, &normal),
                1e-10,
            );
        }
    }

    #[test]
    fn potential_law_reproducing_the_saturating_law_gives_the_same_source_terms() {
        for (dim, text) in [(2, SLIP2D), (3, SLIP3D)] {
            let potential = potential_line(&saturating_potential(dim));
            let replacements = [
                (LINEAR_VISCOSITY, SATURATING),
                (LINEAR_VISCOSITY, potential.as_str()),
            ];
            if dim == 2 {
                same_source_terms::<2>(text, replacements);
            } else {
                same_source_terms::<3>(text, replacements);
            }
        }
    }

    #[test]
    fn moduli_law_reproducing_damaged_hooke_gives_the_same_source_terms() {
        let moduli =
            r#"elasticity = { kind = "moduli", shear_modulus = "1.0*beta", lame_lambda = "beta" }"#;
        same_source_terms::<2>(SLIP2D, [(HOOKE, HOOKE), (HOOKE, moduli)]);
        same_source_terms::<3>(SLIP3D, [(HOOKE, HOOKE), (HOOKE, moduli)]);
    }

    fn expression_matches_saturating<const D: usize>() {
        let constants = BTreeMap::new();
        let ours = PotentialViscosity::new(Arc::new(ExpressionPotential::new(
            Expr::parse(&saturating_potential(D), &POTENTIAL_VARIABLES, &constants).unwrap(),
        )));
        let theirs = SaturatingViscosity {
            linear: LinearViscosity {
                shear: 1.0,
                bulk: 0.5,
            },
            extra_shear: 0.5,
            rate_scale: 0.2,
        };
        let generic =
            Tensor::<D>::from_fn(|i, j| 0.3 - 0.2 * (i + j) as f64 + 0.5 * (i * j) as f64);
        let dev = generic - Tensor::<D>::identity() * (generic.trace() / D as f64);
        let unit = dev / dev.norm();
        let identity = Tensor::<D>::identity();
        let mut rates = vec![
            Tensor::<D>::zeros(),
            identity * 0.4,
            generic,
            generic * 20.0,
        ];
        for n in [1e-3, 1e-9, 1e-12] {
            rates.push(unit * n);
            rates.push(identity * -0.3 + unit * n);
        }
        let direction =
            Tensor::<D>::from_fn(|i, j| 0.1 + 0.4 * (i + j) as f64 - 0.3 * (i * j) as f64);
        for rate in rates {
            let relative = |a: Tensor<D>, b: Tensor<D>| (a - b).norm() / b.norm().max(1e-300);
            let stress = relative(
                Viscosity::<D>::stress(&ours, &rate),
                Viscosity::<D>::stress(&theirs, &rate),
            );
            let tangent = relative(
                Viscosity::<D>::tangent(&ours, &rate, &direction),
                Viscosity::<D>::tangent(&theirs, &rate, &direction),
            );
            let (a, b) = (
                Viscosity::<D>::potential(&ours, &rate),
                Viscosity::<D>::potential(&theirs, &rate),
            );
            assert!(
                stress <= 1e-12 && tangent <= 1e-12 && (a - b).abs() <= 1e-12 * b.abs(),
                "D = {D}, ε = {rate}: relative differences stress {stress:e}, tangent {tangent:e}, potential {a} vs {b}"
            );
        }
        Viscosity::<D>::validate(&ours).unwrap();
    }

    #[test]
    fn expression_potential_matches_saturating_law_in_2d_and_3d_also_at_zero_deviator() {
        expression_matches_saturating::<2>();
        expression_matches_saturating::<3>();
    }

    #[test]
    fn potential_and_moduli_may_use_the_case_constants() {
        let case = case::<2>(
            SLIP2D,
            &[
                ("[domain]", "[constants]\neta = 1.0\nmu = 2.0\n\n[domain]"),
                (
                    LINEAR_VISCOSITY,
                    r#"viscosity = { kind = "potential", potential = "eta*dev_norm^2 + eta*tr_eps^2" }"#,
                ),
                (
                    HOOKE,
                    r#"elasticity = { kind = "moduli", shear_modulus = "mu*beta^2", lame_lambda = "0.5*beta" }"#,
                ),
            ],
        )
        .unwrap();
        let rate = Tensor::<2>::new(0.1, 0.2, 0.2, -0.3);
        // 2η ε_D + 2η tr ε I = 2 ε + tr ε I in 2D with η = 1
        let expected = rate * 2.0 + Tensor::<2>::identity() * rate.trace();
        assert!((case.laws.viscosity.stress(&rate) - expected).norm() < 1e-14);
        let strain = rate;
        let expected =
            strain * (2.0 * 2.0 * 0.25) + Tensor::<2>::identity() * (0.25 * strain.trace());
        assert!((case.laws.elasticity.stress(&strain, 0.5) - expected).norm() < 1e-14);
        let slope = strain * (2.0 * 2.0) + Tensor::<2>::identity() * (0.5 * strain.trace());
        assert!((case.laws.elasticity.damage_derivative(&strain, 0.5) - slope).norm() < 1e-14);
    }

    #[test]
    fn case_rejects_frozen_damage_and_missing_damage_laws_naming_the_key() {
        let frozen = case::<2>(
            SLIP2D,
            &[("[exact]", "[scheme]\ndamage = false\n\n[exact]")],
        );
        let message = frozen.err().expect("damage = false accepted").to_string();
        assert!(message.contains("key `scheme.damage`"), "{message}");
        let text: String = SLIP2D
            .lines()
            .filter(|line| !line.starts_with("damage_diffusion"))
            .map(|line| format!("{line}\n"))
            .collect();
        let message = case::<2>(&text, &[]).err().expect("accepted").to_string();
        assert!(message.contains("key `laws.damage_diffusion`"), "{message}");
    }

    #[test]
    fn case_rejects_concave_potential_naming_the_key() {
        let message = rejection(&potential_line("-dev_norm^2 + tr_eps^2"), HOOKE);
        assert!(
            message.contains("key `laws.viscosity.potential`")
                && message.contains("`-dev_norm^2 + tr_eps^2`")
                && message.contains("not convex"),
            "{message}"
        );
    }

    #[test]
    fn case_rejects_potential_not_strongly_convex_in_the_deviator_naming_the_key() {
        let message = rejection(&potential_line("tr_eps^2"), HOOKE);
        assert!(
            message.contains("key `laws.viscosity.potential`") && message.contains("(3.4)"),
            "{message}"
        );
    }

    #[test]
    fn case_rejects_potential_without_volumetric_stiffness_naming_the_key() {
        // exp(tr ε)·0 adds nothing (and overflows to inf·0 = NaN at large rates)
        let message = rejection(&potential_line("dev_norm^2 + exp(tr_eps)*0"), HOOKE);
        assert!(
            message.contains("key `laws.viscosity.potential`"),
            "{message}"
        );
        let message = rejection(&potential_line("dev_norm^2 + 0*tr_eps"), HOOKE);
        assert!(
            message.contains("key `laws.viscosity.potential`") && message.contains("(3.4)"),
            "{message}"
        );
    }

    #[test]
    fn case_rejects_potential_not_differentiable_at_zero_deviator_naming_the_key() {
        let message = rejection(&potential_line("dev_norm^2 + tr_eps^2 + dev_norm"), HOOKE);
        assert!(
            message.contains("key `laws.viscosity.potential`") && message.contains("Φ_n(t, 0)"),
            "{message}"
        );
    }

    #[test]
    fn case_rejects_potential_losing_convexity_at_large_rates_naming_the_key() {
        let message = rejection(
            &potential_line("dev_norm^2 + tr_eps^2 - 0.9*dev_norm^4"),
            HOOKE,
        );
        assert!(
            message.contains("key `laws.viscosity.potential`") && message.contains("not convex"),
            "{message}"
        );
    }

    #[test]
    fn case_rejects_potential_with_superlinear_gradient_naming_the_key() {
        let message = rejection(&potential_line("dev_norm^2 + tr_eps^2 + dev_norm^6"), HOOKE);
        assert!(
            message.contains("key `laws.viscosity.potential`")
                && message.contains("spread over more than 10⁸"),
            "{message}"
        );
    }

    #[test]
    fn case_rejects_unknown_variable_in_potential_naming_the_key() {
        let message = rejection(&potential_line("eps^2 + tr_eps^2"), HOOKE);
        assert!(
            message.contains("key `laws.viscosity.potential`")
                && message.contains("unknown variable `eps`"),
            "{message}"
        );
    }

    fn moduli_line(shear: &str, lambda: &str) -> String {
        format!(
            r#"elasticity = {{ kind = "moduli", shear_modulus = "{shear}", lame_lambda = "{lambda}" }}"#
        )
    }

    #[test]
    fn case_rejects_negative_shear_modulus_naming_the_key() {
        let message = rejection(LINEAR_VISCOSITY, &moduli_line("beta - 0.1", "beta"));
        assert!(
            message.contains("key `laws.elasticity.shear_modulus`")
                && message.contains("`beta - 0.1`")
                && message.contains("≥ 0"),
            "{message}"
        );
    }

    #[test]
    fn case_rejects_vanishing_undamaged_shear_modulus_naming_the_key() {
        let message = rejection(LINEAR_VISCOSITY, &moduli_line("beta*(1 - beta)", "beta"));
        assert!(
            message.contains("key `laws.elasticity.shear_modulus`") && message.contains("μ(1)"),
            "{message}"
        );
    }

    #[test]
    fn case_rejects_negative_bulk_modulus_naming_the_key() {
        // 2μ + 2λ = 2β − 3β² < 0 for β > 2/3
        let message = rejection(LINEAR_VISCOSITY, &moduli_line("beta", "-1.5*beta^2"));
        assert!(
            message.contains("key `laws.elasticity.lame_lambda`")
                && message.contains("`-1.5*beta^2`")
                && message.contains("2μ(β) + dλ(β)"),
            "{message}"
        );
    }

    #[test]
    fn case_rejects_non_finite_modulus_naming_the_key() {
        let message = rejection(LINEAR_VISCOSITY, &moduli_line("beta", "1/beta"));
        assert!(
            message.contains("key `laws.elasticity.lame_lambda`") && message.contains("not finite"),
            "{message}"
        );
    }

    #[test]
    fn case_rejects_unknown_variable_in_moduli_naming_the_key() {
        let message = rejection(LINEAR_VISCOSITY, &moduli_line("beta*t", "beta"));
        assert!(
            message.contains("key `laws.elasticity.shear_modulus`")
                && message.contains("unknown variable `t`"),
            "{message}"
        );
    }

    #[test]
    fn case_names_the_key_of_other_invalid_law_parameters() {
        let message = rejection(
            r#"viscosity = { kind = "linear", shear = -1.0, bulk = 0.5 }"#,
            HOOKE,
        );
        assert!(message.contains("key `laws.viscosity.shear`"), "{message}");
    }

    proptest::proptest! {
        #[test]
        fn expression_potential_tangent_is_symmetric_and_strongly_monotone(
            entries in proptest::collection::vec(-1.0f64..1.0, 12),
            log_scale in -6.0f64..3.0,
        ) {
            // Φ = |ε_D|² + 0.5 tr² + 0.3 (√(1 + |ε_D|² + tr²) − 1), coupled in (t, n):
            // tangent ≥ min(2, 2·0.5·3) = 2 in 3D
            let constants = BTreeMap::new();
            let law = PotentialViscosity::new(Arc::new(ExpressionPotential::new(
                Expr::parse(
                    "dev_norm^2 + 0.5*tr_eps^2 + 0.3*(sqrt(1 + dev_norm^2 + tr_eps^2) - 1)",
                    &POTENTIAL_VARIABLES,
                    &constants,
                )
                .unwrap(),
            )));
            let symmetric = |values: &[f64]| {
                let m = Tensor::<3>::from_column_slice(values);
                (m + m.transpose()) * 0.5
            };
            let rate = symmetric(&entries[..9]) * 10f64.powf(log_scale);
            let first = symmetric(&entries[3..12]);
            let second = symmetric(&entries[..9]);
            let a = first.dot(&Viscosity::<3>::tangent(&law, &rate, &second));
            let b = second.dot(&Viscosity::<3>::tangent(&law, &rate, &first));
            let size = first.norm() * second.norm();
            proptest::prop_assert!((a - b).abs() <= 1e-12 * size.max(1e-300), "{} vs {}", a, b);
            let quadratic = first.dot(&Viscosity::<3>::tangent(&law, &rate, &first));
            proptest::prop_assert!(quadratic >= 2.0 * first.norm_squared() * (1.0 - 1e-12));
        }
    }
}
