//! The example `bracket_3d` on its committed binary Gmsh mesh of tetrahedra: the physical
//! groups land on the faces they name, the bolt holes are cylinders of the right radius with
//! the outward normal of the body pointing to their axes, and the contact line recorded for
//! the pictures (y = 0.5 on Γ3) carries the nodes the generator put there; the first load
//! period up to its peak converges and presses the whole of Γ3 onto the foundation.

use crate::common;

use common::{checked_run, expected_contact_nodes, facets_of, history_value, scratch};
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::scheme::Simulation;
use simulate::contact_line::{ContactLine, LineCoordinate};
use simulate::history::HISTORY_FILE;
use simulate::pictures::CONTACT_HISTORY_FILE;
use simulate::problem::ProblemSetup;
use simulate::run::RunOptions;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// The bracket Ω = (0, 2) × (0, 1) × (0, 0.75) less two vertical cylinders (bracket_3d.py).
const LENGTH: f64 = 2.0;
const WIDTH: f64 = 1.0;
const HEIGHT: f64 = 0.75;
const HOLE_AXES: [[f64; 2]; 2] = [[1.2, 0.25], [1.2, 0.75]];
const HOLE_RADIUS: f64 = 0.12;
/// Mesh size requested on the holes (bracket_3d.py); Gmsh meets it only roughly, so the bounds
/// below allow chords 25% longer (the committed mesh misses as much area as chords of 0.083).
const HOLE_MESH_SIZE: f64 = 0.09;
/// The line y = 0.5 of Γ3 is split into this many equal intervals (bracket_3d.py).
const MIDLINE_INTERVALS: usize = 32;
/// Gmsh places boundary nodes on the geometry to round-off.
const ON_GEOMETRY: f64 = 1e-9;

fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/bracket_3d.toml")
}

/// Distance of x to the nearer hole axis, and that axis.
fn distance_to_axis(x: &[f64; 3]) -> (f64, [f64; 2]) {
    HOLE_AXES
        .iter()
        .map(|axis| ((x[0] - axis[0]).hypot(x[1] - axis[1]), *axis))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap()
}

fn facet_vertices(mesh: &Mesh<3>, facet: usize) -> Vec<[f64; 3]> {
    mesh.facet(facet).iter().map(|&v| mesh.vertex(v)).collect()
}

fn centroid(points: &[[f64; 3]]) -> [f64; 3] {
    let mut sum = [0.0; 3];
    for p in points {
        for i in 0..3 {
            sum[i] += p[i] / points.len() as f64;
        }
    }
    sum
}

fn total_area(mesh: &Mesh<3>, facets: &[usize]) -> f64 {
    facets.iter().map(|&f| mesh.facet_measure(f)).sum()
}

/// Cross-section a polygon inscribed in a circle of radius r with chords of length at most c
/// misses: 2πr/c circular segments of area at most c³/(12 r) each, π c²/6 in all.
fn inscribed_deficit(chord: f64) -> f64 {
    PI * chord * chord / 6.0
}

#[test]
fn example_mesh_has_the_holes_and_the_groups_on_their_faces() {
    let setup = ProblemSetup::<3>::from_path(&example()).unwrap();
    let mesh = &setup.problem.mesh;
    // at most about 4000 tetrahedra (3940 from gmsh 4.15.2)
    assert!(
        (3000..=4000).contains(&mesh.num_cells()),
        "{} cells",
        mesh.num_cells()
    );
    // the volume is that of the block less the cylinders, up to the polygonal holes
    let chord = 1.25 * HOLE_MESH_SIZE;
    let volume: f64 = (0..mesh.num_cells()).map(|c| mesh.cell_volume(c)).sum();
    let disc = PI * HOLE_RADIUS * HOLE_RADIUS;
    let exact = LENGTH * WIDTH * HEIGHT - 2.0 * disc * HEIGHT;
    assert!(
        volume > exact && volume - exact <= 2.0 * HEIGHT * inscribed_deficit(chord),
        "volume {volume}, block less cylinders {exact}"
    );

    // Γ1 is the face x = 0, whole
    let clamped = facets_of(mesh, BoundaryPart::Dirichlet);
    for &f in &clamped {
        for x in facet_vertices(mesh, f) {
            assert!(x[0].abs() <= ON_GEOMETRY, "Γ1 vertex {x:?}");
        }
        assert!(
            mesh.facet_normal(f)[0] < -1.0 + 1e-12,
            "Γ1 normal points to −x"
        );
    }
    assert!((total_area(mesh, &clamped) - WIDTH * HEIGHT).abs() < 1e-12);

    // Γ3 is the face z = 0 less the two polygonal discs of the holes
    let contact = facets_of(mesh, BoundaryPart::Contact);
    for &f in &contact {
        for x in facet_vertices(mesh, f) {
            assert!(x[2].abs() <= ON_GEOMETRY, "Γ3 vertex {x:?}");
            let (radius, _) = distance_to_axis(&x);
            assert!(
                radius >= HOLE_RADIUS - ON_GEOMETRY,
                "Γ3 vertex {x:?} in a hole"
            );
        }
        assert!(
            mesh.facet_normal(f)[2] < -1.0 + 1e-12,
            "Γ3 normal points down"
        );
    }
    let area = total_area(mesh, &contact);
    let exact = LENGTH * WIDTH - 2.0 * disc;
    assert!(
        area > exact && area - exact <= 2.0 * inscribed_deficit(chord),
        "Γ3 area {area}, face less discs {exact}"
    );

    // Γ2 is the top, the faces y = 0, y = 1, x = 2, and the holes, whose facets are
    // triangles inscribed in the cylinders with the outward normal of the body pointing to
    // the axis
    let mut hole = Vec::new();
    let mut top = Vec::new();
    for f in facets_of(mesh, BoundaryPart::Neumann) {
        let corners = facet_vertices(mesh, f);
        let middle = centroid(&corners);
        let on_plane = |axis: usize, value: f64| {
            (middle[axis] - value).abs() <= ON_GEOMETRY
                && corners
                    .iter()
                    .all(|x| (x[axis] - value).abs() <= ON_GEOMETRY)
        };
        if on_plane(2, HEIGHT) {
            top.push(f);
        } else if !(on_plane(1, 0.0) || on_plane(1, WIDTH) || on_plane(0, LENGTH)) {
            let (_, axis) = distance_to_axis(&middle);
            for x in &corners {
                let radius = (x[0] - axis[0]).hypot(x[1] - axis[1]);
                assert!(
                    (radius - HOLE_RADIUS).abs() <= ON_GEOMETRY,
                    "Γ2 vertex {x:?} is on no face of the block nor on a cylinder (r = {radius})"
                );
            }
            let normal = mesh.facet_normal(f);
            let inward = [axis[0] - middle[0], axis[1] - middle[1]];
            let cosine =
                (normal[0] * inward[0] + normal[1] * inward[1]) / inward[0].hypot(inward[1]);
            assert!(cosine > 0.95, "facet {f}: normal {normal:?}");
            hole.push(f);
        }
    }
    let top_area = total_area(mesh, &top);
    let exact = LENGTH * WIDTH - 2.0 * disc;
    assert!(
        top_area > exact && top_area - exact <= 2.0 * inscribed_deficit(chord),
        "top area {top_area}"
    );
    // the lateral area of the polygonal cylinders is a little less than 2 · 2πr · height
    assert!(hole.len() >= 100, "{} facets on the holes", hole.len());
    let lateral = total_area(mesh, &hole);
    let cylinders = 2.0 * 2.0 * PI * HOLE_RADIUS * HEIGHT;
    assert!(
        lateral < cylinders && lateral > 0.95 * cylinders,
        "lateral area of the holes {lateral}, of the cylinders {cylinders}"
    );
}

#[test]
fn contact_line_is_the_structured_midline_of_the_contact_face() {
    let setup = ProblemSetup::<3>::from_path(&example()).unwrap();
    let simulation = Simulation::new(setup.problem.clone()).unwrap();
    let line = ContactLine::new(simulation.space(), simulation.contact());
    // the nodes of y = 0.5 but the clamped end x = 0, evenly spaced along x
    assert_eq!(line.coordinate, LineCoordinate::Axis(0));
    assert_eq!(line.indices.len(), MIDLINE_INTERVALS);
    let spacing = LENGTH / MIDLINE_INTERVALS as f64;
    for (j, s) in line.coordinates.iter().enumerate() {
        assert!(
            (s - (j + 1) as f64 * spacing).abs() < 1e-12,
            "node {j} of the line at x = {s}"
        );
    }
    for &k in &line.indices {
        let x = simulation.space().node(simulation.contact().nodes[k]);
        assert!((x[1] - 0.5).abs() < 1e-12 && x[2].abs() < 1e-12, "{x:?}");
    }
}

#[test]
fn first_load_peak_converges_and_presses_the_contact_face() {
    let setup = ProblemSetup::<3>::from_path(&example()).unwrap();
    // k = 0.04 and the load period is 1: the load peaks at t = 0.5, between steps 12 and 13
    assert_eq!(setup.problem.steps, 75);
    assert!((setup.problem.final_time - 3.0).abs() < 1e-15);
    let peak = 13;
    let mesh = setup.problem.mesh.clone();

    // the contact nodes are the vertices of Γ3 less those on the clamped face
    let expected_contact_nodes = expected_contact_nodes(&mesh);
    let contact_nodes = Simulation::new(setup.problem.clone())
        .unwrap()
        .contact()
        .len();
    assert_eq!(contact_nodes, expected_contact_nodes);

    let out = scratch("gmsh-example-3d-run");
    let history = checked_run(&setup, &out, peak);
    let count = |step, name| history_value(&history, step, name) as usize;
    for step in 1..=peak {
        assert_eq!(
            count(step, "stick") + count(step, "slip") + count(step, "separated"),
            contact_nodes,
            "step {step}"
        );
    }
    // the gap keeps the body off the foundation until the load grows
    assert_eq!(count(1, "separated"), contact_nodes);
    // at peak load the whole of Γ3 is pressed, with stick and slip zones side by side
    assert_eq!(count(peak, "separated"), 0);
    assert!(count(peak, "stick") > 0 && count(peak, "slip") > 0);
    assert!(history_value(&history, peak, "normal_force") > 0.5);

    // the contact history holds the nodes of the midline every `output.every` steps (the run
    // stops at `--until-step` before the last step N)
    let rows = std::fs::read_to_string(out.join(CONTACT_HISTORY_FILE))
        .unwrap()
        .lines()
        .count();
    let saved = (1..=peak).filter(|n| n % setup.every == 0).count();
    assert!(saved > 0 && saved < peak, "the example records every step");
    assert_eq!(rows, 1 + saved * MIDLINE_INTERVALS);
}

/// On this mesh the condensed friction problem's right-hand side (the force that would stop
/// all sliding) is hundreds of times the forces of (5.1), so a tolerance relative to it would
/// leave the velocity KKT residual at 1.5e-10–3e-10 > 1e-10 whatever the refinement passes did
/// (this variant, contact stiffness 5, would stop at step 7). The velocity step therefore measures
/// stationarity against the forces it balances and tightens the friction tolerance in
/// refinement passes (with the right-hand side S (H⁻¹ b)_c, step 7 needs one). The one-solve
/// path computes the condensed right-hand side as L_cc z_c from the forward half of the solve,
/// instead of S (H⁻¹ b)_c with its cancellation, so every step meets the tolerance in its
/// first pass, with residuals near 1e-12.
#[test]
fn velocity_step_meets_its_tolerance_when_the_friction_rhs_dwarfs_the_forces() {
    let text = std::fs::read_to_string(example()).unwrap();
    let variant = text.replace("stiffness = 4.0", "stiffness = 5.0");
    assert_ne!(variant, text);
    let dir = scratch("gmsh-example-3d-stiff-contact");
    // the mesh is found next to the problem file
    std::fs::copy(
        example().with_file_name("bracket_3d.msh"),
        dir.join("bracket_3d.msh"),
    )
    .unwrap();
    let path = dir.join("stiff_contact.toml");
    std::fs::write(&path, variant).unwrap();
    let setup = ProblemSetup::<3>::from_path(&path).unwrap();
    let out = dir.join("out");
    let outcome = simulate::run::run(
        &setup,
        &RunOptions {
            out: Some(out.clone()),
            quiet: true,
            until_step: Some(8),
            ..RunOptions::default()
        },
    )
    .unwrap();
    assert_eq!(outcome.last_step, 8);
    assert!(outcome.max_kkt.velocity <= 1e-10, "{:?}", outcome.max_kkt);
    // one model solve per step, step 7 included
    let history = std::fs::read_to_string(out.join(HISTORY_FILE)).unwrap();
    for step in 1..=8 {
        assert_eq!(
            history_value(&history, step, "newton_iterations"),
            1.0,
            "step {step}"
        );
        assert!(
            history_value(&history, step, "velocity_kkt") <= 1e-11,
            "step {step}"
        );
    }
}
