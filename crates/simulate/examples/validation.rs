//! Validation of `simulate` against classical analytic solutions of contact mechanics:
//!
//! - `hertz`: Hertz line contact (plane strain) of a half-disc of radius R on a rigid flat,
//!   loaded by a prescribed approach δ of its flat side, frictionless: the contact half-width a
//!   and the peak pressure p0 against a = √(4PR/(πE*)), p0 = 2P/(πa) for the measured load P,
//!   over meshes and foundation stiffnesses c_ν; and the pressure profile p0 √(1 − x²/a²)
//!   against the computed nodal pressures;
//! - `hertz3d`: Hertz contact of a sphere on a flat in 3D — the face of an elastic block pressed
//!   onto a rigid paraboloid of radius R, frictionless, by a prescribed approach (a quarter of
//!   the block, its symmetry planes cutting the contact disc): the contact radius a and the peak
//!   pressure p0 against a = (3PR/4E*)^(1/3), p0 = 3P/(2πa²) for the measured load P, over
//!   graded Gmsh meshes and c_ν, with the Newton iterations per step;
//! - `hemisphere`: a solid hemisphere on a flat (curved second-order mesh, P2, 42 k unknowns),
//!   whole and as a quarter whose symmetry planes cut the contact disc: a and p0 against Hertz
//!   and the quarter against the whole;
//! - `cattaneo`: Cattaneo–Mindlin partial slip of the same half-disc shifted sideways after the
//!   normal load: the stick half-width c against a √(1 − Q/(μP));
//! - `mindlin3d`: Mindlin partial slip of the 3D sphere (half of the block, its symmetry plane
//!   through the contact disc along the load): the stick radius c against a (1 − Q/(μP))^(1/3),
//!   and the shift of the block against Mindlin's tangential compliance;
//! - `sliding`: a block pressed onto the foundation and dragged along it: the tangential
//!   resultant grows and saturates at μP;
//! - `sliding3d`: the same in 3D, dragged at 30° to the block's long side: the resultant and
//!   its direction tend to μP and the drag's as the whole face slips.
//!
//! ```text
//! cargo run --release -p simulate --example validation -- [hertz|hertz3d|hemisphere|cattaneo|mindlin3d|sliding|sliding3d|all] [--quick]
//! ```
//!
//! Each prints its table, writes it to `reports/validation/<name>.md` and draws an SVG beside
//! it. `--quick` runs the coarsest mesh only. The problem files are in `verification/validation/`.
//!
//! Both use the viscosity τ times the elasticity and the step k = τ: with the normal compliance
//! taken implicitly, a step of (5.1) is then E u_n + C(u_n) = F exactly (the viscous term
//! τE(u_n − u_{n−1})/k cancels the explicit elastic term E u_{n−1}), so each step is the static
//! elastic contact problem at its load — a step per load increment, at any c_ν.

use plotters::prelude::*;
use simulate::pictures::read_contact_history;
use simulate::run::RunOptions;
use simulate::zone::{pressure_ellipse, profile_zone};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The folder of the validation problem files.
fn validation_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../verification/validation")
}

/// The report folder.
fn report_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../reports/validation")
}

/// One run of a problem file with some of its lines replaced: the history rows (column →
/// value) and the path of its output folder.
struct Run {
    history: Vec<BTreeMap<String, f64>>,
    out: PathBuf,
    seconds: f64,
}

fn run(template: &str, replacements: &[(&str, String)], name: &str) -> Run {
    let mut text = template.to_string();
    for (from, to) in replacements {
        assert!(text.contains(from), "`{from}` is not in the problem file");
        text = text.replace(from, to);
    }
    let scratch = std::env::temp_dir().join(format!("validation-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).unwrap();
    let problem = scratch.join(format!("{name}.toml"));
    std::fs::write(&problem, text).unwrap();
    let out = scratch.join(name);
    let clock = Instant::now();
    simulate::run_file(
        &problem,
        &RunOptions {
            out: Some(out.clone()),
            overwrite: true,
            quiet: true,
            ..RunOptions::default()
        },
    )
    .unwrap_or_else(|error| panic!("{name}: {error}"));
    let seconds = clock.elapsed().as_secs_f64();
    let csv = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let history = lines
        .map(|line| {
            header
                .iter()
                .cloned()
                .zip(line.split(',').map(|v| v.parse().unwrap_or(f64::NAN)))
                .collect()
        })
        .collect();
    Run {
        history,
        out,
        seconds,
    }
}

/// Relative difference in percent.
fn percent(computed: f64, expected: f64) -> f64 {
    100.0 * (computed - expected) / expected
}

/// The lines of the validation problem files that set E = 1, ν = 0.3 (viscosity τ = 1 times the
/// elasticity), replaced for E = 1 and `poisson`: μ = E/(2(1 + ν)), λ = Eν/((1 + ν)(1 − 2ν)).
fn material(poisson: f64) -> [(&'static str, String); 2] {
    let shear = 1.0 / (2.0 * (1.0 + poisson));
    let lambda = poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    [
        (
            "shear = 0.38461538461538464, bulk = 0.5769230769230769",
            format!("shear = {shear:?}, bulk = {lambda:?}"),
        ),
        (
            "shear_modulus = 0.38461538461538464, lame_lambda = 0.5769230769230769",
            format!("shear_modulus = {shear:?}, lame_lambda = {lambda:?}"),
        ),
    ]
}

/// One Hertz run: the measured load, half-widths and peak pressure, and the Hertz values.
struct Hertz {
    load: f64,
    /// From the zero crossing of the interpolated penetration (`zone_min`, `zone_max`).
    zone_half_width: f64,
    /// From the pressure profile ([`simulate::zone::pressure_ellipse`]).
    profile_half_width: f64,
    peak: f64,
    hertz_half_width: f64,
    hertz_peak: f64,
    pressures: Vec<(f64, f64)>,
    seconds: f64,
}

/// Runs `hertz.toml` on the mesh of contact size `mesh` with c_ν = `stiffness`, E = 1, ν and
/// the approach δ = `approach`.
fn hertz_run(mesh: &str, stiffness: f64, poisson: f64, approach: f64) -> Hertz {
    let template = std::fs::read_to_string(validation_dir().join("hertz.toml")).unwrap();
    let young = 1.0;
    let mesh_path = validation_dir().join(format!("hertz_h{mesh}.msh"));
    let mut replacements = vec![
        (
            "file = \"hertz_h0.0025.msh\"",
            format!("file = \"{}\"", mesh_path.display()),
        ),
        ("stiffness = 1e6", format!("stiffness = {stiffness:e}")),
        ("delta = 0.004 ", format!("delta = {approach:e} ")),
    ];
    replacements.extend(material(poisson));
    let result = run(
        &template,
        &replacements,
        &format!("hertz-{mesh}-{stiffness:e}-{poisson}-{approach}"),
    );
    let last = result.history.last().unwrap();
    let load = last["force_y"];
    let records = read_contact_history(&result.out.join("contact_history.csv")).unwrap();
    let final_step = records.last().unwrap().step;
    let pressures: Vec<(f64, f64)> = records
        .iter()
        .filter(|r| r.step == final_step)
        .map(|r| (r.coordinate, r.normal_pressure))
        .collect();
    let (peak, profile_half_width) =
        pressure_ellipse(&pressures).expect("fewer than two nodes in the contact zone");
    let radius = 1.0;
    let plane_modulus = young / (1.0 - poisson * poisson);
    let hertz_half_width = (4.0 * load * radius / (std::f64::consts::PI * plane_modulus)).sqrt();
    Hertz {
        load,
        zone_half_width: 0.5 * (last["zone_max"] - last["zone_min"]),
        profile_half_width,
        peak,
        hertz_half_width,
        hertz_peak: 2.0 * load / (std::f64::consts::PI * hertz_half_width),
        pressures,
        seconds: result.seconds,
    }
}

/// The Hertz line contact with the gap written as `y`, the vertical distance of the point to
/// the flat (the disc touches it at the origin), on a first-order mesh (straight P2 cells: the
/// arc's edge midpoints lie h²/8R inside the circle, so their gap is too large by that) and on
/// the second-order mesh of the same triangles (isoparametric P2 cells: every node of the arc
/// on the circle), against the gap written as a function of x on the first-order mesh. Per run:
/// the errors of p0 and a (from the pressure ellipse) and the mean deviation of the vertex and
/// of the midpoint pressures from the fitted ellipse over |x| < a/2, in % of p0.
fn hertz_curved(quick: bool) -> String {
    let meshes: &[&str] = if quick { &["0.01"] } else { &["0.01", "0.005"] };
    let mut table = String::from(
        "| h at contact | mesh | gap | p0 error | a error (profile) | vertices − ellipse | midpoints − ellipse | time |\n|---|---|---|---|---|---|---|---|\n",
    );
    for mesh in meshes {
        for (order, gap) in [(1, "R - sqrt(R^2 - x^2)"), (1, "y"), (2, "y")] {
            let file = if order == 1 {
                format!("hertz_h{mesh}.msh")
            } else {
                format!("hertz_h{mesh}_order2.msh")
            };
            let template = std::fs::read_to_string(validation_dir().join("hertz.toml")).unwrap();
            let replacements = vec![
                (
                    "file = \"hertz_h0.0025.msh\"",
                    format!("file = \"{}\"", validation_dir().join(&file).display()),
                ),
                ("gap = \"R - sqrt(R^2 - x^2)\"", format!("gap = \"{gap}\"")),
            ];
            let result = run(
                &template,
                &replacements,
                &format!("hertz-curved-{mesh}-{order}-{}", gap.len()),
            );
            let load = result.history.last().unwrap()["force_y"];
            let records = read_contact_history(&result.out.join("contact_history.csv")).unwrap();
            let final_step = records.last().unwrap().step;
            let mut pressures: Vec<(f64, f64)> = records
                .iter()
                .filter(|r| r.step == final_step)
                .map(|r| (r.coordinate, r.normal_pressure))
                .collect();
            pressures.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (peak, half_width) = pressure_ellipse(&pressures).unwrap();
            let plane_modulus = 1.0 / (1.0 - 0.3 * 0.3);
            let hertz_half_width = (4.0 * load / (std::f64::consts::PI * plane_modulus)).sqrt();
            let hertz_peak = 2.0 * load / (std::f64::consts::PI * hertz_half_width);
            // the contact nodes of the open arc, in order: midpoint, vertex, …, midpoint (its
            // two end vertices are on the prescribed top)
            assert!(pressures.len() % 2 == 1, "{} arc nodes", pressures.len());
            let mut deviations = [(0.0, 0usize); 2];
            for (index, &(x, p)) in pressures.iter().enumerate() {
                if x.abs() < 0.5 * half_width {
                    let ellipse = peak * (1.0 - (x / half_width).powi(2)).sqrt();
                    let class = &mut deviations[index % 2];
                    class.0 += 100.0 * (p - ellipse) / peak;
                    class.1 += 1;
                }
            }
            let mean = |(sum, count): (f64, usize)| sum / count as f64;
            writeln!(
                table,
                "| {mesh} | {} | `{gap}` | {:+.2} % | {:+.2} % | {:+.2} % | {:+.2} % | {:.1} s |",
                if order == 1 {
                    "first order (straight P2)"
                } else {
                    "second order (curved P2)"
                },
                percent(peak, hertz_peak),
                percent(half_width, hertz_half_width),
                mean(deviations[1]),
                mean(deviations[0]),
                result.seconds
            )
            .unwrap();
        }
    }
    table
}

const HERTZ_HEADER: &str = "| h at contact | c_ν | ν | P | a/R | a (zone) | a (profile) | p0 | error a (zone) | error a (profile) | error p0 | time |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";

fn hertz_row(table: &mut String, mesh: &str, stiffness: f64, poisson: f64, h: &Hertz) {
    writeln!(
        table,
        "| {mesh} | {stiffness:.0e} | {poisson} | {:.5e} | {:.4} | {:.5} | {:.5} | {:.5} | {:+.2} % | {:+.2} % | {:+.2} % | {:.1} s |",
        h.load,
        h.hertz_half_width,
        h.zone_half_width,
        h.profile_half_width,
        h.peak,
        percent(h.zone_half_width, h.hertz_half_width),
        percent(h.profile_half_width, h.hertz_half_width),
        percent(h.peak, h.hertz_peak),
        h.seconds
    )
    .unwrap();
}

/// The Hertz line-contact validation: a table over meshes × c_ν at ν = 0.3, a table over ν on
/// the finest mesh, and the pressure profile.
fn hertz(quick: bool) -> String {
    let meshes: &[&str] = if quick {
        &["0.01"]
    } else {
        &["0.01", "0.005", "0.0025"]
    };
    let stiffnesses: &[f64] = if quick {
        &[1e6]
    } else {
        &[10.0, 100.0, 1e3, 1e4, 1e5, 1e6]
    };
    let mut table = format!(
        "Against a = √(4PR/(πE*)) and p0 = 2P/(πa) for the measured load P (E = 1, R = 1).\n\n{HERTZ_HEADER}"
    );
    let mut profile = None;
    for mesh in meshes {
        for &stiffness in stiffnesses {
            let result = hertz_run(mesh, stiffness, 0.3, 0.004);
            hertz_row(&mut table, mesh, stiffness, 0.3, &result);
            profile = Some((mesh.to_string(), stiffness, result));
        }
    }
    if !quick {
        table.push_str("\nThe normal–tangential coupling, on the finest mesh at c_ν = 1e6: the gap is measured along the arc's normal, so the surface's lateral displacement u_x (∝ (1 − 2ν)/(1 − ν)) enters u_ν = u·ν with the slope x/R, a term Hertz's theory neglects; it vanishes as ν → 1/2.\n\n");
        table.push_str(HERTZ_HEADER);
        for poisson in [0.3, 0.4, 0.45, 0.49] {
            let result = hertz_run("0.0025", 1e6, poisson, 0.004);
            hertz_row(&mut table, "0.0025", 1e6, poisson, &result);
        }
        table.push_str("\nThe coupling term grows with the slope x/R at the edge, i.e. with a/R: smaller approaches δ = 0.004, 0.002, 0.001 at ν = 0.3 (finest mesh, c_ν = 1e6):\n\n");
        table.push_str(HERTZ_HEADER);
        for approach in [0.004, 0.002, 0.001] {
            let result = hertz_run("0.0025", 1e6, 0.3, approach);
            hertz_row(&mut table, "0.0025", 1e6, 0.3, &result);
        }
    }
    table.push_str("\nThe arc's geometry at P2 (c_ν = 1e6, ν = 0.3, δ = 0.004): the gap written as `y`, the vertical distance to the flat, is evaluated at the nodes of the arc. On a first-order mesh the P2 cells are straight and the arc's edge midpoints lie h²/8R inside the circle, so their gap is too large by that much; on the second-order mesh of the same triangles the cells along the arc are mapped isoparametrically and every node is on the circle. Deviation of the vertex and midpoint pressures from the fitted ellipse, mean over |x| < a/2, in % of p0:\n\n");
    table.push_str(&hertz_curved(quick));
    let (mesh, stiffness, result) = profile.unwrap();
    let picture = report_dir().join("hertz_pressure.svg");
    pressure_svg(
        &picture,
        &result.pressures,
        result.hertz_half_width,
        result.hertz_peak,
        "Hertz line contact: pressure on the arc",
        &format!("h = {mesh}, c_ν = {stiffness:.0e}, ν = 0.3"),
    );
    table
}

/// One 3D Hertz run: the measured load, radii, peak pressure, the Hertz values and the Newton
/// iterations of each step.
struct Hertz3d {
    load: f64,
    /// From the area of the contact zone of the whole body: √(area/π).
    area_radius: f64,
    /// From the pressure profile along the radius y = 0 ([`pressure_ellipse`]).
    profile_radius: f64,
    peak: f64,
    hertz_radius: f64,
    hertz_peak: f64,
    newton: Vec<usize>,
    pressures: Vec<(f64, f64)>,
    seconds: f64,
}

impl Hertz3d {
    /// The cells of a table row from P on: P, a/R (`radius` R), a (area), a (profile), p0,
    /// their errors against Hertz, the Newton iterations per step and the time.
    fn row(&self, radius: f64) -> String {
        let newton: Vec<String> = self.newton.iter().map(|n| n.to_string()).collect();
        format!(
            "{:.5e} | {:.4} | {:.5} | {:.5} | {:.5} | {:+.2} % | {:+.2} % | {:+.2} % | {} | {:.1} s |",
            self.load,
            self.hertz_radius / radius,
            self.area_radius,
            self.profile_radius,
            self.peak,
            percent(self.area_radius, self.hertz_radius),
            percent(self.profile_radius, self.hertz_radius),
            percent(self.peak, self.hertz_peak),
            newton.join(", "),
            self.seconds
        )
    }
}

/// Runs `hertz3d.toml` on the mesh of contact size `mesh` with c_ν = `stiffness` (E = 1,
/// ν = 0.3).
fn hertz3d_run(mesh: &str, stiffness: f64) -> Hertz3d {
    let template = std::fs::read_to_string(validation_dir().join("hertz3d.toml")).unwrap();
    let mesh_path = validation_dir().join(format!("hertz3d_h{mesh}.msh"));
    let replacements = [
        (
            "file = \"hertz3d_h0.007.msh\"",
            format!("file = \"{}\"", mesh_path.display()),
        ),
        ("stiffness = 1e6", format!("stiffness = {stiffness:e}")),
    ];
    let result = run(
        &template,
        &replacements,
        &format!("hertz3d-{mesh}-{stiffness:e}"),
    );
    hertz3d_result(&result, 4.0, 1.0, 1.0, 0.3)
}

/// The Hertz quantities of a 3D run that holds the share 1/`parts` of the body (4 for a
/// quarter), for a sphere of radius `radius` and the material (`young`, `poisson`).
fn hertz3d_result(result: &Run, parts: f64, radius: f64, young: f64, poisson: f64) -> Hertz3d {
    let last = result.history.last().unwrap();
    let load = parts * last["force_z"];
    let records = read_contact_history(&result.out.join("contact_history.csv")).unwrap();
    let final_step = records.last().unwrap().step;
    let pressures: Vec<(f64, f64)> = records
        .iter()
        .filter(|r| r.step == final_step)
        .map(|r| (r.coordinate, r.normal_pressure))
        .collect();
    let (peak, profile_radius) =
        pressure_ellipse(&pressures).expect("fewer than two nodes in the contact zone");
    let modulus = young / (1.0 - poisson * poisson);
    let hertz_radius = (3.0 * load * radius / (4.0 * modulus)).cbrt();
    Hertz3d {
        load,
        area_radius: (parts * last["contact_zone"] / std::f64::consts::PI).sqrt(),
        profile_radius,
        peak,
        hertz_radius,
        hertz_peak: 3.0 * load / (2.0 * std::f64::consts::PI * hertz_radius * hertz_radius),
        newton: result
            .history
            .iter()
            .map(|row| row["newton_iterations"] as usize)
            .collect(),
        pressures,
        seconds: result.seconds,
    }
}

/// The hemisphere on a flat (curved second-order mesh, P2), whole and as a quarter with its
/// symmetry planes through the contact disc: against Hertz and against each other.
fn hemisphere() -> String {
    let template = std::fs::read_to_string(validation_dir().join("hemisphere.toml")).unwrap();
    let mut table = String::from(
        "Against a = (3PR/4E*)^(1/3) and p0 = 3P/(2πa²) for the measured load P (R = 1.5, E = 2, \
         ν = 0.4, δ = 0.0075, c_ν = 1e6; the quarter's P is four times its load). a (area) is \
         √(area/π) of the contact zone (of the four quarters), a (profile) the radius of the \
         ellipse through the nodal pressures along y = 0, x > 0; p0 the largest nodal pressure.\n\n\
         | model | P | a/R | a (area) | a (profile) | p0 | error a (area) | error a (profile) | error p0 | Newton per step | time |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut results = Vec::new();
    for (model, mesh, parts) in [
        ("whole", "hemisphere_h0.022.msh", 1.0),
        ("quarter", "hemisphere_quarter_h0.022.msh", 4.0),
    ] {
        let mesh_path = validation_dir().join(mesh);
        let mut replacements = vec![(
            "file = \"hemisphere_h0.022.msh\"",
            format!("file = \"{}\"", mesh_path.display()),
        )];
        if parts > 1.0 {
            replacements.push((
                "z = \"-delta*min(t, 1)\"\n",
                "z = \"-delta*min(t, 1)\"\n\n[[displacement]]\npart = \"sym_x\"\nx = \"0\"\nsymmetry = true\n\n\
                 [[displacement]]\npart = \"sym_y\"\ny = \"0\"\nsymmetry = true\n"
                    .to_string(),
            ));
        }
        let result = run(&template, &replacements, &format!("hemisphere-{model}"));
        let h = hertz3d_result(&result, parts, 1.5, 2.0, 0.4);
        writeln!(table, "| {model} | {}", h.row(1.5)).unwrap();
        results.push(h);
    }
    let (whole, quarter) = (&results[0], &results[1]);
    let fits: Vec<(f64, f64)> = results.iter().map(|h| pressure_fit(&h.pressures)).collect();
    writeln!(
        table,
        "\nLeast-squares fit p² = p0² (1 − s²/a²) over the nodes of the profile with p > 0.2 max p: \
         whole p0 = {:.5} ({:+.2} %), a = {:.5} ({:+.2} %); quarter p0 = {:.5} ({:+.2} %), a = {:.5} ({:+.2} %).",
        fits[0].0,
        percent(fits[0].0, whole.hertz_peak),
        fits[0].1,
        percent(fits[0].1, whole.hertz_radius),
        fits[1].0,
        percent(fits[1].0, quarter.hertz_peak),
        fits[1].1,
        percent(fits[1].1, quarter.hertz_radius),
    )
    .unwrap();
    writeln!(
        table,
        "\nQuarter against whole: P {:+.3} %, a (area) {:+.3} %, a (profile) {:+.3} %, p0 {:+.3} %.",
        percent(quarter.load, whole.load),
        percent(quarter.area_radius, whole.area_radius),
        percent(quarter.profile_radius, whole.profile_radius),
        percent(quarter.peak, whole.peak),
    )
    .unwrap();
    pressure_svg(
        &report_dir().join("hemisphere_pressure.svg"),
        &whole.pressures,
        whole.hertz_radius,
        whole.hertz_peak,
        "Hemisphere on a flat: pressure along a radius",
        "whole hemisphere, curved P2, h = 0.022 at the contact, c_ν = 1e6, ν = 0.4",
    );
    table
}

/// The 3D Hertz validation: a table over meshes × c_ν and the pressure along a radius.
fn hertz3d(quick: bool) -> String {
    let meshes: &[&str] = if quick {
        &["0.02"]
    } else {
        &["0.02", "0.01", "0.007"]
    };
    let stiffnesses: &[f64] = if quick { &[1e6] } else { &[1e4, 1e6] };
    let mut table = String::from(
        "Against a = (3PR/4E*)^(1/3) and p0 = 3P/(2πa²) for the measured load P (E = 1, ν = 0.3, R = 1, \
         δ = 0.0036; P is four times the load of the quarter). a (area) is √(area/π) of the contact \
         zone, a (profile) the radius of the ellipse through the nodal pressures along y = 0.\n\n\
         | h at contact | c_ν | P | a/R | a (area) | a (profile) | p0 | error a (area) | error a (profile) | error p0 | Newton per step | time |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut profile = None;
    for mesh in meshes {
        for &stiffness in stiffnesses {
            let h = hertz3d_run(mesh, stiffness);
            writeln!(table, "| {mesh} | {stiffness:.0e} | {}", h.row(1.0)).unwrap();
            profile = Some((mesh.to_string(), stiffness, h));
        }
    }
    let (mesh, stiffness, h) = profile.unwrap();
    pressure_svg(
        &report_dir().join("hertz3d_pressure.svg"),
        &h.pressures,
        h.hertz_radius,
        h.hertz_peak,
        "Hertz sphere on a flat: pressure along a radius",
        &format!("h = {mesh}, c_ν = {stiffness:.0e}, ν = 0.3"),
    );
    table
}

/// The least-squares fit p² = A + B s² over the nodal pressures with p > 0.2 max p: the peak
/// p0 = √A and the radius a = √(−A/B).
fn pressure_fit(pressures: &[(f64, f64)]) -> (f64, f64) {
    let largest = pressures.iter().fold(0.0f64, |m, p| m.max(p.1));
    let points: Vec<(f64, f64)> = pressures
        .iter()
        .filter(|(_, p)| *p > 0.2 * largest)
        .map(|(s, p)| (s * s, p * p))
        .collect();
    let count = points.len() as f64;
    let (sx, sy) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mean_x, mean_y) = (sx / count, sy / count);
    let (covariance, variance) = points.iter().fold((0.0, 0.0), |(c, v), (x, y)| {
        (
            c + (x - mean_x) * (y - mean_y),
            v + (x - mean_x) * (x - mean_x),
        )
    });
    let slope = covariance / variance;
    let intercept = mean_y - slope * mean_x;
    (intercept.sqrt(), (-intercept / slope).sqrt())
}

/// The computed nodal pressures against the Hertz profile p0 √(1 − x²/a²).
fn pressure_svg(
    path: &Path,
    pressures: &[(f64, f64)],
    width: f64,
    peak: f64,
    title: &str,
    label: &str,
) {
    let root = SVGBackend::new(path, (720, 420)).into_drawing_area();
    root.fill(&WHITE).unwrap();
    let range = 1.6 * width;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{title} ({label})"), ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(-range..range, 0.0..1.15 * peak)
        .unwrap();
    chart
        .configure_mesh()
        .x_desc("x")
        .y_desc("normal pressure p_ν")
        .draw()
        .unwrap();
    let curve: Vec<(f64, f64)> = (0..=400)
        .map(|i| {
            let x = -range + 2.0 * range * i as f64 / 400.0;
            let p = if x.abs() < width {
                peak * (1.0 - (x / width).powi(2)).sqrt()
            } else {
                0.0
            };
            (x, p)
        })
        .collect();
    chart
        .draw_series(LineSeries::new(curve, BLACK.stroke_width(2)))
        .unwrap()
        .label("Hertz p0 √(1 − x²/a²) (P measured)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    chart
        .draw_series(
            pressures
                .iter()
                .filter(|(x, _)| x.abs() <= range)
                .map(|&(x, p)| Circle::new((x, p), 3, RED.filled())),
        )
        .unwrap()
        .label("computed nodal p_ν")
        .legend(|(x, y)| Circle::new((x + 10, y), 3, RED.filled()));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .unwrap();
    root.present().unwrap();
}

/// Per row of a dragged block's history: the drag s of its top (1e-4 per unit time after
/// t = 1) and Q/(μ P_(n−1)), the friction resultant against the bound of the step (None in the
/// first step, which has no previous load).
fn drag_ratios(history: &[BTreeMap<String, f64>], friction: f64) -> Vec<(f64, Option<f64>)> {
    let drag_per_step = 1e-4;
    let mut previous_load = f64::NAN;
    history
        .iter()
        .map(|row| {
            let ratio = row["tangential_force"] / (friction * previous_load);
            previous_load = row["normal_force"];
            let drag = drag_per_step * (row["t"] - 1.0).max(0.0);
            (drag, ratio.is_finite().then_some(ratio))
        })
        .collect()
}

/// A ratio for a table: six decimals, or a dash where there is none.
fn ratio_cell(ratio: Option<f64>) -> String {
    ratio.map_or_else(|| "—".into(), |r| format!("{r:.6}"))
}

/// The sliding block: tangential resultant against μP as the drag grows. The friction bound of
/// step n is p_τ at u_{n−1} (5.1), so once the whole face slips Q_n = μ P_{n−1} exactly.
fn sliding() -> String {
    let template = std::fs::read_to_string(validation_dir().join("sliding.toml")).unwrap();
    let result = run(&template, &[], "sliding");
    let mut table = String::from(
        "| step | drag s | P | Q | Q/(μ P_(n−1)) | reaction x + force x | stick | slip |\n|---|---|---|---|---|---|---|---|\n",
    );
    let drags = drag_ratios(&result.history, 0.3);
    for (row, &(drag, ratio)) in result.history.iter().zip(&drags) {
        writeln!(
            table,
            "| {} | {drag:.4} | {:.6e} | {:.6e} | {} | {:.1e} | {} | {} |",
            row["step"],
            row["normal_force"],
            row["tangential_force"],
            ratio_cell(ratio),
            row["reaction_y_max_x"] + row["force_x"],
            row["stick"],
            row["slip"]
        )
        .unwrap();
    }
    let ratios: Vec<(f64, f64)> = drags
        .iter()
        .filter_map(|&(drag, ratio)| ratio.map(|r| (drag, r)))
        .collect();
    writeln!(table, "\n({:.1} s)", result.seconds).unwrap();
    ratio_svg(
        &report_dir().join("sliding.svg"),
        "Sliding block: tangential resultant Q / (μP)",
        &ratios,
    );
    table
}

/// Q/(μP) against the drag, as a curve with its points.
fn ratio_svg(path: &Path, title: &str, ratios: &[(f64, f64)]) {
    let root = SVGBackend::new(path, (720, 380)).into_drawing_area();
    root.fill(&WHITE).unwrap();
    let end = ratios.last().map_or(1.0, |r| r.0);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..end, 0.0..1.1)
        .unwrap();
    chart
        .configure_mesh()
        .x_desc("drag s of the top side")
        .y_desc("Q/(μP)")
        .draw()
        .unwrap();
    chart
        .draw_series(LineSeries::new(ratios.to_vec(), RED.stroke_width(2)))
        .unwrap();
    chart
        .draw_series(
            ratios
                .iter()
                .map(|&(s, r)| Circle::new((s, r), 3, RED.filled())),
        )
        .unwrap();
    root.present().unwrap();
}

/// The sliding block in 3D, dragged at 30° to its long side: Q against μ P_(n−1) and the
/// direction of the friction force against the drag's. Once the whole face slips, every node's
/// friction opposes its own slip, so Q ≤ μ P_(n−1) with equality when the slip is uniform:
/// Q/(μP) and the direction tend to 1 and 30° as the block settles into a rigid translation.
fn sliding3d() -> String {
    let template = std::fs::read_to_string(validation_dir().join("sliding3d.toml")).unwrap();
    let result = run(&template, &[], "sliding3d");
    let mut table = String::from(
        "| step | drag s | P | Q | Q/(μ P_(n−1)) | direction of −F_τ | reaction + force (x, y) | stick | slip | Newton |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let drags = drag_ratios(&result.history, 0.3);
    for (row, &(drag, ratio)) in result.history.iter().zip(&drags) {
        let direction = if row["tangential_force"] > 0.0 {
            format!(
                "{:.3}°",
                (-row["force_y"]).atan2(-row["force_x"]).to_degrees()
            )
        } else {
            "—".into()
        };
        writeln!(
            table,
            "| {} | {drag:.4} | {:.6e} | {:.6e} | {} | {direction} | {:.1e}, {:.1e} | {} | {} | {} |",
            row["step"],
            row["normal_force"],
            row["tangential_force"],
            ratio_cell(ratio),
            row["reaction_z_max_x"] + row["force_x"],
            row["reaction_z_max_y"] + row["force_y"],
            row["stick"],
            row["slip"],
            row["newton_iterations"]
        )
        .unwrap();
    }
    let ratios: Vec<(f64, f64)> = drags
        .iter()
        .filter_map(|&(drag, ratio)| ratio.map(|r| (drag, r)))
        .collect();
    writeln!(table, "\n({:.1} s)", result.seconds).unwrap();
    ratio_svg(
        &report_dir().join("sliding3d.svg"),
        "Sliding block in 3D: tangential resultant Q / (μP)",
        &ratios,
    );
    table
}

/// The stick zone's size c/a against Q/(μP): the theory's curve `theory` (label, function) and
/// the computed points of each labelled curve.
fn stick_svg(
    path: &Path,
    title: &str,
    theory: (&str, fn(f64) -> f64),
    curves: &[(String, Vec<(f64, f64)>)],
) {
    let root = SVGBackend::new(path, (640, 420)).into_drawing_area();
    root.fill(&WHITE).unwrap();
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..1.0, 0.0..1.05)
        .unwrap();
    chart
        .configure_mesh()
        .x_desc("Q/(μP)")
        .y_desc("c/a")
        .draw()
        .unwrap();
    let (label, curve) = theory;
    chart
        .draw_series(LineSeries::new(
            (0..=100).map(|i| {
                let q = i as f64 / 100.0;
                (q, curve(q))
            }),
            BLACK.stroke_width(2),
        ))
        .unwrap()
        .label(label)
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    for ((label, points), colour) in curves.iter().zip([RED, BLUE]) {
        chart
            .draw_series(
                points
                    .iter()
                    .map(|&(q, c)| Circle::new((q, c), 4, colour.filled())),
            )
            .unwrap()
            .label(label)
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, colour.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .unwrap();
    root.present().unwrap();
}

/// Mindlin partial slip in 3D: per tangential step, the stick radius c along the diameter
/// y = 0 in the direction of the load (half the extent of the loaded nodes that stick) against
/// a (1 − Q/(μP))^(1/3), a from the pressure profile of the same step; on each mesh.
fn mindlin3d(quick: bool) -> String {
    let template = std::fs::read_to_string(validation_dir().join("mindlin3d.toml")).unwrap();
    let friction = 0.5;
    let meshes: &[&str] = if quick { &["0.02"] } else { &["0.02", "0.01"] };
    let mut table = String::from(
        "Half of the block (symmetry plane y = 0), E = 1, ν = 0.3, μ = 0.5, R = 1, δ = 0.0036 \
         (a/R = 0.061), c_ν = 1e6; P and Q are twice the loads of the half; s is the \
         coordinate along the diameter y = 0 from its centre.\n\n",
    );
    let mut curves = Vec::new();
    let mut compliances = Vec::new();
    for mesh in meshes {
        let mesh_path = validation_dir().join(format!("mindlin3d_h{mesh}.msh"));
        let replacements = [(
            "file = \"mindlin3d_h0.01.msh\"",
            format!("file = \"{}\"", mesh_path.display()),
        )];
        let result = run(&template, &replacements, &format!("mindlin3d-{mesh}"));
        let records = read_contact_history(&result.out.join("contact_history.csv")).unwrap();
        writeln!(
            table,
            "h = {mesh} at the contact ({:.1} s):\n\n| step | Q/(μP) | c/a | (1 − Q/(μP))^(1/3) | difference | stick zone centre / a | Newton | friction iterations |\n|---|---|---|---|---|---|---|---|",
            result.seconds
        )
        .unwrap();
        compliances.push((
            mesh.to_string(),
            mindlin_compliance(&result.history, friction),
        ));
        let mut points = Vec::new();
        for row in result.history.iter().skip(1) {
            let step = row["step"] as usize;
            // the profile runs from x = −0.2: s − 0.2 is x, centred on the contact
            let (radius, stick) = profile_zone(&records, step, 0.2).expect("no contact zone");
            let (stick, centre) = stick.unwrap_or((0.0, 0.0));
            let ratio = row["tangential_force"] / (friction * row["normal_force"]);
            let stick_ratio = stick / radius;
            let theory = (1.0 - ratio).max(0.0).cbrt();
            writeln!(
                table,
                "| {step} | {ratio:.3} | {stick_ratio:.3} | {theory:.3} | {:+.3} | {:+.3} | {} | {} |",
                stick_ratio - theory,
                centre / radius,
                row["newton_iterations"],
                row["friction_iterations"]
            )
            .unwrap();
            points.push((ratio, stick_ratio));
        }
        table.push('\n');
        curves.push((mesh.to_string(), points));
    }
    let curves: Vec<(String, Vec<(f64, f64)>)> = curves
        .into_iter()
        .map(|(mesh, points)| (format!("computed, h = {mesh}"), points))
        .collect();
    stick_svg(
        &report_dir().join("mindlin3d.svg"),
        "Mindlin in 3D: stick radius c/a",
        ("(1 − Q/(μP))^(1/3)", |q| (1.0 - q).cbrt()),
        &curves,
    );
    table.push_str(MINDLIN_COMPLIANCE);
    for (mesh, rows) in compliances {
        table.push_str(&rows.replace("{mesh}", &mesh));
    }
    table
}

const MINDLIN_COMPLIANCE: &str = "**Tangential compliance.** The face z = 1 is shifted by s = 2e-4 (n − 1) at step n. Mindlin's compliance of an elastic half-space on a rigid sphere is δ_M(Q) = 3(2 − ν)μP/(16Ga) [1 − (1 − Q/(μP))^(2/3)] (Johnson, Contact Mechanics, (7.42)), a the Hertz radius of the measured load. The block is not a half-space: its top is at a finite distance from the contact, and it shears. A compliance C_b Q linear in Q, fitted by least squares over the partial-slip steps (Q < 0.95 μP), measures that difference; the table gives s − δ_M(Q) in % of δ_M(μP):\n\n";

/// The tangential compliance of a Mindlin run (see [`MINDLIN_COMPLIANCE`]): a table of s, Q,
/// δ_M(Q) and s − δ_M(Q) per step after the normal load, and the fitted C_b; `{mesh}` stands
/// for the mesh in its heading.
fn mindlin_compliance(history: &[BTreeMap<String, f64>], friction: f64) -> String {
    let (young, poisson, radius, shift) = (1.0, 0.3, 1.0, 2e-4);
    let shear = young / (2.0 * (1.0 + poisson));
    let plane = young / (1.0 - poisson * poisson);
    // per step after the normal load: step, s, Q/(μP), δ_M(Q), δ_M(μP), Q (the half's, doubled)
    let rows: Vec<(usize, f64, f64, f64, f64, f64)> = history
        .iter()
        .skip(1)
        .map(|row| {
            let step = row["step"] as usize;
            let (load, force) = (2.0 * row["normal_force"], 2.0 * row["tangential_force"]);
            let a = (3.0 * load * radius / (4.0 * plane)).cbrt();
            let full = 3.0 * (2.0 - poisson) * friction * load / (16.0 * shear * a);
            let ratio = (force / (friction * load)).min(1.0);
            let mindlin = full * (1.0 - (1.0 - ratio).powf(2.0 / 3.0));
            (
                step,
                shift * (step as f64 - 1.0),
                ratio,
                mindlin,
                full,
                force,
            )
        })
        .collect();
    let partial = rows.iter().filter(|r| r.2 < 0.95);
    let numerator: f64 = partial.clone().map(|r| r.5 * (r.1 - r.3)).sum();
    let denominator: f64 = partial.map(|r| r.5 * r.5).sum();
    let block = numerator / denominator;
    let mut table = format!(
        "h = {{mesh}}: fitted C_b = {block:.4} (Mindlin's compliance at Q = μP/2 is {:.1} per unit Q)\n\n| step | Q/(μP) | s | δ_M(Q) | (s − δ_M) / δ_M(μP) |\n|---|---|---|---|---|\n",
        rows.iter()
            .min_by(|a, b| (a.2 - 0.5).abs().total_cmp(&(b.2 - 0.5).abs()))
            .map_or(f64::NAN, |r| r.3 / r.5)
    );
    for &(step, s, ratio, mindlin, full, _) in &rows {
        writeln!(
            table,
            "| {step} | {ratio:.3} | {s:.2e} | {mindlin:.3e} | {:+.2} % |",
            100.0 * (s - mindlin) / full
        )
        .unwrap();
    }
    table.push('\n');
    table
}

/// Cattaneo–Mindlin partial slip: per tangential step, the stick half-width c (half the extent
/// of the loaded nodes that stick; node-quantized to ±h/2 per side) against
/// a √(1 − Q/(μP)), a from the pressure profile of the same step, for ν = 0.3 and 0.49.
fn cattaneo(quick: bool) -> String {
    let template = std::fs::read_to_string(validation_dir().join("cattaneo.toml")).unwrap();
    let friction = 0.5;
    let mesh = if quick { "0.01" } else { "0.0025" };
    let mut table = String::new();
    let mut curves = Vec::new();
    for poisson in [0.3, 0.49] {
        let mesh_path = validation_dir().join(format!("hertz_h{mesh}.msh"));
        let mut replacements = vec![(
            "file = \"hertz_h0.0025.msh\"",
            format!("file = \"{}\"", mesh_path.display()),
        )];
        replacements.extend(material(poisson));
        let result = run(&template, &replacements, &format!("cattaneo-{poisson}"));
        let records = read_contact_history(&result.out.join("contact_history.csv")).unwrap();
        writeln!(
            table,
            "ν = {poisson}, h = {mesh} at the contact ({:.1} s):\n\n| step | Q/(μP) | c/a | √(1 − Q/(μP)) | difference | stick zone centre / a |\n|---|---|---|---|---|---|",
            result.seconds
        )
        .unwrap();
        let mut points = Vec::new();
        for row in result.history.iter().skip(1) {
            let step = row["step"] as usize;
            let (half_width, stick) = profile_zone(&records, step, 0.0).expect("no contact zone");
            let (stick, centre) = stick.unwrap_or((0.0, 0.0));
            let ratio = row["tangential_force"] / (friction * row["force_y"]);
            let stick_ratio = stick / half_width;
            let theory = (1.0 - ratio).max(0.0).sqrt();
            writeln!(
                table,
                "| {step} | {ratio:.3} | {stick_ratio:.3} | {theory:.3} | {:+.3} | {:+.3} |",
                stick_ratio - theory,
                centre / half_width
            )
            .unwrap();
            points.push((ratio, stick_ratio));
        }
        table.push('\n');
        curves.push((poisson, points));
    }
    let curves: Vec<(String, Vec<(f64, f64)>)> = curves
        .into_iter()
        .map(|(poisson, points)| (format!("computed, ν = {poisson}"), points))
        .collect();
    stick_svg(
        &report_dir().join("cattaneo.svg"),
        "Cattaneo–Mindlin: stick half-width c/a",
        ("√(1 − Q/(μP))", |q| (1.0 - q).sqrt()),
        &curves,
    );
    table
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let which = args
        .iter()
        .find(|a| !a.starts_with("--"))
        .map_or("all", String::as_str);
    std::fs::create_dir_all(report_dir()).unwrap();
    let mut reports = Vec::new();
    if which == "hertz" || which == "all" {
        reports.push(("hertz", hertz(quick)));
    }
    if which == "hertz3d" || which == "all" {
        reports.push(("hertz3d", hertz3d(quick)));
    }
    if which == "hemisphere" || which == "all" {
        reports.push(("hemisphere", hemisphere()));
    }
    if which == "cattaneo" || which == "all" {
        reports.push(("cattaneo", cattaneo(quick)));
    }
    if which == "mindlin3d" || which == "all" {
        reports.push(("mindlin3d", mindlin3d(quick)));
    }
    if which == "sliding" || which == "all" {
        reports.push(("sliding", sliding()));
    }
    if which == "sliding3d" || which == "all" {
        reports.push(("sliding3d", sliding3d()));
    }
    for (name, table) in reports {
        println!("## {name}\n\n{table}");
        let text = format!(
            "# Validation: {name}\n\n`cargo run --release -p simulate --example validation -- {name}{}`\n\n{table}",
            if quick { " --quick" } else { "" }
        );
        std::fs::write(report_dir().join(format!("{name}.md")), text).unwrap();
    }
}
