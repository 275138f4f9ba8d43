//! The built-in manufactured cases satisfy their strong form (docs/model.md §1, §5) at random
//! points, and bad case files get errors that name the file, the key and the problem.
//!
//! Div σ and Δβ are recomputed here by central differences of σ and ∇β (independent of the
//! chain rule used to derive f0 and q), so those checks hold to the differencing accuracy
//! (≈1e-7 relative); the contact, friction and damage-inclusion conditions are algebraic and
//! hold to round-off.

use contact_damage::fem::mesh::{BoundaryPart::Contact, Mesh};
use nalgebra::SVector;
use verify::case::{parse_case_file, Case};
use verify::cli::BUILT_IN_CASES;
use verify::domain::Domain;
use verify::manufactured::{jet, tangential_part, value, value_gradient, SLIP_ROUNDOFF};

/// Sample points: proptest's ChaCha generator with a fixed seed.
struct Rng(proptest::test_runner::TestRng);
impl Rng {
    fn new(seed: u8) -> Self {
        Self(proptest::test_runner::TestRng::from_seed(
            proptest::test_runner::RngAlgorithm::ChaCha,
            &[seed; 32],
        ))
    }
    fn uniform(&mut self) -> f64 {
        use proptest::prelude::RngExt;
        self.0.random::<f64>()
    }
}

/// Case files of `verification/` that are not built in (used by examples).
const OTHER_CASES: [(&str, &str); 1] = [("layer2d", include_str!("../verification/layer2d.toml"))];

fn load<const D: usize>(name: &str) -> Case<D> {
    let (_, text) = BUILT_IN_CASES
        .iter()
        .chain(&OTHER_CASES)
        .find(|(n, _)| *n == name)
        .unwrap();
    let origin = format!("built-in:{name}");
    Case::new(parse_case_file(text, &origin).unwrap(), &origin).unwrap()
}

/// A random point of Ω: of the unit box (away from its sides) for a box case, of a random cell
/// of `mesh` (by random barycentric coordinates) for a mesh case.
fn interior_point<const D: usize>(case: &Case<D>, mesh: &Mesh<D>, rng: &mut Rng) -> [f64; D] {
    match case.domain {
        Domain::Box { .. } => std::array::from_fn(|_| 0.05 + 0.9 * rng.uniform()),
        Domain::Mesh { .. } => {
            let cell = mesh.cell((rng.uniform() * mesh.num_cells() as f64) as usize);
            barycentric_point(mesh, cell, rng)
        }
    }
}

/// A random point of Γ3 with the outward unit normal there: of the box side x_a = 0 that is
/// Γ3, or of a random Γ3 facet of `mesh`.
fn contact_point<const D: usize>(
    case: &Case<D>,
    mesh: &Mesh<D>,
    rng: &mut Rng,
) -> ([f64; D], [f64; D]) {
    match &case.domain {
        Domain::Box { sides, .. } => {
            let axis = (0..D).find(|&a| sides[a][0] == Contact).unwrap();
            let mut normal = [0.0; D];
            normal[axis] = -1.0;
            let mut x: [f64; D] = std::array::from_fn(|_| 0.02 + 0.96 * rng.uniform());
            x[axis] = 0.0;
            (x, normal)
        }
        Domain::Mesh { .. } => {
            let facets: Vec<usize> = (0..mesh.num_facets())
                .filter(|&f| mesh.facet_part(f) == Contact)
                .collect();
            let f = facets[(rng.uniform() * facets.len() as f64) as usize];
            (
                barycentric_point(mesh, mesh.facet(f), rng),
                mesh.facet_normal(f),
            )
        }
    }
}

fn barycentric_point<const D: usize>(mesh: &Mesh<D>, corners: &[usize], rng: &mut Rng) -> [f64; D] {
    let weights: Vec<f64> = corners.iter().map(|_| 0.05 + rng.uniform()).collect();
    let total: f64 = weights.iter().sum();
    std::array::from_fn(|i| {
        corners
            .iter()
            .zip(&weights)
            .map(|(&v, w)| mesh.vertex(v)[i] * w / total)
            .sum()
    })
}

#[derive(Default, Debug)]
struct Zones {
    separation: usize,
    stick: usize,
    slip: usize,
    bound_active: usize,
    /// Contact points where the friction bound vanishes, p_τ = 0 < p_ν ((1 − δ p_ν)₊ = 0, (2.12)).
    frictionless: usize,
}

fn check_strong_form<const D: usize>(name: &str) -> Zones {
    let case = load::<D>(name);
    let laws = &case.laws;
    let exact = &case.exact;
    let mut rng = Rng::new(42);
    let final_time = case.file.final_time;
    let mut zones = Zones::default();
    let fine = case.mesh(1).unwrap();
    for _ in 0..200 {
        let x = interior_point(&case, &fine, &mut rng);
        let t = final_time * rng.uniform();
        // (2.3): Div σ + f0 = 0, Div σ by central differences of σ
        let h = 1e-5;
        let mut divergence = SVector::<f64, D>::zeros();
        for j in 0..D {
            let (mut plus, mut minus) = (x, x);
            plus[j] += h;
            minus[j] -= h;
            let sigma_plus = exact.stress(laws, &exact.point_state(&plus, t));
            let sigma_minus = exact.stress(laws, &exact.point_state(&minus, t));
            for i in 0..D {
                divergence[i] += (sigma_plus[(i, j)] - sigma_minus[(i, j)]) / (2.0 * h);
            }
        }
        let f0 = exact.body_force(laws, &x, t);
        for i in 0..D {
            assert!(
                (divergence[i] + f0[i]).abs() < 1e-6 * (1.0 + f0[i].abs()),
                "{name}: Div σ + f0 = {} at {x:?}",
                divergence[i] + f0[i]
            );
        }
        // (2.2) with q: β̇ − κΔβ + η = φ + q, Δβ by central differences of ∇β
        let mut laplacian = 0.0;
        for j in 0..D {
            let (mut plus, mut minus) = (x, x);
            plus[j] += h;
            minus[j] -= h;
            laplacian += (value_gradient(&exact.damage, &plus, t).1[j]
                - value_gradient(&exact.damage, &minus, t).1[j])
                / (2.0 * h);
        }
        let beta = jet(&exact.damage, &x, t);
        let state = exact.point_state(&x, t);
        let strain = (state.displacement_gradient + state.displacement_gradient.transpose()) * 0.5;
        let eta = value(&exact.damage_multiplier, &x, t);
        let residual = beta.rate - laws.damage_diffusion * laplacian + eta
            - laws.damage_source.source(&strain, beta.value)
            - exact.damage_supply(laws, &x, t);
        assert!(
            residual.abs() < 1e-6,
            "{name}: damage equation residual {residual:e} at {x:?}"
        );
        // η ∈ ∂ψ_K(β)
        if beta.value >= 1.0 {
            assert!(eta >= 0.0);
            zones.bound_active += 1;
        } else if beta.value <= 0.0 {
            assert!(eta <= 0.0);
        } else {
            assert_eq!(eta, 0.0, "{name}: η ≠ 0 where 0 < β < 1");
        }
    }
    // (2.7)–(2.8) with f3 on Γ3: r = σν − f3 satisfies r_ν = −p_ν and −r_τ ∈ p_τ ∂|·|(u̇_τ)
    for _ in 0..400 {
        let (x, normal) = contact_point(&case, &fine, &mut rng);
        let nu = SVector::<f64, D>::from_column_slice(&normal);
        let t = final_time * rng.uniform();
        let state = exact.point_state(&x, t);
        let sigma_n = exact.stress(laws, &state) * nu;
        let f3 =
            SVector::<f64, D>::from_column_slice(&exact.contact_traction(laws, &x, t, &normal));
        let r = sigma_n - f3;
        let penetration = exact.penetration(&state, &x, t, &nu);
        let (p_normal, p_friction) = (
            laws.contact.normal_pressure(penetration),
            laws.contact.friction_bound(penetration),
        );
        let scale = 1.0 + sigma_n.norm();
        assert!(
            (r.dot(&nu) + p_normal).abs() < 1e-12 * scale,
            "{name}: r_ν = {} ≠ −p_ν = {} at {x:?}, ν = {normal:?}",
            r.dot(&nu),
            -p_normal
        );
        let r_tangential = r - nu * r.dot(&nu);
        let slip = tangential_part(&state.velocity, &nu);
        if penetration > 0.0 && p_friction == 0.0 {
            zones.frictionless += 1;
        }
        if penetration <= 0.0 {
            zones.separation += 1;
            assert!(r_tangential.norm() < 1e-12 * scale);
        } else if slip.norm() > SLIP_ROUNDOFF * state.velocity.norm() {
            zones.slip += 1;
            assert!(
                (-r_tangential - slip / slip.norm() * p_friction).norm() < 1e-12 * scale,
                "{name}: slip law"
            );
        } else {
            zones.stick += 1;
            assert!(
                r_tangential.norm() < p_friction,
                "{name}: stick needs |σ_τ| < p_τ strictly"
            );
        }
    }
    zones
}

#[test]
fn slip2d_satisfies_its_strong_form() {
    let zones = check_strong_form::<2>("slip2d");
    assert!(
        zones.slip > 0 && zones.stick == 0 && zones.bound_active == 0,
        "{zones:?}"
    );
}

#[test]
fn zones2d_satisfies_its_strong_form_with_all_zones() {
    let zones = check_strong_form::<2>("zones2d");
    assert!(
        zones.separation > 0 && zones.stick > 0 && zones.slip > 0 && zones.bound_active > 0,
        "{zones:?}"
    );
}

#[test]
fn layer2d_satisfies_its_strong_form_with_all_zones() {
    let zones = check_strong_form::<2>("layer2d");
    assert!(
        zones.separation > 0 && zones.stick > 0 && zones.slip > 0 && zones.bound_active > 0,
        "{zones:?}"
    );
}

#[test]
fn slip3d_satisfies_its_strong_form() {
    let zones = check_strong_form::<3>("slip3d");
    assert!(zones.slip > 0 && zones.stick == 0, "{zones:?}");
}

#[test]
fn zones3d_satisfies_its_strong_form_with_all_zones() {
    let zones = check_strong_form::<3>("zones3d");
    assert!(
        zones.separation > 0 && zones.stick > 0 && zones.slip > 0 && zones.bound_active > 0,
        "{zones:?}"
    );
}

/// The cases of the whole model (nonlinear viscosity, wear-modified bound) satisfy their strong
/// form with all three contact zones and the active damage bound; the wear cases also have a
/// contact zone where the friction bound (1 − δ p_ν)₊ vanishes.
#[test]
fn loads2d_satisfies_its_strong_form_with_all_zones_a_free_roller_component_and_a_negative_gap() {
    let zones = check_strong_form::<2>("loads2d");
    assert_all_zones(&zones);
    let case = load::<2>("loads2d");
    let exact = &case.exact;
    // u_D = u on the prescribed parts: nonzero on y = 1; on the roller x = 0, u_x = 0 is
    // prescribed and the free u_y is not zero
    let top = [0.3, 1.0];
    assert!(value(&exact.displacement[0], &top, 1.0).abs() > 1e-3);
    assert!(value(&exact.displacement[1], &top, 1.0).abs() > 1e-3);
    let roller = [0.0, 0.7];
    assert_eq!(value(&exact.displacement[0], &roller, 0.5), 0.0);
    assert!(value(&exact.displacement[1], &roller, 0.5).abs() > 1e-3);
    // the gap moves and is negative on part of Γ3 (y = 0) while the body is in contact there
    let contact = [0.9, 0.0];
    assert!(value(&exact.gap, &contact, 0.0) > 0.0);
    assert!(value(&exact.gap, &contact, 1.0) < 0.0);
    let problem = case.problem(4, 1, 4).unwrap();
    assert_eq!(problem.data.dirichlet.len(), 2);
    let names: Vec<&str> = problem
        .data
        .dirichlet
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    assert_eq!(names, ["y_max", "x_min"]);
    assert!(
        problem.data.dirichlet[1].components[1].is_none(),
        "the roller leaves u_y free"
    );
}

/// The 3D analogue of loads2d: all three components prescribed on z = 1, a roller on x = 0
/// fixing u_x (tangential to Γ3 where the two meet) and leaving u_y, u_z free, the moving gap.
#[test]
fn loads3d_satisfies_its_strong_form_with_all_zones_free_roller_components_and_a_negative_gap() {
    let zones = check_strong_form::<3>("loads3d");
    assert_all_zones(&zones);
    let case = load::<3>("loads3d");
    let exact = &case.exact;
    // u_D = u on z = 1 is nonzero in every component; on the roller x = 0, u_x = 0 is
    // prescribed and the free u_y, u_z are not zero
    let top = [0.8, 0.3, 1.0];
    for component in &exact.displacement {
        assert!(value(component, &top, 1.0).abs() > 1e-3);
    }
    let roller = [0.0, 0.4, 0.7];
    assert_eq!(value(&exact.displacement[0], &roller, 0.5), 0.0);
    assert!(value(&exact.displacement[1], &roller, 0.5).abs() > 1e-3);
    assert!(value(&exact.displacement[2], &roller, 0.5).abs() > 1e-3);
    // the gap moves and is negative on part of Γ3 (z = 0) while the body is in contact there
    let contact = [0.9, 0.5, 0.0];
    assert!(value(&exact.gap, &contact, 0.0) > 0.0);
    assert!(value(&exact.gap, &contact, 1.0) < 0.0);
    let problem = case.problem(3, 1, 4).unwrap();
    let names: Vec<&str> = problem
        .data
        .dirichlet
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    assert_eq!(names, ["z_max", "x_min"]);
    let roller = &problem.data.dirichlet[1].components;
    assert!(
        roller[0].is_some() && roller[1].is_none() && roller[2].is_none(),
        "the roller fixes u_x only"
    );
}

fn assert_all_zones(zones: &Zones) {
    assert!(
        zones.separation > 0 && zones.stick > 0 && zones.slip > 0 && zones.bound_active > 0,
        "{zones:?}"
    );
}

#[test]
fn cases_of_the_whole_model_satisfy_their_strong_form_with_all_zones() {
    for name in ["mild2d", "strong2d", "carreau2d", "implicit2d"] {
        let zones = check_strong_form::<2>(name);
        assert_all_zones(&zones);
        assert_eq!(zones.frictionless, 0, "{name}: {zones:?}");
    }
    for name in ["mild3d", "strong3d"] {
        let zones = check_strong_form::<3>(name);
        assert_all_zones(&zones);
        assert_eq!(zones.frictionless, 0, "{name}: {zones:?}");
    }
}

#[test]
fn wear_cases_satisfy_their_strong_form_with_a_frictionless_contact_zone() {
    let zones = check_strong_form::<2>("wear2d");
    assert_all_zones(&zones);
    assert!(zones.frictionless > 0, "wear2d: {zones:?}");
    let zones = check_strong_form::<3>("wear3d");
    assert_all_zones(&zones);
    assert!(zones.frictionless > 0, "wear3d: {zones:?}");
}

fn error_of(replace: &str, with: &str) -> String {
    let text = include_str!("../verification/zones2d.toml");
    assert!(
        text.contains(replace),
        "test setup: `{replace}` not in the case file"
    );
    let text = text.replacen(replace, with, 1);
    match parse_case_file(&text, "my_case.toml")
        .and_then(|file| Case::<2>::new(file, "my_case.toml"))
    {
        Ok(_) => panic!("the case with `{with}` should be rejected"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn case_reader_reports_syntax_errors_with_position() {
    let message = error_of("final_time = 1.0", "final_time = = 1.0");
    assert!(
        message.contains("my_case.toml") && message.contains("line 16, column 14"),
        "{message}"
    );
}

#[test]
fn case_reader_rejects_unknown_variable() {
    let message = error_of("\"0.01\"", "\"0.01*w\"");
    assert!(
        message.contains("exact.gap") && message.contains("unknown variable `w`"),
        "{message}"
    );
}

#[test]
fn case_reader_rejects_nonzero_displacement_on_clamped_side() {
    let message = error_of(
        "\"-(0.1 + 0.1*t)*x^2*(1-y)\"",
        "\"-(0.1 + 0.1*t)*(x+0.1)^2*(1-y)\"",
    );
    assert!(
        message.contains("exact.u[1]") && message.contains("Γ1"),
        "{message}"
    );
}

#[test]
fn case_reader_rejects_damage_outside_unit_interval() {
    let message = error_of("beta = \"1 - t*(0.3", "beta = \"1.2 - t*(0.3");
    assert!(
        message.contains("exact.beta") && message.contains("outside [0, 1]"),
        "{message}"
    );
}

#[test]
fn case_reader_rejects_stick_traction_beyond_the_friction_bound() {
    let message = error_of(
        "stick_traction = [\"0.5\", \"0\"]",
        "stick_traction = [\"1.01\", \"0\"]",
    );
    assert!(
        message.contains("exact.stick_traction") && message.contains("> 1"),
        "{message}"
    );
}

#[test]
fn case_reader_rejects_multiplier_outside_subdifferential() {
    let message = error_of(
        "damage_multiplier = \"0.2*max(0, x_bound - x)\"",
        "damage_multiplier = \"0.1\"",
    );
    assert!(message.contains("exact.damage_multiplier"), "{message}");
}

#[test]
fn case_reader_rejects_invalid_law_parameter() {
    let message = error_of("stiffness = 10.0", "stiffness = -10.0");
    assert!(message.contains("contact.stiffness"), "{message}");
}

#[test]
fn case_reader_rejects_an_unknown_contact_treatment_naming_the_line() {
    let message = error_of("[laws]", "[scheme]\ncontact = \"sometimes\"\n\n[laws]");
    assert!(
        message.contains("my_case.toml")
            && message.contains("line 28")
            && message.contains("sometimes")
            && message.contains("implicit"),
        "{message}"
    );
}

#[test]
fn case_reader_rejects_studies_whose_rates_would_be_undefined_naming_the_key() {
    // identical mesh levels: h does not change
    let message = error_of(
        "h = { cells = [4, 8, 16, 32]",
        "h = { cells = [4, 4, 16, 32]",
    );
    assert!(message.contains("studies.order1.h.cells"), "{message}");
    // a k-study with a repeated step count
    let message = error_of(
        "k = { cells = 16, steps = [2, 4, 8, 16]",
        "k = { cells = 16, steps = [2, 4, 4, 16]",
    );
    assert!(message.contains("studies.order1.k.steps"), "{message}");
    // a reference that does not contain the times of the levels
    let message = error_of("reference_steps = 128 }", "reference_steps = 100 }");
    assert!(
        message.contains("studies.order1.k.reference_steps"),
        "{message}"
    );
    // lists of different lengths
    let message = error_of(
        "diagonal = { cells = [4, 8, 16, 32], steps = [2, 4, 8, 16] }",
        "diagonal = { cells = [4, 8, 16, 32], steps = [2, 4, 8] }",
    );
    assert!(message.contains("studies.order1.diagonal"), "{message}");
}

#[test]
fn case_reader_rejects_a_prescribed_displacement_on_the_contact_side_or_a_bad_component() {
    for (with, key, expected) in [
        (
            "[[displacement]]\npart = \"y_min\"\ncomponents = [\"y\"]\n\n[constants]",
            "displacement[0].part",
            "Γ3",
        ),
        (
            "[[displacement]]\npart = \"x_max\"\ncomponents = [\"y\"]\n\n[constants]",
            "displacement[0].part",
            "traction",
        ),
        (
            "[[displacement]]\npart = \"x_min\"\ncomponents = [\"w\"]\n\n[constants]",
            "displacement[0].components[0]",
            "`w`",
        ),
        (
            "[[displacement]]\npart = \"x_left\"\ncomponents = [\"x\"]\n\n[constants]",
            "displacement[0].part",
            "unknown side",
        ),
    ] {
        let message = error_of("[constants]", with);
        assert!(
            message.contains("my_case.toml") && message.contains(key) && message.contains(expected),
            "{message}"
        );
    }
}

#[test]
fn case_reader_rejects_a_gap_that_is_not_finite() {
    let message = error_of("gap = \"0.01\"", "gap = \"0.01 + log(x - 0.5)\"");
    assert!(
        message.contains("exact.gap") && message.contains("not finite"),
        "{message}"
    );
}

// Cases on Gmsh meshes: the rotated zones cases on their committed meshes, and the curved
// cases on their second-order meshes.

#[test]
fn curved_cases_satisfy_their_strong_form_with_separation_and_slip_on_the_curved_boundary() {
    for zones in [
        check_strong_form::<2>("curved2d"),
        check_strong_form::<3>("curved3d"),
    ] {
        assert!(
            zones.separation > 0 && zones.slip > 0 && zones.bound_active == 0,
            "{zones:?}"
        );
    }
    // their meshes carry curved edges, kept by refinement
    let case = load::<2>("curved2d");
    assert!(case.mesh(0).unwrap().has_curved_edges());
    let case = load::<3>("curved3d");
    assert!(case.mesh(1).unwrap().has_curved_edges());
}

#[test]
fn tilted_cases_satisfy_their_strong_form_with_all_zones_on_the_tilted_contact_boundary() {
    let zones = check_strong_form::<2>("tilted2d");
    assert_all_zones(&zones);
    let zones = check_strong_form::<3>("tilted3d");
    assert_all_zones(&zones);
    // the contact boundary is not axis-aligned: its normal has two nonzero components
    let case = load::<3>("tilted3d");
    let mesh = case.mesh(0).unwrap();
    let f = (0..mesh.num_facets())
        .find(|&f| mesh.facet_part(f) == Contact)
        .unwrap();
    let normal = mesh.facet_normal(f);
    assert!(
        normal.iter().filter(|n| n.abs() > 0.1).count() >= 2,
        "{normal:?}"
    );
}

const TILTED2D: &str = include_str!("../verification/tilted2d.toml");
const TILTED2D_MESH: &[u8] = include_bytes!("../verification/meshes/tilted2d.msh");

/// tilted2d with `replace` replaced by `with`, written into a fresh folder with its mesh at
/// `meshes/tilted2d.msh` (unless `mesh` is None), and read from there.
fn tilted_case_on_disk(
    replace: &str,
    with: &str,
    mesh: Option<&[u8]>,
) -> (tempfile::TempDir, Result<Case<2>, verify::InputError>) {
    assert!(TILTED2D.contains(replace), "test setup: `{replace}`");
    let folder = tempfile::tempdir().unwrap();
    if let Some(bytes) = mesh {
        std::fs::create_dir(folder.path().join("meshes")).unwrap();
        std::fs::write(folder.path().join("meshes/tilted2d.msh"), bytes).unwrap();
    }
    let path = folder.path().join("my_case.toml");
    std::fs::write(&path, TILTED2D.replacen(replace, with, 1)).unwrap();
    let case = verify::case::read_case_file(&path)
        .and_then(|file| Case::<2>::new(file, &path.display().to_string()));
    (folder, case)
}

fn tilted_error(replace: &str, with: &str, mesh: Option<&[u8]>) -> String {
    match tilted_case_on_disk(replace, with, mesh).1 {
        Ok(_) => panic!("the case with `{with}` should be rejected"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_case_file_reads_its_mesh_relative_to_its_folder_and_refines_it() {
    let (_folder, case) = tilted_case_on_disk("name", "name", Some(TILTED2D_MESH));
    let case = case.unwrap();
    let (coarse, fine) = (case.mesh(0).unwrap(), case.mesh(2).unwrap());
    assert_eq!(fine.num_cells(), 16 * coarse.num_cells());
    assert!((fine.max_cell_diameter() - 0.25 * coarse.max_cell_diameter()).abs() < 1e-14);
}

#[test]
fn bad_domain_mesh_input_gets_an_error_naming_the_file_and_the_key() {
    // no such file
    let message = tilted_error("name", "name", None);
    assert!(
        message.contains("my_case.toml")
            && message.contains("key `domain.mesh`")
            && message.contains("meshes/tilted2d.msh"),
        "{message}"
    );
    // not a Gmsh file
    let message = tilted_error(
        "name",
        "name",
        Some(b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"),
    );
    assert!(
        message.contains("key `domain.mesh`")
            && message.contains("tilted2d.msh:2")
            && message.contains("4.1"),
        "{message}"
    );
    // a group the file lacks
    let message = tilted_error(
        "contact = [\"contact\"]",
        "contact = [\"foundation\"]",
        Some(TILTED2D_MESH),
    );
    assert!(
        message.contains("key `domain.contact`") && message.contains("\"foundation\""),
        "{message}"
    );
    // the contact group left out: its facets are untagged boundary facets
    let message = tilted_error("contact = [\"contact\"]", "", Some(TILTED2D_MESH));
    assert!(
        message.contains("key `domain.mesh`") && message.contains("no boundary part"),
        "{message}"
    );
    // a box and a mesh at once
    let message = tilted_error(
        "[domain]",
        "[domain]\nlower = [0.0, 0.0]",
        Some(TILTED2D_MESH),
    );
    assert!(
        message.contains("key `domain.lower`") && message.contains("not both"),
        "{message}"
    );
    // box levels on a mesh, and too many refinements
    let message = tilted_error(
        "h = { refinements = [0, 1, 2, 3, 4]",
        "h = { cells = [4, 8, 16, 32, 64]",
        Some(TILTED2D_MESH),
    );
    assert!(
        message.contains("key `studies.order1.h.cells`") && message.contains("refinements"),
        "{message}"
    );
    let message = tilted_error(
        "h = { refinements = [0, 1, 2, 3, 4]",
        "h = { refinements = [0, 1, 2, 3, 30]",
        Some(TILTED2D_MESH),
    );
    assert!(
        message.contains("key `studies.order1.h.refinements`")
            && message.contains("30 refinements"),
        "{message}"
    );
    let message = tilted_error("k = { refinements = 2,", "k = {", Some(TILTED2D_MESH));
    assert!(
        message.contains("key `studies.order1.k.refinements`"),
        "{message}"
    );
}

#[test]
fn mesh_keys_on_a_box_case_are_rejected_naming_the_key() {
    let message = error_of("[domain]", "[domain]\ncontact = [\"bottom\"]");
    assert!(
        message.contains("key `domain.contact`") && message.contains("domain.mesh"),
        "{message}"
    );
    let message = error_of(
        "h = { cells = [4, 8, 16, 32]",
        "h = { refinements = [0, 1, 2, 3]",
    );
    assert!(
        message.contains("key `studies.order1.h.refinements`"),
        "{message}"
    );
}
