//! The validation examples of `verification/validation/` rerun reduced: the full tables come
//! from `cargo run --release -p simulate --example validation` (docs/results/validation.md).

use crate::common;

use common::scratch;
use simulate::pictures::read_contact_history;
use simulate::run::RunOptions;
use simulate::zone::{pressure_ellipse, profile_zone};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn validation_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../verification/validation")
}

/// Runs the validation problem `name` with lines replaced; returns the history rows and the
/// output folder.
fn run(name: &str, replacements: &[(&str, String)]) -> (Vec<BTreeMap<String, f64>>, PathBuf) {
    run_in(name, name, replacements)
}

/// [`run`] in the scratch folder `validation-<folder>`: tests that run one problem in
/// parallel each take their own folder.
fn run_in(
    name: &str,
    folder: &str,
    replacements: &[(&str, String)],
) -> (Vec<BTreeMap<String, f64>>, PathBuf) {
    let mut text = std::fs::read_to_string(validation_dir().join(format!("{name}.toml"))).unwrap();
    for (from, to) in replacements {
        assert!(text.contains(from), "`{from}` is not in {name}.toml");
        text = text.replace(from, to);
    }
    let dir = scratch(&format!("validation-{folder}"));
    let problem = dir.join(format!("{name}.toml"));
    std::fs::write(&problem, text).unwrap();
    let out = dir.join("out");
    let options = RunOptions {
        out: Some(out.clone()),
        quiet: true,
        ..RunOptions::default()
    };
    simulate::run_file(&problem, &options).unwrap();
    let csv = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows = lines
        .map(|line| {
            header
                .iter()
                .map(|h| h.to_string())
                .zip(line.split(',').map(|v| v.parse().unwrap_or(f64::NAN)))
                .collect()
        })
        .collect();
    (rows, out)
}

/// The nodal pressures (s, p_ν) of the last step recorded in the run's `contact_history.csv`.
fn last_pressures(out: &Path) -> Vec<(f64, f64)> {
    let records = read_contact_history(&out.join("contact_history.csv")).unwrap();
    let step = records.last().unwrap().step;
    records
        .iter()
        .filter(|r| r.step == step)
        .map(|r| (r.coordinate, r.normal_pressure))
        .collect()
}

/// Asserts that each computed value (name, computed, Hertz's) lies within `tolerance`,
/// relative, of Hertz's.
fn assert_hertz(values: [(&str, f64, f64); 2], tolerance: f64) {
    for (what, computed, expected) in values {
        let error = (computed - expected).abs() / expected;
        assert!(
            error <= tolerance,
            "{what}: {computed} vs Hertz {expected} ({:.2} %)",
            100.0 * error
        );
    }
}

/// A block dragged along the foundation: the friction force grows while parts of Γ3 stick and
/// saturates at μP once the whole face slips — with the friction bound of step n taken at
/// u_{n−1} (5.1), exactly Q_n = μ P_{n−1}; the grip's reaction balances it at every step.
#[test]
fn sliding_block_friction_saturates_at_mu_times_the_normal_force() {
    let (rows, _) = run("sliding", &[]);
    let friction = 0.3;
    let mut saturated = 0;
    for pair in rows.windows(2) {
        let (before, row) = (&pair[0], &pair[1]);
        let bound = friction * before["normal_force"];
        let q = row["tangential_force"];
        assert!(q <= bound * (1.0 + 1e-9), "Q = {q:e} above μP = {bound:e}");
        if row["stick"] == 0.0 {
            assert!(
                (q - bound).abs() <= 1e-9 * bound,
                "full slip: Q = {q:e}, μP = {bound:e}"
            );
            saturated += 1;
        }
        // k = τ makes each step the static problem: the top's grip balances the foundation
        let balance = row["reaction_y_max_x"] + row["force_x"];
        assert!(
            balance.abs() <= 1e-9 * row["normal_force"],
            "x balance {balance:e}"
        );
    }
    // the drag first sticks (Q < μP), then slides
    assert!(rows[3]["tangential_force"] < 0.5 * friction * rows[2]["normal_force"]);
    assert!(saturated >= 10, "only {saturated} fully slipping steps");
}

/// The block dragged in 3D at 30° to its long side: every node's friction opposes its own slip,
/// so the resultant Q never exceeds μ P_(n−1) (the bound of step n is taken at u_(n−1)); once
/// the whole face slips and the block settles into a rigid translation Q/(μ P_(n−1)) → 1 and
/// the friction force turns to oppose the drag (29.7° at the last step, 27.9° while it
/// sticks: the block is stiffer in shear along its long side); the grip balances it at every
/// step.
#[test]
fn sliding_block_in_3d_saturates_at_mu_p_opposite_to_the_drag() {
    let (rows, _) = run("sliding3d", &[]);
    let friction = 0.3;
    let mut fully_slipping = 0;
    for pair in rows.windows(2) {
        let (before, row) = (&pair[0], &pair[1]);
        let bound = friction * before["normal_force"];
        let q = row["tangential_force"];
        assert!(q <= bound * (1.0 + 1e-9), "Q = {q:e} above μP = {bound:e}");
        for axis in ["x", "y"] {
            let balance = row[&format!("reaction_z_max_{axis}")] + row[&format!("force_{axis}")];
            assert!(
                balance.abs() <= 1e-9 * row["normal_force"],
                "{axis} balance {balance:e}"
            );
        }
        if row["stick"] == 0.0 {
            fully_slipping += 1;
        }
    }
    assert!(
        fully_slipping >= 10,
        "only {fully_slipping} fully slipping steps"
    );
    // sticking at first, then saturated and opposite to the drag
    assert!(rows[2]["tangential_force"] < 0.5 * friction * rows[1]["normal_force"]);
    let (before, last) = (&rows[rows.len() - 2], &rows[rows.len() - 1]);
    let ratio = last["tangential_force"] / (friction * before["normal_force"]);
    assert!(ratio > 0.9999, "Q/(μP) = {ratio}");
    let direction = (-last["force_y"]).atan2(-last["force_x"]).to_degrees();
    assert!((direction - 30.0).abs() < 0.5, "friction at {direction}°");
}

/// Hertz line contact on the coarse mesh (h = 0.01 at the contact, P2, c_ν = 1e6, ν = 0.3):
/// the peak pressure and the half-width of the computed pressure ellipse against Hertz's
/// formulas for the measured load. Tolerance 1 %: the finest mesh of the full table differs by
/// 0.7 % at ν = 0.3 through the normal–tangential coupling that Hertz's theory neglects
/// (shrinking to 0.2 % ≈ (a/R)² as ν → 1/2, docs/results/validation.md), and this mesh by 0.3 %; an error in E*, R,
/// the load or the contact rule moves them by far more.
#[test]
fn hertz_line_contact_on_the_coarse_mesh_matches_the_theory() {
    let mesh = validation_dir().join("hertz_h0.01.msh");
    let (rows, out) = run(
        "hertz",
        &[(
            "file = \"hertz_h0.0025.msh\"",
            format!("file = \"{}\"", mesh.display()),
        )],
    );
    let last = rows.last().unwrap();
    let load = last["force_y"];
    let pressures = last_pressures(&out);
    let (peak, half_width) = pressure_ellipse(&pressures).expect("no contact zone");
    let plane_modulus = 1.0 / (1.0 - 0.3f64.powi(2));
    let hertz_width = (4.0 * load / (std::f64::consts::PI * plane_modulus)).sqrt();
    let hertz_peak = 2.0 * load / (std::f64::consts::PI * hertz_width);
    assert!((0.03..=0.05).contains(&hertz_width), "a/R = {hertz_width}");
    assert_hertz(
        [("p0", peak, hertz_peak), ("a", half_width, hertz_width)],
        0.01,
    );
    // the zone from the zero crossing lies within a node spacing (h/2) of the ellipse's edge
    let zone = 0.5 * (last["zone_max"] - last["zone_min"]);
    assert!(
        (zone - half_width).abs() <= 0.005,
        "zone half-width {zone} vs {half_width}"
    );
    // equilibrium at the prescribed approach: the top's reaction balances the contact force
    let balance = last["reaction_top_y"] + last["force_y"];
    assert!(balance.abs() <= 1e-8 * load, "y balance {balance:e}");
}

/// The mean deviation, in % of p0, of the pressures of the even and of the odd nodes of the arc
/// (sorted along it) from the fitted ellipse over |x| < a/2, with p0 and a. The contact nodes of
/// the open arc alternate midpoint, vertex, …, midpoint at P2 (its end vertices are on the
/// prescribed top): the even ones are the edge midpoints.
fn midpoint_and_vertex_deviations(mut pressures: Vec<(f64, f64)>) -> ([f64; 2], f64, f64) {
    pressures.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert!(pressures.len() % 2 == 1, "{} arc nodes", pressures.len());
    let (peak, half_width) = pressure_ellipse(&pressures).expect("no contact zone");
    let mut sums = [(0.0, 0.0); 2];
    for (index, &(x, p)) in pressures.iter().enumerate() {
        if x.abs() < 0.5 * half_width {
            let ellipse = peak * (1.0 - (x / half_width).powi(2)).sqrt();
            sums[index % 2].0 += 100.0 * (p - ellipse) / peak;
            sums[index % 2].1 += 1.0;
        }
    }
    (sums.map(|(sum, count)| sum / count), peak, half_width)
}

/// The Hertz half-disc on the coarse mesh's second-order twin (6-node triangles, the arc's
/// edge nodes on the circle), with the gap written as `y`, the vertical distance to the flat:
/// the cells along the arc are mapped isoparametrically, so vertex and midpoint pressures lie
/// on one ellipse (mean deviations within 0.5 % of p0: measured +0.29 % and +0.06 %) and p0 and
/// a match Hertz within 0.5 % (+0.33 %, −0.06 %). The same gap on the first-order mesh, whose
/// straight P2 midpoints lie h²/8R inside the circle, puts the midpoints 10 % below the
/// ellipse (−10.6 %) and p0 10 % off: the measure sees what a straight arc does.
#[test]
fn hertz_half_disc_on_a_second_order_mesh_has_one_smooth_pressure_profile() {
    let measure = |file: &str| {
        let mesh = validation_dir().join(file);
        let (rows, out) = run_in(
            "hertz",
            &format!("hertz-gap-y-{file}"),
            &[
                (
                    "file = \"hertz_h0.0025.msh\"",
                    format!("file = \"{}\"", mesh.display()),
                ),
                ("gap = \"R - sqrt(R^2 - x^2)\"", "gap = \"y\"".to_string()),
            ],
        );
        let load = rows.last().unwrap()["force_y"];
        let plane_modulus = 1.0 / (1.0 - 0.3f64.powi(2));
        let hertz_width = (4.0 * load / (std::f64::consts::PI * plane_modulus)).sqrt();
        let hertz_peak = 2.0 * load / (std::f64::consts::PI * hertz_width);
        let (deviations, peak, width) = midpoint_and_vertex_deviations(last_pressures(&out));
        (
            deviations,
            [("p0", peak, hertz_peak), ("a", width, hertz_width)],
        )
    };
    let (curved, hertz) = measure("hertz_h0.01_order2.msh");
    assert!(
        curved.iter().all(|d| d.abs() <= 0.5),
        "midpoints, vertices − ellipse: {curved:?} % of p0"
    );
    assert_hertz(hertz, 0.005);
    let (straight, _) = measure("hertz_h0.01.msh");
    assert!(
        straight[0] < -5.0,
        "straight midpoints − ellipse: {straight:?} % of p0"
    );
}

/// Hertz contact of a sphere on a flat in 3D, on the coarse graded mesh (h = 0.02 at the
/// contact, about 3 cells across the contact radius a ≈ 0.06, P2, c_ν = 1e6, ν = 0.3): a quarter
/// of a block pressed onto a rigid paraboloid, its symmetry planes cutting the contact disc.
/// The peak pressure and the radius of the pressure ellipse along y = 0 (`output.profile`)
/// against a = (3PR/4E*)^(1/3), p0 = 3P/(2πa²) for the measured load P = 4 × the quarter's.
/// Tolerance 1.5 %: this mesh gives −0.6 % (a) and −1.0 % (p0), the finer meshes of the full
/// table within 0.2 % (docs/results/validation.md); an error in E*, R, the load, the symmetry
/// planes or the contact rule moves them by far more. The step at rest after the load takes at
/// most 2 Newton iterations, and the quarter is in equilibrium.
#[test]
fn hertz_sphere_in_3d_on_the_coarse_mesh_matches_the_theory() {
    let mesh = validation_dir().join("hertz3d_h0.02.msh");
    let (rows, out) = run(
        "hertz3d",
        &[(
            "file = \"hertz3d_h0.007.msh\"",
            format!("file = \"{}\"", mesh.display()),
        )],
    );
    let last = rows.last().unwrap();
    let load = 4.0 * last["force_z"];
    let pressures = last_pressures(&out);
    let (peak, radius) = pressure_ellipse(&pressures).expect("no contact zone");
    let modulus = 1.0 / (1.0 - 0.3f64.powi(2));
    let hertz_radius = (3.0 * load / (4.0 * modulus)).cbrt();
    let hertz_peak = 3.0 * load / (2.0 * std::f64::consts::PI * hertz_radius.powi(2));
    assert!(
        (0.05..=0.07).contains(&hertz_radius),
        "a/R = {hertz_radius}"
    );
    assert_hertz(
        [("p0", peak, hertz_peak), ("a", radius, hertz_radius)],
        0.015,
    );
    // the load is reached in step 1; step 2, at rest, starts from v = 0
    assert_eq!(rows.len(), 2);
    assert!(
        last["newton_iterations"] <= 2.0,
        "{}",
        last["newton_iterations"]
    );
    // equilibrium: the top's reaction balances the contact force
    let balance = last["reaction_top_z"] + last["force_z"];
    assert!(balance.abs() <= 1e-8 * load, "z balance {balance:e}");
}

/// The hemisphere on a flat (curved second-order mesh, P2, the natural gap z), whole (42 k
/// unknowns) and as the quarter whose symmetry planes cut the contact disc: the quarter's
/// contact nodes on the planes keep the contact rule, so both give the same load and contact
/// area — measured 0.04 % and 0.10 % apart, asserted within 0.3 %. The radius
/// of the zone is within 3 % of Hertz's a = (3PR/4E*)^(1/3) at this resolution (measured
/// 2.4 %, five cells across a), the step at rest takes at most 2 Newton iterations, and the
/// top's reaction balances the contact force.
#[test]
fn whole_and_quarter_hemisphere_carry_the_same_load_on_the_same_contact_area() {
    let quarter_planes =
        "z = \"-delta*min(t, 1)\"\n\n[[displacement]]\npart = \"sym_x\"\nx = \"0\"\n\
                          symmetry = true\n\n[[displacement]]\npart = \"sym_y\"\ny = \"0\"\n\
                          symmetry = true\n";
    let measured: Vec<(f64, f64)> = [
        ("whole", "hemisphere_h0.022.msh", 1.0),
        ("quarter", "hemisphere_quarter_h0.022.msh", 4.0),
    ]
    .into_iter()
    .map(|(model, mesh, parts)| {
        let mesh = validation_dir().join(mesh);
        let mut replacements = vec![(
            "file = \"hemisphere_h0.022.msh\"",
            format!("file = \"{}\"", mesh.display()),
        )];
        if parts > 1.0 {
            replacements.push(("z = \"-delta*min(t, 1)\"\n", quarter_planes.to_string()));
        }
        let (rows, _) = run_in("hemisphere", &format!("hemisphere-{model}"), &replacements);
        let last = rows.last().unwrap();
        assert_eq!(rows.len(), 2);
        assert!(
            last["newton_iterations"] <= 2.0,
            "{model}: {}",
            last["newton_iterations"]
        );
        let balance = last["reaction_top_z"] + last["force_z"];
        assert!(
            balance.abs() <= 1e-8 * last["force_z"],
            "{model}: z balance {balance:e}"
        );
        let load = parts * last["force_z"];
        let area_radius = (parts * last["contact_zone"] / std::f64::consts::PI).sqrt();
        let modulus = 2.0 / (1.0 - 0.4f64.powi(2));
        let hertz_radius = (3.0 * load * 1.5 / (4.0 * modulus)).cbrt();
        assert!(
            (area_radius - hertz_radius).abs() <= 0.03 * hertz_radius,
            "{model}: a from the area {area_radius} vs Hertz {hertz_radius}"
        );
        (load, area_radius)
    })
    .collect();
    let (whole, quarter) = (measured[0], measured[1]);
    for (what, whole, quarter) in [("P", whole.0, quarter.0), ("a (area)", whole.1, quarter.1)] {
        assert!(
            (quarter - whole).abs() <= 0.003 * whole,
            "{what}: quarter {quarter} vs whole {whole}"
        );
    }
}

/// Mindlin partial slip in 3D on the coarse mesh (h = 0.02 at the contact, P2: nodes about
/// 0.01 = 0.16 a apart along the diameter): half of the block, its symmetry plane y = 0
/// through the contact disc along the load. After the frictionless normal load, the shift of
/// the top along x shrinks a central stick disc whose radius c, the half extent of the sticking
/// loaded nodes on the diameter y = 0, follows a (1 − Q/(μP))^(1/3) to within one node spacing
/// (the measured c is quantized by it; the largest difference on this mesh is 0.12 a), until
/// the whole contact slips.
#[test]
fn mindlin_stick_disc_in_3d_follows_the_theory_on_the_coarse_mesh() {
    let mesh = validation_dir().join("mindlin3d_h0.02.msh");
    let spacing = 0.01;
    let (rows, out) = run(
        "mindlin3d",
        &[(
            "file = \"mindlin3d_h0.01.msh\"",
            format!("file = \"{}\"", mesh.display()),
        )],
    );
    let records = read_contact_history(&out.join("contact_history.csv")).unwrap();
    let mut largest_ratio: f64 = 0.0;
    for row in rows.iter().skip(1) {
        let step = row["step"] as usize;
        let (radius, stick) = profile_zone(&records, step, 0.2).expect("no contact zone");
        let (stick, _) = stick.unwrap_or((0.0, 0.0));
        let ratio = row["tangential_force"] / (0.5 * row["normal_force"]);
        assert!(ratio <= 1.0 + 1e-9, "step {step}: Q/μP = {ratio}");
        largest_ratio = largest_ratio.max(ratio);
        let theory = radius * (1.0 - ratio).max(0.0).cbrt();
        if ratio < 0.99 {
            assert!(
                (stick - theory).abs() <= spacing,
                "step {step}, Q/μP = {ratio:.3}: c = {stick} vs {theory}"
            );
        }
    }
    assert!(largest_ratio > 0.999, "Q/μP reached only {largest_ratio}");
    assert_mindlin_compliance(&rows);
}

/// The top's shift s = 2e-4 (n − 1) against Mindlin's tangential compliance of an elastic
/// half-space on a rigid sphere, δ_M(Q) = 3(2 − ν)μP/(16Ga) [1 − (1 − Q/(μP))^(2/3)] (Johnson
/// (7.42)), over the partial-slip steps (Q < 0.95 μP): |s − δ_M(Q)| stays within 1 % of
/// δ_M(μP) (measured 0.4 % on this mesh; the block's own compliance is not separated, see
/// docs/results/validation.md). P and Q are twice the half model's; a is Hertz's for P. A
/// compliance 10 % off moves s − δ_M by up to 8 % of δ_M(μP); (2 − ν) written 2, by 15 %.
fn assert_mindlin_compliance(rows: &[BTreeMap<String, f64>]) {
    let (friction, poisson) = (0.5, 0.3);
    let shear = 1.0 / (2.0 * (1.0 + poisson));
    let mut partial = 0;
    for row in rows.iter().skip(1) {
        let (load, force) = (2.0 * row["normal_force"], 2.0 * row["tangential_force"]);
        let slip = force / (friction * load);
        if slip >= 0.95 {
            continue;
        }
        partial += 1;
        let radius = (0.75 * load * (1.0 - poisson * poisson)).cbrt();
        let full = 3.0 * (2.0 - poisson) * friction * load / (16.0 * shear * radius);
        let mindlin = full * (1.0 - (1.0 - slip).powf(2.0 / 3.0));
        let shift = 2e-4 * (row["step"] - 1.0);
        assert!(
            (shift - mindlin).abs() <= 0.01 * full,
            "Q/μP = {slip:.3}: s = {shift:e}, δ_M = {mindlin:e} ({:+.2} % of δ_M(μP))",
            100.0 * (shift - mindlin) / full
        );
    }
    assert!(partial >= 6, "{partial} partial-slip steps");
}

/// Cattaneo–Mindlin partial slip on the coarse mesh (P2, h = 0.01 at the contact: nodes 0.005
/// apart): after the frictionless normal load, the sideways shift of the top grows a central
/// stick zone whose half-width c follows a √(1 − Q/(μP)). The computed c is the half extent
/// of the sticking loaded nodes, so it is quantized by the node spacing; the tolerance is one
/// node spacing (0.11 a). At ν = 0.49 (no normal–tangential coupling) the stick zone stays
/// centred to within half a node spacing.
#[test]
fn cattaneo_mindlin_stick_zone_follows_the_theory_on_the_coarse_mesh() {
    let mesh = validation_dir().join("hertz_h0.01.msh");
    let spacing = 0.005;
    for poisson in [0.3f64, 0.49] {
        let shear = 1.0 / (2.0 * (1.0 + poisson));
        let lambda = poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
        let (rows, out) = run(
            "cattaneo",
            &[
                (
                    "file = \"hertz_h0.0025.msh\"",
                    format!("file = \"{}\"", mesh.display()),
                ),
                (
                    "shear = 0.38461538461538464, bulk = 0.5769230769230769",
                    format!("shear = {shear:?}, bulk = {lambda:?}"),
                ),
                (
                    "shear_modulus = 0.38461538461538464, lame_lambda = 0.5769230769230769",
                    format!("shear_modulus = {shear:?}, lame_lambda = {lambda:?}"),
                ),
            ],
        );
        let records = read_contact_history(&out.join("contact_history.csv")).unwrap();
        let mut largest_ratio: f64 = 0.0;
        for row in rows.iter().skip(1) {
            let step = row["step"] as usize;
            let (half_width, stick) = profile_zone(&records, step, 0.0).expect("no contact zone");
            let (stick_half_width, centre) =
                stick.unwrap_or_else(|| panic!("ν = {poisson}, step {step}: nothing sticks"));
            let ratio = row["tangential_force"] / (0.5 * row["force_y"]);
            largest_ratio = largest_ratio.max(ratio);
            let theory = half_width * (1.0 - ratio).sqrt();
            assert!(
                (stick_half_width - theory).abs() <= spacing,
                "ν = {poisson}, step {step}, Q/μP = {ratio:.3}: c = {stick_half_width} vs {theory}"
            );
            if poisson > 0.45 {
                assert!(
                    centre.abs() <= 0.5 * spacing,
                    "ν = {poisson}: centre {centre}"
                );
            }
        }
        assert!(
            largest_ratio > 0.6,
            "ν = {poisson}: Q/μP reached only {largest_ratio}"
        );
    }
}
