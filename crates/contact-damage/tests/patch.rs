//! Patch tests: P1 reproduces linear and P2 quadratic velocity fields exactly for the linear
//! viscoelastic operator of (5.1) (linear elasticity in the strain rate) with clamped (Γ1) and
//! traction (Γ2) data, in 2D and 3D, on distorted meshes.

use crate::common;

use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::model::laws::{LinearViscosity, Tensor, Viscosity};
use contact_damage::scheme::Simulation;
use nalgebra::{SMatrix, SVector};
use std::sync::Arc;

/// Velocity field v(x) = x_0 (c + B x) (vanishes on x_0 = 0) with its gradient and Div 𝒜ε(v).
struct Field<const D: usize> {
    constant: SVector<f64, D>,
    linear: SMatrix<f64, D, D>,
}

impl<const D: usize> Field<D> {
    fn value(&self, x: &[f64; D]) -> SVector<f64, D> {
        let p = SVector::<f64, D>::from_column_slice(x);
        (self.constant + self.linear * p) * x[0]
    }
    /// ∂v_i/∂x_j = δ_{j0} (c + B x)_i + x_0 B_ij.
    fn gradient(&self, x: &[f64; D]) -> SMatrix<f64, D, D> {
        let p = SVector::<f64, D>::from_column_slice(x);
        let mut g = self.linear * x[0];
        let first = self.constant + self.linear * p;
        for i in 0..D {
            g[(i, 0)] += first[i];
        }
        g
    }
}

fn run_patch<const D: usize>(mesh: Mesh<D>, degree: usize, field: Field<D>) -> f64 {
    let law = LinearViscosity {
        shear: 1.0,
        bulk: 0.5,
    };
    let field = Arc::new(field);
    let stress = {
        let field = field.clone();
        move |x: &[f64; D]| {
            let g = field.gradient(x);
            Viscosity::<D>::stress(&law, &((g + g.transpose()) * 0.5))
        }
    };
    // Div 𝒜ε(v) by central differences is exact for the affine stress of a quadratic v
    let stress_body = stress.clone();
    let body_force = move |x: &[f64; D], _t: f64| -> [f64; D] {
        let h = 1e-3;
        let mut div = SVector::<f64, D>::zeros();
        for j in 0..D {
            let mut plus = *x;
            let mut minus = *x;
            plus[j] += h;
            minus[j] -= h;
            let d: Tensor<D> = (stress_body(&plus) - stress_body(&minus)) / (2.0 * h);
            for i in 0..D {
                div[i] += d[(i, j)];
            }
        }
        std::array::from_fn(|i| -div[i])
    };
    let traction = move |x: &[f64; D], _t: f64, n: &[f64; D]| -> [f64; D] {
        let s = stress(x) * SVector::<f64, D>::from_column_slice(n);
        std::array::from_fn(|i| s[i])
    };
    let mut data = common::quiet_data::<D>();
    data.body_force = Some(Arc::new(body_force));
    data.traction = Some(Arc::new(traction));
    let mut problem = common::problem(mesh, degree, data, 1.0, 1);
    problem.model.viscosity = Arc::new(law);
    // β0 = 0: G vanishes, so (5.1) is linear elasticity in the velocity
    problem.data.initial_damage = Arc::new(|_| 0.0);
    let mut simulation = Simulation::new(problem).unwrap();
    let velocity = simulation.step().unwrap().velocity;
    let space = simulation.space();
    let mut worst: f64 = 0.0;
    for node in 0..space.num_nodes() {
        let exact = field.value(&space.node(node));
        for i in 0..D {
            worst = worst.max((velocity.velocity[node * D + i] - exact[i]).abs());
        }
    }
    worst
}

fn no_contact_square(cells: usize) -> Mesh<2> {
    use BoundaryPart::*;
    Mesh::box_mesh(
        [0.0, 0.0],
        [1.0, 1.0],
        [cells, cells],
        [[Dirichlet, Neumann], [Neumann, Neumann]],
    )
    .unwrap()
}

fn no_contact_cube(cells: usize) -> Mesh<3> {
    use BoundaryPart::*;
    Mesh::box_mesh(
        [0.0; 3],
        [1.0; 3],
        [cells; 3],
        [[Dirichlet, Neumann], [Neumann, Neumann], [Neumann, Neumann]],
    )
    .unwrap()
}

#[test]
fn p1_reproduces_linear_velocity_in_2d() {
    let mesh = common::distorted(&no_contact_square(4), 0.25, 0.2);
    let field = Field {
        constant: SVector::<f64, 2>::new(0.3, -0.7),
        linear: SMatrix::zeros(),
    };
    let error = run_patch(mesh, 1, field);
    assert!(error < 1e-11, "P1 patch test error {error:e}");
}

#[test]
fn p2_reproduces_quadratic_velocity_in_2d() {
    let mesh = common::distorted(&no_contact_square(3), 1.0 / 3.0, 0.2);
    let field = Field {
        constant: SVector::<f64, 2>::new(0.3, -0.7),
        linear: SMatrix::<f64, 2, 2>::new(0.5, -1.0, 0.25, 2.0),
    };
    let error = run_patch(mesh, 2, field);
    assert!(error < 1e-11, "P2 patch test error {error:e}");
}

#[test]
fn p1_reproduces_linear_velocity_in_3d() {
    let mesh = common::distorted(&no_contact_cube(3), 1.0 / 3.0, 0.15);
    let field = Field {
        constant: SVector::<f64, 3>::new(0.3, -0.7, 0.2),
        linear: SMatrix::zeros(),
    };
    let error = run_patch(mesh, 1, field);
    assert!(error < 1e-11, "P1 3D patch test error {error:e}");
}

#[test]
fn p2_reproduces_quadratic_velocity_in_3d() {
    let mesh = common::distorted(&no_contact_cube(2), 0.5, 0.15);
    let field = Field {
        constant: SVector::<f64, 3>::new(0.3, -0.7, 0.2),
        linear: SMatrix::<f64, 3, 3>::new(0.5, -1.0, 0.3, 0.25, 2.0, -0.4, 0.1, 0.2, -0.6),
    };
    let error = run_patch(mesh, 2, field);
    assert!(error < 1e-11, "P2 3D patch test error {error:e}");
}

#[test]
fn p1_does_not_reproduce_quadratic_velocity() {
    // the same test with a quadratic field and P1 must fail: the patch test can detect errors
    let mesh = common::distorted(&no_contact_square(4), 0.25, 0.2);
    let field = Field {
        constant: SVector::<f64, 2>::new(0.3, -0.7),
        linear: SMatrix::<f64, 2, 2>::new(0.5, -1.0, 0.25, 2.0),
    };
    let error = run_patch(mesh, 1, field);
    assert!(
        error > 1e-4,
        "P1 cannot be exact for a quadratic field, error {error:e}"
    );
}
