//! The load data of Problem P as fields evaluated in batches: f0 (2.3), f2 (2.6), and the extra
//! data of manufactured solutions (f3 on Γ3, the damage supply q and flux κ ∂β/∂ν,
//! docs/model.md §5).
//!
//! The scheme evaluates each field once per step over all quadrature points of a chunk of cells
//! (or over all quadrature points of a boundary part), so that an implementation can amortize
//! its per-call cost (e.g. a compiled expression run instruction by instruction over a batch).
//! A field of the bulk data (f0, q) may also ask to be evaluated at several step times per call
//! ([`BatchVectorField::times_per_evaluation`]), to read its time-independent work per point
//! once for all of them.
//! Every closure `Fn(&[f64; D], f64) -> …` is such a field (blanket implementations, one point
//! at a time), so `Arc::new(|x: &[f64; 2], t: f64| …)` keeps working as a [`VectorField`].

use nalgebra::SMatrix;
use std::sync::Arc;

/// A vector field of (x, t) evaluated over a batch of points: f0.
pub trait BatchVectorField<const D: usize>: Send + Sync {
    /// `out[p] = f(points[p], time)` for every p (`out.len() == points.len()`).
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [[f64; D]]);

    /// The field at several times, time-major: `out[i · points.len() + p] = f(points[p],
    /// times[i])` (`out.len() == times.len() · points.len()`), each time bitwise as
    /// [`BatchVectorField::evaluate`]. The default evaluates one time after the other.
    fn evaluate_at_times(&self, points: &[[f64; D]], times: &[f64], out: &mut [[f64; D]]) {
        if !points.is_empty() {
            for (&time, out) in times.iter().zip(out.chunks_mut(points.len())) {
                self.evaluate(points, time, out);
            }
        }
    }

    /// How many upcoming step times the scheme should pass to
    /// [`BatchVectorField::evaluate_at_times`] at once (see [`crate::scheme::loads::BulkData`]). The
    /// default, 1, evaluates the field at each step for that step only; an implementation
    /// that gains from several times per call (its time-independent work per point done once)
    /// says how many, and is then evaluated ahead of the steps that use the values.
    fn times_per_evaluation(&self) -> usize {
        1
    }
}

/// A vector boundary datum of (x, t, outward normal) over a batch of boundary points: f2, f3.
pub trait BatchBoundaryVectorField<const D: usize>: Send + Sync {
    /// `out[p] = f(points[p], time, normals[p])` for every p (all slices of one length).
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [[f64; D]]);
}

/// A scalar field of (x, t) over a batch of points: the damage supply q.
pub trait BatchScalarField<const D: usize>: Send + Sync {
    /// `out[p] = q(points[p], time)` for every p.
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [f64]);

    /// As [`BatchVectorField::evaluate_at_times`]: `out[i · points.len() + p] = q(points[p],
    /// times[i])`, each time bitwise as [`BatchScalarField::evaluate`].
    fn evaluate_at_times(&self, points: &[[f64; D]], times: &[f64], out: &mut [f64]) {
        if !points.is_empty() {
            for (&time, out) in times.iter().zip(out.chunks_mut(points.len())) {
                self.evaluate(points, time, out);
            }
        }
    }

    /// As [`BatchVectorField::times_per_evaluation`].
    fn times_per_evaluation(&self) -> usize {
        1
    }
}

/// A symmetric tensor field of (x, t) evaluated over a batch of points: a stress given as data
/// ([`Data::body_stress`](crate::model::problem::Data::body_stress)).
pub trait BatchTensorField<const D: usize>: Send + Sync {
    /// `out[p] = S(points[p], time)` for every p (`out.len() == points.len()`).
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [SMatrix<f64, D, D>]);
}

/// A scalar boundary datum of (x, t, outward normal) over a batch: the damage flux κ ∂β/∂ν.
pub trait BatchBoundaryScalarField<const D: usize>: Send + Sync {
    /// `out[p] = g(points[p], time, normals[p])` for every p.
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [f64]);
}

impl<const D: usize, F> BatchVectorField<D> for F
where
    F: Fn(&[f64; D], f64) -> [f64; D] + Send + Sync,
{
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        for (x, value) in points.iter().zip(out) {
            *value = self(x, time);
        }
    }
}

impl<const D: usize, F> BatchBoundaryVectorField<D> for F
where
    F: Fn(&[f64; D], f64, &[f64; D]) -> [f64; D] + Send + Sync,
{
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        for ((x, normal), value) in points.iter().zip(normals).zip(out) {
            *value = self(x, time, normal);
        }
    }
}

impl<const D: usize, F> BatchScalarField<D> for F
where
    F: Fn(&[f64; D], f64) -> f64 + Send + Sync,
{
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [f64]) {
        for (x, value) in points.iter().zip(out) {
            *value = self(x, time);
        }
    }
}

impl<const D: usize, F> BatchBoundaryScalarField<D> for F
where
    F: Fn(&[f64; D], f64, &[f64; D]) -> f64 + Send + Sync,
{
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [f64]) {
        for ((x, normal), value) in points.iter().zip(normals).zip(out) {
            *value = self(x, time, normal);
        }
    }
}

impl<const D: usize, F> BatchTensorField<D> for F
where
    F: Fn(&[f64; D], f64) -> SMatrix<f64, D, D> + Send + Sync,
{
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [SMatrix<f64, D, D>]) {
        for (x, value) in points.iter().zip(out) {
            *value = self(x, time);
        }
    }
}

/// A vector field of (x, t): f0.
pub type VectorField<const D: usize> = Arc<dyn BatchVectorField<D>>;
/// A shared [`BatchTensorField`].
pub type TensorField<const D: usize> = Arc<dyn BatchTensorField<D>>;
/// A vector boundary datum of (x, t, outward normal): f2, f3.
pub type BoundaryVectorField<const D: usize> = Arc<dyn BatchBoundaryVectorField<D>>;
/// A scalar field of (x, t): q.
pub type ScalarField<const D: usize> = Arc<dyn BatchScalarField<D>>;
/// A scalar boundary datum of (x, t, outward normal): the damage flux κ ∂β/∂ν.
pub type BoundaryScalarField<const D: usize> = Arc<dyn BatchBoundaryScalarField<D>>;

/// A scalar field of (x, t) evaluated point by point: the gap g and the prescribed
/// displacement components u_D,i (they are needed at nodes, not at quadrature points).
pub type PointScalarField<const D: usize> = Arc<dyn Fn(&[f64; D], f64) -> f64 + Send + Sync>;
/// A vector boundary datum of (x, t, outward normal) evaluated point by point: the traction on
/// the free components of a part of Γ1.
pub type PointBoundaryVectorField<const D: usize> =
    Arc<dyn Fn(&[f64; D], f64, &[f64; D]) -> [f64; D] + Send + Sync>;
/// A time-independent scalar field of x: g, β0.
pub type StaticScalarField<const D: usize> = Arc<dyn Fn(&[f64; D]) -> f64 + Send + Sync>;
/// A time-independent vector field of x: u0.
pub type StaticVectorField<const D: usize> = Arc<dyn Fn(&[f64; D]) -> [f64; D] + Send + Sync>;
