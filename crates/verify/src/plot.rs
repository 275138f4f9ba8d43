//! Log–log convergence plots (error against mesh size `h` or time step `k`) written as SVG.
//!
//! Each series is drawn as markers joined by lines; reference slopes `O(h^p)` are dashed lines
//! `error = C h^p` through an anchor point, spanning the range of mesh sizes of the data, so the
//! observed order of convergence can be read off against the rate predicted by Theorem 5.2.

use std::path::Path;

use plotters::element::DashedPathElement;
use plotters::prelude::*;

use crate::output::write_atomic;
use crate::InputError;

/// Width and height of the plot in SVG pixels.
const PLOT_SIZE: (u32, u32) = (800, 600);

/// One convergence curve.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend entry, e.g. "‖u − u_hk‖_V".
    pub label: String,
    /// Points `(h or k, error)`. Points with a non-positive or non-finite coordinate cannot be
    /// shown on log axes and are skipped.
    pub points: Vec<(f64, f64)>,
}

/// A reference line `error = C · h^slope`, drawn dashed.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceSlope {
    /// Exponent `p` of `O(h^p)`.
    pub slope: f64,
    /// Legend entry, e.g. "O(h^1)" (see [`ReferenceSlope::order`]).
    pub label: String,
    /// Point `(h, error)` the line passes through; `None` for the first plottable point of the
    /// first series that has one.
    pub anchor: Option<(f64, f64)>,
}

impl ReferenceSlope {
    /// Reference slope `O(variable^slope)` through the first data point, labelled e.g.
    /// `"O(h^1)"` or `"O(k^1.5)"`.
    pub fn order(slope: f64, variable: &str) -> Self {
        ReferenceSlope {
            slope,
            label: format!("O({variable}^{slope})"),
            anchor: None,
        }
    }

    /// The same reference line through `anchor = (h, error)` instead of the first data point.
    pub fn through(mut self, anchor: (f64, f64)) -> Self {
        self.anchor = Some(anchor);
        self
    }
}

/// True if `(h, error)` can be shown on log–log axes.
fn is_plottable(&(abscissa, ordinate): &(f64, f64)) -> bool {
    abscissa.is_finite() && ordinate.is_finite() && abscissa > 0.0 && ordinate > 0.0
}

/// Range `[low, high]` of positive values padded by 5% of its width in decades on each side
/// (or by a factor 2 if it is a single value), for log axes.
fn padded_log_range(low: f64, high: f64) -> (f64, f64) {
    let decades = (high / low).log10();
    if decades <= 1e-12 {
        (low / 2.0, high * 2.0)
    } else {
        let pad = 10f64.powf(0.05 * decades);
        (low / pad, high * pad)
    }
}

/// Tick label of a log axis: `1e-3`, `2.5e-2`, ...
fn format_tick(value: &f64) -> String {
    let text = format!("{value:.1e}");
    // "1.0e-3" → "1e-3"
    text.replacen(".0e", "e", 1)
}

/// Write a log–log convergence plot of `series` with dashed `references` to the SVG file
/// `path` (atomically, creating parent directories).
///
/// Points that cannot be shown on log axes (non-positive or non-finite) are skipped; it is an
/// error if no series has a plottable point, or if a reference slope or anchor is not a finite
/// (positive) number.
pub fn loglog_svg(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    references: &[ReferenceSlope],
) -> Result<(), InputError> {
    let plot_error = |message: String| InputError::Plot {
        path: path.to_path_buf(),
        message,
    };

    let curves: Vec<(&str, Vec<(f64, f64)>)> = series
        .iter()
        .map(|curve| {
            let points = curve.points.iter().copied().filter(is_plottable).collect();
            (curve.label.as_str(), points)
        })
        .filter(|(_, points): &(&str, Vec<(f64, f64)>)| !points.is_empty())
        .collect();
    let Some(first_point) = curves.first().map(|(_, points)| points[0]) else {
        return Err(plot_error(
            "no positive finite data point to plot on log–log axes".to_string(),
        ));
    };

    let all_points = curves.iter().flat_map(|(_, points)| points.iter().copied());
    let (mut x_low, mut x_high, mut y_low, mut y_high) = all_points.fold(
        (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64),
        |(x_low, x_high, y_low, y_high), (x, y)| {
            (x_low.min(x), x_high.max(x), y_low.min(y), y_high.max(y))
        },
    );

    // Reference lines over the data range of h, through their anchors.
    let mut lines = Vec::with_capacity(references.len());
    for reference in references {
        if !reference.slope.is_finite() {
            return Err(plot_error(format!(
                "reference `{}`: slope {} is not finite",
                reference.label, reference.slope
            )));
        }
        let anchor = reference.anchor.unwrap_or(first_point);
        if !is_plottable(&anchor) {
            return Err(plot_error(format!(
                "reference `{}`: anchor ({}, {}) is not a positive finite point",
                reference.label, anchor.0, anchor.1
            )));
        }
        let line_at = |h: f64| (h, anchor.1 * (h / anchor.0).powf(reference.slope));
        let (from, to) = (line_at(x_low.min(anchor.0)), line_at(x_high.max(anchor.0)));
        if !is_plottable(&from) || !is_plottable(&to) {
            return Err(plot_error(format!(
                "reference `{}`: the line leaves the range of f64 over the data",
                reference.label
            )));
        }
        lines.push((reference.label.as_str(), from, to));
    }
    for &(_, from, to) in &lines {
        x_low = x_low.min(from.0);
        x_high = x_high.max(to.0);
        y_low = y_low.min(from.1.min(to.1));
        y_high = y_high.max(from.1.max(to.1));
    }
    let (x_low, x_high) = padded_log_range(x_low, x_high);
    let (y_low, y_high) = padded_log_range(y_low, y_high);

    let mut svg = String::new();
    {
        let drawing_error = |error: &dyn std::fmt::Display| plot_error(error.to_string());
        let root = SVGBackend::with_string(&mut svg, PLOT_SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| drawing_error(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d((x_low..x_high).log_scale(), (y_low..y_high).log_scale())
            .map_err(|e| drawing_error(&e))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .x_label_formatter(&format_tick)
            .y_label_formatter(&format_tick)
            .draw()
            .map_err(|e| drawing_error(&e))?;

        for (index, (label, points)) in curves.iter().enumerate() {
            let color = Palette99::pick(index).to_rgba();
            chart
                .draw_series(
                    LineSeries::new(points.iter().copied(), color.stroke_width(2)).point_size(4),
                )
                .map_err(|e| drawing_error(&e))?
                .label(*label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        for (label, from, to) in &lines {
            let style = BLACK.mix(0.6).stroke_width(1);
            chart
                .draw_series(DashedLineSeries::new([*from, *to], 8, 5, style))
                .map_err(|e| drawing_error(&e))?
                .label(*label)
                .legend(move |(x, y)| {
                    DashedPathElement::new(vec![(x, y), (x + 20, y)], 5, 3, style)
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| drawing_error(&e))?;
        root.present().map_err(|e| drawing_error(&e))?;
    }
    write_atomic(path, svg.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn convergence_series() -> Vec<Series> {
        let mesh_sizes = [0.5, 0.25, 0.125, 0.0625];
        vec![
            Series {
                label: "energy error".to_string(),
                points: mesh_sizes.iter().map(|&h| (h, 0.3 * h)).collect(),
            },
            Series {
                label: "L2 error".to_string(),
                // Skipped points: zero, negative, NaN and infinite coordinates.
                points: mesh_sizes
                    .iter()
                    .map(|&h| (h, 0.1 * h * h))
                    .chain([
                        (0.0, 1.0),
                        (0.1, -1.0),
                        (f64::NAN, 1.0),
                        (0.1, f64::INFINITY),
                    ])
                    .collect(),
            },
        ]
    }

    #[test]
    fn writes_an_svg_with_series_and_reference_labels() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("plots/convergence.svg");
        let references = [
            ReferenceSlope::order(1.0, "h"),
            ReferenceSlope::order(2.0, "h").through((0.5, 0.01)),
        ];
        loglog_svg(
            &path,
            "Convergence in h",
            "mesh size h",
            "error",
            &convergence_series(),
            &references,
        )
        .unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(svg.contains("<svg"), "not an SVG document");
        assert!(
            svg.trim_end().ends_with("</svg>"),
            "SVG document not closed"
        );
        for text in [
            "Convergence in h",
            "mesh size h",
            "energy error",
            "L2 error",
            "O(h^1)",
            "O(h^2)",
        ] {
            assert!(svg.contains(text), "missing label `{text}`");
        }
        assert!(svg.contains("<polyline") || svg.contains("<path"));
        assert!(
            !svg.contains("NaN") && !svg.contains("inf"),
            "non-finite coordinates"
        );
    }

    #[test]
    fn reference_label_formats_fractional_orders() {
        assert_eq!(ReferenceSlope::order(1.0, "h").label, "O(h^1)");
        assert_eq!(ReferenceSlope::order(1.5, "k").label, "O(k^1.5)");
    }

    #[test]
    fn no_positive_data_is_an_error() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("empty.svg");
        let series = [Series {
            label: "bad".to_string(),
            points: vec![(0.0, 1.0), (1.0, 0.0), (f64::NAN, f64::NAN)],
        }];
        let error = loglog_svg(&path, "t", "h", "e", &series, &[]).unwrap_err();
        assert!(matches!(error, InputError::Plot { .. }), "{error}");
        assert!(error.to_string().contains("empty.svg"), "{error}");
        assert!(!path.exists());
        let error = loglog_svg(&path, "t", "h", "e", &[], &[]).unwrap_err();
        assert!(matches!(error, InputError::Plot { .. }), "{error}");
    }

    #[test]
    fn invalid_reference_is_an_error() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("reference.svg");
        let references = [ReferenceSlope::order(1.0, "h").through((-1.0, 1.0))];
        let error =
            loglog_svg(&path, "t", "h", "e", &convergence_series(), &references).unwrap_err();
        assert!(error.to_string().contains("anchor"), "{error}");
    }

    #[test]
    fn single_point_gets_a_nonempty_range() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("single.svg");
        let series = [Series {
            label: "one point".to_string(),
            points: vec![(0.1, 0.01)],
        }];
        loglog_svg(
            &path,
            "t",
            "h",
            "e",
            &series,
            &[ReferenceSlope::order(1.0, "h")],
        )
        .unwrap();
        assert!(std::fs::read_to_string(&path)
            .unwrap()
            .contains("one point"));
    }

    #[test]
    fn unwritable_directory_gives_an_error_naming_the_path() {
        let scratch = tempfile::tempdir().unwrap();
        // The directory is missing and cannot be created: a regular file is in the way.
        let blocker = scratch.path().join("file-not-directory");
        std::fs::write(&blocker, b"").unwrap();
        let path = blocker.join("missing/convergence.svg");
        let error = loglog_svg(&path, "t", "h", "e", &convergence_series(), &[]).unwrap_err();
        assert!(
            error.to_string().contains(&blocker.display().to_string()),
            "error does not name the path: {error}"
        );
    }
}
