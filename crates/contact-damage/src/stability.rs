//! The step limit of the explicit terms of the velocity step (5.1).
//!
//! The scheme (5.1) takes the elastic stress G(ε(u_{n−1}), β_{n−1}) and — in the paper's form —
//! the normal compliance p_ν(u_{n−1,ν} − g) at the previous step. Linearized about a state, the
//! displacement update u_n = u_{n−1} + k v_n then reads
//!
//! u_n − u* = (I − k H^{-1} B)(u_{n−1} − u*),   B = K_G + C,
//!
//! with H the viscous operator (the bilinear form of 𝒜), K_G the elastic stiffness ∂G/∂ε and C
//! the contact stiffness Σ_a ω_a p_ν′(r_a) ν_a ⊗ ν_a. H is symmetric positive definite and B
//! symmetric positive semidefinite, so the eigenvalues λ of H^{-1}B are real and ≥ 0, and the
//! iteration is stable if and only if k λ_max ≤ 2: the step limit is k_max = 2 / λ_max. Above it
//! the error mode of λ_max is amplified by |1 − kλ_max| > 1 at each step — the displacement
//! grows without bound, or, where p_ν switches off on separation, the contact force settles into
//! a cycle of period two. With the implicit normal compliance
//! ([`ContactTreatment::Implicit`](crate::scheme::ContactTreatment)) only K_G remains explicit,
//! and the limit is the elastic one, 2/λ_max(H^{-1}K_G) (= 2τ for a viscosity τ times the
//! elasticity).
//!
//! **Estimate.** λ_max is computed by the power method on H^{-1}B (one solve with H per
//! iteration), with the Rayleigh quotient xᵀBx / xᵀHx as the estimate; for this symmetric-definite
//! pencil the quotient increases monotonically towards λ_max from below, so the estimated limit
//! is an upper bound of the true one that tightens with the iterations (stop: relative change
//! below 10⁻⁴, or 200 iterations). The operators are taken at the state of the worst case for
//! stability: no damage (β = 1, the stiffest G), zero strain (the tangent of G and 𝒜 at rest),
//! and p_ν′ at the largest current penetration (at least just past contact onset), on every
//! contact node at once.

use crate::assembly::{assemble_cell_vector, field_strain, physical_gradients};
use crate::laws::{ContactLaw, Elasticity, Tensor};
use crate::linalg::multiply;
use crate::quadrature::QuadratureRule;
use crate::space::Tabulation;
use crate::velocity::VelocityOperator;
use crate::Result;
use nalgebra::SVector;

/// The estimated step limit of (5.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepLimit {
    /// The estimate of λ_max(H^{-1}B) (1/time).
    pub largest_rate: f64,
    /// k_max = 2 / λ_max (infinite when B = 0).
    pub time_step: f64,
    /// Power iterations done.
    pub iterations: usize,
    /// Whether the contact stiffness C was part of B (explicit normal compliance).
    pub includes_contact: bool,
}

/// Relative change of the Rayleigh quotient at which the power method stops.
const RELATIVE_CHANGE: f64 = 1e-4;
/// Iteration limit of the power method.
const MAX_ITERATIONS: usize = 200;

/// Estimates the step limit 2/λ_max(H^{-1}(K_G + C)) of (5.1) by the power method (module
/// documentation). `penetrations` are the current r_a = u_ν(a) − g(a) at the contact nodes;
/// `include_contact` = false leaves C out (implicit normal compliance).
pub fn step_limit<const D: usize>(
    operator: &mut VelocityOperator<D>,
    elasticity: &dyn Elasticity<D>,
    contact_law: &dyn ContactLaw,
    penetrations: &[f64],
    include_contact: bool,
) -> Result<StepLimit> {
    operator.factorize_viscous()?;
    let operator = &*operator;
    let (viscous, solver) = (operator.factored_matrix(), operator.solver());
    let space = operator.space();
    let contact = operator.contact();
    let tabulation = Tabulation::cell_rule(
        space.element(),
        &QuadratureRule::<D>::simplex(2 * space.degree() - 2),
    );
    // p_ν′ at the largest penetration, and at least just past contact onset
    let onset = f64::EPSILON.sqrt();
    let worst = penetrations.iter().fold(onset, |m, &r| m.max(r));
    let contact_stiffness = if include_contact {
        contact_law
            .normal_stiffness(worst)
            .max(contact_law.normal_stiffness(onset))
    } else {
        0.0
    };
    // B x in the system frame, for x Cartesian node-major
    let stiffness = |x: &[f64]| -> Vec<f64> {
        let n = tabulation.nodes;
        let mut product = assemble_cell_vector(space, D, |cell, out| {
            out.fill(0.0);
            let geometry = space.geometry(cell);
            let nodes = space.cell_nodes(cell);
            let mut grads = [SVector::<f64, D>::zeros(); crate::element::MAX_CELL_NODES];
            for q in 0..tabulation.len() {
                physical_gradients(geometry, &tabulation, q, &mut grads);
                let strain = field_strain(nodes, &grads[..n], x);
                let stress = elasticity.strain_derivative(&Tensor::<D>::zeros(), 1.0, &strain);
                let weight = tabulation.weights[q] * geometry.det.abs();
                for a in 0..n {
                    let force = stress * grads[a];
                    for i in 0..D {
                        out[a * D + i] += weight * force[i];
                    }
                }
            }
        });
        if contact_stiffness > 0.0 {
            for (k, &node) in contact.nodes.iter().enumerate() {
                let normal = contact.normal(k);
                let u = SVector::<f64, D>::from_column_slice(&x[node * D..node * D + D]);
                let force = normal * (contact.weights[k] * contact_stiffness * u.dot(&normal));
                for i in 0..D {
                    product[node * D + i] += force[i];
                }
            }
        }
        operator.to_system(&product)
    };
    let size = operator.size();
    // a start with components along every mode: a deterministic scrambled sequence
    let mut x: Vec<f64> = (0..size)
        .map(|i| ((i as f64 + 1.0) * 0.618_033_988_749_895).fract() - 0.5)
        .collect();
    x = operator.to_cartesian(&operator.to_system(&x));
    let mut rate = 0.0;
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        let system = operator.to_system(&x);
        let hx = multiply(viscous, &system);
        let norm = dot(&system, &hx).sqrt();
        if norm == 0.0 || !norm.is_finite() {
            break;
        }
        let b = stiffness(&x);
        let quotient = dot(&system, &b) / (norm * norm);
        let change = (quotient - rate).abs();
        rate = quotient;
        if rate == 0.0 || change <= RELATIVE_CHANGE * rate {
            break;
        }
        let next = solver.solve(&b)?;
        let scale = dot(&next, &multiply(viscous, &next)).sqrt();
        if scale == 0.0 || !scale.is_finite() {
            break;
        }
        x = operator.to_cartesian(&next.iter().map(|v| v / scale).collect::<Vec<_>>());
    }
    Ok(StepLimit {
        largest_rate: rate,
        time_step: if rate > 0.0 {
            2.0 / rate
        } else {
            f64::INFINITY
        },
        iterations,
        includes_contact: include_contact,
    })
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
