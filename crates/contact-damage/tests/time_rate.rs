//! Time-loop test: an exact solution that lies in V^h × X^h in space (u linear in x, β constant
//! in x), so the only error left is the time error of the scheme (5.1)–(5.5), which must
//! converge with rate 1 in k.

use crate::common;

use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::model::laws::Tensor;
use contact_damage::scheme::Simulation;
use nalgebra::SVector;
use std::sync::Arc;

/// u(x, t) = x_0 c(t), β(x, t) = b(t).
fn displacement_coefficient<const D: usize>(t: f64) -> SVector<f64, D> {
    SVector::<f64, D>::from_fn(|i, _| match i {
        0 => 0.1 * (2.0 * t).sin(),
        1 => 0.05 * (1.0 - t.cos()),
        _ => 0.02 * t * t,
    })
}

fn velocity_coefficient<const D: usize>(t: f64) -> SVector<f64, D> {
    SVector::<f64, D>::from_fn(|i, _| match i {
        0 => 0.2 * (2.0 * t).cos(),
        1 => 0.05 * t.sin(),
        _ => 0.04 * t,
    })
}

fn damage(t: f64) -> f64 {
    0.9 - 0.2 * t * t
}

fn damage_rate(t: f64) -> f64 {
    -0.4 * t
}

/// ∇(x_0 c) = c ⊗ e_0.
fn gradient<const D: usize>(c: &SVector<f64, D>) -> Tensor<D> {
    let mut g = Tensor::<D>::zeros();
    for i in 0..D {
        g[(i, 0)] = c[i];
    }
    (g + g.transpose()) * 0.5
}

fn final_error<const D: usize>(mesh: Mesh<D>, steps: usize) -> f64 {
    let model = common::model::<D>();
    let mut data = common::quiet_data::<D>();
    let (viscosity, elasticity, source) = (
        model.viscosity.clone(),
        model.elasticity.clone(),
        model.damage_source.clone(),
    );
    // σ is constant in space: f0 = 0, f2 = σν on Γ2, and on the separated Γ3 the extra traction
    // of docs/model.md §5 is f3 = σν (p_ν = p_τ = 0)
    let traction = Arc::new(move |_x: &[f64; D], t: f64, n: &[f64; D]| {
        let sigma = viscosity.stress(&gradient(&velocity_coefficient::<D>(t)))
            + elasticity.stress(&gradient(&displacement_coefficient::<D>(t)), damage(t));
        let s = sigma * SVector::<f64, D>::from_column_slice(n);
        std::array::from_fn(|i| s[i])
    });
    data.traction = Some(traction.clone());
    data.contact_traction = Some(traction);
    // q = β̇ − κΔβ − φ(ε(u), β) with Δβ = 0
    data.damage_supply = Some(Arc::new(move |_x: &[f64; D], t: f64| {
        damage_rate(t) - source.source(&gradient(&displacement_coefficient::<D>(t)), damage(t))
    }));
    data.initial_damage = Arc::new(|_| damage(0.0));
    // Γ3 exists but the gap keeps it separated: the contact code runs with p_ν = 0
    data.gap = Arc::new(|_, _| 1.0);
    let final_time = 1.0;
    let mut simulation =
        Simulation::new(common::problem(mesh, 1, data, final_time, steps)).unwrap();
    simulation.run(|_| Ok(())).unwrap();
    let state = simulation.state();
    let space = simulation.space();
    let c = displacement_coefficient::<D>(final_time);
    let mut worst: f64 = 0.0;
    for node in 0..space.num_nodes() {
        let x = space.node(node);
        for i in 0..D {
            worst = worst.max((state.displacement[node * D + i] - x[0] * c[i]).abs());
        }
        worst = worst.max((state.damage[node] - damage(final_time)).abs());
    }
    worst
}

fn assert_rate_one<const D: usize>(mesh: impl Fn() -> Mesh<D>) {
    let errors: Vec<f64> = [8, 16, 32, 64]
        .iter()
        .map(|&n| final_error(mesh(), n))
        .collect();
    let rates: Vec<f64> = errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    for rate in &rates[1..] {
        assert!(
            (rate - 1.0).abs() < 0.1,
            "time rates {rates:?} (errors {errors:?}) should approach 1"
        );
    }
}

#[test]
fn scheme_converges_with_rate_one_in_time_2d() {
    use BoundaryPart::*;
    assert_rate_one(|| {
        Mesh::box_mesh(
            [0.0, 0.0],
            [1.0, 1.0],
            [3, 3],
            [[Dirichlet, Neumann], [Contact, Neumann]],
        )
        .unwrap()
    });
}

#[test]
fn scheme_converges_with_rate_one_in_time_3d() {
    use BoundaryPart::*;
    assert_rate_one(|| {
        Mesh::box_mesh(
            [0.0; 3],
            [1.0; 3],
            [2, 2, 2],
            [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]],
        )
        .unwrap()
    });
}
