//! CI rate assertions: reduced convergence studies (coarser levels than the default CLI study)
//! for l = 1, 2 and d = 2, 3 on the built-in cases with separation, stick and slip zones and an
//! active damage bound: linear viscosity (zones2d/3d), the nonlinear viscosity of (3.4), mild
//! and strong (mild2d/3d, strong2d/3d), the wear-modified friction bound (2.12) (wear2d/3d),
//! laws written in the case file (carreau2d: a viscosity potential and β-dependent moduli), and
//! the implicit normal compliance with a stiff foundation (implicit2d), and prescribed
//! displacement, a roller and a moving, partly negative gap (loads2d), and the cases on Gmsh
//! meshes with a tilted contact boundary, unstructured triangles and tetrahedra refined
//! uniformly (tilted2d/3d).
//! Each study must pass its verdict (observed least-squares rate ≥ expected − `RATE_TOLERANCE`
//! for every component bounded by Theorem 5.2), every step's KKT residual must be below 1e-9,
//! and every case must really show the three contact zones and the active bound.

use verify::case::{parse_case_file, Case, LevelStudy, TimeStudy};
use verify::cli::BUILT_IN_CASES;
use verify::study::{level_study, time_study, StudyKind, StudyResult, RATE_TOLERANCE};

fn case<const D: usize>(name: &str) -> Case<D> {
    let (_, text) = BUILT_IN_CASES
        .iter()
        .find(|(n, _)| *n == name)
        .expect("built-in case");
    let origin = format!("built-in:{name}");
    Case::new(parse_case_file(text, &origin).unwrap(), &origin).unwrap()
}

fn assert_study(study: &StudyResult) {
    for rate in &study.rates {
        println!(
            "{}-study l={}: {:<20} least squares {:.3} pairwise {:?}",
            study.kind.name(),
            study.degree,
            rate.component,
            rate.least_squares,
            rate.pairwise
        );
    }
    for rate in &study.rates {
        if let (Some(expected), Some(pass)) = (rate.expected, rate.pass) {
            assert!(
                pass && rate.least_squares >= expected - RATE_TOLERANCE,
                "{}-study l={}: {} rate {:.3} < expected {:.2} − {RATE_TOLERANCE} (pairwise {:?})",
                study.kind.name(),
                study.degree,
                rate.component,
                rate.least_squares,
                expected,
                rate.pairwise
            );
        }
    }
    for run in &study.runs {
        assert!(
            run.stats.max_velocity_kkt < 1e-9 && run.stats.max_damage_kkt < 1e-9,
            "KKT residuals {:e} / {:e} at cells {} steps {}",
            run.stats.max_velocity_kkt,
            run.stats.max_damage_kkt,
            run.cells,
            run.steps
        );
    }
    // the three contact zones and the active damage bound occurred in the finest run of the
    // mesh studies (the k-studies run on one coarse mesh, which need not resolve the zones)
    if study.kind == StudyKind::K {
        return;
    }
    let stats = &study.runs.last().unwrap().stats;
    assert!(
        stats.steps_with_separation > 0 && stats.steps_with_stick > 0 && stats.steps_with_slip > 0,
        "zones not all seen: {stats:?}"
    );
    assert!(
        stats.steps_with_upper_bound > 0,
        "damage bound β = 1 never active: {stats:?}"
    );
}

fn levels(cells: &[usize], steps: &[usize]) -> LevelStudy {
    LevelStudy {
        cells: cells.to_vec(),
        refinements: Vec::new(),
        steps: steps.to_vec(),
    }
}

/// Levels by uniform refinement of a Gmsh mesh.
fn refined(refinements: &[usize], steps: &[usize]) -> LevelStudy {
    LevelStudy {
        cells: Vec::new(),
        refinements: refinements.to_vec(),
        steps: steps.to_vec(),
    }
}

/// A k-study on the Gmsh mesh refined `refinements` times.
fn refined_k(refinements: usize, steps: &[usize], reference_steps: usize) -> TimeStudy {
    TimeStudy {
        cells: 0,
        refinements: Some(refinements),
        steps: steps.to_vec(),
        reference_steps,
    }
}

/// The reduced 2D studies of order 1 (h, diagonal, k) on a built-in 2D case.
fn studies_2d_order1(name: &str) {
    let case = case::<2>(name);
    assert_study(&level_study(&case, 1, StudyKind::H, &levels(&[4, 8, 16], &[2, 8, 32])).unwrap());
    assert_study(
        &level_study(
            &case,
            1,
            StudyKind::Diagonal,
            &levels(&[4, 8, 16], &[2, 4, 8]),
        )
        .unwrap(),
    );
    let k = TimeStudy {
        cells: 16,
        steps: vec![4, 8, 16],
        reference_steps: 64,
        refinements: None,
    };
    assert_study(&time_study(&case, 1, &k).unwrap());
}

/// The reduced 2D studies of order 2 (h, diagonal, k) on a built-in 2D case.
fn studies_2d_order2(name: &str) {
    let case = case::<2>(name);
    assert_study(&level_study(&case, 2, StudyKind::H, &levels(&[2, 4, 8], &[4, 16, 64])).unwrap());
    assert_study(
        &level_study(
            &case,
            2,
            StudyKind::Diagonal,
            &levels(&[2, 4, 8], &[2, 6, 16]),
        )
        .unwrap(),
    );
    let k = TimeStudy {
        cells: 8,
        steps: vec![4, 8, 16],
        reference_steps: 64,
        refinements: None,
    };
    assert_study(&time_study(&case, 2, &k).unwrap());
}

/// The reduced 3D studies of order 1 (h, diagonal, k) on a built-in 3D case.
fn studies_3d_order1(name: &str) {
    let case = case::<3>(name);
    assert_study(&level_study(&case, 1, StudyKind::H, &levels(&[3, 6], &[2, 8])).unwrap());
    assert_study(&level_study(&case, 1, StudyKind::Diagonal, &levels(&[3, 6], &[2, 4])).unwrap());
    let k = TimeStudy {
        cells: 3,
        steps: vec![16, 32, 64],
        reference_steps: 256,
        refinements: None,
    };
    assert_study(&time_study(&case, 1, &k).unwrap());
}

/// The reduced 3D studies of order 2 (h, k) on a built-in 3D case.
fn studies_3d_order2(name: &str) {
    let case = case::<3>(name);
    assert_study(&level_study(&case, 2, StudyKind::H, &levels(&[1, 2, 4], &[4, 16, 64])).unwrap());
    let k = TimeStudy {
        cells: 2,
        steps: vec![32, 64, 128],
        reference_steps: 512,
        refinements: None,
    };
    assert_study(&time_study(&case, 2, &k).unwrap());
}

#[test]
fn rates_2d_order1() {
    studies_2d_order1("zones2d");
}

#[test]
fn rates_2d_order2() {
    studies_2d_order2("zones2d");
}

#[test]
fn rates_3d_order1() {
    studies_3d_order1("zones3d");
}

#[test]
fn rates_3d_order2() {
    studies_3d_order2("zones3d");
}

// The whole model: nonlinear viscosity (mild and strong) and the wear-modified bound (2.12).

#[test]
fn rates_mild_nonlinear_viscosity_2d_order1() {
    studies_2d_order1("mild2d");
}

#[test]
fn rates_mild_nonlinear_viscosity_2d_order2() {
    studies_2d_order2("mild2d");
}

#[test]
fn rates_strong_nonlinear_viscosity_2d_order1() {
    studies_2d_order1("strong2d");
}

#[test]
fn rates_strong_nonlinear_viscosity_2d_order2() {
    studies_2d_order2("strong2d");
}

#[test]
fn rates_wear_2d_order1() {
    studies_2d_order1("wear2d");
}

#[test]
fn rates_wear_2d_order2() {
    studies_2d_order2("wear2d");
}

#[test]
fn rates_user_written_laws_2d_order1() {
    studies_2d_order1("carreau2d");
}

#[test]
fn rates_user_written_laws_2d_order2() {
    studies_2d_order2("carreau2d");
}

#[test]
fn rates_implicit_contact_2d_order1() {
    studies_2d_order1("implicit2d");
}

#[test]
fn rates_implicit_contact_2d_order2() {
    studies_2d_order2("implicit2d");
}

#[test]
fn rates_prescribed_displacement_roller_moving_gap_2d_order1() {
    studies_2d_order1("loads2d");
}

#[test]
fn rates_prescribed_displacement_roller_moving_gap_2d_order2() {
    studies_2d_order2("loads2d");
}

#[test]
fn rates_mild_nonlinear_viscosity_3d_order1() {
    studies_3d_order1("mild3d");
}

#[test]
fn rates_mild_nonlinear_viscosity_3d_order2() {
    studies_3d_order2("mild3d");
}

#[test]
fn rates_strong_nonlinear_viscosity_3d_order1() {
    studies_3d_order1("strong3d");
}

#[test]
fn rates_strong_nonlinear_viscosity_3d_order2() {
    studies_3d_order2("strong3d");
}

#[test]
fn rates_wear_3d_order1() {
    studies_3d_order1("wear3d");
}

#[test]
fn rates_wear_3d_order2() {
    studies_3d_order2("wear3d");
}

// Cases on Gmsh meshes: unstructured triangles and tetrahedra, levels by uniform refinement,
// a tilted contact boundary (the normal frames are not axis-aligned).

#[test]
fn rates_gmsh_mesh_tilted_contact_2d_order1() {
    let case = case::<2>("tilted2d");
    assert_study(&level_study(&case, 1, StudyKind::H, &refined(&[0, 1, 2], &[2, 8, 32])).unwrap());
    assert_study(
        &level_study(
            &case,
            1,
            StudyKind::Diagonal,
            &refined(&[0, 1, 2], &[2, 4, 8]),
        )
        .unwrap(),
    );
    assert_study(&time_study(&case, 1, &refined_k(2, &[4, 8, 16], 64)).unwrap());
}

#[test]
fn rates_gmsh_mesh_tilted_contact_2d_order2() {
    let case = case::<2>("tilted2d");
    assert_study(&level_study(&case, 2, StudyKind::H, &refined(&[0, 1, 2], &[4, 16, 64])).unwrap());
    assert_study(
        &level_study(
            &case,
            2,
            StudyKind::Diagonal,
            &refined(&[0, 1, 2], &[2, 6, 16]),
        )
        .unwrap(),
    );
    assert_study(&time_study(&case, 2, &refined_k(1, &[4, 8, 16], 64)).unwrap());
}

#[test]
fn rates_gmsh_mesh_unstructured_tetrahedra_3d_order1() {
    let case = case::<3>("tilted3d");
    let h = level_study(&case, 1, StudyKind::H, &refined(&[0, 1], &[2, 8])).unwrap();
    assert_study(&h);
    // the shape-regularity measure is recorded per level and stays bounded
    let (q0, q1) = (h.runs[0].shape_regularity, h.runs[1].shape_regularity);
    assert!(q0 >= 1.0 && q1 <= 2.0 * q0, "shape regularity {q0} → {q1}");
    assert_eq!(h.runs[1].mesh_cells, 8 * h.runs[0].mesh_cells);
    assert_study(&time_study(&case, 1, &refined_k(0, &[16, 32, 64], 256)).unwrap());
}
