//! The example `plate_with_hole_2d` on its committed Gmsh mesh: the physical groups land on
//! the sides they name and the hole is a circle of the right radius with the outward normal of
//! the body pointing into it; the first two load periods of the example converge, the contact
//! zone closes under the load and opens again without it, and damage starts on the hole.

use crate::common;

use common::{checked_run, expected_contact_nodes, facets_of, history_value, scratch};
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::scheme::Simulation;
use simulate::problem::ProblemSetup;
use simulate::run::read_saved_state;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// The plate Ω = (0, 2) × (0, 1) minus the disc of radius 0.2 centred at (1.0, 0.5).
const LENGTH: f64 = 2.0;
const HEIGHT: f64 = 1.0;
const HOLE_CENTRE: [f64; 2] = [1.0, 0.5];
const HOLE_RADIUS: f64 = 0.2;
/// Gmsh places boundary nodes on the geometry to round-off.
const ON_GEOMETRY: f64 = 1e-9;
/// Mesh size on the hole (plate_with_hole_2d.py); a chord of length h stays within
/// h²/(8 r) ≈ 4e-4 of its circle.
const HOLE_MESH_SIZE: f64 = 0.025;

fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/plate_with_hole_2d.toml")
}

fn distance_to_centre(x: &[f64; 2]) -> f64 {
    (x[0] - HOLE_CENTRE[0]).hypot(x[1] - HOLE_CENTRE[1])
}

fn facet_midpoint(mesh: &Mesh<2>, facet: usize) -> [f64; 2] {
    let [a, b] = [
        mesh.vertex(mesh.facet(facet)[0]),
        mesh.vertex(mesh.facet(facet)[1]),
    ];
    [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])]
}

fn total_length(mesh: &Mesh<2>, facets: &[usize]) -> f64 {
    facets.iter().map(|&f| mesh.facet_measure(f)).sum()
}

#[test]
fn example_mesh_has_the_hole_and_the_groups_on_their_sides() {
    let setup = ProblemSetup::<2>::from_path(&example()).unwrap();
    let mesh = &setup.problem.mesh;
    // a few thousand triangles
    assert!(
        (1000..=5000).contains(&mesh.num_cells()),
        "{} cells",
        mesh.num_cells()
    );
    // the area is that of the plate less the disc, up to the polygonal hole: inscribed in the
    // circle with chords of length at most h, it misses 2πr/h circular segments of area
    // h³/(12 r) each, π h²/6 in all
    let area: f64 = (0..mesh.num_cells()).map(|c| mesh.cell_volume(c)).sum();
    let exact = LENGTH * HEIGHT - PI * HOLE_RADIUS * HOLE_RADIUS;
    assert!(
        area > exact && area - exact <= PI * HOLE_MESH_SIZE * HOLE_MESH_SIZE / 6.0,
        "area {area}, plate less disc {exact}"
    );

    // Γ1 is the left side, Γ3 the bottom, each whole
    let clamped = facets_of(mesh, BoundaryPart::Dirichlet);
    let contact = facets_of(mesh, BoundaryPart::Contact);
    for &f in &clamped {
        for &v in mesh.facet(f) {
            assert!(
                mesh.vertex(v)[0].abs() <= ON_GEOMETRY,
                "Γ1 vertex {:?}",
                mesh.vertex(v)
            );
        }
    }
    for &f in &contact {
        for &v in mesh.facet(f) {
            assert!(
                mesh.vertex(v)[1].abs() <= ON_GEOMETRY,
                "Γ3 vertex {:?}",
                mesh.vertex(v)
            );
        }
        assert!(
            mesh.facet_normal(f)[1] < -1.0 + 1e-12,
            "Γ3 normal points down"
        );
    }
    assert!((total_length(mesh, &clamped) - HEIGHT).abs() < 1e-12);
    assert!((total_length(mesh, &contact) - LENGTH).abs() < 1e-12);

    // Γ2 is the top, the right side and the hole; the hole's facets are chords of the circle
    // and the outward normal of the body points into the disc
    let mut hole = Vec::new();
    for f in facets_of(mesh, BoundaryPart::Neumann) {
        let midpoint = facet_midpoint(mesh, f);
        let ends = mesh.facet(f).iter().map(|&v| mesh.vertex(v));
        if midpoint[1] >= HEIGHT - ON_GEOMETRY {
            assert!(ends.clone().all(|x| (x[1] - HEIGHT).abs() <= ON_GEOMETRY));
        } else if midpoint[0] >= LENGTH - ON_GEOMETRY {
            assert!(ends.clone().all(|x| (x[0] - LENGTH).abs() <= ON_GEOMETRY));
        } else {
            for x in ends {
                let radius = distance_to_centre(&x);
                assert!(
                    (radius - HOLE_RADIUS).abs() <= ON_GEOMETRY,
                    "Γ2 vertex {x:?} is on no side of the plate nor on the circle (r = {radius})"
                );
            }
            let sag = HOLE_RADIUS - distance_to_centre(&midpoint);
            assert!(
                sag > 0.0 && sag <= HOLE_MESH_SIZE * HOLE_MESH_SIZE / (8.0 * HOLE_RADIUS) + 1e-9,
                "facet {f} at {midpoint:?}: sag {sag}"
            );
            let normal = mesh.facet_normal(f);
            let inward = [HOLE_CENTRE[0] - midpoint[0], HOLE_CENTRE[1] - midpoint[1]];
            let cosine =
                (normal[0] * inward[0] + normal[1] * inward[1]) / distance_to_centre(&midpoint);
            assert!(cosine > 0.99, "facet {f}: normal {normal:?}");
            hole.push(f);
        }
    }
    // about 2πr/h facets, each shorter than its arc by h³/(24 r²): π h²/(12 r) in all
    assert!(hole.len() >= 50, "{} facets on the hole", hole.len());
    let perimeter = total_length(mesh, &hole);
    let circumference = 2.0 * PI * HOLE_RADIUS;
    assert!(
        perimeter < circumference
            && circumference - perimeter
                <= PI * HOLE_MESH_SIZE * HOLE_MESH_SIZE / (12.0 * HOLE_RADIUS),
        "hole perimeter {perimeter}"
    );
}

#[test]
fn first_two_load_periods_converge_close_and_open_contact_and_damage_the_hole() {
    let setup = ProblemSetup::<2>::from_path(&example()).unwrap();
    // k = 0.02 and the load period is 1: peaks at steps 25 and 75, no load at 50 and 100
    assert_eq!(setup.problem.steps, 250);
    assert!((setup.problem.final_time - 5.0).abs() < 1e-15);
    let mesh = setup.problem.mesh.clone();

    // the contact nodes are the vertices of Γ3 less the clamped corner
    let expected_contact_nodes = expected_contact_nodes(&mesh);
    let contact_nodes = Simulation::new(setup.problem.clone())
        .unwrap()
        .contact()
        .len();
    assert_eq!(contact_nodes, expected_contact_nodes);

    let out = scratch("gmsh-example-run");
    let history = checked_run(&setup, &out, 100);
    let count = |step, name| history_value(&history, step, name) as usize;
    for step in 1..=100 {
        assert_eq!(
            count(step, "stick") + count(step, "slip") + count(step, "separated"),
            contact_nodes,
            "step {step}"
        );
    }
    // the gap keeps the body off the foundation until the load grows
    assert_eq!(count(1, "separated"), contact_nodes);
    // at peak load the whole of Γ3 is pressed, with stick and slip zones side by side
    for peak in [25, 75] {
        assert_eq!(count(peak, "separated"), 0, "step {peak}");
        assert!(
            count(peak, "stick") > 0 && count(peak, "slip") > 0,
            "step {peak}"
        );
        assert!(history_value(&history, peak, "normal_force") > 0.5);
    }
    // without load, part of Γ3 lifts off again and nothing sticks
    for unloaded in [50, 100] {
        assert!(
            count(unloaded, "separated") >= contact_nodes / 4,
            "step {unloaded}: {} separated",
            count(unloaded, "separated")
        );
        assert_eq!(count(unloaded, "stick"), 0, "step {unloaded}");
    }

    // damage: P1, so the nodal values are at the mesh vertices; the least β is on the hole,
    // far below the values away from the hole and the clamp
    let saved = read_saved_state(&out).unwrap();
    assert_eq!(saved.step, 100);
    let damage = saved.damage;
    assert_eq!(damage.len(), mesh.num_vertices());
    assert!(damage.iter().all(|beta| (0.0..=1.0).contains(beta)));
    let (weakest, least) = damage
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(vertex, &beta)| (mesh.vertex(vertex), beta))
        .unwrap();
    assert!(
        (distance_to_centre(&weakest) - HOLE_RADIUS).abs() <= ON_GEOMETRY,
        "least damage value {least} at {weakest:?}, not on the hole"
    );
    assert!(least < 0.9, "least damage value {least}");
    let away = |x: &[f64; 2]| (x[0] > 1.6 && x[1] > 0.6) || (x[0] < 0.5 && x[1] < 0.4);
    for (vertex, beta) in damage.iter().enumerate() {
        let x = mesh.vertex(vertex);
        if away(&x) {
            assert!(*beta > 0.95, "β = {beta} at {x:?}");
        }
    }
}

/// `mesh.gmsh.refinements = 1` refines the example's mesh uniformly (what `--convergence`
/// does per level): four times the triangles, the same area and the same length of every group.
#[test]
fn refined_example_mesh_keeps_its_groups() {
    let coarse = ProblemSetup::<2>::from_path(&example()).unwrap();
    let dir = scratch("gmsh-refined");
    let text = std::fs::read_to_string(example()).unwrap();
    let refined_text = text.replace(
        "contact = [\"bottom\"] }",
        "contact = [\"bottom\"], refinements = 1 }",
    );
    assert_ne!(text, refined_text);
    std::fs::copy(
        example().with_file_name("plate_with_hole_2d.msh"),
        dir.join("plate_with_hole_2d.msh"),
    )
    .unwrap();
    let path = dir.join("refined.toml");
    std::fs::write(&path, refined_text).unwrap();
    let fine = ProblemSetup::<2>::from_path(&path).unwrap();
    let (coarse, fine) = (&coarse.problem.mesh, &fine.problem.mesh);
    assert_eq!(fine.num_cells(), 4 * coarse.num_cells());
    let area = |mesh: &Mesh<2>| {
        (0..mesh.num_cells())
            .map(|c| mesh.cell_volume(c))
            .sum::<f64>()
    };
    assert!((area(fine) - area(coarse)).abs() < 1e-12 * area(coarse));
    for part in [
        BoundaryPart::Dirichlet,
        BoundaryPart::Neumann,
        BoundaryPart::Contact,
    ] {
        let length = |mesh: &Mesh<2>| total_length(mesh, &facets_of(mesh, part));
        assert!(
            (length(fine) - length(coarse)).abs() < 1e-12 * length(coarse),
            "{part:?}: {} vs {}",
            length(fine),
            length(coarse)
        );
    }
}
