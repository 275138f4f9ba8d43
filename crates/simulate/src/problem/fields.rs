//! The load expressions as the fields the solver evaluates: the variables of each kind of
//! expression, vector fields of D expressions, compiled fields, the batched loads f0 and f2, and
//! the load curve of f2.

use super::file::problem_error;
use crate::watch::LoadWatch;
use contact_damage::model::fields::{BatchBoundaryVectorField, BatchVectorField};
use contact_input::expr::compiled::with_registers;
use contact_input::expr::split::BATCH;
use contact_input::expr::{Expr, Program};
use contact_input::file::parse_expr;
use contact_input::{FileKind, InputError};
use std::collections::BTreeMap;

/// Variables of the body force: position and time.
pub const FIELD_VARIABLES: [&str; 4] = ["x", "y", "z", "t"];
/// Variables of the traction f2: position, time and outward unit normal.
pub const TRACTION_VARIABLES: [&str; 7] = ["x", "y", "z", "t", "nx", "ny", "nz"];
/// Variables of the gap and the initial data: position only.
pub const STATIC_VARIABLES: [&str; 3] = ["x", "y", "z"];

/// D expressions of a vector field.
pub(super) fn parse_vector<const D: usize>(
    origin: &str,
    key: &str,
    sources: &[String],
    variables: &[&str],
    constants: &BTreeMap<String, f64>,
) -> Result<[Expr; D], InputError> {
    if sources.len() != D {
        return Err(problem_error(
            origin,
            key,
            format!("need {D} components, got {}", sources.len()),
        ));
    }
    let parsed: Vec<Expr> = sources
        .iter()
        .enumerate()
        .map(|(i, s)| {
            parse_expr(
                FileKind::Problem,
                origin,
                &format!("{key}[{i}]"),
                s,
                variables,
                constants,
            )
        })
        .collect::<Result<_, _>>()?;
    Ok(parsed
        .try_into()
        .unwrap_or_else(|_| unreachable!("the length was checked")))
}

/// The variable values of an expression: the position padded to (x, y, z), then `extra`
/// (t, then the normal for the traction).
pub(super) fn point_values<const D: usize>(x: &[f64; D], extra: &[f64]) -> Vec<f64> {
    let mut values = [0.0; MAX_VARIABLES];
    let len = fill_point_values(x, extra, &mut values);
    values[..len].to_vec()
}

/// Most variables of a load expression: x, y, z, t and a normal ([`TRACTION_VARIABLES`]).
const MAX_VARIABLES: usize = TRACTION_VARIABLES.len();

/// Lays out the variables of a load expression at the point x in `values`: x, y, z (zero
/// beyond D), then `extra`; returns how many were written.
fn fill_point_values<const D: usize>(
    x: &[f64; D],
    extra: &[f64],
    values: &mut [f64; MAX_VARIABLES],
) -> usize {
    values[..D].copy_from_slice(x);
    values[D..3].fill(0.0);
    values[3..3 + extra.len()].copy_from_slice(extra);
    3 + extra.len()
}

pub(super) fn eval_vector<const D: usize>(exprs: &[Expr; D], values: &[f64]) -> [f64; D] {
    std::array::from_fn(|i| exprs[i].eval_f64(values))
}

/// The N components of a load field compiled into one program (common subexpressions shared),
/// evaluated per point on f64 without walking the expression trees.
pub(super) struct CompiledField<const N: usize> {
    program: Program,
}

impl<const N: usize> CompiledField<N> {
    pub(super) fn new(exprs: &[Expr; N]) -> Self {
        let components: Vec<&Expr> = exprs.iter().collect();
        Self {
            program: Program::fuse(&components),
        }
    }

    /// The components at the point x (the variables of [`fill_point_values`]).
    pub(super) fn eval<const D: usize>(&self, x: &[f64; D], extra: &[f64]) -> [f64; N] {
        let mut values = [0.0; MAX_VARIABLES];
        let len = fill_point_values(x, extra, &mut values);
        with_registers(|registers: &mut Vec<f64>| {
            self.program.eval_array(&values[..len], registers)
        })
    }
}

/// f0 or f2 given by N expressions, evaluated over a whole batch of points per call (the
/// solver passes all quadrature points of a chunk of cells, or of the boundary facets): the
/// interpreter dispatches once per instruction and batch of [`BATCH`] points instead of once
/// per instruction and point ([`Program::eval_batch`], bitwise the values of
/// [`CompiledField::eval`]). A non-finite value is recorded by the watch under `key`.
pub(super) struct BatchLoad<const N: usize> {
    field: CompiledField<N>,
    key: &'static str,
    symbol: &'static str,
    watch: LoadWatch,
    /// The factor of `loads.traction_curve` (f2 only).
    curve: Option<LoadCurve>,
}

impl<const N: usize> BatchLoad<N> {
    /// The field of `exprs`, its non-finite values recorded by `watch` under `key`.
    pub(super) fn new(
        exprs: &[Expr; N],
        key: &'static str,
        symbol: &'static str,
        watch: &LoadWatch,
        curve: Option<LoadCurve>,
    ) -> Self {
        Self {
            field: CompiledField::new(exprs),
            key,
            symbol,
            watch: watch.clone(),
            curve,
        }
    }

    /// The values at `points` (and `normals`, the last variables of f2) at time `time`, with the
    /// curve factor: `each(p, values at points[p])`.
    fn for_points<const D: usize>(
        &self,
        points: &[[f64; D]],
        normals: Option<&[[f64; D]]>,
        time: f64,
        mut each: impl FnMut(usize, [f64; N]),
    ) {
        let program = &self.field.program;
        let variables = program.variable_count();
        let factor = self.curve.as_ref().map(|curve| curve.factor(time));
        with_registers(|registers: &mut Vec<f64>| {
            // x, y, z (zero beyond D), t, then the normal (zero beyond D).
            let mut inputs = [[0.0; BATCH]; MAX_VARIABLES];
            inputs[3] = [time; BATCH];
            for (batch, chunk) in points.chunks(BATCH).enumerate() {
                let offset = batch * BATCH;
                let count = chunk.len();
                for (p, x) in chunk.iter().enumerate() {
                    for (j, &xj) in x.iter().enumerate() {
                        inputs[j][p] = xj;
                    }
                    if let Some(normals) = normals {
                        for (j, &nj) in normals[offset + p].iter().enumerate() {
                            inputs[4 + j][p] = nj;
                        }
                    }
                }
                let columns: [&[f64]; MAX_VARIABLES] = std::array::from_fn(|v| &inputs[v][..count]);
                program.eval_batch(&columns[..variables], count, registers);
                for p in 0..count {
                    let values: [f64; N] = std::array::from_fn(|i| {
                        let value = program.batch_output(registers, count, i)[p];
                        factor.map_or(value, |factor| value * factor)
                    });
                    let point = offset + p;
                    each(
                        point,
                        self.watch
                            .check(self.key, self.symbol, values, &points[point], time),
                    );
                }
            }
        })
    }
}

impl<const D: usize> BatchVectorField<D> for BatchLoad<D> {
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        self.for_points(points, None, time, |p, values| out[p] = values);
    }
}

impl<const D: usize> BatchBoundaryVectorField<D> for BatchLoad<D> {
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        self.for_points(points, Some(normals), time, |p, values| out[p] = values);
    }
}

/// A piecewise-linear load curve [[t, factor], …]: linear between its points, constant
/// outside them.
#[derive(Debug, Clone)]
pub struct LoadCurve {
    points: Vec<(f64, f64)>,
}

impl LoadCurve {
    /// Checks the points (at least one; pairs of finite numbers; times strictly increasing);
    /// errors name `origin` and `key`.
    pub fn new(origin: &str, key: &str, points: &[Vec<f64>]) -> Result<Self, InputError> {
        if points.is_empty() {
            return Err(problem_error(
                origin,
                key,
                "give at least one [t, factor] point",
            ));
        }
        let mut parsed: Vec<(f64, f64)> = Vec::with_capacity(points.len());
        for (i, point) in points.iter().enumerate() {
            let &[t, factor] = point.as_slice() else {
                return Err(problem_error(
                    origin,
                    &format!("{key}[{i}]"),
                    format!("a point is [t, factor], got {point:?}"),
                ));
            };
            if !(t.is_finite() && factor.is_finite()) {
                return Err(problem_error(
                    origin,
                    &format!("{key}[{i}]"),
                    format!("t and factor must be finite, got {point:?}"),
                ));
            }
            if let Some(&(previous, _)) = parsed.last() {
                if t <= previous {
                    return Err(problem_error(
                        origin,
                        &format!("{key}[{i}]"),
                        format!("times must increase strictly, got {t} after {previous}"),
                    ));
                }
            }
            parsed.push((t, factor));
        }
        Ok(Self { points: parsed })
    }

    /// The factor at time t.
    pub fn factor(&self, t: f64) -> f64 {
        let points = &self.points;
        let after = points.partition_point(|&(time, _)| time <= t);
        if after == 0 {
            return points[0].1;
        }
        if after == points.len() {
            return points[after - 1].1;
        }
        let ((t0, f0), (t1, f1)) = (points[after - 1], points[after]);
        f0 + (f1 - f0) * (t - t0) / (t1 - t0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The compiled loads give the values of the expression trees, bit for bit, at points
    /// spread over a box and over time.
    #[test]
    fn compiled_loads_are_bitwise_the_expression_trees() {
        let constants: BTreeMap<String, f64> = [
            ("pressure", 1.2),
            ("width", 0.4),
            ("center", 1.2),
            ("period", 1.0),
        ]
        .map(|(k, v)| (k.to_string(), v))
        .into_iter()
        .collect();
        let parse =
            |source: &str, variables: &[&str]| Expr::parse(source, variables, &constants).unwrap();
        let traction = [
            parse(
                "0.3*pressure*max(0, ny)*exp(-((x - center)/width)^2)*(1 - cos(2*pi*t/period))/2",
                &TRACTION_VARIABLES,
            ),
            parse(
                "-pressure*max(0, nz + ny)*exp(-((x - center)/width)^2)*(1 - cos(2*pi*t/period))/2",
                &TRACTION_VARIABLES,
            ),
            parse("sqrt(1 + x^2 + z^2)*sin(t)/(2 + nx)", &TRACTION_VARIABLES),
        ];
        let force = [
            parse("x*y - z^3 + t", &FIELD_VARIABLES),
            parse("tanh(x - t)*log(2 + y)", &FIELD_VARIABLES),
            parse("min(x, y)^2.5 + abs(z - 0.5)", &FIELD_VARIABLES),
        ];
        let compiled_traction = CompiledField::new(&traction);
        let compiled_force = CompiledField::new(&force);
        for p in 0..200 {
            let x: [f64; 3] =
                std::array::from_fn(|i| ((p * (7 + 4 * i) + 3 * i) % 97) as f64 / 48.0);
            let t = (p % 13) as f64 / 6.0;
            let normal = [[0.0, -1.0, 0.0], [0.6, 0.8, 0.0], [0.0, 0.0, 1.0]][p % 3];
            let extra = [t, normal[0], normal[1], normal[2]];
            let expected = eval_vector(&traction, &point_values(&x, &extra));
            let compiled = compiled_traction.eval(&x, &extra);
            let expected_force = eval_vector(&force, &point_values(&x, &[t]));
            let compiled_force = compiled_force.eval(&x, &[t]);
            for (a, b) in compiled
                .iter()
                .chain(&compiled_force)
                .zip(expected.iter().chain(&expected_force))
            {
                assert_eq!(a.to_bits(), b.to_bits(), "{a} vs {b} at x = {x:?}, t = {t}");
            }
        }
    }

    /// The batched loads (f0 over cell points, f2 over facet points with their normals and the
    /// load curve) give the point-by-point compiled values bit for bit, over more than two
    /// batches, in 2D and 3D.
    fn batched_loads_are_bitwise_the_compiled_loads<const D: usize>() {
        let constants = BTreeMap::new();
        let parse =
            |source: &str, variables: &[&str]| Expr::parse(source, variables, &constants).unwrap();
        let traction: [Expr; D] = std::array::from_fn(|i| {
            parse(
                [
                    "0.3*max(0, ny)*exp(-((x - 0.5)/0.4)^2)*(1 - cos(2*pi*t))/2 + nx*y",
                    "-max(0, nz + ny)*sqrt(1 + x^2 + z^2)*sin(t)/(2 + nx)",
                    "min(x, y)^2.5 + abs(z - 0.5)*nz",
                ][i],
                &TRACTION_VARIABLES,
            )
        });
        let force: [Expr; D] = std::array::from_fn(|i| {
            parse(
                [
                    "x*y - z^3 + t",
                    "tanh(x - t)*log(2 + y)",
                    "min(x, y)^2.5 + abs(z - 0.5)",
                ][i],
                &FIELD_VARIABLES,
            )
        });
        let curve = LoadCurve::new(
            "test",
            "curve",
            &[vec![0.0, 0.0], vec![0.7, 1.3], vec![2.0, 0.4]],
        )
        .unwrap();
        let batched = |exprs: &[Expr; D], curve: Option<LoadCurve>| {
            BatchLoad::<D>::new(exprs, "key", "f", &LoadWatch::default(), curve)
        };
        let (batched_force, batched_traction) = (
            batched(&force, None),
            batched(&traction, Some(curve.clone())),
        );
        let (compiled_force, compiled_traction) =
            (CompiledField::new(&force), CompiledField::new(&traction));
        let points: Vec<[f64; D]> = (0..2 * BATCH + 13)
            .map(|p| std::array::from_fn(|i| ((p * (7 + 4 * i) + 3 * i) % 97) as f64 / 48.0))
            .collect();
        let normals: Vec<[f64; D]> = (0..2 * BATCH + 13)
            .map(|p| {
                let angle = 0.37 * p as f64;
                std::array::from_fn(|i| [angle.cos(), angle.sin(), 0.0][i])
            })
            .collect();
        for t in [0.0, 0.45, 1.5] {
            let mut forces = vec![[0.0; D]; points.len()];
            BatchVectorField::evaluate(&batched_force, &points, t, &mut forces);
            let mut tractions = vec![[0.0; D]; points.len()];
            BatchBoundaryVectorField::evaluate(
                &batched_traction,
                &points,
                &normals,
                t,
                &mut tractions,
            );
            for (p, x) in points.iter().enumerate() {
                let mut extra = [t, 0.0, 0.0, 0.0];
                extra[1..1 + D].copy_from_slice(&normals[p]);
                let expected_traction = compiled_traction
                    .eval(x, &extra)
                    .map(|f| f * curve.factor(t));
                let expected_force = compiled_force.eval(x, &[t]);
                for (a, b) in forces[p]
                    .iter()
                    .chain(&tractions[p])
                    .zip(expected_force.iter().chain(&expected_traction))
                {
                    assert_eq!(a.to_bits(), b.to_bits(), "{a} vs {b} at x = {x:?}, t = {t}");
                }
            }
        }
    }

    #[test]
    fn batched_loads_are_bitwise_the_compiled_loads_in_2d_and_3d() {
        batched_loads_are_bitwise_the_compiled_loads::<2>();
        batched_loads_are_bitwise_the_compiled_loads::<3>();
    }
}
