//! SVG pictures of a run: the damage field at chosen times and the contact history on Γ3.
//!
//! - `damage_NNNNNN.svg`: β_n on the mesh (2D: every triangle filled with the colour of the mean
//!   of its nodal values), or on the contact face Γ3 (3D: its facets projected onto the plane
//!   of the face), with a colour bar 0..1;
//! - `contact_history.svg`: along a line of Γ3, the contact status (separated, stick, slip) of
//!   every saved step (`output.every`) as a space–time map, and below it the normal pressure
//!   p_ν and the accumulated slip Σ_{m ≤ n} k |v_{m,τ}| at a few times.
//!
//! The contact history is drawn from `contact_history.csv` (one row per contact node of the
//! line and saved step, appended during the run and truncated on `--resume` like
//! `history.csv`), so that a resumed run draws the whole run. Which nodes make the line, and
//! the coordinate `s` along it: [`crate::contact_line`].

use crate::contact_line::{axis_of_spread, AXIS_NAMES};
use contact_damage::fem::mesh::BoundaryPart;
use contact_damage::fem::space::LagrangeSpace;
use contact_input::output::write_atomic;
use contact_input::InputError;
use plotters::prelude::*;
use std::path::Path;

/// Name of the per-node contact history.
pub const CONTACT_HISTORY_FILE: &str = "contact_history.csv";
/// Header of the per-node contact history (status: 0 separated, 1 stick, 2 slip; slip_rate
/// |v_{n,τ}|; accumulated_slip Σ_{m ≤ n} k |v_{m,τ}|).
pub const CONTACT_HISTORY_HEADER: &str =
    "step,t,s,status,normal_pressure,slip_rate,accumulated_slip";
/// Name of the contact history picture.
pub const CONTACT_HISTORY_PICTURE: &str = "contact_history.svg";
/// Legend of the contact status values 0, 1, 2.
pub const STATUS_LABELS: [&str; 3] = ["separated", "stick", "slip"];
/// Colours of the contact status values 0, 1, 2 (grey, blue, orange).
const STATUS_COLORS: [RGBColor; 3] = [
    RGBColor(200, 200, 200),
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
];

/// File name of the damage picture of step n.
pub fn damage_picture_file(step: usize) -> String {
    format!("damage_{step:06}.svg")
}

/// Steps n = round(t / k), clamped to 1..=N, of the picture times `times` (sorted, unique).
pub fn picture_steps(times: &[f64], time_step: f64, steps: usize) -> Vec<usize> {
    let mut chosen: Vec<usize> = times
        .iter()
        .map(|t| ((t / time_step).round() as usize).clamp(1, steps))
        .collect();
    chosen.sort_unstable();
    chosen.dedup();
    chosen
}

/// Colour of β ∈ [0, 1] on the viridis scale (dark violet at 0 = fully damaged, yellow at
/// 1 = sound), linear between five anchor colours; values outside are clamped.
pub fn damage_color(beta: f64) -> RGBColor {
    const ANCHORS: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let position = if beta.is_nan() {
        0.0
    } else {
        beta.clamp(0.0, 1.0)
    } * 4.0;
    let low = (position.floor() as usize).min(3);
    let weight = position - low as f64;
    let (a, b) = (ANCHORS[low], ANCHORS[low + 1]);
    let mix = |x: f64, y: f64| (x + weight * (y - x)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// A row of `contact_history.csv`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactRecord {
    /// n.
    pub step: usize,
    /// t_n.
    pub time: f64,
    /// Coordinate along Γ3.
    pub coordinate: f64,
    /// 0 separated, 1 stick, 2 slip.
    pub status: usize,
    /// p_ν used in step n.
    pub normal_pressure: f64,
    /// |v_{n,τ}|.
    pub slip_rate: f64,
    /// Σ_{m ≤ n} k |v_{m,τ}|.
    pub accumulated_slip: f64,
}

fn parse_record(line: &str) -> Option<ContactRecord> {
    let fields: Vec<&str> = line.split(',').collect();
    if fields.len() != 7 {
        return None;
    }
    let record = ContactRecord {
        step: fields[0].parse().ok()?,
        time: fields[1].parse().ok()?,
        coordinate: fields[2].parse().ok()?,
        status: fields[3].parse().ok()?,
        normal_pressure: fields[4].parse().ok()?,
        slip_rate: fields[5].parse().ok()?,
        accumulated_slip: fields[6].parse().ok()?,
    };
    (record.status <= 2 && record.time.is_finite() && record.coordinate.is_finite())
        .then_some(record)
}

/// Reads `contact_history.csv`; a malformed row is an error naming its line.
pub fn read_contact_history(path: &Path) -> Result<Vec<ContactRecord>, InputError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::io("reading contact history", path, e))?;
    let mut lines = text.lines();
    if lines.next() != Some(CONTACT_HISTORY_HEADER) {
        return Err(InputError::InvalidInput(format!(
            "{}: the first line is not the contact history header",
            path.display()
        )));
    }
    lines
        .enumerate()
        .map(|(index, line)| {
            parse_record(line).ok_or_else(|| {
                InputError::InvalidInput(format!(
                    "{}:{}: expected `{CONTACT_HISTORY_HEADER}`, found `{line}`",
                    path.display(),
                    index + 2
                ))
            })
        })
        .collect()
}

/// Keeps the header and the rows of the `recorded_steps` (the saved steps up to the one resumed
/// from) of `contact_history.csv` — there must be exactly `rows_per_step` complete rows of
/// each, in order — and drops the rest (steps done after the last saved step, possibly a row
/// cut short by a crash); rewritten atomically.
pub fn truncate_contact_history(
    path: &Path,
    recorded_steps: &[usize],
    rows_per_step: usize,
) -> Result<(), InputError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::io("reading contact history", path, e))?;
    let mut lines = text.lines();
    if lines.next() != Some(CONTACT_HISTORY_HEADER) {
        return Err(InputError::InvalidInput(format!(
            "{}: the first line is not the contact history header",
            path.display()
        )));
    }
    let mut kept = format!("{CONTACT_HISTORY_HEADER}\n");
    for row in 0..recorded_steps.len() * rows_per_step {
        let expected = recorded_steps[row / rows_per_step];
        let line = lines.next().unwrap_or("");
        if parse_record(line).map(|r| r.step) != Some(expected) {
            return Err(InputError::InvalidInput(format!(
                "{}:{}: expected a complete row of step {expected}, found `{line}`",
                path.display(),
                row + 2
            )));
        }
        kept.push_str(line);
        kept.push('\n');
    }
    write_atomic(path, kept.as_bytes())
}

fn plot_error(path: &Path) -> impl Fn(&dyn std::fmt::Display) -> InputError + '_ {
    move |error| InputError::Plot {
        path: path.to_path_buf(),
        message: error.to_string(),
    }
}

/// Range [low, high] of `values` padded by 2% (or ±1 if empty or flat).
fn padded_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (low, high) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |acc, v| {
        (acc.0.min(v), acc.1.max(v))
    });
    if !(low.is_finite() && high.is_finite()) {
        return (-1.0, 1.0);
    }
    let pad = 0.02 * (high - low);
    if pad > 0.0 {
        (low - pad, high + pad)
    } else {
        (low - 1.0, high + 1.0)
    }
}

/// Draws β (`damage`, nodal values of `space`) at time `time` into the SVG file `path`: in 2D
/// on every cell, in 3D on the facets of Γ3 projected onto the plane of the face; each
/// polygon has the colour ([`damage_color`]) of the mean of its nodal values.
pub fn damage_svg<const D: usize>(
    path: &Path,
    space: &LagrangeSpace<D>,
    damage: &[f64],
    step: usize,
    time: f64,
) -> Result<(), InputError> {
    let mesh = space.mesh();
    // polygons (projected vertex coordinates) and their mean β
    let mut polygons: Vec<(Vec<(f64, f64)>, f64)> = Vec::new();
    let mean = |nodes: &[usize]| nodes.iter().map(|&a| damage[a]).sum::<f64>() / nodes.len() as f64;
    let (first, second, where_) = if D == 2 {
        for c in 0..mesh.num_cells() {
            let corners = mesh
                .cell(c)
                .iter()
                .map(|&v| {
                    let x = mesh.vertex(v);
                    (x[0], x[1])
                })
                .collect();
            polygons.push((corners, mean(space.cell_nodes(c))));
        }
        (0, 1, "Ω")
    } else {
        let facets: Vec<usize> = (0..mesh.num_facets())
            .filter(|&f| mesh.facet_part(f) == BoundaryPart::Contact)
            .collect();
        let points: Vec<[f64; D]> = facets
            .iter()
            .flat_map(|&f| mesh.facet(f).iter().map(|&v| mesh.vertex(v)))
            .collect();
        if points.is_empty() {
            return Err(InputError::InvalidInput(
                "the damage picture of a 3D run needs a contact face Γ3, and it is empty".into(),
            ));
        }
        let all: Vec<usize> = (0..D).collect();
        let normal = axis_of_spread(&points, true, &all);
        let in_plane: Vec<usize> = all.into_iter().filter(|&i| i != normal).collect();
        for &f in &facets {
            let corners = mesh
                .facet(f)
                .iter()
                .map(|&v| {
                    let x = mesh.vertex(v);
                    (x[in_plane[0]], x[in_plane[1]])
                })
                .collect();
            polygons.push((corners, mean(space.facet_nodes(f))));
        }
        (in_plane[0], in_plane[1], "Γ3")
    };
    let (x_low, x_high) = padded_range(polygons.iter().flat_map(|(c, _)| c.iter().map(|p| p.0)));
    let (y_low, y_high) = padded_range(polygons.iter().flat_map(|(c, _)| c.iter().map(|p| p.1)));
    // keep the aspect ratio of the domain: 740 px for the width of the mesh
    let plot_height = (740.0 * (y_high - y_low) / (x_high - x_low)).clamp(200.0, 900.0);
    let size = (900, plot_height as u32 + 110);
    let error = plot_error(path);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| error(&e))?;
        let (left, right) = root.split_horizontally(size.0 - 120);
        let left = left
            .titled(
                &format!("damage β on {where_}, step {step}, t = {time:.4}"),
                ("sans-serif", 20),
            )
            .map_err(|e| error(&e))?;
        // one length unit is as many pixels along both axes (a circle stays round): the
        // plotting area is what the margins (10) and label areas (45, 35) leave
        let (width, height) = left.dim_in_pixel();
        let plot_width = f64::from(width.saturating_sub(2 * 10 + 45).max(1));
        let plot_height = f64::from(height.saturating_sub(2 * 10 + 35).max(1));
        let scale = ((x_high - x_low) / plot_width).max((y_high - y_low) / plot_height);
        let widen = |low: f64, high: f64, pixels: f64| {
            let middle = 0.5 * (low + high);
            (middle - 0.5 * scale * pixels, middle + 0.5 * scale * pixels)
        };
        let (x_low, x_high) = widen(x_low, x_high, plot_width);
        let (y_low, y_high) = widen(y_low, y_high, plot_height);
        let mut chart = ChartBuilder::on(&left)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .build_cartesian_2d(x_low..x_high, y_low..y_high)
            .map_err(|e| error(&e))?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(AXIS_NAMES[first])
            .y_desc(AXIS_NAMES[second])
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .draw()
            .map_err(|e| error(&e))?;
        chart
            .draw_series(
                polygons
                    .into_iter()
                    .map(|(corners, beta)| Polygon::new(corners, damage_color(beta).filled())),
            )
            .map_err(|e| error(&e))?;

        let mut bar = ChartBuilder::on(&right)
            .caption("β", ("sans-serif", 18))
            .margin_top(10)
            .margin_bottom(45)
            .margin_right(45)
            .y_label_area_size(0)
            .right_y_label_area_size(45)
            .build_cartesian_2d(0.0..1.0, 0.0..1.0)
            .map_err(|e| error(&e))?;
        bar.configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .y_labels(6)
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| error(&e))?;
        const BANDS: usize = 50;
        bar.draw_series((0..BANDS).map(|i| {
            let (low, high) = (i as f64 / BANDS as f64, (i + 1) as f64 / BANDS as f64);
            Rectangle::new(
                [(0.0, low), (1.0, high)],
                damage_color(0.5 * (low + high)).filled(),
            )
        }))
        .map_err(|e| error(&e))?;
        root.present().map_err(|e| error(&e))?;
    }
    // no anti-aliasing of the polygons: it would show hairline seams between the cells
    let svg = svg.replacen("<svg ", "<svg shape-rendering=\"crispEdges\" ", 1);
    write_atomic(path, svg.as_bytes())
}

/// Draws the contact history `records` (rows of `contact_history.csv`, in step order) into
/// the SVG file `path`: the status of every node along Γ3 (`coordinate_label`) and step as a
/// space–time map, and the normal pressure and the accumulated slip along Γ3 at the steps
/// `pressure_steps` (those without records are left out).
pub fn contact_history_svg(
    path: &Path,
    records: &[ContactRecord],
    coordinate_label: &str,
    pressure_steps: &[usize],
) -> Result<(), InputError> {
    if records.is_empty() {
        return Err(InputError::InvalidInput(format!(
            "{}: no contact history to draw (no contact node or no step)",
            path.display()
        )));
    }
    let (steps, coordinates) = records_by_step(path, records)?;
    let count = coordinates.len();
    let last_time = steps[steps.len() - 1][0].time;
    let rectangles = status_rectangles(&steps, &coordinates);
    let (s_low, s_high) = (coordinates[0], coordinates[count - 1]);
    let s_range = if s_high > s_low {
        (s_low, s_high)
    } else {
        (s_low - 1.0, s_high + 1.0)
    };
    let curves: Vec<&[ContactRecord]> = steps
        .iter()
        .copied()
        .filter(|rows| pressure_steps.contains(&rows[0].step))
        .collect();
    let (_, p_high) = padded_range(
        curves
            .iter()
            .flat_map(|rows| rows.iter().map(|r| r.normal_pressure))
            .chain([0.0]),
    );
    let (_, slip_high) = padded_range(
        curves
            .iter()
            .flat_map(|rows| rows.iter().map(|r| r.accumulated_slip))
            .chain([0.0]),
    );

    let error = plot_error(path);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 1250)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| error(&e))?;
        let (top, rest) = root.split_vertically(520);
        let (middle, bottom) = rest.split_vertically(365);
        draw_status_map(&top, &rectangles, s_range, last_time, coordinate_label)
            .map_err(|e| error(&e))?;

        let entries: Vec<(String, RGBAColor, bool)> = curves
            .iter()
            .enumerate()
            .map(|(index, rows)| {
                (
                    format!("t = {:.4}", rows[0].time),
                    Palette99::pick(index).to_rgba(),
                    false,
                )
            })
            .collect();
        let panels: [CurvePanel<'_, '_>; 2] = [
            (
                &middle,
                "normal pressure p_ν on Γ3",
                "p_ν",
                p_high,
                |r| r.normal_pressure,
            ),
            (
                &bottom,
                "accumulated slip Σ k |v_τ| on Γ3",
                "slip",
                slip_high,
                |r| r.accumulated_slip,
            ),
        ];
        for panel in panels {
            draw_curve_panel(panel, &curves, &entries, s_range, coordinate_label)
                .map_err(|e| error(&e))?;
        }
        root.present().map_err(|e| error(&e))?;
    }
    write_atomic(path, svg.as_bytes())
}

/// The records grouped by step, in step order (the rows of one step are consecutive, in the
/// order of s), and the coordinates s of the first step, which every step must have.
fn records_by_step<'r>(
    path: &Path,
    records: &'r [ContactRecord],
) -> Result<(Vec<&'r [ContactRecord]>, Vec<f64>), InputError> {
    let mut steps: Vec<&[ContactRecord]> = records
        .chunk_by(|a, b| a.step == b.step)
        .collect::<Vec<_>>();
    steps.sort_by_key(|rows| rows[0].step);
    let coordinates: Vec<f64> = steps[0].iter().map(|r| r.coordinate).collect();
    if let Some(rows) = steps.iter().find(|rows| {
        rows.len() != coordinates.len()
            || rows
                .iter()
                .zip(&coordinates)
                .any(|(r, s)| r.coordinate != *s)
    }) {
        return Err(InputError::InvalidInput(format!(
            "{}: step {} has other contact nodes than step {}",
            path.display(),
            rows[0].step,
            steps[0][0].step
        )));
    }
    Ok((steps, coordinates))
}

/// The space–time rectangles of each contact status (0, 1, 2): node j along s covers the cell
/// halfway to its neighbours, step i the time interval (t_{i−1}, t_i], and a run of steps of
/// equal status at a node is one rectangle.
fn status_rectangles(steps: &[&[ContactRecord]], coordinates: &[f64]) -> [Vec<[(f64, f64); 2]>; 3] {
    // cell of node j along s: halfway to its neighbours
    let count = coordinates.len();
    let edge = |j: usize| -> f64 {
        if j == 0 {
            coordinates[0]
        } else if j == count {
            coordinates[count - 1]
        } else {
            0.5 * (coordinates[j - 1] + coordinates[j])
        }
    };
    // time interval of step i: (t_{i-1}, t_i]
    let start_time = |i: usize| if i == 0 { 0.0 } else { steps[i - 1][0].time };
    let mut rectangles: [Vec<[(f64, f64); 2]>; 3] = Default::default();
    for j in 0..count {
        // runs of equal status in time, one rectangle each
        let mut begin = 0;
        for i in 1..=steps.len() {
            if i == steps.len() || steps[i][j].status != steps[begin][j].status {
                rectangles[steps[begin][j].status].push([
                    (edge(j), start_time(begin)),
                    (edge(j + 1), steps[i - 1][0].time),
                ]);
                begin = i;
            }
        }
    }
    rectangles
}

/// The space–time map of the contact status in `area`: s in `s_range` across, t in
/// [0, `last_time`] up, the `rectangles` of each status in its colour, with the legend.
fn draw_status_map(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    rectangles: &[Vec<[(f64, f64); 2]>; 3],
    (s_low, s_high): (f64, f64),
    last_time: f64,
    coordinate_label: &str,
) -> Result<(), String> {
    let mut map = ChartBuilder::on(area)
        .caption("contact status on Γ3 over time", ("sans-serif", 20))
        .margin(10)
        .margin_right(130)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(s_low..s_high, 0.0..last_time)
        .map_err(|e| e.to_string())?;
    map.configure_mesh()
        .disable_mesh()
        .x_desc(coordinate_label)
        .y_desc("t")
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()
        .map_err(|e| e.to_string())?;
    for (status, cells) in rectangles.iter().enumerate() {
        let color = STATUS_COLORS[status];
        map.draw_series(
            cells
                .iter()
                .map(|&corners| Rectangle::new(corners, color.filled())),
        )
        .map_err(|e| e.to_string())?;
    }
    let entries: Vec<(String, RGBAColor, bool)> = STATUS_LABELS
        .iter()
        .zip(STATUS_COLORS)
        .map(|(label, color)| (label.to_string(), color.to_rgba(), true))
        .collect();
    draw_legend(area, &entries)
}

/// One panel of curves along Γ3: the value of the panel at the steps of `curves`, one colour
/// each, over s in `s_range`, with the legend `entries`.
fn draw_curve_panel(
    (area, caption, label, high, value): CurvePanel<'_, '_>,
    curves: &[&[ContactRecord]],
    entries: &[(String, RGBAColor, bool)],
    (s_low, s_high): (f64, f64),
    coordinate_label: &str,
) -> Result<(), String> {
    let mut lines = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 20))
        .margin(10)
        .margin_right(130)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(s_low..s_high, 0.0..high)
        .map_err(|e| e.to_string())?;
    lines
        .configure_mesh()
        .x_desc(coordinate_label)
        .y_desc(label)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .light_line_style(WHITE)
        .draw()
        .map_err(|e| e.to_string())?;
    for (index, rows) in curves.iter().enumerate() {
        let color = Palette99::pick(index).to_rgba();
        lines
            .draw_series(
                LineSeries::new(
                    rows.iter().map(|r| (r.coordinate, value(r))),
                    color.stroke_width(2),
                )
                .point_size(2),
            )
            .map_err(|e| e.to_string())?;
    }
    draw_legend(area, entries)
}

/// A panel of curves along Γ3: area, caption, axis label, upper end of the axis, value.
type CurvePanel<'a, 'b> = (
    &'a DrawingArea<SVGBackend<'b>, plotters::coord::Shift>,
    &'static str,
    &'static str,
    f64,
    fn(&ContactRecord) -> f64,
);

/// Legend in the right margin (130 px) of `area`: a filled square (`filled = true`) or a line
/// of each colour, and its label.
fn draw_legend(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    entries: &[(String, RGBAColor, bool)],
) -> Result<(), String> {
    let left = area.dim_in_pixel().0 as i32 - 120;
    for (index, (label, color, filled)) in entries.iter().enumerate() {
        let y = 50 + 22 * index as i32;
        if *filled {
            area.draw(&Rectangle::new(
                [(left, y - 7), (left + 14, y + 7)],
                color.filled(),
            ))
            .map_err(|e| e.to_string())?;
        } else {
            area.draw(&PathElement::new(
                vec![(left, y), (left + 18, y)],
                color.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?;
        }
        area.draw(&Text::new(
            label.as_str(),
            (left + 24, y - 7),
            ("sans-serif", 14),
        ))
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Steps at which the pressure is drawn: for each picture step the nearest step of `records`
/// (the earlier one on a tie; the contact history holds every `output.every`-th step), and the
/// step of the largest total pressure on the line.
pub fn pressure_steps(records: &[ContactRecord], picture_steps: &[usize]) -> Vec<usize> {
    let mut totals: Vec<(usize, f64)> = Vec::new();
    for record in records {
        match totals.last_mut() {
            Some((step, total)) if *step == record.step => *total += record.normal_pressure,
            _ => totals.push((record.step, record.normal_pressure)),
        }
    }
    let mut chosen: Vec<usize> = picture_steps
        .iter()
        .filter_map(|&wanted| {
            totals
                .iter()
                .map(|&(step, _)| step)
                .min_by_key(|&step| (step.abs_diff(wanted), step))
        })
        .collect();
    if let Some(&(step, _)) = totals.iter().max_by(|a, b| a.1.total_cmp(&b.1)) {
        chosen.push(step);
    }
    chosen.sort_unstable();
    chosen.dedup();
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn damage_colors_run_from_violet_to_yellow_and_clamp() {
        assert_eq!(damage_color(0.0), RGBColor(68, 1, 84));
        assert_eq!(damage_color(1.0), RGBColor(253, 231, 37));
        assert_eq!(damage_color(0.5), RGBColor(33, 145, 140));
        assert_eq!(damage_color(-3.0), damage_color(0.0));
        assert_eq!(damage_color(7.0), damage_color(1.0));
    }

    #[test]
    fn picture_steps_are_the_nearest_steps_clamped_and_unique() {
        assert_eq!(picture_steps(&[2.5, 5.0], 0.02, 250), vec![125, 250]);
        assert_eq!(picture_steps(&[5.0, 0.001, 4.999], 0.02, 250), vec![1, 250]);
    }

    #[test]
    fn contact_history_is_truncated_to_the_saved_step() {
        let dir = std::env::temp_dir().join(format!("simulate-contact-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(CONTACT_HISTORY_FILE);
        let rows = |n: usize| format!("{n},0.1,0,1,0.5,0,0\n{n},0.1,1,2,0.25,0.5,0.05\n");
        let text = format!(
            "{CONTACT_HISTORY_HEADER}\n{}{}{}3,0.3,0",
            rows(1),
            rows(2),
            rows(3)
        );
        std::fs::write(&path, text).unwrap();
        truncate_contact_history(&path, &[1, 2], 2).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            format!("{CONTACT_HISTORY_HEADER}\n{}{}", rows(1), rows(2))
        );
        let records = read_contact_history(&path).unwrap();
        assert_eq!(records.len(), 4);
        assert_eq!(records[3].status, 2);
        assert_eq!(records[3].accumulated_slip, 0.05);
        assert_eq!(pressure_steps(&records, &[1, 9]), vec![1, 2]);
        let error = truncate_contact_history(&path, &[1, 2, 3], 2)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains(":6: expected a complete row of step 3"),
            "{error}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
